//! Brushed DC motor: PWM duty -> voltage -> current -> torque, with back-EMF, rotor and
//! wheel inertia, viscous and Coulomb friction.
//!
//! The winding inductance is left out: its time constant (L/R, well under a millisecond
//! for these motors) is shorter than the control tick, so the current is taken as settled
//! within each tick. The speed update is implicit in the damping terms (back-EMF and
//! viscous), so it is stable at any tick length; Coulomb friction holds the rotor still
//! while the drive torque stays below it (the dead band at low command).

use calib_core::control::PiGains;

/// Motor constants, on the motor side of the gearbox.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DcParams {
    /// Supply voltage at duty 1.
    pub v_supply: f64,
    /// Torque constant, N m / A.
    pub k_t: f64,
    /// Back-EMF constant, V s / rad.
    pub k_e: f64,
    /// Winding resistance, ohm.
    pub r_ohm: f64,
    /// Rotor inertia plus wheel inertia reflected through the gear, kg m^2.
    pub inertia: f64,
    /// Viscous friction, N m s / rad.
    pub viscous: f64,
    /// Coulomb friction, N m.
    pub coulomb: f64,
}

impl DcParams {
    /// A plausible small gearmotor for a robot: no-load *wheel* speed `wheel_no_load_rad_s`
    /// at 12 V, a 20 ms mechanical time constant, light friction. Papers give no motor
    /// data for the DC robots, so this is the documented assumption.
    pub fn typical(gear_ratio: f64, wheel_no_load_rad_s: f64) -> Self {
        let v = 12.0;
        let r = 4.0;
        let k = v / (wheel_no_load_rad_s * gear_ratio);
        let damping = k * k / r;
        DcParams {
            v_supply: v,
            k_t: k,
            k_e: k,
            r_ohm: r,
            inertia: 0.02 * damping,
            viscous: 0.01 * damping,
            coulomb: 0.0,
        }
    }

    /// Coulomb torque that makes the feed-forward duty for `deadband_rad_s` (wheel) just
    /// balance friction: commands below it leave the wheel still, as the catalogue's
    /// `coulomb_friction` says.
    pub fn with_deadband(mut self, gear_ratio: f64, deadband_rad_s: f64) -> Self {
        let w_m = deadband_rad_s * gear_ratio;
        self.coulomb = (self.k_t * self.k_e / self.r_ohm + self.viscous) * w_m;
        self
    }

    /// Steady-state duty for a wheel rate (no load, no Coulomb term).
    pub fn duty_per_wheel_rad_s(&self, gear_ratio: f64) -> f64 {
        // V = k_e w + R (b w) / k_t
        gear_ratio * (self.k_e + self.r_ohm * self.viscous / self.k_t) / self.v_supply
    }

    /// Gains for calib-core's PI wheel-velocity loop on this motor: feed-forward from the
    /// steady state, a static term for Coulomb friction, PI tuned for a ~10 ms closed loop.
    pub fn pi_gains(&self, gear_ratio: f64) -> PiGains {
        let kff = self.duty_per_wheel_rad_s(gear_ratio);
        let tau_m = self.inertia * self.r_ohm / (self.k_t * self.k_e);
        PiGains {
            kp: (kff * tau_m / 0.01) as f32,
            ki: (kff / 0.01) as f32,
            kff: kff as f32,
            kstatic: (self.coulomb * self.r_ohm / self.k_t / self.v_supply) as f32,
            out_max: 1.0,
        }
    }
}

/// One motor's state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DcMotor {
    /// Motor constants.
    pub params: DcParams,
    /// Motor shaft speed, rad/s.
    pub omega: f64,
    /// Precomputed torque per volt and total damping.
    torque_per_volt: f64,
    damping: f64,
}

impl DcMotor {
    /// A motor at rest with these constants.
    pub fn new(params: DcParams) -> Self {
        DcMotor {
            params,
            omega: 0.0,
            torque_per_volt: params.k_t / params.r_ohm,
            damping: params.k_t * params.k_e / params.r_ohm + params.viscous,
        }
    }

    /// Advances by `dt` with PWM duty `duty` (clamped to [-1, 1]); returns the motor shaft
    /// angle moved, rad.
    pub fn step(&mut self, duty: f64, dt: f64) -> f64 {
        let p = &self.params;
        let duty = if duty.is_finite() {
            duty.clamp(-1.0, 1.0)
        } else {
            0.0
        };
        let drive = self.torque_per_volt * duty * p.v_supply;
        let w0 = self.omega;
        let friction = if w0 != 0.0 {
            p.coulomb * w0.signum()
        } else if drive.abs() <= p.coulomb {
            // Static: friction cancels the drive exactly, the rotor stays.
            return 0.0;
        } else {
            p.coulomb * drive.signum()
        };
        let mut w =
            (w0 + dt / p.inertia * (drive - friction)) / (1.0 + dt * self.damping / p.inertia);
        // Friction stops the rotor; it does not reverse it.
        if w0 != 0.0 && w.signum() != w0.signum() {
            w = 0.0;
        }
        self.omega = w;
        0.5 * (w0 + w) * dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reaches_no_load_speed_with_its_time_constant() {
        let p = DcParams::typical(1.0, 20.0);
        let mut m = DcMotor::new(p);
        // Full duty: final speed V k_t / (R damping) = 20 / 1.01 rad/s (viscous 1 %).
        let mut t = 0.0;
        let mut t63: Option<f64> = None;
        while t < 0.5 {
            m.step(1.0, 1e-4);
            t += 1e-4;
            if t63.is_none() && m.omega > 0.632 * 20.0 / 1.01 {
                t63 = Some(t);
            }
        }
        assert!((m.omega - 20.0 / 1.01).abs() < 1e-3, "{}", m.omega);
        // 20 ms nominal time constant, shortened 1 % by the viscous term.
        assert!((t63.unwrap() - 0.0198).abs() < 3e-4, "{t63:?}");
    }

    #[test]
    fn coulomb_friction_is_a_dead_band() {
        let p = DcParams::typical(1.0, 20.0).with_deadband(1.0, 0.5);
        let kff = p.duty_per_wheel_rad_s(1.0);
        let mut m = DcMotor::new(p);
        let mut moved = 0.0;
        for _ in 0..1000 {
            moved += m.step(kff * 0.45, 1e-3);
        }
        assert_eq!(moved, 0.0);
        for _ in 0..1000 {
            moved += m.step(kff * 1.5, 1e-3);
        }
        // Above the band it runs at (1.5 - 0.5) rad/s in steady state.
        assert!((m.omega - 1.0).abs() < 1e-3, "{}", m.omega);
        assert!(moved > 0.5);
    }
}
