//! Pin and timer assignments of the wheelcal controller board (STM32F405RG, LQFP64), and
//! the drivers that implement firmware-app's traits on them. Another board is another
//! file like this one behind a feature.
//!
//! | function | peripheral | pins |
//! |---|---|---|
//! | encoder wheel 0..3 (QEI, x4) | TIM3, TIM4, TIM5, TIM8 | PA6/PA7, PB6/PB7, PA0/PA1, PC6/PC7 |
//! | DC PWM or stepper STEP, wheel 0..3 | TIM2 CH1..CH4 | PA5, PB3, PB10, PB11 |
//! | direction, wheel 0..3 | GPIO | PB12, PB13, PB14, PB15 |
//! | driver enable (all wheels) | GPIO, external pull-down | PB2 |
//! | protocol serial | USART2 | TX PA2, RX PA3 |
//! | protocol over USB (CDC-ACM, full speed, no VBUS sensing) | OTG_FS | DM PA11, DP PA12 |
//! | watchdog | IWDG | |
//! | settings storage | internal flash sectors 10-11 | |
//!
//! TIM12 is embassy's time driver. The motor outputs moved from TIM1 (PA8..PA11) to TIM2
//! because the USB device's pins are fixed at PA11/PA12, and TIM1's channel 4 has no other
//! pin on the 64-pin package. The enable line has a pull-down, so after any reset
//! (the watchdog's included) the bridges and stepper drivers are off until the firmware
//! has booted and the control task drives them.
//!
//! TIM2 serves either drive type, chosen at run time from the robot parameters: 20 kHz
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
use embassy_stm32::interrupt::Priority;
use embassy_stm32::pac;
use embassy_stm32::pac::timer::vals::Ocm;
use embassy_stm32::peripherals::{
    PA0, PA1, PA5, PA6, PA7, PB10, PB11, PB3, PB6, PB7, PC6, PC7, TIM2, TIM3, TIM4, TIM5, TIM8,
};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::{OutputCompareMode, RoundTo, Timer};
use embassy_stm32::timer::qei::{Config as QeiConfig, Qei};
use embassy_stm32::timer::simple_pwm::PwmPin;
use embassy_stm32::timer::Channel;
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

/// The motor timer's four output pins, kept alive (dropping them would release the pins).
type MotorPins = (
    PwmPin<'static, TIM2, embassy_stm32::timer::Ch1>,
    PwmPin<'static, TIM2, embassy_stm32::timer::Ch2>,
    PwmPin<'static, TIM2, embassy_stm32::timer::Ch3>,
    PwmPin<'static, TIM2, embassy_stm32::timer::Ch4>,
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
        // TIM5 is 32-bit (Qei writes only the low half of its reload, which stays
        // 0xFFFF_FFFF), but `count()` reads the counter's low 16 bits, and those wrap
        // exactly as the 16-bit timers' counters do.
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

/// Half step periods in 1 MHz ticks per TIM2 channel (0 = not stepping), read by the
/// compare interrupt.
static HALF_PERIOD: [AtomicU16; 4] = [const { AtomicU16::new(0) }; 4];
/// 1 MHz timer ticks.
const STEP_TICK_HZ: u32 = 1_000_000;
/// Fastest step rate (a 25 us half period: 80 k interrupts/s for two wheels at full speed).
const MAX_STEP_HZ: f32 = 20_000.0;
/// Slowest: the 16-bit compare step limits the half period to 65 ms.
const MIN_STEP_HZ: f32 = STEP_TICK_HZ as f32 / 2.0 / 65_535.0;
const PWM_HZ: u32 = 20_000;

/// TIM2's channel for a wheel.
fn channel(wheel: usize) -> Channel {
    [Channel::Ch1, Channel::Ch2, Channel::Ch3, Channel::Ch4][wheel & 3]
}

/// Interrupt priorities. The stepper's compare interrupt is the most urgent: it must
/// re-arm a channel within half a step period (25 us at 20 kHz). The drivers' interrupts
/// (time driver, UART, flash) come next; the control executor is below them at
/// `ceiling::CEILING`, the link and storage tasks in thread mode.
pub fn set_priorities() {
    interrupt::TIM2.set_priority(Priority::P0);
    interrupt::TIM8_BRK_TIM12.set_priority(Priority::P1);
    interrupt::USART2.set_priority(Priority::P2);
    interrupt::FLASH.set_priority(Priority::P2);
    interrupt::OTG_FS.set_priority(Priority::P2);
}

/// Motor outputs: TIM2 channels (PWM or STEP), direction lines and the enable line.
pub struct Motors {
    timer: Timer<'static, TIM2>,
    _pins: MotorPins,
    dir: [Output<'static>; 4],
    enable: Output<'static>,
    mode: Option<DriveType>,
}

impl Motors {
    pub fn new(
        tim: Peri<'static, TIM2>,
        ch1: Peri<'static, PA5>,
        ch2: Peri<'static, PB3>,
        ch3: Peri<'static, PB10>,
        ch4: Peri<'static, PB11>,
        dir: [Output<'static>; 4],
        enable: Output<'static>,
    ) -> Self {
        // TIM2's priority is set once, in `set_priorities`.
        Motors {
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
        }
    }

    /// Sets TIM2 up for the robot's drive type (at boot and when the parameters change).
    pub fn set_mode(&mut self, kind: DriveType) {
        if self.mode == Some(kind) {
            return;
        }
        self.stop_all();
        let t = &mut self.timer;
        t.stop();
        interrupt::TIM2.disable();
        match kind {
            DriveType::Dc => {
                t.set_frequency(Hertz(PWM_HZ), RoundTo::Slower);
                for w in 0..4 {
                    t.set_output_compare_mode(channel(w), OutputCompareMode::PwmMode1);
                    t.set_compare_value(channel(w), 0);
                    t.enable_input_interrupt(channel(w), false);
                }
            }
            DriveType::Stepper => {
                t.set_tick_freq(Hertz(STEP_TICK_HZ));
                // 16-bit wrap like the compare arithmetic below (TIM2 could count 32).
                t.set_max_compare_value(u16::MAX as u32);
                for w in 0..4 {
                    t.set_output_compare_mode(channel(w), OutputCompareMode::ForceInactive);
                }
                interrupt::TIM2.unpend();
                // SAFETY: the handler below only touches TIM2 and HALF_PERIOD.
                unsafe { interrupt::TIM2.enable() };
            }
        }
        for w in 0..4 {
            t.enable_channel(channel(w), true);
        }
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
        // The application never sends a non-finite duty (it faults instead); if one came
        // anyway it must be 0, not full power: `NaN.abs().min(1.0)` is 1.0.
        let duty = if duty.is_finite() { duty } else { 0.0 };
        self.enable.set_high();
        self.direction(wheel, duty >= 0.0);
        let max = self.timer.get_max_compare_value() as f32;
        let d = (duty.abs().min(1.0) * max) as u32;
        self.timer.set_compare_value(channel(wheel), d);
    }

    fn set_steps(&mut self, wheel: usize, steps_per_s: f32, _steps: i32) {
        if wheel >= 4 || self.mode != Some(DriveType::Stepper) {
            return;
        }
        self.enable.set_high();
        self.direction(wheel, steps_per_s >= 0.0);
        let rate = steps_per_s.abs();
        // NaN and infinity fail this range: no stepping.
        if !(MIN_STEP_HZ..=f32::MAX).contains(&rate) {
            HALF_PERIOD[wheel].store(0, Ordering::Relaxed);
            return;
        }
        let half = (STEP_TICK_HZ as f32 / 2.0 / rate.min(MAX_STEP_HZ)) as u16;
        let was = HALF_PERIOD[wheel].swap(half.max(1), Ordering::Relaxed);
        if was == 0 {
            // Start stepping: first edge half a period from now. CCMR and DIER are shared
            // with the compare interrupt, which is not masked while the control task runs:
            // their read-modify-writes are the only code that masks it (a few instructions).
            let t = &self.timer;
            let now = t.regs_core().cnt().read().cnt();
            t.set_compare_value(channel(wheel), now.wrapping_add(half) as u32);
            critical_section::with(|_| {
                t.set_output_compare_mode(channel(wheel), OutputCompareMode::Toggle);
                clear_cc_flag(wheel);
                t.enable_input_interrupt(channel(wheel), true);
            });
        }
    }

    fn stop_all(&mut self) {
        self.enable.set_low();
        let t = &self.timer;
        for (w, half) in HALF_PERIOD.iter().enumerate() {
            half.store(0, Ordering::Relaxed);
            if self.mode == Some(DriveType::Stepper) {
                critical_section::with(|_| {
                    t.enable_input_interrupt(channel(w), false);
                    t.set_output_compare_mode(channel(w), OutputCompareMode::ForceInactive);
                });
            }
            t.set_compare_value(channel(w), 0);
        }
    }
}

/// Clears one compare flag. SR's flags are cleared by writing 0 and kept by writing 1;
/// a read-modify-write (what the HAL's `clear_input_interrupt` does) could clear another
/// channel's flag that rose in between and lose that channel's edge.
fn clear_cc_flag(ch: usize) {
    pac::TIM2.sr().write(|w| {
        w.0 = !0;
        w.set_ccif(ch, false);
    });
}

/// Stepper pulses: each due channel toggles its STEP pin in hardware; here its next
/// toggle is scheduled half a period later, or the channel is parked when stopped.
/// It runs at the most urgent priority, so nothing preempts its read-modify-writes.
/// It uses TIM2's typed register block (the interrupt cannot borrow the `Timer`).
#[interrupt]
fn TIM2() {
    let r = pac::TIM2;
    let sr = r.sr().read();
    let dier = r.dier().read();
    for (ch, half) in HALF_PERIOD.iter().enumerate() {
        // A parked channel's flag also rises (its compare still matches once a wrap); it
        // is left alone, so a channel being started by `set_steps` is not advanced early.
        if !sr.ccif(ch) || !dier.ccie(ch) {
            continue;
        }
        clear_cc_flag(ch);
        let half = half.load(Ordering::Relaxed);
        if half == 0 {
            r.dier().modify(|w| w.set_ccie(ch, false));
            r.ccmr_output(ch / 2)
                .modify(|w| w.set_ocm(ch % 2, Ocm::FORCE_INACTIVE));
        } else {
            // 16-bit arithmetic: the counter wraps at 0xFFFF (set_mode).
            let c = r.ccr(ch).read() as u16;
            r.ccr(ch).write_value(c.wrapping_add(half) as u32);
        }
    }
}

/// Whether the watchdog is still carrying a prescaler or reload write into its clock
/// domain (PVU/RVU): a reload before they clear could use the old values.
pub fn watchdog_updating() -> bool {
    let sr = pac::IWDG.sr().read();
    sr.pvu() || sr.rvu()
}

/// Direction and enable lines, all low (reverse, disabled) at start.
pub fn output(pin: Peri<'static, impl embassy_stm32::gpio::Pin>) -> Output<'static> {
    Output::new(pin, Level::Low, Speed::Low)
}

// Zeroes CCM RAM (the `.ccmram` section: the trial-log ring and its `ConstStaticCell`
// flag) before `main`, as the runtime does for `.bss`: the section is NOLOAD, so without
// this the cell would start with whatever a previous run (or power-up) left there.
// Assembly, because no Rust may run before RAM is initialised.
core::arch::global_asm!(
    ".section .text.__pre_init,\"ax\",%progbits",
    ".global __pre_init",
    ".type __pre_init,%function",
    ".thumb_func",
    "__pre_init:",
    "    ldr r0, =__sccmram",
    "    ldr r1, =__eccmram",
    "    movs r2, #0",
    "1:  cmp r0, r1",
    "    bhs 2f",
    "    str r2, [r0], #4",
    "    b 1b",
    "2:  bx lr",
);
