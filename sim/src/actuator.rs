//! One wheel's drive chain: input -> (dead band, lag) -> motor -> gear with backlash ->
//! wheel angle.
//!
//! Angles are kept in *wheel* radians on both sides of the gear (the motor angle divided
//! by the gear ratio), so an encoder on either shaft reads with the robot file's counts
//! per wheel revolution, and backlash is a wheel-side angle as the catalogue states it.

use crate::motor::{DcMotor, DcParams};
use crate::stepper::StepperMotor;
use calib_core::robot::{Drive, DriveType};
use calib_core::stepper::StepAccumulator;

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
    /// Motor off: the wheel rolls with the ground and back-drives the motor (001 turns
    /// the actuators of the wheels a path does not use off).
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
                let w = self.lag(w, dt);
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
        self.motor_angle += dm;
        let before = self.wheel_angle;
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
        self.stepper.lost()
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
}
