//! What the wheels say the body did, row by row, for the recording stage's checks: the
//! encoders' travel (or, without encoders, the commands held over each row) through the
//! nominal kinematics, as body-frame steps between consecutive rows.

use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::Robot;
use formats::recording::Recording;

/// Per row k >= 1, the body-frame step from row k - 1 to row k (dx, dy, dtheta); row 0
/// is zero. `None` when the robot has neither an encoder nor a command on every driven
/// wheel, or its kinematics cannot be built.
pub(super) fn body_steps(robot: &Robot, rec: &Recording) -> Option<Vec<Twist<f64>>> {
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let nw = robot.wheels.len();
    if rec.wheels.len() != nw || rec.is_empty() {
        return None;
    }
    let rpc = robot.drive.rad_per_count();
    let enc_all = rpc.is_some() && rec.wheels.iter().all(|w| w.enc.is_some());
    let cmd_all = rec.wheels.iter().all(|w| w.cmd.is_some());
    if !enc_all && !cmd_all {
        return None;
    }
    let n = rec.len();
    let mut out = Vec::with_capacity(n);
    out.push(Twist::zero());
    let mut d = vec![0.0; nw];
    for k in 1..n {
        let dt = rec.t[k] - rec.t[k - 1];
        for (i, w) in rec.wheels.iter().enumerate() {
            d[i] = if enc_all {
                match w
                    .enc
                    .as_ref()
                    .and_then(|e| Some((*e.get(k - 1)?, *e.get(k)?)))
                {
                    Some((Some(a), Some(b))) => (b as f64 - a as f64) * rpc.unwrap_or(0.0),
                    _ => 0.0,
                }
            } else {
                w.cmd
                    .as_ref()
                    .and_then(|c| *c.get(k - 1)?)
                    .map_or(0.0, |c| c * dt)
            };
        }
        let tw = kin.forward(&d);
        out.push(
            if tw.vx.is_finite() && tw.vy.is_finite() && tw.omega.is_finite() {
                tw
            } else {
                Twist::zero()
            },
        );
    }
    Some(out)
}

/// The median of `v` (NaN when empty); reorders `v`.
pub(super) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    let mid = v.len() / 2;
    v.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    v[mid]
}

/// 1.4826 times the median absolute deviation from the median: a standard deviation
/// that a few gross values do not move (NaN when empty).
pub(super) fn robust_sd(v: &[f64]) -> f64 {
    let mut w: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    let m = median(&mut w);
    for x in w.iter_mut() {
        *x = (*x - m).abs();
    }
    1.4826 * median(&mut w)
}

/// The resolution a pose channel was written at: the smallest step between consecutive
/// values (0 when every value repeats or the series is short). Continuous readings give a
/// step near the file's printed precision; quantised ones (a capture system reporting
/// whole millimetres) give the quantum, which floors every noise estimate: a robust
/// sigma of quantised data is zero when most steps repeat, and then every step looks like
/// a jump or a stale sample.
pub(super) fn quantum(v: &[f64]) -> f64 {
    let q = v
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| d.is_finite() && *d > 1e-12)
        .fold(f64::INFINITY, f64::min);
    if q.is_finite() {
        q
    } else {
        0.0
    }
}

/// The sd of the difference of two samples each rounded to a grid of step `q` (uniform
/// error of sd q / sqrt 12 each).
pub(super) fn quantum_sd(q: f64) -> f64 {
    q / 6f64.sqrt()
}
