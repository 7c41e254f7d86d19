//! Mechanism families: every catalogue effect can come about in more than one
//! physical way. Each mechanism is a variant of [`Effect`] (its [`Effect::base`] is the
//! catalogue effect, [`Effect::mechanism`] its name), fitted like any candidate; the
//! selection keeps the one the data favour and never two of the same catalogue effect.
//!
//! This module holds the variants' models that are not a change of an existing stage's
//! equations: transport delay of the commands, stepper losses in quanta or by stalling,
//! asymmetric play, the body-acceleration and creep forms of traction slip (applied to the
//! wheel angles before the ground stage), saturating side slip and cables in a region.

use crate::actuator::{ActuatorParams, STALL_RELEASE_RAD_S};
use crate::effects::{Effect, Model};
use crate::replay::Prepared;
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};

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
            (cmd[k] - cmd[k - 1]) / (t[k] - t[k - 1]).max(crate::MIN_DT_S)
        } else {
            0.0
        };
        let fwd = (cmd[k + 1] - cmd[k]) / dt.max(crate::MIN_DT_S);
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

/// Side slip of the lateral-slip mechanisms as a displacement over one row: linear
/// v_y = -k v_x omega, or saturating at `sat`: v_y = -sat tanh(k v_x omega / sat).
pub fn side_slip(m: &Model, d: &Twist<f64>, dt: f64) -> f64 {
    let dt = dt.max(1e-12);
    if let Some(p) = m.get(Effect::LateralSaturating) {
        // A saturation speed of a nanometre per second is no side slip at all.
        let (k, sat) = (p[0], p[1].max(1e-9));
        let v = k * (d.vx / dt) * (d.omega / dt);
        return -sat * (v / sat).tanh() * dt;
    }
    match m.get(Effect::LateralSlip) {
        Some(p) => -p[0] * d.vx * d.omega / dt,
        None => 0.0,
    }
}

/// Cables (spacing, loss) of either floor_bumps mechanism, with the region's bounds in
/// world x (infinite for the whole floor).
pub fn cables(m: &Model) -> Option<(f64, f64, f64, f64)> {
    if let Some(p) = m.get(Effect::BumpsRegion) {
        return Some((p[0], p[1], p[2].min(p[3]), p[2].max(p[3])));
    }
    m.get(Effect::FloorBumps)
        .map(|p| (p[0], p[1], f64::NEG_INFINITY, f64::INFINITY))
}

/// Cables crossed between world x0 and x1 within [lo, hi].
pub fn crossings(x0: f64, x1: f64, spacing: f64, lo: f64, hi: f64) -> f64 {
    let (a, b) = (x0.min(x1).max(lo), x0.max(x1).min(hi));
    if a >= b {
        return 0.0;
    }
    ((b / spacing).floor() - (a / spacing).floor()).abs()
}

/// Starting grid of the region mechanism: bounds from where the measured path went
/// (quantiles of world x), spacing and loss per metre as the whole-floor grid.
pub fn region_grid(p: &Prepared) -> Vec<Vec<f64>> {
    let mut xs: Vec<f64> = p.pose_at_row.iter().map(|q| q.0).collect();
    if xs.is_empty() {
        return Vec::new();
    }
    xs.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| xs[((xs.len() - 1) as f64 * f) as usize];
    let cuts: Vec<f64> = [0.0, 0.25, 0.5, 0.75, 1.0].iter().map(|&f| q(f)).collect();
    let mut g = Vec::new();
    for i in 0..cuts.len() {
        for j in i + 1..cuts.len() {
            if i == 0 && j == cuts.len() - 1 {
                continue; // the whole floor is the other mechanism
            }
            for s in [0.02, 0.05] {
                for frac in [0.005, 0.02] {
                    g.push(vec![s, s * frac, cuts[i] - 0.05, cuts[j] + 0.05]);
                }
            }
        }
    }
    g
}

/// Starting points of the region mechanism from the region signature of the residual
/// left by `model` ([`crate::signature::region_loss`]): its stretch of world x, at the
/// grid's spacings with the losses per crossing the signature's loss per metre asks (the
/// quantile grid's losses stop at 2 % of the spacing). The bounds are then scanned
/// (`select`), but from a start whose loss is near the data's.
pub fn region_seeds(ev: &crate::residuals::Evaluator, model: &Model) -> Vec<Vec<f64>> {
    let Some(r) = crate::signature::region_loss(ev, model) else {
        return Vec::new();
    };
    if !(r.loss_per_m > 0.0 && r.loss_per_m.is_finite() && r.end_m > r.start_m) {
        return Vec::new();
    }
    // A cable takes its toll along the wheel's rolling direction's share of the
    // crossing, and the wheel crosses at all in proportion to its travel along x: the
    // loss per metre rolled is about half the loss per metre across the cables.
    let mut g = Vec::new();
    for s in [0.02, 0.05] {
        for k in [1.0, 2.0, 4.0] {
            g.push(vec![
                s,
                (k * s * r.loss_per_m).clamp(1e-6, 0.05),
                r.start_m,
                r.end_m,
            ]);
        }
    }
    g
}

/// Whether a mechanism variant can act on this recording. Creep rewrites the driven
/// wheels' angles and needs every wheel driven (a free wheel would report the body). The
/// body bound needs every wheel's angles, and, with free wheels, driven wheels that
/// resolve the body twist on their own (what the drive asks for).
pub fn applies(p: &Prepared, e: Effect) -> bool {
    let all_driven = p.robot.wheels.iter().all(|w| w.driven);
    let all_known = p.wheels.iter().all(|w| w.enc_rad.is_some());
    match e {
        Effect::SlipCreep => all_driven,
        Effect::SlipBody => all_driven || (all_known && driven_kinematics(&p.robot).is_some()),
        _ => true,
    }
}

/// The driven wheels' kinematics (indices into the robot's wheels), when they resolve the
/// body twist on their own.
fn driven_kinematics(robot: &calib_core::Robot) -> Option<(Kinematics<f64>, Vec<usize>)> {
    let idx: Vec<usize> = (0..robot.wheels.len())
        .filter(|&i| robot.wheels[i].driven)
        .collect();
    if idx.is_empty() {
        return None;
    }
    let mut sub = robot.clone();
    sub.wheels.clear();
    for &i in &idx {
        let _ = sub.wheels.push(robot.wheels[i].clone());
    }
    Kinematics::<f64>::new(&sub, &Corrections::None)
        .ok()
        .map(|k| (k, idx))
}

/// The wheel angles the ground stage should use under the body-bound or creep forms of
/// traction slip (`None`: the model has neither, use the measured angles).
pub fn slip_angles(
    p: &Prepared,
    m: &Model,
    angles: &[Option<&[f64]>],
) -> Option<Vec<Option<Vec<f64>>>> {
    let body = m.get(Effect::SlipBody).map(|v| v[0]);
    let creep = m.get(Effect::SlipCreep).map(|v| v[0]);
    if body.is_none() && creep.is_none() {
        return None;
    }
    let n = p.rows();
    let robot = m.apply_geometry(&p.robot);
    let mut out: Vec<Option<Vec<f64>>> = angles.iter().map(|a| a.map(|s| s.to_vec())).collect();
    if let Some(tc) = creep {
        // Each contact follows its wheel with slip = creep_s * acceleration.
        for (i, a) in out.iter_mut().enumerate() {
            let Some(a) = a else { continue };
            if !robot.wheels[i].driven {
                continue;
            }
            let src = a.clone();
            let mut c = 0.0;
            let mut pos = src[0];
            for k in 0..n - 1 {
                let dt = (p.t[k + 1] - p.t[k]).max(crate::MIN_DT_S);
                let want = (src[k + 1] - src[k]) / dt;
                let e = (-dt / tc.max(crate::MIN_DT_S)).exp();
                pos += want * dt + (c - want) * tc * (1.0 - e);
                c = want + (c - want) * e;
                a[k + 1] = pos;
            }
        }
    }
    if let Some(mu) = body {
        let known: Vec<usize> = (0..out.len()).filter(|&i| out[i].is_some()).collect();
        if known.len() != robot.wheels.len() {
            return Some(out);
        }
        if !robot.wheels.iter().all(|w| w.driven) {
            body_bound_with_free_wheels(p, &robot, mu, &mut out);
            return Some(out);
        }
        let Ok(kin) = Kinematics::<f64>::new(&robot, &Corrections::None) else {
            return Some(out);
        };
        let m_w = known.len();
        let mut inc = vec![0.0; m_w];
        let mut dw = vec![0.0; m_w];
        // Body velocity from the wheels, over three rows (encoder quantisation).
        let vel = |k: usize, inc: &mut [f64], out: &[Option<Vec<f64>>]| -> Twist<f64> {
            let (k1, k2) = (k.saturating_sub(1), (k + 2).min(n - 1));
            let span = (p.t[k2] - p.t[k1]).max(crate::MIN_DT_S);
            for (j, &i) in known.iter().enumerate() {
                let a = out[i].as_ref().expect("known");
                inc[j] = (a[k2] - a[k1]) / span;
            }
            kin.forward(inc)
        };
        let mut v: Option<(f64, f64)> = None;
        let mut shift = vec![0.0; m_w];
        let src = out.clone();
        for k in 0..n - 1 {
            let dt = (p.t[k + 1] - p.t[k]).max(crate::MIN_DT_S);
            let want = vel(k, &mut inc, &src);
            let a = (mu * crate::replay::G * p.driven_share[k]).max(1e-12) * dt;
            let (vx0, vy0) = *v.get_or_insert((want.vx, want.vy));
            let (dx, dy) = (want.vx - vx0, want.vy - vy0);
            let d = dx.hypot(dy);
            let f = if d > a { a / d } else { 1.0 };
            let (vx1, vy1) = (vx0 + dx * f, vy0 + dy * f);
            v = Some((vx1, vy1));
            // Body displacement lost (or gained) this row against what the wheels say.
            let diff = Twist::new(
                (0.5 * (vx0 + vx1) - want.vx) * dt,
                (0.5 * (vy0 + vy1) - want.vy) * dt,
                0.0,
            );
            kin.inverse_into(&diff, &mut dw);
            for (j, &i) in known.iter().enumerate() {
                shift[j] += dw[j];
                if let Some(a) = out[i].as_mut() {
                    a[k + 1] = src[i].as_ref().expect("known")[k + 1] + shift[j];
                }
            }
        }
    }
    Some(out)
}

/// The body bound on a robot with free wheels: the driven wheels say what the drive asks
/// of the body; its linear velocity follows at most `mu g` times the driven wheels'
/// share of the weight per second (the yaw rate as asked), and every wheel's angle is
/// then what that body motion makes of it. The free wheels' encoders, which roll with
/// the body, are compared with those angles by the ground stage, not used to drive it.
fn body_bound_with_free_wheels(
    p: &Prepared,
    robot: &calib_core::Robot,
    mu: f64,
    out: &mut [Option<Vec<f64>>],
) {
    let Some((drive, idx)) = driven_kinematics(robot) else {
        return;
    };
    let Ok(all) = Kinematics::<f64>::new(robot, &Corrections::None) else {
        return;
    };
    let n = p.rows();
    let src: Vec<Vec<f64>> = idx
        .iter()
        .map(|&i| out[i].clone().expect("every wheel has angles"))
        .collect();
    let mut rates = vec![0.0; idx.len()];
    // What the drive asks, over three rows (encoder quantisation).
    let asked = |k: usize, rates: &mut [f64]| -> Twist<f64> {
        let (k1, k2) = (k.saturating_sub(1), (k + 2).min(n - 1));
        let span = (p.t[k2] - p.t[k1]).max(crate::MIN_DT_S);
        for (r, a) in rates.iter_mut().zip(&src) {
            *r = (a[k2] - a[k1]) / span;
        }
        drive.forward(rates)
    };
    let (mut dw, mut dw_body) = (vec![0.0; robot.wheels.len()], vec![0.0; robot.wheels.len()]);
    let mut angle: Vec<f64> = out
        .iter()
        .map(|a| a.as_ref().map_or(0.0, |a| a[0]))
        .collect();
    let mut v: Option<(f64, f64)> = None;
    for k in 0..n - 1 {
        let dt = (p.t[k + 1] - p.t[k]).max(crate::MIN_DT_S);
        let want = asked(k, &mut rates);
        let a = (mu * crate::replay::G * p.driven_share[k]).max(1e-12) * dt;
        let (vx0, vy0) = *v.get_or_insert((want.vx, want.vy));
        let (dx, dy) = (want.vx - vx0, want.vy - vy0);
        let d = dx.hypot(dy);
        let f = if d > a { a / d } else { 1.0 };
        let (vx1, vy1) = (vx0 + dx * f, vy0 + dy * f);
        v = Some((vx1, vy1));
        // The driven wheels keep their own increments less what the body did not follow;
        // the free wheels roll with the body.
        let body = Twist::new(0.5 * (vx0 + vx1) * dt, 0.5 * (vy0 + vy1) * dt, 0.0);
        let lag = Twist::new(body.vx - want.vx * dt, body.vy - want.vy * dt, 0.0);
        all.inverse_into(&lag, &mut dw);
        all.inverse_into(&Twist::new(body.vx, body.vy, want.omega * dt), &mut dw_body);
        for (i, a) in out.iter_mut().enumerate() {
            let Some(a) = a else { continue };
            angle[i] += match idx.iter().position(|&x| x == i) {
                Some(j) => src[j][k + 1] - src[j][k] + dw[i],
                None => dw_body[i],
            };
            a[k + 1] = angle[i];
        }
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
