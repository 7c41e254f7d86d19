//! One wheel's drive chain: input -> (dead band, lag) -> motor -> gear with backlash ->
//! wheel angle.
//!
//! Angles are kept in *wheel* radians on both sides of the gear (the motor angle divided
//! by the gear ratio), so an encoder on either shaft reads with the robot file's counts
//! per wheel revolution, and backlash is a wheel-side angle as the catalogue states it.

use crate::effects::{Mechanism, MechanismFaults};
use crate::motor::{DcMotor, DcParams};
use crate::stepper::StepperMotor;
use calib_core::robot::{Drive, DriveType};
use calib_core::stepper::StepAccumulator;
use std::collections::VecDeque;

/// A stalled stepper re-locks once the commanded wheel rate is back under this, rad/s.
const STALL_RELEASE_RAD_S: f64 = 0.2;

/// What the board asks of one wheel during one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum WheelInput {
    /// Ideal wheel rate, rad/s (kinematic tests, recordings). The catalogue's actuator
    /// effects still act on it: dead band, lag, backlash, and on stepper drives with a
    /// pull-out limit the rate goes through a step generator and the stepper model.
    Rate(f64),
    /// DC motor PWM duty in [-1, 1] (clamped).
    Duty(f64),
    /// Stepper: microsteps to issue during this tick (signed).
    Steps(i32),
    /// Motor off: the wheel rolls with the ground and back-drives the motor
    /// ([Redundant omni] turns the actuators of the wheels a path does not use off).
    Free,
}

impl Default for WheelInput {
    fn default() -> Self {
        WheelInput::Rate(0.0)
    }
}

/// The drive chain of one wheel.
#[derive(Debug, Clone)]
pub struct Actuator {
    gear_ratio: f64,
    steps_per_wheel_rad: f64,
    dc: DcMotor,
    stepper: StepperMotor,
    /// Step generator for `Rate` inputs when the stepper model must run (pull-out set).
    step_gen: Option<StepAccumulator>,
    deadband: f64,
    tau: f64,
    /// Lag filter state (rate or duty, whichever input is used).
    lagged: f64,
    backlash: f64,
    motor_angle: f64,
    wheel_angle: f64,
    mech: MechanismFaults,
    /// Transport delay line of the (dead-banded) rate, one entry per tick.
    delay_line: VecDeque<f64>,
    /// Asymmetric backlash: direction of the last motor motion and play still to take up.
    play_dir: f64,
    play_left: f64,
    /// Quanta / stall steppers: previous commanded rate, stalled flag, wheel angle of one
    /// electrical cycle, a small random stream, steps lost (wheel rad).
    prev_cmd: f64,
    stalled: bool,
    cycle_rad: f64,
    max_accel: Option<f64>,
    rng: u64,
    lost_rad: f64,
}

impl Actuator {
    /// The chain for `drive` with the catalogue's actuator effects.
    pub fn new(
        drive: &Drive,
        dc: DcParams,
        deadband_rad_s: f64,
        tau_s: f64,
        backlash_rad: f64,
        max_accel_rad_s2: Option<f64>,
    ) -> Self {
        let spr = drive.steps_per_wheel_rad();
        let stepper_pullout = if drive.kind == DriveType::Stepper {
            max_accel_rad_s2
        } else {
            None
        };
        Actuator {
            gear_ratio: drive.gear_ratio,
            steps_per_wheel_rad: spr,
            dc: DcMotor::new(dc.with_deadband(drive.gear_ratio, deadband_rad_s)),
            stepper: StepperMotor::new(drive.microsteps, stepper_pullout.map(|a| a * spr)),
            step_gen: stepper_pullout.map(|_| StepAccumulator::new(spr)),
            deadband: deadband_rad_s,
            tau: tau_s,
            lagged: 0.0,
            backlash: backlash_rad,
            motor_angle: 0.0,
            wheel_angle: 0.0,
            mech: MechanismFaults::default(),
            delay_line: VecDeque::new(),
            play_dir: 0.0,
            play_left: 0.0,
            prev_cmd: 0.0,
            stalled: false,
            cycle_rad: 4.0 * drive.microsteps.max(1) as f64 / spr.max(1e-12),
            max_accel: stepper_pullout,
            rng: 0,
            lost_rad: 0.0,
        }
    }

    /// Uses the effects' mechanisms; `seed` drives the random step drops.
    pub fn with_mechanisms(mut self, mech: &MechanismFaults, seed: u64) -> Self {
        self.mech = *mech;
        self.rng = seed | 1;
        if matches!(mech.missed, Mechanism::Quanta | Mechanism::Stall) {
            // These mechanisms act on the commanded rate directly, not through the rotor.
            self.step_gen = None;
        }
        self
    }

    /// Uniform draw in [0, 1) (xorshift64*).
    fn uniform(&mut self) -> f64 {
        self.rng ^= self.rng >> 12;
        self.rng ^= self.rng << 25;
        self.rng ^= self.rng >> 27;
        (self.rng.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The lag stage for the mechanism in use.
    fn shape(&mut self, x: f64, dt: f64) -> f64 {
        match self.mech.lag {
            Mechanism::Delay if self.tau > 0.0 => {
                let n = (self.tau / dt).round().max(1.0) as usize;
                self.delay_line.push_back(x);
                while self.delay_line.len() > n + 1 {
                    self.delay_line.pop_front();
                }
                if self.delay_line.len() > n {
                    self.delay_line[0]
                } else {
                    0.0
                }
            }
            Mechanism::Slew => {
                let s = self.mech.slew_rad_s2.unwrap_or(f64::INFINITY) * dt;
                self.lagged += (x - self.lagged).clamp(-s, s);
                self.lagged
            }
            _ => self.lag(x, dt),
        }
    }

    /// Quanta and stall steppers: the wheel travel over one tick at commanded rate `w`.
    fn stepper_mechanism(&mut self, w: f64, dt: f64) -> f64 {
        let accel = (w - self.prev_cmd) / dt;
        self.prev_cmd = w;
        let over = self.max_accel.is_some_and(|a| accel.abs() > a);
        match self.mech.missed {
            Mechanism::Stall => {
                if over && w != 0.0 {
                    self.stalled = true;
                } else if w.abs() < STALL_RELEASE_RAD_S {
                    self.stalled = false;
                }
                if self.stalled {
                    self.lost_rad += w * dt;
                    0.0
                } else {
                    w * dt
                }
            }
            _ => {
                if over && w != 0.0 && self.uniform() < self.mech.missed_rate_hz * dt {
                    // One electrical cycle dropped, against the motion.
                    let q = self.cycle_rad.copysign(w);
                    self.lost_rad += q;
                    w * dt - q
                } else {
                    w * dt
                }
            }
        }
    }

    fn lag(&mut self, x: f64, dt: f64) -> f64 {
        if self.tau > 0.0 {
            self.lagged += (x - self.lagged) * (1.0 - (-dt / self.tau).exp());
        } else {
            self.lagged = x;
        }
        self.lagged
    }

    /// Advances one tick; returns the wheel angle increment (rad).
    pub fn step(&mut self, input: WheelInput, dt: f64) -> f64 {
        let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
        let dm = match input {
            WheelInput::Rate(w) => {
                let w = finite(w);
                let w = if w.abs() < self.deadband { 0.0 } else { w };
                let w = self.shape(w, dt);
                if matches!(self.mech.missed, Mechanism::Quanta | Mechanism::Stall)
                    && self.max_accel.is_some()
                {
                    let dm = self.stepper_mechanism(w, dt);
                    return self.gear(dm);
                }
                match &mut self.step_gen {
                    Some(gen) => {
                        let n = gen.advance(w as f32, dt as f32);
                        self.stepper.step(n, dt, Some(w * self.steps_per_wheel_rad))
                            / self.steps_per_wheel_rad
                    }
                    None => w * dt,
                }
            }
            WheelInput::Duty(d) => {
                let d = self.lag(finite(d), dt);
                self.dc.step(d, dt) / self.gear_ratio
            }
            WheelInput::Steps(n) => self.stepper.step(n, dt, None) / self.steps_per_wheel_rad,
            WheelInput::Free => 0.0,
        };
        self.gear(dm)
    }

    /// Moves the motor by `dm`; the wheel follows through the gear's play. Returns the
    /// wheel's increment.
    fn gear(&mut self, dm: f64) -> f64 {
        self.motor_angle += dm;
        let before = self.wheel_angle;
        if self.mech.backlash == Mechanism::Asymmetric && self.backlash > 0.0 {
            if dm != 0.0 {
                let dir = dm.signum();
                if dir != self.play_dir {
                    // Reversal: the play of the new direction, less what is still open.
                    let a = self.mech.backlash_asymmetry;
                    let b = self.backlash * if dir > 0.0 { 1.0 + a } else { 1.0 - a };
                    self.play_left = (b - self.play_left).max(0.0);
                    self.play_dir = dir;
                }
                let take = self.play_left.min(dm.abs());
                self.play_left -= take;
                self.wheel_angle += dm - take.copysign(dm);
            }
            return self.wheel_angle - before;
        }
        let half = 0.5 * self.backlash;
        let gap = self.motor_angle - self.wheel_angle;
        if gap > half {
            self.wheel_angle = self.motor_angle - half;
        } else if gap < -half {
            self.wheel_angle = self.motor_angle + half;
        }
        self.wheel_angle - before
    }

    /// The ground turned the wheel by `dphi` over `dt` with the motor off: the motor
    /// follows (the gear's play stays where it was).
    pub fn backdrive(&mut self, dphi: f64, dt: f64) {
        self.wheel_angle += dphi;
        self.motor_angle += dphi;
        self.dc.omega = dphi / dt * self.gear_ratio;
        self.lagged = 0.0;
    }

    /// Motor shaft angle in wheel radians (motor angle / gear ratio).
    pub fn motor_angle(&self) -> f64 {
        self.motor_angle
    }

    /// Wheel angle (after the gear's play).
    pub fn wheel_angle(&self) -> f64 {
        self.wheel_angle
    }

    /// Motor speed in wheel rad/s (DC model; for PI tests without encoders).
    pub fn dc_wheel_rate(&self) -> f64 {
        self.dc.omega / self.gear_ratio
    }

    /// Microsteps dropped by the stepper so far.
    pub fn steps_lost(&self) -> i64 {
        self.stepper.lost() + (self.lost_rad * self.steps_per_wheel_rad).round() as i64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn backlash_delays_the_wheel_after_a_reversal() {
        // 0.05 rad of play at 2 rad/s: the wheel waits 25 ms after the motor reverses.
        let drive = Drive::default();
        let mut a = Actuator::new(&drive, DcParams::typical(1.0, 20.0), 0.0, 0.0, 0.05, None);
        let dt = 1e-4;
        for _ in 0..5000 {
            a.step(WheelInput::Rate(2.0), dt);
        }
        let mut still = 0;
        for _ in 0..5000 {
            if a.step(WheelInput::Rate(-2.0), dt) == 0.0 {
                still += 1;
            }
        }
        let delay = still as f64 * dt;
        // One tick of resolution either side.
        assert!((delay - 0.05 / 2.0).abs() <= dt + 1e-12, "delay {delay}");
        // Afterwards the wheel lags the motor by exactly half the play.
        assert!((a.motor_angle() - a.wheel_angle() + 0.025).abs() < 1e-12);
    }

    #[test]
    fn lag_and_dead_band() {
        let drive = Drive::default();
        let mut a = Actuator::new(&drive, DcParams::typical(1.0, 20.0), 0.5, 0.1, 0.0, None);
        assert_eq!(a.step(WheelInput::Rate(0.4), 1e-3), 0.0);
        // First-order lag: after tau the rate is 63.2 % of the step.
        let mut last = 0.0;
        for _ in 0..100 {
            last = a.step(WheelInput::Rate(1.0), 1e-3) / 1e-3;
        }
        assert!((last - (1.0 - (-1.0f64).exp())).abs() < 1e-9, "{last}");
    }

    fn with(mech: MechanismFaults, drive: &Drive, tau: f64, b: f64, a: Option<f64>) -> Actuator {
        Actuator::new(drive, DcParams::typical(1.0, 20.0), 0.0, tau, b, a).with_mechanisms(&mech, 7)
    }

    #[test]
    fn transport_delay_and_slew() {
        let drive = Drive::default();
        let dt = 1e-3;
        // Delay of 50 ms: nothing moves for 50 ticks, then the full rate at once.
        let mech = MechanismFaults {
            lag: Mechanism::Delay,
            ..Default::default()
        };
        let mut a = with(mech, &drive, 0.05, 0.0, None);
        let moved: Vec<f64> = (0..100)
            .map(|_| a.step(WheelInput::Rate(2.0), dt))
            .collect();
        assert!(moved[..50].iter().all(|&m| m == 0.0));
        assert!(moved[50..].iter().all(|&m| (m - 2.0 * dt).abs() < 1e-12));
        // Slew of 20 rad/s^2: a step to 2 rad/s takes 0.1 s, losing 0.5 * 2 * 0.1 = 0.1 rad.
        let mech = MechanismFaults {
            lag: Mechanism::Slew,
            slew_rad_s2: Some(20.0),
            ..Default::default()
        };
        let mut a = with(mech, &drive, 0.0, 0.0, None);
        let total: f64 = (0..1000).map(|_| a.step(WheelInput::Rate(2.0), dt)).sum();
        assert!((2.0 - total - 0.1).abs() < 2.0 * dt * 2.0, "{total}");
    }

    #[test]
    fn asymmetric_backlash_loses_different_play_each_way() {
        // 0.1 rad mean play, asymmetry 0.5: 0.15 rad lost turning forward again, 0.05
        // turning backward.
        let drive = Drive::default();
        let mech = MechanismFaults {
            backlash: Mechanism::Asymmetric,
            backlash_asymmetry: 0.5,
            ..Default::default()
        };
        let mut a = with(mech, &drive, 0.0, 0.1, None);
        let dt = 1e-3;
        let mut run = |w: f64| -> f64 { (0..1000).map(|_| a.step(WheelInput::Rate(w), dt)).sum() };
        run(1.0);
        let back = run(-1.0);
        let fwd = run(1.0);
        assert!((back + 1.0 - 0.05).abs() < 1e-9, "{back}");
        assert!((fwd - 1.0 + 0.15).abs() < 1e-9, "{fwd}");
    }

    #[test]
    fn stepper_quanta_and_stall() {
        // mobolab-like stepper: 200 steps x 16 microsteps, no gear: a cycle is 4/200 rev.
        let drive = Drive {
            kind: DriveType::Stepper,
            microsteps: 16,
            ..Drive::default()
        };
        let cycle = std::f64::consts::TAU * 4.0 / 200.0;
        let dt = 1e-3;
        let mech = MechanismFaults {
            missed: Mechanism::Quanta,
            missed_rate_hz: 20.0,
            ..Default::default()
        };
        let mut a = with(mech, &drive, 0.0, 0.0, Some(10.0));
        // 10 ramps of 0.5 s at 20 rad/s^2 (over the 10 rad/s^2 limit) and back down at 5.
        let mut w: f64 = 0.0;
        let mut total = 0.0;
        let mut ideal = 0.0;
        for _ in 0..10 {
            for k in 0..2500 {
                w = if k < 500 {
                    w + 20.0 * dt
                } else {
                    (w - 5.0 * dt).max(0.0)
                };
                ideal += w * dt;
                total += a.step(WheelInput::Rate(w), dt);
            }
        }
        let lost = ideal - total;
        let n = lost / cycle;
        // Whole cycles, about 20 Hz x 5 s over the limit = 100 (Poisson: 4 sigma = 40).
        assert!((n - n.round()).abs() < 1e-6, "{n}");
        assert!((n - 100.0).abs() < 40.0, "{n}");
        // Stall: over the limit the wheel stops until the command rests again.
        let mech = MechanismFaults {
            missed: Mechanism::Stall,
            ..Default::default()
        };
        let mut a = with(mech, &drive, 0.0, 0.0, Some(10.0));
        let mut w: f64 = 0.0;
        let mut total = 0.0;
        for k in 0..2000 {
            w = if k < 100 {
                w + 20.0 * dt
            } else if k < 1000 {
                w
            } else {
                0.0
            };
            total += a.step(WheelInput::Rate(w), dt);
        }
        // Stalled at the first tick over the limit: nothing moved.
        assert_eq!(total, 0.0);
        // Re-locked after the rest: a ramp at 5 rad/s^2 (within the limit) for 0.2 s
        // moves 5 * 1e-6 * (1 + ... + 200) = 0.1005 rad.
        let after: f64 = (0..200)
            .map(|k| a.step(WheelInput::Rate(5.0 * (k + 1) as f64 * dt), dt))
            .sum();
        assert!(
            (after - 0.1005).abs() < 1e-9,
            "re-locked after rest: {after}"
        );
    }
}
