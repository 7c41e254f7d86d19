//! Pin and timer assignments of the wheelcal controller board (STM32F405RG, LQFP64), and
//! the drivers that implement firmware-app's traits on them. Another board is another
//! file like this one behind a feature.
//!
//! | function | peripheral | pins |
//! |---|---|---|
//! | encoder wheel 0..3 (QEI, x4) | TIM3, TIM4, TIM5, TIM8 | PA6/PA7, PB6/PB7, PA0/PA1, PC6/PC7 |
//! | DC PWM or stepper STEP, wheel 0..3 | TIM1 CH1..CH4 | PA8, PA9, PA10, PA11 |
//! | direction, wheel 0..3 | GPIO | PB12, PB13, PB14, PB15 |
//! | driver enable (all wheels) | GPIO, external pull-down | PB2 |
//! | protocol serial | USART2 | TX PA2, RX PA3 |
//! | watchdog | IWDG | |
//! | settings storage | internal flash sectors 10-11 | |
//!
//! TIM2 is embassy's time driver. The enable line has a pull-down, so after any reset
//! (the watchdog's included) the bridges and stepper drivers are off until the firmware
//! has booted and the control task drives them.
//!
//! TIM1 serves either drive type, chosen at run time from the robot parameters: 20 kHz
//! edge-aligned PWM for DC H-bridges, or free-running at 1 MHz with each channel in
//! output-compare toggle mode for steppers, its compare register advanced by half a step
//! period in the capture/compare interrupt, so four wheels step at independent rates from
//! one timer without any bit-banging.

use calib_core::encoder::CounterWidth;
use calib_core::robot::DriveType;
use core::sync::atomic::{AtomicU16, Ordering};
use embassy_stm32::gpio::{Level, Output, OutputType, Speed};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::InterruptExt;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::Ocm;
use embassy_stm32::peripherals::{
    IWDG, PA0, PA1, PA10, PA11, PA6, PA7, PA8, PA9, PB6, PB7, PC6, PC7, TIM1, TIM3, TIM4, TIM5,
    TIM8,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{RoundTo, Timer};
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::Peri;
use firmware_app::{EncoderSource, WheelDriver};

/// Serial speed of the protocol link.
pub const BAUD: u32 = 115_200;
/// Settings storage: flash offsets of sectors 10 and 11 (0x080C0000..0x08100000).
pub const STORAGE: core::ops::Range<u32> = 0x000C_0000..0x0010_0000;
/// Watchdog while running: a control task stuck for this long resets the board.
pub const WATCHDOG_US: u32 = 50_000;
/// Watchdog during a settings save: erasing a 128 KiB sector stalls the CPU for up to
/// 2 s (4 s worst case), so the timeout is lengthened for the save only, with the motors
/// off.
pub const WATCHDOG_SAVE_US: u32 = 8_000_000;

/// Clock tree: 8 MHz crystal, 168 MHz core, APB1 42 MHz (timers 84), APB2 84 MHz
/// (timers 168).
pub fn config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::*;
    let mut c = embassy_stm32::Config::default();
    c.rcc.hse = Some(Hse {
        freq: Hertz(8_000_000),
        mode: HseMode::Oscillator,
    });
    c.rcc.pll_src = PllSource::HSE;
    c.rcc.pll = Some(Pll {
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL168,
        divp: Some(PllPDiv::DIV2),
        divq: Some(PllQDiv::DIV7),
        divr: None,
    });
    c.rcc.ahb_pre = AHBPrescaler::DIV1;
    c.rcc.apb1_pre = APBPrescaler::DIV4;
    c.rcc.apb2_pre = APBPrescaler::DIV2;
    c.rcc.sys = Sysclk::PLL1_P;
    c
}

/// A timer and the two pins of its encoder.
pub type QeiPins<T, A, B> = (Peri<'static, T>, Peri<'static, A>, Peri<'static, B>);

/// TIM1's four output pins, kept alive (dropping them would release the pins).
type Tim1Pins = (
    PwmPin<'static, TIM1, embassy_stm32::timer::Ch1>,
    PwmPin<'static, TIM1, embassy_stm32::timer::Ch2>,
    PwmPin<'static, TIM1, embassy_stm32::timer::Ch3>,
    PwmPin<'static, TIM1, embassy_stm32::timer::Ch4>,
);

/// The four quadrature counters.
pub struct Encoders {
    pub e0: Qei<'static, TIM3>,
    pub e1: Qei<'static, TIM4>,
    pub e2: Qei<'static, TIM5>,
    pub e3: Qei<'static, TIM8>,
}

impl Encoders {
    /// Each argument is a timer and its channel 1 and 2 pins.
    pub fn new(
        (t3, a3, b3): QeiPins<TIM3, PA6, PA7>,
        (t4, a4, b4): QeiPins<TIM4, PB6, PB7>,
        (t5, a5, b5): QeiPins<TIM5, PA0, PA1>,
        (t8, a8, b8): QeiPins<TIM8, PC6, PC7>,
    ) -> Self {
        let c = QeiConfig::default();
        Encoders {
            e0: Qei::new(t3, a3, b3, c),
            e1: Qei::new(t4, a4, b4, c),
            e2: Qei::new(t5, a5, b5, c),
            e3: Qei::new(t8, a8, b8, c),
        }
    }
}

impl EncoderSource for Encoders {
    fn width(&self) -> CounterWidth {
        // TIM5 is 32-bit but runs with a 16-bit reload like the others.
        CounterWidth::Bits16
    }

    fn raw(&mut self, wheel: usize) -> u32 {
        match wheel {
            0 => self.e0.count() as u32,
            1 => self.e1.count() as u32,
            2 => self.e2.count() as u32,
            3 => self.e3.count() as u32,
            _ => 0,
        }
    }
}

/// Half step periods in 1 MHz ticks per TIM1 channel (0 = not stepping), read by the
/// compare interrupt.
static HALF_PERIOD: [AtomicU16; 4] = [const { AtomicU16::new(0) }; 4];
/// 1 MHz timer ticks.
const STEP_TICK_HZ: u32 = 1_000_000;
/// Fastest step rate (a 25 us half period: 80 k interrupts/s for two wheels at full speed).
const MAX_STEP_HZ: f32 = 20_000.0;
/// Slowest: the 16-bit compare step limits the half period to 65 ms.
const MIN_STEP_HZ: f32 = STEP_TICK_HZ as f32 / 2.0 / 65_535.0;
const PWM_HZ: u32 = 20_000;

fn tim1() -> pac::timer::TimGp16 {
    // SAFETY: TIM1's registers are a superset of the general-purpose 16-bit layout; the
    // timer is owned by `Motors` and only touched from its methods and the CC interrupt.
    unsafe { pac::timer::TimGp16::from_ptr(pac::TIM1.as_ptr()) }
}

/// Motor outputs: TIM1 channels (PWM or STEP), direction lines and the enable line.
pub struct Motors {
    timer: Timer<'static, TIM1>,
    _pins: Tim1Pins,
    dir: [Output<'static>; 4],
    enable: Output<'static>,
    mode: Option<DriveType>,
}

impl Motors {
    pub fn new(
        tim: Peri<'static, TIM1>,
        ch1: Peri<'static, PA8>,
        ch2: Peri<'static, PA9>,
        ch3: Peri<'static, PA10>,
        ch4: Peri<'static, PA11>,
        dir: [Output<'static>; 4],
        enable: Output<'static>,
    ) -> Self {
        let m = Motors {
            timer: Timer::new(tim),
            _pins: (
                PwmPin::new(ch1, OutputType::PushPull),
                PwmPin::new(ch2, OutputType::PushPull),
                PwmPin::new(ch3, OutputType::PushPull),
                PwmPin::new(ch4, OutputType::PushPull),
            ),
            dir,
            enable,
            mode: None,
        };
        interrupt::TIM1_CC.set_priority(interrupt::Priority::P1);
        m
    }

    /// Sets TIM1 up for the robot's drive type (at boot and when the parameters change).
    pub fn set_mode(&mut self, kind: DriveType) {
        if self.mode == Some(kind) {
            return;
        }
        self.stop_all();
        let r = tim1();
        self.timer.stop();
        match kind {
            DriveType::Dc => {
                interrupt::TIM1_CC.disable();
                self.timer.set_frequency(Hertz(PWM_HZ), RoundTo::Slower);
                for ch in 0..4 {
                    r.ccmr_output(ch / 2)
                        .modify(|w| w.set_ocm(ch % 2, Ocm::PWM_MODE1));
                    r.ccr(ch).write(|w| w.set_ccr(0));
                    r.dier().modify(|w| w.set_ccie(ch, false));
                }
            }
            DriveType::Stepper => {
                self.timer.set_tick_freq(Hertz(STEP_TICK_HZ));
                r.arr().write(|w| w.set_arr(u16::MAX));
                for ch in 0..4 {
                    r.ccmr_output(ch / 2)
                        .modify(|w| w.set_ocm(ch % 2, Ocm::FORCE_INACTIVE));
                }
                interrupt::TIM1_CC.unpend();
                // SAFETY: the handler below only touches TIM1 and HALF_PERIOD.
                unsafe { interrupt::TIM1_CC.enable() };
            }
        }
        r.ccer().modify(|w| {
            for ch in 0..4 {
                w.set_cce(ch, true);
            }
        });
        self.timer.enable_outputs();
        self.timer.generate_update_event();
        self.timer.start();
        self.mode = Some(kind);
    }

    fn direction(&mut self, wheel: usize, forward: bool) {
        if let Some(d) = self.dir.get_mut(wheel) {
            d.set_level(if forward { Level::High } else { Level::Low });
        }
    }
}

impl WheelDriver for Motors {
    fn set_duty(&mut self, wheel: usize, duty: f32) {
        if wheel >= 4 || self.mode != Some(DriveType::Dc) {
            return;
        }
        self.enable.set_high();
        self.direction(wheel, duty >= 0.0);
        let r = tim1();
        let max = r.arr().read().arr() as f32;
        let d = (duty.abs().min(1.0) * max) as u16;
        r.ccr(wheel).write(|w| w.set_ccr(d));
    }

    fn set_steps(&mut self, wheel: usize, steps_per_s: f32, _steps: i32) {
        if wheel >= 4 || self.mode != Some(DriveType::Stepper) {
            return;
        }
        self.enable.set_high();
        self.direction(wheel, steps_per_s >= 0.0);
        let rate = steps_per_s.abs();
        let r = tim1();
        if !(MIN_STEP_HZ..=f32::MAX).contains(&rate) {
            HALF_PERIOD[wheel].store(0, Ordering::Relaxed);
            return;
        }
        let half = (STEP_TICK_HZ as f32 / 2.0 / rate.min(MAX_STEP_HZ)) as u16;
        let was = HALF_PERIOD[wheel].swap(half.max(1), Ordering::Relaxed);
        if was == 0 {
            // Start stepping: first edge half a period from now.
            let now = r.cnt().read().cnt();
            r.ccr(wheel).write(|w| w.set_ccr(now.wrapping_add(half)));
            r.ccmr_output(wheel / 2)
                .modify(|w| w.set_ocm(wheel % 2, Ocm::TOGGLE));
            r.sr().write(|w| {
                w.0 = !0;
                w.set_ccif(wheel, false);
            });
            r.dier().modify(|w| w.set_ccie(wheel, true));
        }
    }

    fn stop_all(&mut self) {
        self.enable.set_low();
        let r = tim1();
        for (ch, half) in HALF_PERIOD.iter().enumerate() {
            half.store(0, Ordering::Relaxed);
            r.ccr(ch).write(|w| w.set_ccr(0));
            if self.mode == Some(DriveType::Stepper) {
                r.dier().modify(|w| w.set_ccie(ch, false));
                r.ccmr_output(ch / 2)
                    .modify(|w| w.set_ocm(ch % 2, Ocm::FORCE_INACTIVE));
            }
        }
    }
}

/// Stepper pulses: each due channel toggles its STEP pin in hardware; here its next
/// toggle is scheduled half a period later, or the channel is parked when stopped.
#[interrupt]
fn TIM1_CC() {
    let r = tim1();
    let sr = r.sr().read();
    for (ch, half) in HALF_PERIOD.iter().enumerate() {
        if !sr.ccif(ch) {
            continue;
        }
        r.sr().write(|w| {
            w.0 = !0;
            w.set_ccif(ch, false);
        });
        let half = half.load(Ordering::Relaxed);
        if half == 0 {
            r.dier().modify(|w| w.set_ccie(ch, false));
            r.ccmr_output(ch / 2)
                .modify(|w| w.set_ocm(ch % 2, Ocm::FORCE_INACTIVE));
        } else {
            let c = r.ccr(ch).read().ccr();
            r.ccr(ch).write(|w| w.set_ccr(c.wrapping_add(half)));
        }
    }
}

/// The independent watchdog, petted by the control task.
pub struct Watchdog {
    iwdg: Peri<'static, IWDG>,
}

impl Watchdog {
    pub fn start(iwdg: Peri<'static, IWDG>) -> Self {
        let mut w = Watchdog { iwdg };
        IndependentWatchdog::new(w.iwdg.reborrow(), WATCHDOG_US).unleash();
        w
    }

    pub fn pet(&mut self) {
        pac::IWDG
            .kr()
            .write(|w| w.set_key(pac::iwdg::vals::Key::RESET));
    }

    /// Changes the timeout of the running watchdog (and pets it). The prescaler and
    /// reload registers ignore writes while a previous update is still being carried into
    /// the watchdog's clock domain, so wait for that first (a few LSI periods).
    pub fn set_timeout(&mut self, us: u32) {
        self.pet();
        for _ in 0..1_000_000 {
            let sr = pac::IWDG.sr().read();
            if !sr.pvu() && !sr.rvu() {
                break;
            }
        }
        let _ = IndependentWatchdog::new(self.iwdg.reborrow(), us);
        self.pet();
    }
}

/// Direction and enable lines, all low (reverse, disabled) at start.
pub fn output(pin: Peri<'static, impl embassy_stm32::gpio::Pin>) -> Output<'static> {
    Output::new(pin, Level::Low, Speed::Low)
}
