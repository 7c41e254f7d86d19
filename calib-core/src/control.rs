//! Wheel velocity control for DC motors: PI with feed-forward and anti-windup.
//!
//! Feed-forward carries the bulk of the command (the voltage that balances back-EMF at
//! the setpoint), so the PI only corrects the remainder and stays gentle. Anti-windup is
//! conditional integration: the integrator stops growing while the output is saturated
//! in the direction the error pushes.

/// PI gains and output limits (output in duty, -1..1, or volts: the caller decides).
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, postcard_schema::Schema,
)]
pub struct PiGains {
    /// Proportional gain (output per rad/s of error).
    pub kp: f32,
    /// Integral gain (output per rad of accumulated error, i.e. per rad/s per s).
    pub ki: f32,
    /// Output per unit setpoint (duty per rad/s).
    pub kff: f32,
    /// Constant output added in the direction of motion (overcomes Coulomb friction).
    pub kstatic: f32,
    /// Output limit: the output and the integrator stay within ±`out_max`.
    pub out_max: f32,
}

/// `x` limited to [-m, m], NaN kept NaN. Not `max`/`min`, which drop a NaN operand
/// (`NaN.max(-m).min(m)` is -m: full reverse duty from a NaN), and not `clamp`, whose
/// panic path costs ~6 KiB of flash on the board. The caller checks the result is finite.
fn limit(x: f32, m: f32) -> f32 {
    if x > m {
        m
    } else if x < -m {
        -m
    } else {
        x
    }
}

/// One wheel's velocity controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PiController {
    /// Gains and limits in use.
    pub gains: PiGains,
    integral: f32,
}

impl PiController {
    /// A controller with the given gains and an empty integrator.
    pub fn new(gains: PiGains) -> Self {
        PiController {
            gains,
            integral: 0.0,
        }
    }

    /// Clears the integrator (at stop, so a stopped robot does not creep on restart).
    pub fn reset(&mut self) {
        self.integral = 0.0;
    }

    /// Output for `setpoint` and `measured` (rad/s) over a tick of `dt` seconds.
    pub fn update(&mut self, setpoint: f32, measured: f32, dt: f32) -> f32 {
        let g = &self.gains;
        let err = setpoint - measured;
        let stat = if setpoint > 0.0 {
            g.kstatic
        } else if setpoint < 0.0 {
            -g.kstatic
        } else {
            0.0
        };
        let ff = g.kff * setpoint + stat;
        let unsat = ff + g.kp * err + self.integral;
        let pushing_out = (unsat >= g.out_max && err > 0.0) || (unsat <= -g.out_max && err < 0.0);
        if !pushing_out {
            self.integral += g.ki * err * dt;
            // Never let the integrator alone exceed the output range.
            self.integral = limit(self.integral, g.out_max);
        }
        limit(ff + g.kp * err + self.integral, g.out_max)
    }

    /// Current integrator value (output units).
    pub fn integral(&self) -> f32 {
        self.integral
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// First-order plant: J dw/dt = k u - b w  (u in duty).
    fn simulate(ctrl: &mut PiController, setpoint: f32, load: f32, ticks: usize) -> f32 {
        let (k, b, dt) = (20.0f32, 1.0f32, 1e-3f32);
        let mut w = 0.0f32;
        for _ in 0..ticks {
            let u = ctrl.update(setpoint, w, dt);
            w += dt / 0.05 * (k * u - b * w - load);
        }
        w
    }

    /// A NaN setpoint or measurement must come out as NaN (for the board's finite check to
    /// catch), never as a saturated duty: `max`/`min` turned it into -out_max, full reverse.
    #[test]
    fn nan_in_is_nan_out_not_full_duty() {
        let gains = PiGains {
            kp: 0.05,
            ki: 2.0,
            kff: 0.05,
            kstatic: 0.02,
            out_max: 1.0,
        };
        for (sp, meas) in [
            (f32::NAN, 1.0),
            (1.0, f32::NAN),
            (f32::INFINITY, f32::INFINITY),
        ] {
            let mut c = PiController::new(gains);
            let u = c.update(sp, meas, 1e-3);
            assert!(u.is_nan(), "update({sp}, {meas}) = {u}, expected NaN");
        }
        // Finite inputs beyond the range still saturate at exactly +-out_max.
        let mut c = PiController::new(gains);
        assert_eq!(c.update(1e6, 0.0, 1e-3), 1.0);
        assert_eq!(c.update(-1e6, 0.0, 1e-3), -1.0);
    }

    #[test]
    fn tracks_with_load_and_no_windup() {
        let gains = PiGains {
            kp: 0.05,
            ki: 2.0,
            kff: 1.0 / 20.0,
            kstatic: 0.0,
            out_max: 1.0,
        };
        let mut c = PiController::new(gains);
        // Feed-forward matches the unloaded plant; a load must be removed by the integral.
        let w = simulate(&mut c, 10.0, 2.0, 3000);
        assert!((w - 10.0).abs() < 0.01 * 10.0, "w = {w}");
        // Demand beyond the plant's reach (20 rad/s at full duty): output saturates, the
        // integrator does not run away; on return to 5 rad/s it settles quickly.
        let mut c = PiController::new(gains);
        simulate(&mut c, 40.0, 0.0, 2000);
        assert!(c.integral() <= 1.0);
        let w = simulate(&mut c, 5.0, 0.0, 500);
        assert!((w - 5.0).abs() < 0.05 * 5.0, "w = {w}");
    }
}
