//! Actuator-stage mechanism variants: transport delay of the commands, stepper losses in
//! quanta or by stalling, and play that differs by direction. Each is a variant of a
//! catalogue [`Effect`](crate::effects::Effect) (its [`base`](crate::effects::Effect::base)), fitted like any candidate; the selection
//! keeps the one the data favour and never two of the same catalogue effect.

use super::{ActuatorParams, STALL_RELEASE_RAD_S};

/// Integral of a command from t[0] to `tau` (0 before t[0]: the robot was at rest), held
/// between rows or linear between them. `j` is a monotone search hint.
fn command_integral(
    t: &[f64],
    cmd: &[f64],
    cum: &[f64],
    linear: bool,
    tau: f64,
    j: &mut usize,
) -> f64 {
    let n = t.len();
    if tau <= t[0] {
        return 0.0;
    }
    while *j + 1 < n && t[*j + 1] <= tau {
        *j += 1;
    }
    while *j > 0 && t[*j] > tau {
        *j -= 1;
    }
    let k = *j;
    let s = tau - t[k];
    if k + 1 >= n {
        return cum[n - 1] + cmd[n - 1] * s;
    }
    let c0 = cmd[k];
    let slope = if linear {
        (cmd[k + 1] - cmd[k]) / (t[k + 1] - t[k]).max(1e-12)
    } else {
        0.0
    };
    cum[k] + c0 * s + 0.5 * slope * s * s
}

/// The command delayed by `delay`, as held per-row means (exact for the chosen
/// interpretation of the logged commands).
pub fn delay_commands(t: &[f64], cmd: &[f64], delay: f64, linear: bool) -> Vec<f64> {
    let n = t.len();
    let mut cum = vec![0.0; n];
    for k in 1..n {
        let dt = t[k] - t[k - 1];
        let c = if linear {
            0.5 * (cmd[k - 1] + cmd[k])
        } else {
            cmd[k - 1]
        };
        cum[k] = cum[k - 1] + c * dt;
    }
    let mut out = vec![0.0; n];
    let mut j = 0;
    let mut prev = command_integral(t, cmd, &cum, linear, t[0] - delay, &mut j);
    for k in 0..n.saturating_sub(1) {
        let next = command_integral(t, cmd, &cum, linear, t[k + 1] - delay, &mut j);
        out[k] = (next - prev) / (t[k + 1] - t[k]).max(1e-12);
        prev = next;
    }
    if n >= 2 {
        out[n - 1] = out[n - 2];
    }
    out
}

/// Play between motor and wheel that may differ by direction: after a reversal to
/// forward the motor turns b (1 + a) before the wheel follows, to backward b (1 - a).
#[derive(Debug, Clone, Copy, Default)]
pub struct Play {
    dir: f64,
    left: f64,
}

impl Play {
    /// The wheel's increment for a motor increment `dm`.
    pub fn take(&mut self, dm: f64, b: f64, a: f64) -> f64 {
        if dm == 0.0 {
            return 0.0;
        }
        let dir = dm.signum();
        if dir != self.dir {
            let width = b * if dir > 0.0 { 1.0 + a } else { 1.0 - a };
            self.left = (width - self.left).max(0.0);
            self.dir = dir;
        }
        let take = self.left.min(dm.abs());
        self.left -= take;
        dm - take.copysign(dm)
    }
}

/// Stepper losses without rotor dynamics: while the commanded wheel acceleration is over
/// the limit, whole electrical cycles are dropped at `quanta_rate_hz` on average (the
/// expected loss is modelled), or the rotor stalls until the command is back near rest.
pub fn simulate_stepper_losses(t: &[f64], cmd: &[f64], p: &ActuatorParams, out: &mut Vec<f64>) {
    let n = t.len();
    out.clear();
    out.push(0.0);
    let a_max = p.max_accel_rad_s2.unwrap_or(f64::INFINITY);
    let cycle = p.step_cycle_rad.unwrap_or(0.0);
    let (mut motor, mut wheel) = (0.0, 0.0);
    let mut stalled = false;
    for k in 0..n - 1 {
        let dt = t[k + 1] - t[k];
        let c = if p.deadband_rad_s.is_some_and(|d| cmd[k].abs() < d) {
            0.0
        } else {
            cmd[k]
        };
        // Commanded acceleration where the command changes (the larger of the two sides,
        // so a ramp's first row counts).
        let back = if k > 0 {
            (cmd[k] - cmd[k - 1]) / (t[k] - t[k - 1]).max(fitkit::MIN_DT_S)
        } else {
            0.0
        };
        let fwd = (cmd[k + 1] - cmd[k]) / dt.max(fitkit::MIN_DT_S);
        let over = back.abs().max(fwd.abs()) > a_max && c != 0.0;
        let inc = if p.stall {
            if over {
                stalled = true;
            } else if c.abs() < STALL_RELEASE_RAD_S {
                stalled = false;
            }
            if stalled {
                0.0
            } else {
                c * dt
            }
        } else if over {
            let lost = (p.quanta_rate_hz.unwrap_or(0.0) * cycle * dt).min((c * dt).abs());
            c * dt - lost.copysign(c)
        } else {
            c * dt
        };
        motor += inc;
        match p.backlash_rad {
            Some(b) => wheel = crate::actuator::take_up_play(motor, wheel, b),
            None => wheel = motor,
        }
        out.push(wheel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn delayed_command_is_shifted_exactly() {
        // Held command 0 then 2 rad/s from t = 0.1 s, rows every 0.02 s, delay 0.03 s:
        // the row [0.12, 0.14] sees the step at 0.13: mean 1.0.
        let t: Vec<f64> = (0..20).map(|k| k as f64 * 0.02).collect();
        let cmd: Vec<f64> = t
            .iter()
            .map(|&x| if x >= 0.1 - 1e-9 { 2.0 } else { 0.0 })
            .collect();
        let d = delay_commands(&t, &cmd, 0.03, false);
        assert!(d[5].abs() < 1e-12, "{}", d[5]);
        assert!((d[6] - 1.0).abs() < 1e-9, "{}", d[6]);
        assert!((d[7] - 2.0).abs() < 1e-9);
    }

    #[test]
    fn asymmetric_play() {
        let mut p = Play::default();
        let fwd: f64 = (0..100).map(|_| p.take(0.01, 0.1, 0.5)).sum();
        let back: f64 = (0..100).map(|_| p.take(-0.01, 0.1, 0.5)).sum();
        let fwd2: f64 = (0..100).map(|_| p.take(0.01, 0.1, 0.5)).sum();
        // First engagement forward 0.15, backward 0.05, forward again 0.15.
        assert!(
            (fwd - 0.85).abs() < 1e-9 && (back + 0.95).abs() < 1e-9,
            "{fwd} {back}"
        );
        assert!((fwd2 - 0.85).abs() < 1e-9);
    }
}
