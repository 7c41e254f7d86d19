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
//! Both share the application through a critical-section mutex; the serial side holds it
//! only while one byte is handled (a full answer is encoded then, ~1 KiB at most).
#![no_std]
#![no_main]

mod board;

use calib_core::protocol::Stored;
use core::cell::RefCell;
use defmt::{info, unwrap, warn};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_futures::select::{select, Either};
use embassy_stm32::flash::{Async, Flash};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::peripherals::USART2;
use embassy_stm32::usart::{BufferedUart, Config as UartConfig};
use embassy_stm32::{bind_interrupts, flash, usart};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use embedded_io_async::{Read, Write};
use firmware_app::{App, PersistItem, Server, Step, Store};
use {defmt_rtt as _, panic_probe as _};

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<USART2>;
    FLASH => flash::InterruptHandler;
});

/// Trial-log ring: all of CCM RAM.
const LOG_BYTES: usize = 64 * 1024;
#[link_section = ".ccmram"]
static mut LOG_BUF: [u8; LOG_BYTES] = [0; LOG_BYTES];

type Shared<T> = Mutex<CriticalSectionRawMutex, RefCell<Option<T>>>;
static APP: Shared<App<'static>> = Mutex::new(RefCell::new(None));
static WATCHDOG: Shared<board::Watchdog> = Mutex::new(RefCell::new(None));

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
    // SAFETY: the only reference to LOG_BUF, taken once before any task runs. It lives in
    // NOLOAD CCM RAM, so it is cleared here.
    let log: &'static mut [u8; LOG_BYTES] = unsafe { &mut *core::ptr::addr_of_mut!(LOG_BUF) };
    log.fill(0);
    let app = App::new(
        loaded.params,
        loaded.corrections,
        loaded.boot,
        log,
        now_us(),
    );
    let kind = app.params().robot.drive.kind;
    APP.lock(|a| a.replace(Some(app)));

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
    static mut TX_BUF: [u8; 2048] = [0; 2048];
    static mut RX_BUF: [u8; 1024] = [0; 1024];
    // SAFETY: the only references to these buffers, taken once here.
    let (tx_buf, rx_buf) = unsafe {
        (
            &mut *core::ptr::addr_of_mut!(TX_BUF),
            &mut *core::ptr::addr_of_mut!(RX_BUF),
        )
    };
    let uart =
        unwrap!(BufferedUart::new(p.USART2, p.PA3, p.PA2, tx_buf, rx_buf, Irqs, uart_config).ok());

    WATCHDOG.lock(|w| w.replace(Some(board::Watchdog::start(p.IWDG))));

    interrupt::UART4.set_priority(Priority::P6);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    high.spawn(unwrap!(control(encoders, motors)));
    spawner.spawn(unwrap!(storage(flash_store)));
    spawner.spawn(unwrap!(serial(uart)));
}

/// The 1 kHz control tick; pets the watchdog after each tick.
#[embassy_executor::task]
async fn control(mut encoders: board::Encoders, mut motors: board::Motors) {
    let mut ticker = Ticker::every(Duration::from_hz(firmware_app::TICK_HZ as u64));
    loop {
        ticker.next().await;
        let now = now_us();
        APP.lock(|a| {
            if let Some(app) = a.borrow_mut().as_mut() {
                motors.set_mode(app.params().robot.drive.kind);
                app.tick(now, &mut encoders, &mut motors);
            }
        });
        WATCHDOG.lock(|w| {
            if let Some(w) = w.borrow_mut().as_mut() {
                w.pet();
            }
        });
    }
}

/// Runs `f` on the application (always present once the tasks run).
fn with_app<R>(f: impl FnOnce(&mut App<'static>) -> R) -> Option<R> {
    APP.lock(|a| a.borrow_mut().as_mut().map(f))
}

/// The protocol link: request handler, telemetry, settings saves.
#[embassy_executor::task]
async fn serial(mut uart: BufferedUart<'static>) {
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
            let step = APP.lock(|a| match a.borrow_mut().as_mut() {
                Some(app) => match server.push(b, app, now) {
                    Step::Idle => None,
                    Step::Send(w) => Some(Ok(w.len())),
                    Step::Persist { seq, item } => Some(Err((seq, item))),
                },
                None => None,
            });
            match step {
                None => {}
                Some(Ok(len)) => {
                    let _ = uart.write_all(server.last_frame(len)).await;
                }
                Some(Err((seq, item))) => {
                    SAVE.send(item).await;
                    let ok = SAVED.wait().await;
                    let r = with_app(|app| app.persisted(ok));
                    if let Some(r) = r {
                        let _ = uart.write_all(server.reply(seq, &r)).await;
                    }
                }
            }
        }
        let tele = APP.lock(|a| match a.borrow_mut().as_mut() {
            Some(app) => server.telemetry(app).map(|t| t.len()),
            None => None,
        });
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
        WATCHDOG.lock(|w| {
            if let Some(w) = w.borrow_mut().as_mut() {
                w.set_timeout(board::WATCHDOG_SAVE_US);
            }
        });
        let ok = store.save(&item).await.is_ok();
        WATCHDOG.lock(|w| {
            if let Some(w) = w.borrow_mut().as_mut() {
                w.set_timeout(board::WATCHDOG_US);
            }
        });
        if !ok {
            warn!("settings save failed");
        }
        SAVED.signal(ok);
    }
}
