//! Actuator stage: commanded wheel rates -> wheel angles, with the actuator effects of the
//! model applied in the order the hardware applies them (friction dead band, motor lag,
//! lost steps, gear backlash).
//!
//! A command is held from its row to the next, as a controller's set-point is.

use crate::effects::{Effect, Model};

/// Parameters of the actuator effects in a model, with "absent" as `None`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ActuatorParams {
    pub deadband_rad_s: Option<f64>,
    pub tau_s: Option<f64>,
    pub max_accel_rad_s2: Option<f64>,
    pub backlash_rad: Option<f64>,
}

impl ActuatorParams {
    pub fn from_model(m: &Model) -> Self {
        ActuatorParams {
            deadband_rad_s: m.get(Effect::CoulombFriction).map(|p| p[0]),
            tau_s: m.get(Effect::MotorLag).map(|p| p[0]),
            max_accel_rad_s2: m.get(Effect::MissedSteps).map(|p| p[0]),
            backlash_rad: m.get(Effect::Backlash).map(|p| p[0]),
        }
    }
}

/// Wheel angle (rad, 0 at the first row) for each row, from the held commands.
pub fn simulate_wheel(t: &[f64], cmd: &[f64], p: &ActuatorParams, out: &mut Vec<f64>) {
    out.clear();
    let n = t.len();
    if n == 0 {
        return;
    }
    out.reserve(n);
    out.push(0.0);
    let mut motor = 0.0;
    let mut wheel = 0.0;
    // Rate state of the lag and of the acceleration limit.
    let mut rate = if p.deadband_rad_s.is_some_and(|d| cmd[0].abs() < d) {
        0.0
    } else {
        cmd[0]
    };
    let mut last_tau_dt = (f64::NAN, 0.0);
    for k in 0..n - 1 {
        let dt = t[k + 1] - t[k];
        let mut c = cmd[k];
        if let Some(d) = p.deadband_rad_s {
            if c.abs() < d {
                c = 0.0;
            }
        }
        let inc = match (p.tau_s, p.max_accel_rad_s2) {
            (None, None) => c * dt,
            (Some(tau), None) => {
                // Exact solution of rate' = (c - rate) / tau over the interval.
                let e = if last_tau_dt.0 == dt {
                    last_tau_dt.1
                } else {
                    let e = (-dt / tau.max(1e-9)).exp();
                    last_tau_dt = (dt, e);
                    e
                };
                let inc = c * dt + (rate - c) * tau * (1.0 - e);
                rate = c + (rate - c) * e;
                inc
            }
            (tau, Some(a)) => {
                // The lag (if any) shapes the demand; the motor cannot follow faster than
                // a. Integrated exactly for a ramp that may reach the demand mid-interval.
                let mut demand = c;
                if let Some(tau) = tau {
                    let e = (-dt / tau.max(1e-9)).exp();
                    demand = c + (rate - c) * e;
                }
                let gap = demand - rate;
                let a = a.max(1e-12);
                let t_reach = gap.abs() / a;
                if t_reach >= dt {
                    let new_rate = rate + gap.signum() * a * dt;
                    let inc = 0.5 * (rate + new_rate) * dt;
                    rate = new_rate;
                    inc
                } else {
                    let inc = 0.5 * (rate + demand) * t_reach + demand * (dt - t_reach);
                    rate = demand;
                    inc
                }
            }
        };
        motor += inc;
        match p.backlash_rad {
            Some(b) => {
                let half = 0.5 * b;
                if motor - wheel > half {
                    wheel = motor - half;
                } else if wheel - motor > half {
                    wheel = motor + half;
                }
            }
            None => wheel = motor,
        }
        out.push(wheel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * dt).collect()
    }

    #[test]
    fn nominal_integrates_held_command() {
        let t = times(11, 0.1);
        let cmd = vec![2.0; 11];
        let mut out = Vec::new();
        simulate_wheel(&t, &cmd, &ActuatorParams::default(), &mut out);
        assert!((out[10] - 2.0).abs() < 1e-12);
    }

    #[test]
    fn lag_falls_behind_by_tau_times_rate() {
        // A ramp-free step to 5 rad/s from rest with tau 0.1 s: after many tau the wheel
        // trails the command by tau * rate = 0.5 rad.
        let t = times(2001, 0.001);
        let mut cmd = vec![5.0; 2001];
        cmd[0] = 5.0;
        let p = ActuatorParams {
            tau_s: Some(0.1),
            ..Default::default()
        };
        let mut out = Vec::new();
        // Start from rest: the first command is 0.
        let mut c0 = cmd.clone();
        c0[0] = 0.0;
        simulate_wheel(&t, &c0, &p, &mut out);
        let ideal = 5.0 * 1.999;
        assert!(
            (ideal - out[2000] - 0.5).abs() < 0.01,
            "{}",
            ideal - out[2000]
        );
    }

    #[test]
    fn backlash_loses_the_band_at_a_reversal() {
        let t = times(201, 0.01);
        let cmd: Vec<f64> = (0..201).map(|k| if k < 100 { 1.0 } else { -1.0 }).collect();
        let p = ActuatorParams {
            backlash_rad: Some(0.2),
            ..Default::default()
        };
        let mut out = Vec::new();
        simulate_wheel(&t, &cmd, &p, &mut out);
        // Forward 1 rad (wheel trails by 0.1), back 1 rad: the wheel ends 0.2 below the
        // motor's forward-then-back, i.e. at motor + 0.1 = 0.1.
        assert!((out[200] - 0.1).abs() < 1e-9, "{}", out[200]);
    }
}
