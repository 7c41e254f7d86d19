//! Actuator stage: commanded wheel rates -> wheel angles, with the actuator effects of the
//! model applied in the order the hardware applies them (friction dead band, motor lag,
//! lost steps, gear backlash).
//!
//! A command is held from its row to the next, as a controller's set-point is.

pub mod variants;

use crate::effects::{Effect, Model};

/// Parameters of the actuator effects in a model, with "absent" as `None`.
#[derive(Debug, Clone, Copy, Default)]
pub struct ActuatorParams {
    /// Coulomb friction: commands below this magnitude leave the wheel still, rad/s.
    pub deadband_rad_s: Option<f64>,
    /// Motor lag: first-order time constant from command to wheel rate, s.
    pub tau_s: Option<f64>,
    /// Acceleration the motor can follow (missed steps, slew limit), rad/s².
    pub max_accel_rad_s2: Option<f64>,
    /// Gear backlash: total play between motor and wheel, rad.
    pub backlash_rad: Option<f64>,
    /// Stepper drives: wheel angle of one electrical cycle (four full steps), the unit in
    /// which a rotor that lost synchronism drops steps. `None`: a plain rate limit.
    pub step_cycle_rad: Option<f64>,
    /// Read commands as samples of a signal that varies linearly between rows (the
    /// controller ran faster than the log) instead of values held until the next row.
    pub linear: bool,
    /// Mechanism variants: transport delay of the command, s.
    pub delay_s: Option<f64>,
    /// Asymmetric backlash: play taken up turning forward is b (1 + a), backward b (1 - a).
    pub backlash_asymmetry: Option<f64>,
    /// Missed steps in quanta: one electrical cycle lost `rate` times a second (on average)
    /// while the commanded acceleration is over `max_accel_rad_s2`.
    pub quanta_rate_hz: Option<f64>,
    /// Missed steps by stalling: over the limit the wheel stops until the command rests.
    pub stall: bool,
    /// Friction droop: every command loses this much rate in its sign (rad/s).
    pub droop_rad_s: Option<f64>,
}

impl ActuatorParams {
    /// These parameters for wheel `i` (its index in the robot): the model's per-wheel
    /// mechanisms (play, lag, delay, acceleration limit, dead band) set that wheel's own
    /// value.
    pub fn for_wheel(self, m: &Model, i: usize) -> Self {
        let own = |e: Effect| m.get(e).and_then(|v| v.get(i)).copied();
        ActuatorParams {
            backlash_rad: own(Effect::BacklashPerWheel).or(self.backlash_rad),
            tau_s: own(Effect::LagPerWheel).or(self.tau_s),
            delay_s: own(Effect::DelayPerWheel).or(self.delay_s),
            max_accel_rad_s2: own(Effect::SlewPerWheel).or(self.max_accel_rad_s2),
            deadband_rad_s: own(Effect::DeadBandPerWheel).or(self.deadband_rad_s),
            ..self
        }
    }
}

/// A stalled stepper re-locks when the command is back near rest (rad/s).
pub const STALL_RELEASE_RAD_S: f64 = 0.2;

impl ActuatorParams {
    /// The actuator-stage parameters of `m`'s effects (held commands, no stepper cycle).
    pub fn from_model(m: &Model) -> Self {
        let quanta = m.get(Effect::MissedQuanta);
        let stall = m.get(Effect::MissedStall);
        let asym = m.get(Effect::BacklashAsymmetric);
        ActuatorParams {
            deadband_rad_s: m.get(Effect::CoulombFriction).map(|p| p[0]),
            tau_s: m.get(Effect::MotorLag).map(|p| p[0]),
            max_accel_rad_s2: m
                .get(Effect::MissedSteps)
                .or(quanta)
                .or(stall)
                .or(m.get(Effect::LagSlew))
                .map(|p| p[0]),
            backlash_rad: m.get(Effect::Backlash).or(asym).map(|p| p[0]),
            linear: false,
            step_cycle_rad: None,
            delay_s: m.get(Effect::LagDelay).map(|p| p[0]),
            backlash_asymmetry: asym.map(|p| p[1]),
            quanta_rate_hz: quanta.map(|p| p[1]),
            stall: stall.is_some(),
            droop_rad_s: m.get(Effect::FrictionDroop).map(|p| p[0]),
        }
    }
}

/// exp(-dt / tau) for one `tau`, remembered for the last few row intervals: a decimated
/// recording's rows alternate between a few intervals (a fixed rate plus the pose rows
/// kept between: 29 distinct on the 120k-row bench, where one remembered value missed
/// 64 % of the rows and four miss 0.07 %), and `exp` was 4 % of a diagnosis. The same
/// values, to the bit.
struct Decay {
    tau: f64,
    dt: [f64; 4],
    e: [f64; 4],
    next: usize,
}

impl Decay {
    fn new(tau: f64) -> Self {
        Decay {
            tau: tau.max(fitkit::MIN_DT_S),
            dt: [f64::NAN; 4],
            e: [0.0; 4],
            next: 0,
        }
    }

    #[inline]
    fn of(&mut self, dt: f64) -> f64 {
        if let Some(i) = self.dt.iter().position(|d| *d == dt) {
            return self.e[i];
        }
        let e = (-dt / self.tau).exp();
        (self.dt[self.next], self.e[self.next]) = (dt, e);
        self.next = (self.next + 1) % self.dt.len();
        e
    }
}

/// Wheel angle (rad, 0 at the first row) for each row, from the held commands.
pub fn simulate_wheel(t: &[f64], cmd: &[f64], p: &ActuatorParams, out: &mut Vec<f64>) {
    out.clear();
    let n = t.len();
    if n == 0 {
        return;
    }
    if let Some(delay) = p.delay_s {
        // Transport delay: the wheel turns as the command did `delay` earlier (at rest
        // before the recording). Exact for held commands: the delayed command's mean over
        // each row interval from the integral of the held command.
        let delayed = variants::delay_commands(t, cmd, delay, p.linear);
        let q = ActuatorParams {
            delay_s: None,
            linear: false,
            ..*p
        };
        return simulate_wheel(t, &delayed, &q, out);
    }
    if let Some(d) = p.droop_rad_s {
        // Droop: the loop settles short of every command by the friction over its gain.
        let drooped: Vec<f64> = cmd
            .iter()
            .map(|c| c.signum() * (c.abs() - d).max(0.0))
            .collect();
        let q = ActuatorParams {
            droop_rad_s: None,
            ..*p
        };
        return simulate_wheel(t, &drooped, &q, out);
    }
    if p.quanta_rate_hz.is_some() || p.stall {
        return variants::simulate_stepper_losses(t, cmd, p, out);
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
    let mut decay = p.tau_s.map(Decay::new);
    let mut stepper = Rotor::default();
    let mut play = variants::Play::default();
    for k in 0..n - 1 {
        let dt = t[k + 1] - t[k];
        let (c0, c1) = if p.linear {
            (cmd[k], cmd[k + 1])
        } else {
            (cmd[k], cmd[k])
        };
        // Value held over the interval by the dynamic effects (midpoint of a ramp).
        let mut c = 0.5 * (c0 + c1);
        if let Some(d) = p.deadband_rad_s {
            if c.abs() < d {
                c = 0.0;
            }
        }
        let inc = match (p.tau_s, p.max_accel_rad_s2) {
            (None, None) => match p.deadband_rad_s {
                Some(d) if c0 != c1 => ramp_outside_deadband(c0, c1, d) * dt,
                _ => c * dt,
            },
            (Some(tau), None) => {
                // Exact solution of rate' = (c(t) - rate) / tau for a command varying
                // linearly over the interval (held: slope 0).
                let e = decay.as_mut().map_or(0.0, |d| d.of(dt));
                let dead = |v: f64| match p.deadband_rad_s {
                    Some(d) if v.abs() < d => 0.0,
                    _ => v,
                };
                let (a0, a1) = (dead(c0), dead(c1));
                let slope = (a1 - a0) / dt;
                let k0 = rate - a0 + slope * tau;
                let inc = a0 * dt + 0.5 * slope * dt * dt - slope * tau * dt + k0 * tau * (1.0 - e);
                rate = a1 - slope * tau + k0 * e;
                inc
            }
            (tau, Some(a)) if p.step_cycle_rad.is_some() => {
                let cycle = p.step_cycle_rad.unwrap_or(1.0);
                stepper.advance(c0, c1, dt, tau, a, cycle)
            }
            (_, Some(a)) => {
                // The lag (if any) shapes the demand; the motor cannot follow faster than
                // a. Integrated exactly for a ramp that may reach the demand mid-interval.
                let mut demand = c;
                if let Some(d) = decay.as_mut() {
                    demand = c + (rate - c) * d.of(dt);
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
            Some(b) if p.backlash_asymmetry.is_some() => {
                let a = p.backlash_asymmetry.unwrap_or(0.0);
                wheel += play.take(inc, b, a);
            }
            Some(b) => wheel = take_up_play(motor, wheel, b),
            None => wheel = motor,
        }
        out.push(wheel);
    }
}

/// Time constant with which a stepper's field pulls the rotor onto the commanded
/// position (stiff compared with the motion, soft compared with a 1 ms sub-step).
const STEPPER_SYNC_S: f64 = 0.005;
/// Sub-step of the stepper rotor model (its pull is too stiff for a log's row interval).
const STEPPER_SUBSTEP_S: f64 = 1e-3;
/// Lag behind the commanded position under which a rotor counts as in step (rad): under
/// a millionth of an encoder count's angle, so skipping its decay changes no fit.
const STEPPER_IN_STEP_RAD: f64 = 1e-9;

/// A stepper rotor with pull-out: it follows the commanded position with acceleration
/// bounded by `a`; once more than half an electrical cycle behind (or ahead) it has
/// slipped and re-locks a whole cycle (four full steps) away: those steps are lost.
#[derive(Debug, Clone, Copy, Default)]
struct Rotor {
    commanded: f64,
    lost: f64,
    pos: f64,
    rate: f64,
    lag_rate: f64,
}

impl Rotor {
    /// Advances over one row interval with the command going linearly from c0 to c1;
    /// returns the rotor's movement. A rotor in step with a held command that one
    /// sub-step's acceleration can reach follows it exactly, so the row is not
    /// sub-stepped (most rows of a long drive; within [`STEPPER_IN_STEP_RAD`]).
    fn advance(&mut self, c0: f64, c1: f64, dt: f64, tau: Option<f64>, a: f64, cycle: f64) -> f64 {
        let h = dt / Self::substep_count(dt) as f64;
        let e = self.commanded - self.lost - self.pos;
        if tau.is_none()
            && c0 == c1
            && e.abs() <= STEPPER_IN_STEP_RAD
            && (c0 - self.rate).abs() + e.abs() / STEPPER_SYNC_S <= a * h
        {
            let inc = c0 * dt;
            self.commanded += inc;
            self.pos += inc;
            self.rate = c0;
            return inc;
        }
        self.substeps(c0, c1, dt, tau, a, cycle)
    }

    /// Sub-steps per row: at most 1000, so a gap in a log cannot stall the replay.
    fn substep_count(dt: f64) -> usize {
        (dt / STEPPER_SUBSTEP_S).ceil().clamp(1.0, 1000.0) as usize
    }

    /// [`Rotor::advance`] by sub-steps of at most [`STEPPER_SUBSTEP_S`].
    fn substeps(&mut self, c0: f64, c1: f64, dt: f64, tau: Option<f64>, a: f64, cycle: f64) -> f64 {
        let n = Self::substep_count(dt);
        let h = dt / n as f64;
        let before = self.pos;
        let lag_keep = tau.map(|tau| (-h / tau.max(fitkit::MIN_DT_S)).exp());
        for i in 0..n {
            let mut c = c0 + (c1 - c0) * (i as f64 + 0.5) / n as f64;
            if let Some(keep) = lag_keep {
                self.lag_rate += (c - self.lag_rate) * (1.0 - keep);
                c = self.lag_rate;
            }
            let e = self.commanded - self.lost - self.pos;
            self.commanded += c * h;
            let pull = pull_rate(e.abs(), a);
            let want = c + pull.copysign(e);
            self.rate += (want - self.rate).clamp(-a * h, a * h);
            self.pos += self.rate * h;
            let e = self.commanded - self.lost - self.pos;
            if e.abs() > 0.5 * cycle {
                self.lost += cycle * (e / cycle).round();
            }
        }
        self.pos - before
    }
}

/// The rate at which the field pulls a rotor `lag` behind (rad) back, accelerating at
/// most `a`: proportional to the lag, but never faster than it can stop in time. The same
/// value, to the bit, as `(lag / STEPPER_SYNC_S).min((2 a lag).sqrt())`; the square root
/// is skipped where the linear term is clearly the smaller (a lag under
/// 2 a STEPPER_SYNC_S², 0.94 mrad at a = 18.84 rad/s²), as it lies on the rotor's chain of
/// dependent operations from one sub-step to the next.
fn pull_rate(lag: f64, a: f64) -> f64 {
    let linear = lag / STEPPER_SYNC_S;
    let braking_sq = 2.0 * a * lag;
    // linear^2 below braking_sq by more than the products' rounding (a few ulps) means
    // linear < sqrt(braking_sq) exactly.
    if linear * linear < braking_sq * (1.0 - 1e-12) {
        linear
    } else {
        linear.min(braking_sq.sqrt())
    }
}

/// Mean over a unit interval of c(s) = c0 + (c1 - c0) s where |c(s)| >= d (zero inside
/// the dead band): the exact travel of a linearly varying command with Coulomb friction.
/// Symmetric backlash of total play `b`: the wheel stays put until the motor has crossed
/// half the play on either side, then follows it at that distance.
pub(crate) fn take_up_play(motor: f64, wheel: f64, b: f64) -> f64 {
    let half = 0.5 * b;
    if motor - wheel > half {
        motor - half
    } else if wheel - motor > half {
        motor + half
    } else {
        wheel
    }
}

fn ramp_outside_deadband(c0: f64, c1: f64, d: f64) -> f64 {
    // Integrate c over the parts of [0, 1] where c >= d and where c <= -d.
    let slope = c1 - c0;
    let part = |lo_val: f64, sign: f64| -> f64 {
        // s range where sign * c(s) >= lo_val.
        let (a, b) = if slope * sign > 0.0 {
            (((lo_val * sign - c0) / slope).clamp(0.0, 1.0), 1.0)
        } else {
            (0.0, ((lo_val * sign - c0) / slope).clamp(0.0, 1.0))
        };
        if b <= a {
            return 0.0;
        }
        c0 * (b - a) + 0.5 * slope * (b * b - a * a)
    };
    part(d, 1.0) + part(d, -1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pull's shortcut gives the plain formula's value to the bit: over lags from
    /// 1e-12 to 1 rad and accelerations from 0.1 to 1e4 rad/s², and at the crossover
    /// (linear = braking exactly: lag = 2 a STEPPER_SYNC_S^2) and its neighbours.
    #[test]
    fn the_pulls_shortcut_is_the_formula_to_the_bit() {
        let plain = |lag: f64, a: f64| (lag / STEPPER_SYNC_S).min((2.0 * a * lag).sqrt());
        let mut lags: Vec<f64> = (0..=1200)
            .map(|k| 10f64.powf(-12.0 + k as f64 / 100.0))
            .collect();
        let mut n = 0;
        for a in [0.1, 1.0, 18.8397202, 100.0, 1e4] {
            let cross = 2.0 * a * STEPPER_SYNC_S * STEPPER_SYNC_S;
            let mut x = cross;
            for _ in 0..64 {
                x = f64::from_bits(x.to_bits() - 1);
            }
            for _ in 0..128 {
                lags.push(x);
                x = f64::from_bits(x.to_bits() + 1);
            }
            for &lag in &lags {
                assert_eq!(
                    pull_rate(lag, a).to_bits(),
                    plain(lag, a).to_bits(),
                    "lag {lag:e}, a {a}"
                );
                n += 1;
            }
        }
        assert!(n > 6000);
        assert_eq!(pull_rate(0.0, 5.0), 0.0);
    }

    fn times(n: usize, dt: f64) -> Vec<f64> {
        (0..n).map(|k| k as f64 * dt).collect()
    }

    #[test]
    fn ramp_through_deadband() {
        // c from -1 to 3 with d = 1: only s in [0.5, 1] counts (c from 1 to 3): mean 1.0.
        assert!((ramp_outside_deadband(-1.0, 3.0, 1.0) - 1.0).abs() < 1e-12);
        // Entirely inside: nothing; entirely outside: the plain mean.
        assert!(ramp_outside_deadband(-0.5, 0.5, 1.0).abs() < 1e-12);
        assert!((ramp_outside_deadband(2.0, 4.0, 1.0) - 3.0).abs() < 1e-12);
        assert!((ramp_outside_deadband(-2.0, -4.0, 1.0) + 3.0).abs() < 1e-12);
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

    /// A rotor in step with a held command that it can follow within one sub-step's
    /// acceleration moves by the command exactly, so a row in step is not sub-stepped.
    /// Tolerance 1e-8 rad, three millionths of an encoder count (3.3e-3 rad at 1920
    /// counts per revolution): the lag a rotor in step keeps ([`STEPPER_IN_STEP_RAD`]),
    /// met again after each slip, plus the rounding of 8 sub-steps' sums over 6,000 rows.
    #[test]
    fn a_rotor_in_step_skips_its_sub_steps_within_three_millionths_of_a_count() {
        // A two-hour-like drive at 120 rows/s: smooth commands (up to 12 rad/s, about
        // 20 rad/s^2), holds, reversals, and steps of 6 rad/s that pull out a weak rotor.
        let dt = 1.0 / 120.0;
        let n = 6000;
        let t = times(n, dt);
        let cmd: Vec<f64> = (0..n)
            .map(|k| {
                let x = k as f64 * dt;
                let smooth = 12.0 * (0.35 * x).sin() * (0.11 * x + 0.3).cos();
                let held = if (x % 7.0) < 1.5 {
                    (smooth * 4.0).round() / 4.0
                } else {
                    smooth
                };
                if (x % 11.0) < 0.05 {
                    held + 6.0
                } else {
                    held
                }
            })
            .collect();
        let cycle = 4.0 * std::f64::consts::TAU / (200.0 * 4.875);
        for a in [1.0, 5.0, 50.0, 500.0, 3000.0] {
            let p = ActuatorParams {
                max_accel_rad_s2: Some(a),
                step_cycle_rad: Some(cycle),
                ..Default::default()
            };
            let mut fast = Vec::new();
            simulate_wheel(&t, &cmd, &p, &mut fast);
            // The reference: every row sub-stepped.
            let mut rotor = Rotor::default();
            let mut exact = vec![0.0];
            for k in 0..n - 1 {
                let step = rotor.substeps(cmd[k], cmd[k], t[k + 1] - t[k], None, a, cycle);
                exact.push(exact[k] + step);
            }
            let worst = fast
                .iter()
                .zip(&exact)
                .map(|(f, e)| (f - e).abs())
                .fold(0.0, f64::max);
            assert!(worst < 1e-8, "a = {a}: {worst:e} rad");
            // The case exercises both paths: the strong rotors keep step, the weak lose
            // some (whole cycles).
            if a >= 500.0 {
                assert!((exact[n - 1] - cmd.iter().take(n - 1).sum::<f64>() * dt).abs() < 1e-6);
            }
            if a <= 5.0 {
                let lost = cmd.iter().take(n - 1).sum::<f64>() * dt - exact[n - 1];
                assert!(lost.abs() > cycle, "a = {a}: lost {lost}");
            }
        }
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
