//! Pose jumps: a SLAM trajectory jumps when it closes a loop (or relocalises). Between two
//! consecutive pose samples the body cannot move much further than its wheels say, so a
//! step of the pose stream that departs from the wheel odometry's step by far more than
//! the steps usually do is a jump.
//!
//! The odometry step between two pose stamps comes from the wheel joints (interpolated at
//! the stamps) through the nominal kinematics; its systematic error (a few per cent of the
//! step, a few tenths of a millimetre at walking speed and 30 Hz) is far below the noise
//! of any pose sensor, so the comparison's scatter is the sensor's step noise. A step is a
//! jump when its position or heading departure exceeds [`SIGMAS`] robust scales (1.4826 x
//! the median absolute departure) and a floor ([`MIN_JUMP_M`], [`MIN_JUMP_RAD`]) that
//! keeps a sub-millimetre motion-capture stream from flagging its own noise, and stands
//! out of its [`NEIGHBOURS`] steps on each side (twice their departure at least): a stream
//! lagging the wheels departs on every step of a turn's onset, a jump on one step.

use crate::joints::JointSeries;
use crate::poses::PoseSeries;
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::robot::Robot;
use serde::Serialize;

/// Robust sigmas a step must depart by to be a jump.
pub const SIGMAS: f64 = 6.0;
/// Steps on each side a jump must stand out of (half their departure at most).
pub const NEIGHBOURS: usize = 5;
/// Smallest position jump reported, m.
pub const MIN_JUMP_M: f64 = 0.01;
/// Smallest heading jump reported, rad (about 1 deg).
pub const MIN_JUMP_RAD: f64 = 0.0175;

/// One jump of the pose stream.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Jump {
    /// Stamp of the pose sample before the jump, ns since the epoch.
    pub from_ns: i64,
    /// Stamp of the pose sample after it.
    pub to_ns: i64,
    /// Position departure from the wheel odometry's step, m.
    pub position_m: f64,
    /// Heading departure, rad (signed).
    pub heading_rad: f64,
}

/// The pose steps' departures from the odometry: the robust sigmas (m, rad) and the jumps.
#[derive(Debug, Clone, PartialEq, Default, Serialize)]
pub struct JumpReport {
    /// Robust sigma of the position departure per pose step, m.
    pub step_sigma_m: f64,
    /// Robust sigma of the heading departure per pose step, rad.
    pub step_sigma_rad: f64,
    /// The jumps, in time order.
    pub jumps: Vec<Jump>,
}

/// Joint positions (rad) at `t`, linear between the samples around it.
fn joints_at(js: &JointSeries, t: i64) -> Option<Vec<f64>> {
    let s = &js.stamps_ns;
    let i = s.partition_point(|&x| x < t);
    if i < s.len() && s[i] == t {
        return Some(js.positions[i].clone());
    }
    if i == 0 || i == s.len() {
        return None;
    }
    let w = (t - s[i - 1]) as f64 / (s[i] - s[i - 1]) as f64;
    Some(
        js.positions[i - 1]
            .iter()
            .zip(&js.positions[i])
            .map(|(a, b)| a + (b - a) * w)
            .collect(),
    )
}

fn robust_sigma(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    let mut a: Vec<f64> = v.iter().map(|x| x.abs()).collect();
    a.sort_by(f64::total_cmp);
    1.4826 * a[a.len() / 2]
}

/// Finds the jumps of `poses` against the wheel odometry of `joints` (positions in the
/// robot's wheel order). `None` when the robot's wheels cannot give a body motion.
pub fn find_jumps(robot: &Robot, joints: &JointSeries, poses: &PoseSeries) -> Option<JumpReport> {
    let k = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let mut steps = Vec::new(); // (from, to, position departure, heading departure)
    let mut prev: Option<(usize, Vec<f64>)> = None;
    for i in 0..poses.stamps_ns.len() {
        let Some(q) = joints_at(joints, poses.stamps_ns[i]) else {
            prev = None;
            continue;
        };
        if let Some((j, qp)) = &prev {
            let dq: Vec<f64> = q.iter().zip(qp).map(|(a, b)| a - b).collect();
            let tw = k.forward(&dq);
            // The odometry step in the frame of pose j (midpoint heading for the arc).
            let (c, s) = ((tw.omega / 2.0).cos(), (tw.omega / 2.0).sin());
            let (ox, oy) = (c * tw.vx - s * tw.vy, s * tw.vx + c * tw.vy);
            let th = poses.yaw[*j];
            let (dx, dy) = (poses.x[i] - poses.x[*j], poses.y[i] - poses.y[*j]);
            let (mx, my) = (
                th.cos() * dx + th.sin() * dy,
                -th.sin() * dx + th.cos() * dy,
            );
            let dth = (poses.yaw[i] - poses.yaw[*j]) - tw.omega;
            steps.push((*j, i, (mx - ox).hypot(my - oy), dth));
        }
        prev = Some((i, q));
    }
    let sp = robust_sigma(&steps.iter().map(|s| s.2).collect::<Vec<_>>());
    let sh = robust_sigma(&steps.iter().map(|s| s.3).collect::<Vec<_>>());
    // A jump is one step standing out of its neighbours; steps that depart together
    // (a pose stream lagging the wheels while the robot starts or stops turning departs
    // by the lag x the angular acceleration on every step of the turn's onset, with
    // alternating signs when the lag jitters) are timing, not jumps.
    let isolated = |s: usize, f: &dyn Fn(usize) -> f64| {
        let lo = s.saturating_sub(NEIGHBOURS);
        let hi = (s + NEIGHBOURS + 1).min(steps.len());
        (lo..hi).all(|k| k == s || f(k) < 0.5 * f(s))
    };
    let pos = |k: usize| steps[k].2;
    let head = |k: usize| steps[k].3.abs();
    let jumps = (0..steps.len())
        .filter(|&s| {
            let p = pos(s) > SIGMAS * sp && pos(s) > MIN_JUMP_M && isolated(s, &pos);
            let h = head(s) > SIGMAS * sh && head(s) > MIN_JUMP_RAD && isolated(s, &head);
            p || h
        })
        .map(|s| Jump {
            from_ns: poses.stamps_ns[steps[s].0],
            to_ns: poses.stamps_ns[steps[s].1],
            position_m: steps[s].2,
            heading_rad: steps[s].3,
        })
        .collect();
    Some(JumpReport {
        step_sigma_m: sp,
        step_sigma_rad: sh,
        jumps,
    })
}
