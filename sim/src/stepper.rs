//! Stepper motor with pull-out: the rotor follows the commanded (micro)step position
//! exactly while it can, and loses synchronism when the demanded acceleration exceeds
//! what its torque allows.
//!
//! Model: the rotor's acceleration is bounded by `max_accel` (the pull-out torque over the
//! load inertia, expressed as a wheel acceleration). The magnetic field pulls the rotor
//! towards the commanded position; when the rotor falls more than two full steps behind
//! (or ahead), it has passed the unstable equilibrium and re-locks one electrical cycle,
//! four full steps of a two-phase motor, away. Steps are therefore dropped in multiples
//! of four full steps, as real steppers do.
//!
//! The commanded rate the rotor is asked to follow is the step train smoothed over 20 ms
//! (or the exact rate when the caller knows it): a pulse train quantised to 1 ms ticks
//! jitters by a whole step per tick, which a real rotor filters out mechanically and which
//! must not count as acceleration.

/// Time constant with which the field pulls the rotor onto the commanded position.
const TAU_SYNC_S: f64 = 0.005;
/// Smoothing of the step train into a commanded rate.
const TAU_RATE_S: f64 = 0.02;

/// One stepper motor's state, positions in microsteps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepperMotor {
    microsteps: f64,
    /// Pull-out limit in microsteps/s^2 (None: the rotor follows every step).
    max_accel: Option<f64>,
    commanded: i64,
    /// Microsteps lost (multiples of 4 full steps, signed: positive = rotor behind).
    lost: i64,
    rotor: f64,
    rate: f64,
    cmd_rate: f64,
}

impl StepperMotor {
    /// `microsteps` per full step; `max_accel_usteps_s2` from the pull-out limit.
    pub fn new(microsteps: u32, max_accel_usteps_s2: Option<f64>) -> Self {
        StepperMotor {
            microsteps: microsteps.max(1) as f64,
            max_accel: max_accel_usteps_s2,
            commanded: 0,
            lost: 0,
            rotor: 0.0,
            rate: 0.0,
            cmd_rate: 0.0,
        }
    }

    /// Applies `steps` commanded microsteps over `dt`; returns the rotor movement in
    /// microsteps. `rate_hint`: the exact commanded rate in microsteps/s when known.
    pub fn step(&mut self, steps: i32, dt: f64, rate_hint: Option<f64>) -> f64 {
        // Position error at the start of the tick: the rate below then moves the rotor
        // with the command over the tick.
        let e = (self.commanded - self.lost) as f64 - self.rotor;
        self.commanded += steps as i64;
        let before = self.rotor;
        let Some(a_max) = self.max_accel else {
            self.rotor = self.commanded as f64;
            return self.rotor - before;
        };
        self.cmd_rate = match rate_hint {
            Some(r) => r,
            None => {
                let k = 1.0 - (-dt / TAU_RATE_S).exp();
                self.cmd_rate + (steps as f64 / dt - self.cmd_rate) * k
            }
        };
        let cmd_rate = self.cmd_rate;
        // Pull towards the target, no faster than the rotor could still stop in time.
        let pull = (e.abs() / TAU_SYNC_S).min((2.0 * a_max * e.abs()).sqrt());
        let want = cmd_rate + pull.copysign(e);
        let dv = (want - self.rate).clamp(-a_max * dt, a_max * dt);
        self.rate += dv;
        self.rotor += self.rate * dt;
        let cycle = 4.0 * self.microsteps;
        loop {
            let e = (self.commanded - self.lost) as f64 - self.rotor;
            if e > 0.5 * cycle {
                self.lost += cycle as i64;
            } else if e < -0.5 * cycle {
                self.lost -= cycle as i64;
            } else {
                break;
            }
        }
        self.rotor - before
    }

    /// Microsteps commanded so far.
    pub fn commanded(&self) -> i64 {
        self.commanded
    }

    /// Microsteps lost to pull-out (multiples of four full steps).
    pub fn lost(&self) -> i64 {
        self.lost
    }

    /// Rotor position, microsteps.
    pub fn rotor(&self) -> f64 {
        self.rotor
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::stepper::StepAccumulator;

    /// Drives a trapezoid of step rates (usteps/s) through a step generator: up at
    /// `a_up`, hold, down at 10000 usteps/s^2 (within every limit used), then rest.
    fn drive(m: &mut StepperMotor, peak: f64, a_up: f64) {
        let mut acc = StepAccumulator::new(1.0);
        let dt = 1e-3;
        let mut rate = 0.0f64;
        for k in 0..3000 {
            rate = if k < 1500 {
                (rate + a_up * dt).min(peak)
            } else {
                (rate - 10000.0 * dt).max(0.0)
            };
            let n = acc.advance(rate as f32, dt as f32);
            m.step(n, dt, None);
        }
        for _ in 0..1000 {
            m.step(0, dt, None);
        }
    }

    #[test]
    fn follows_exactly_within_the_limit() {
        // 2000 usteps/s reached at 10000 usteps/s^2 against a limit of 20000.
        let mut m = StepperMotor::new(1, Some(20000.0));
        drive(&mut m, 2000.0, 10000.0);
        assert_eq!(m.lost(), 0);
        // At rest the pull-in has decayed as exp(-t / 5 ms) for 1 s: nothing is left.
        assert!((m.rotor() - m.commanded() as f64).abs() < 1e-6);
    }

    #[test]
    fn pull_out_drops_multiples_of_four_full_steps() {
        // 8 microsteps; command 20000 usteps/s^2 towards 8000 usteps/s against a limit of
        // 2000 usteps/s^2 (the step train is smoothed over 20 ms, so the rotor is asked for
        // ~1e4, still 5x too much): the rotor slips until it reaches speed.
        let mut m = StepperMotor::new(8, Some(2000.0 * 5.0));
        drive(&mut m, 8000.0, 1e6);
        let missing = m.commanded() as f64 - m.rotor();
        assert!(m.lost() > 0);
        // Whole electrical cycles: 4 full steps = 32 microsteps.
        assert_eq!(m.lost() % 32, 0);
        assert!(
            (missing - m.lost() as f64).abs() < 1e-6,
            "{missing} vs {}",
            m.lost()
        );
        // Size: at 1e4 usteps/s^2 the rotor needs 0.8 s to reach 8000 usteps/s and covers
        // 3200 usteps meanwhile; the command (a near step in rate) covers ~6400: ~3200
        // lost; the smoothing of the command (20 ms) and the rotor's pull-in over the last
        // cycles shorten it by a few hundred.
        assert!((m.lost() - 3200).abs() < 800, "{}", m.lost());
    }
}
