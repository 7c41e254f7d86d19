//! Noise-free synthetic recordings for calibrate's unit tests. The encoders count a
//! known wheel motion, and the poses are dead-reckoned from those very counts with a
//! known robot (calib-core's exact arc, as the fit steps), so that robot explains the
//! poses to rounding and any other geometry does not.

use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{integrate_arc, Pose};
use calib_core::robot::Robot;
use formats::recording::Recording;

/// The robot file `robots/<name>.toml`.
pub(super) fn robot(name: &str) -> Robot {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

/// `rows` rows at `rate_hz`. Wheel i turns at `rates(t)[i]` rad/s, its angle counted at
/// the robot's encoder resolution; the poses (every row) are `truth` dead-reckoned over
/// those counts from `start`, read back as calibrate reads them (angles from the first
/// count, increments between rows).
pub(super) fn recording(
    truth: &Robot,
    rows: usize,
    rate_hz: f64,
    start: Pose<f64>,
    rates: impl Fn(f64) -> Vec<f64>,
) -> Recording {
    let rpc = truth.drive.rad_per_count().unwrap();
    let n = truth.wheels.len();
    let t: Vec<f64> = (0..rows).map(|k| k as f64 / rate_hz).collect();
    let mut angle = vec![0.0; n];
    let mut counts: Vec<Vec<i64>> = vec![Vec::with_capacity(rows); n];
    for (k, &tk) in t.iter().enumerate() {
        if k > 0 {
            for (a, w) in angle.iter_mut().zip(rates(tk)) {
                *a += w / rate_hz;
            }
        }
        for (c, a) in counts.iter_mut().zip(&angle) {
            c.push((a / rpc).round() as i64);
        }
    }
    let kin = Kinematics::<f64>::new(truth, &Corrections::None).unwrap();
    let rad = |i: usize, k: usize| (counts[i][k] - counts[i][0]) as f64 * rpc;
    let mut pose = start;
    let mut rec = Recording::new(truth, false, true);
    for k in 0..rows {
        if k > 0 {
            let inc: Vec<f64> = (0..n).map(|i| rad(i, k) - rad(i, k - 1)).collect();
            pose = integrate_arc(pose, &kin.forward(&inc));
        }
        rec.x.push(Some(pose.x));
        rec.y.push(Some(pose.y));
        rec.theta.push(Some(pose.theta));
    }
    for (w, c) in rec.wheels.iter_mut().zip(counts) {
        w.enc = Some(c.into_iter().map(Some).collect());
    }
    rec.t = t;
    rec
}

/// A differential drive's wheel rates (rad/s, left and right in the robot's wheel order)
/// wandering both ways: each side 4 rad/s +- 60 %, out of phase, so the path turns left
/// and right on arcs of every radius and the turn rate changes sign.
pub(super) fn wander(robot: &Robot) -> impl Fn(f64) -> Vec<f64> + '_ {
    move |t: f64| {
        robot
            .wheels
            .iter()
            .map(|w| {
                let phase = if w.is_left() { 0.0 } else { 2.0 };
                4.0 * (1.0 + 0.6 * (0.5 * t + phase).sin())
            })
            .collect()
    }
}
