//! wheelcal firmware for STM32F405 wheel controllers: thin embassy glue around
//! `firmware-app`, which holds all the logic (and runs unchanged in the host's virtual
//! board).
//!
//! Tasks:
//! - `control` (interrupt executor, high priority): the 1 kHz tick and the watchdog;
//! - `serial` and `usb_link` (thread executor): the protocol over USART2 and over USB
//!   CDC-ACM (`/dev/ttyACM*` on Linux), each with its own framing state on the one
//!   application ([`link`]);
//! - `usb_device` (thread executor): the USB device stack;
//! - `storage` (thread executor): settings saves to flash sectors 10-11, asked for by a
//!   link (the handler answers a save only once it is written).
//!
//! They share the application through a priority-ceiling mutex ([`ceiling`]): a link
//! holds it only while one byte is handled (a full answer is encoded then, ~1 KiB at
//! most), and holding it masks only the control executor, never the stepper's compare
//! interrupt, which runs at the most urgent priority.
//!
//! Statics are `StaticCell`s initialised at run time, so nothing large sits in `.data`
//! (an initialiser image in flash) and there is no `static mut`.
#![no_std]
#![no_main]

mod board;
mod ceiling;
mod link;

use calib_core::protocol::Stored;
use ceiling::CeilingRawMutex;
use core::cell::RefCell;
use defmt::{info, unwrap, warn};
use embassy_executor::{InterruptExecutor, Spawner};
use embassy_stm32::flash::{Async, Flash};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::peripherals::{IWDG, USART2, USB_OTG_FS};
use embassy_stm32::usart::{BufferedUart, Config as UartConfig};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{bind_interrupts, flash, usart, usb, Peri};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Instant, Ticker, Timer};
use embassy_usb::class::cdc_acm::{CdcAcmClass, State as CdcState};
use embassy_usb::UsbDevice;
use firmware_app::{App, Store};
use link::{UsbDriver, SAVES};
use static_cell::{ConstStaticCell, StaticCell};
use {defmt_rtt as _, panic_probe as _};

bind_interrupts!(struct Irqs {
    USART2 => usart::BufferedInterruptHandler<USART2>;
    FLASH => flash::InterruptHandler;
    OTG_FS => usb::InterruptHandler<USB_OTG_FS>;
});

/// Trial-log ring: all of CCM RAM but the cell's flag word (the ring takes any length).
/// The section is NOLOAD and zeroed at reset by `__pre_init` (board.rs), so the cell
/// starts as its all-zero initialiser says.
const LOG_BYTES: usize = 64 * 1024 - 4;
#[link_section = ".ccmram"]
static LOG_BUF: ConstStaticCell<[u8; LOG_BYTES]> = ConstStaticCell::new([0; LOG_BYTES]);
static TX_BUF: ConstStaticCell<[u8; 2048]> = ConstStaticCell::new([0; 2048]);
static RX_BUF: ConstStaticCell<[u8; 1024]> = ConstStaticCell::new([0; 1024]);
/// USB: received packets (the OTG FIFO is drained here), descriptors, control transfers.
static USB_EP_OUT: ConstStaticCell<[u8; 256]> = ConstStaticCell::new([0; 256]);
static USB_CONFIG_DESC: ConstStaticCell<[u8; 128]> = ConstStaticCell::new([0; 128]);
static USB_BOS_DESC: ConstStaticCell<[u8; 32]> = ConstStaticCell::new([0; 32]);
static USB_CONTROL: ConstStaticCell<[u8; 64]> = ConstStaticCell::new([0; 64]);
static CDC_STATE: StaticCell<CdcState<'static>> = StaticCell::new();

/// The application, shared by the control task and the link.
type SharedApp = Mutex<CeilingRawMutex, RefCell<App<'static>>>;
static APP: StaticCell<SharedApp> = StaticCell::new();

static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

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
        p.TIM2,
        p.PA5,
        p.PB3,
        p.PB10,
        p.PB11,
        dir,
        board::output(p.PB2),
    );
    motors.set_mode(kind);

    let mut uart_config = UartConfig::default();
    uart_config.baudrate = board::BAUD;
    let (tx_buf, rx_buf) = (TX_BUF.take(), RX_BUF.take());
    let uart =
        unwrap!(BufferedUart::new(p.USART2, p.PA3, p.PA2, tx_buf, rx_buf, Irqs, uart_config).ok());

    // USB full speed on PA11/PA12; no VBUS sensing (PA9 is not wired to VBUS).
    let mut otg = usb::Config::default();
    otg.vbus_detection = false;
    let driver = usb::Driver::new_fs(p.USB_OTG_FS, Irqs, p.PA12, p.PA11, USB_EP_OUT.take(), otg);
    // pid.codes' test VID/PID; Linux binds cdc_acm by class, so it shows as /dev/ttyACM*.
    let mut usb_config = embassy_usb::Config::new(0x1209, 0x0001);
    usb_config.manufacturer = Some("wheelcal");
    usb_config.product = Some("wheelcal wheel controller");
    usb_config.max_power = 100;
    let mut builder = embassy_usb::Builder::new(
        driver,
        usb_config,
        USB_CONFIG_DESC.take(),
        USB_BOS_DESC.take(),
        &mut [],
        USB_CONTROL.take(),
    );
    let cdc = CdcAcmClass::new(
        &mut builder,
        CDC_STATE.init(CdcState::new()),
        link::USB_PACKET as u16,
    );
    let usb = builder.build();

    board::set_priorities();
    interrupt::UART4.set_priority(ceiling::CEILING);
    let high = EXECUTOR_HIGH.start(interrupt::UART4);
    high.spawn(unwrap!(control(app, encoders, motors, p.IWDG)));
    spawner.spawn(unwrap!(storage(flash_store)));
    spawner.spawn(unwrap!(serial(app, uart)));
    spawner.spawn(unwrap!(usb_device(usb)));
    spawner.spawn(unwrap!(usb_link(app, cdc)));
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

/// The protocol over USART2.
#[embassy_executor::task]
async fn serial(app: &'static SharedApp, mut uart: BufferedUart<'static>) {
    link::serve(app, &mut uart, 1).await
}

/// The protocol over USB CDC-ACM.
#[embassy_executor::task]
async fn usb_link(app: &'static SharedApp, cdc: CdcAcmClass<'static, UsbDriver>) {
    link::serve(app, &mut link::UsbPort(cdc), 2).await
}

/// The USB device stack (enumeration, control requests, suspend).
#[embassy_executor::task]
async fn usb_device(mut usb: UsbDevice<'static, UsbDriver>) {
    usb.run().await
}

/// Writes settings to flash. Saves only happen with the motors stopped (the handler
/// refuses them while moving); a sector erase stalls the CPU for up to seconds, so the
/// watchdog is given time for it and set back afterwards.
#[embassy_executor::task]
async fn storage(mut store: Store<Flash<'static, Async>>) {
    loop {
        let item = SAVES.next().await;
        RETIME.signal(board::WATCHDOG_SAVE_US);
        RETIMED.wait().await;
        let ok = store.save(&item).await.is_ok();
        RETIME.signal(board::WATCHDOG_US);
        RETIMED.wait().await;
        if !ok {
            warn!("settings save failed");
        }
        SAVES.finished(ok);
    }
}
