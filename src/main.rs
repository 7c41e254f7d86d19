//! wheelcal firmware for STM32F405 wheel controllers: thin embassy glue around
//! `firmware-app`, which holds all the logic (and runs unchanged in the host's virtual
//! board).
//!
//! Tasks:
//! - `control` (interrupt executor, high priority): the 1 kHz tick and the watchdog;
//! - `serial` (thread executor): bytes from USART2 through the request handler, answers
//!   and telemetry back;
//! - `storage` (thread executor): settings saves to flash sectors 10-11, asked for by
//!   `serial` (the handler answers a save only once it is written).
//!
//! Both share the application through a priority-ceiling mutex ([`ceiling`]): the serial
//! side holds it only while one byte is handled (a full answer is encoded then, ~1 KiB at
//! most), and holding it masks only the control executor, never the stepper's TIM1_CC
//! interrupt, which runs at the most urgent priority.
//!
//! Statics are `StaticCell`s initialised at run time, so nothing large sits in `.data`
//! (an initialiser image in flash) and there is no `static mut`.
#![no_std]
#![no_main]

mod board;
mod ceiling;

use calib_core::protocol::Stored;
use ceiling::CeilingRawMutex;
use core::cell::RefCell;
use defmt::{info, unwrap, warn};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::flash::{Async, Flash};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::peripherals::{IWDG, USART2};
use embassy_stm32::usart::{BufferedUart, Config as UartConfig};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, flash, usart, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use embedded_io_async::{Read, Write};
use firmware_app::{App, PersistItem, Server, Step, Store};
use static_cell::{ConstStaticCell, StaticCell};
use {defmt_rtt as _, panic_probe as _};

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<USART2>;
    FLASH => flash::InterruptHandler;
});

/// Trial-log ring: all of CCM RAM but the cell's flag word (the ring takes any length).
/// The section is NOLOAD and zeroed at reset by `__pre_init` (board.rs), so the cell
/// starts as its all-zero initialiser says.
const LOG_BYTES: usize = 64 * 1024 - 4;
#[link_section = ".ccmram"]
static LOG_BUF: ConstStaticCell<[u8; LOG_BYTES]> = ConstStaticCell::new([0; LOG_BYTES]);
static TX_BUF: ConstStaticCell<[u8; 2048]> = ConstStaticCell::new([0; 2048]);
static RX_BUF: ConstStaticCell<[u8; 1024]> = ConstStaticCell::new([0; 1024]);

/// The application, shared by the control task and the link.
type SharedApp = Mutex<CeilingRawMutex, RefCell<App<'static>>>;
static APP: StaticCell<SharedApp> = StaticCell::new();

static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

/// Saves asked for by the request handler, and whether each worked.
static SAVE: Channel<CriticalSectionRawMutex, PersistItem, 1> = Channel::new();
static SAVED: Signal<CriticalSectionRawMutex, bool> = Signal::new();

#[interrupt]
unsafe fn UART4() {
    // UART4 is unused: its vector runs the high-priority executor.
    // SAFETY: only this vector drives EXECUTOR_HIGH.
    unsafe { EXECUTOR_HIGH.on_interrupt() }
}

fn now_us() -> u64 {
    Instant::now().as_micros()
}

#[embassy_executor::main]
async fn main(spawner: Spawner) {
    let p = embassy_stm32::init(board::config());
    info!("{}", firmware_app::FIRMWARE_VERSION);

    let mut flash_store = unwrap!(Store::new(Flash::new(p.FLASH, Irqs), board::STORAGE).ok());
    let loaded = flash_store.load().await;
    if loaded.boot.params != Stored::Loaded || loaded.boot.corrections != Stored::Loaded {
        warn!(
            "settings: params {}, corrections {}: defaults in use where not loaded",
            loaded.boot.params, loaded.boot.corrections
        );
    }
    let log = LOG_BUF.take();
    let app = App::new(
        loaded.params,
        loaded.corrections,
        loaded.boot,
        log,
        now_us(),
    );
    let kind = app.params().robot.drive.kind;
    let app: &'static SharedApp = APP.init(Mutex::new(RefCell::new(app)));

    let encoders = board::Encoders::new(
        (p.TIM3, p.PA6, p.PA7),
        (p.TIM4, p.PB6, p.PB7),
        (p.TIM5, p.PA0, p.PA1),
        (p.TIM8, p.PC6, p.PC7),
    );
    let dir = [
        board::output(p.PB12),
        board::output(p.PB13),
        board::output(p.PB14),
        board::output(p.PB15),
    ];
    let mut motors = board::Motors::new(
        p.TIM1,
        p.PA8,
        p.PA9,
        p.PA10,
        p.PA11,
        dir,
        board::output(p.PB2),
    );
    motors.set_mode(kind);

    let mut uart_config = UartConfig::default();
    uart_config.baudrate = board::BAUD;
    let (tx_buf, rx_buf) = (TX_BUF.take(), RX_BUF.take());
    let uart =
        unwrap!(BufferedUart::new(p.USART2, p.PA3, p.PA2, tx_buf, rx_buf, Irqs, uart_config).ok());

    board::set_priorities();
    interrupt::UART4.set_priority(ceiling::CEILING);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    high.spawn(unwrap!(control(app, encoders, motors, p.IWDG)));
    spawner.spawn(unwrap!(storage(flash_store)));
    spawner.spawn(unwrap!(serial(app, uart)));
}

/// Watchdog timeout asked for by the storage task, applied by the control task (which
/// owns the watchdog), and its acknowledgement once the watchdog runs with it.
static RETIME: Signal<CriticalSectionRawMutex, u32> = Signal::new();
static RETIMED: Signal<CriticalSectionRawMutex, ()> = Signal::new();

/// The 1 kHz control tick; owns the watchdog and pets it after each tick.
#[embassy_executor::task]
async fn control(
    app: &'static SharedApp,
    mut encoders: board::Encoders,
    mut motors: board::Motors,
    mut iwdg: Peri<'static, IWDG>,
) {
    let mut dog = IndependentWatchdog::new(iwdg.reborrow(), board::WATCHDOG_US);
    dog.unleash();
    let mut ticker = Ticker::every(Duration::from_hz(firmware_app::TICK_HZ as u64));
    loop {
        ticker.next().await;
        let now = now_us();
        app.lock(|a| {
            let mut a = a.borrow_mut();
            motors.set_mode(a.params().robot.drive.kind);
            a.tick(now, &mut encoders, &mut motors);
        });
        dog.pet();
        if let Some(us) = RETIME.try_take() {
            // ST's order: write prescaler and reload, wait until the watchdog's clock
            // domain has taken both (PVU/RVU clear, a few LSI periods), then reload, so
            // the reload uses the new values. Ticks pause meanwhile (the motors are off:
            // saves are refused while moving); the old timeout, just petted, covers it.
            dog = IndependentWatchdog::new(iwdg.reborrow(), us);
            while board::watchdog_updating() {
                Timer::after_micros(100).await;
            }
            dog.pet();
            RETIMED.signal(());
        }
    }
}

/// Runs `f` on the application.
fn with_app<R>(app: &SharedApp, f: impl FnOnce(&mut App<'static>) -> R) -> R {
    app.lock(|a| f(&mut a.borrow_mut()))
}

/// The protocol link: request handler, telemetry, settings saves.
#[embassy_executor::task]
async fn serial(app: &'static SharedApp, mut uart: BufferedUart<'static>) {
    let mut server = Server::new();
    let mut buf = [0u8; 64];
    loop {
        // Wake at least every 10 ms for telemetry.
        let n = match select(uart.read(&mut buf), Timer::after_millis(10)).await {
            Either::First(Ok(n)) => n,
            Either::First(Err(_)) => 0, // framing/overrun: the decoder resynchronises
            Either::Second(()) => 0,
        };
        for &b in &buf[..n] {
            let now = now_us();
            let step = with_app(app, |a| match server.push(b, a, now) {
                Step::Idle => None,
                Step::Send(w) => Some(Ok(w.len())),
                Step::Persist { seq, item } => Some(Err((seq, item))),
            });
            match step {
                None => {}
                Some(Ok(len)) => {
                    let _ = uart.write_all(server.last_frame(len)).await;
                }
                Some(Err((seq, item))) => {
                    SAVE.send(item).await;
                    let ok = SAVED.wait().await;
                    let r = with_app(app, |a| a.persisted(ok));
                    let _ = uart.write_all(server.reply(seq, &r)).await;
                }
            }
        }
        let tele = with_app(app, |a| server.telemetry(a).map(|t| t.len()));
        if let Some(len) = tele {
            let _ = uart.write_all(server.last_telemetry(len)).await;
        }
    }
}

/// Writes settings to flash. Saves only happen with the motors stopped (the handler
/// refuses them while moving); a sector erase stalls the CPU for up to seconds, so the
/// watchdog is given time for it and set back afterwards.
#[embassy_executor::task]
async fn storage(mut store: Store<Flash<'static, Async>>) {
    loop {
        let item = SAVE.receive().await;
        RETIME.signal(board::WATCHDOG_SAVE_US);
        RETIMED.wait().await;
        let ok = store.save(&item).await.is_ok();
        RETIME.signal(board::WATCHDOG_US);
        RETIMED.wait().await;
        if !ok {
            warn!("settings save failed");
        }
        SAVED.signal(ok);
    }
}
