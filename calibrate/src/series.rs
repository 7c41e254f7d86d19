//! A recording reduced to what calibration replays ([`Series`]): the wheels' increments
//! per row and the ground-truth poses, with the encoder glitches, pose glitches and pose
//! jumps found while reading it reported as [`Event`]s, the distance samples the
//! objective compares, and the dead-reckoned [`Path`] of a geometry. Also the
//! per-recording start pose and clocks ([`Nuisance`]) and the dead-reckoning errors a
//! user gets from a geometry ([`dead_reckoning_rmse`]).

use crate::error::CalibrateError;
use crate::params::{robot_with, ParamSpec};
use crate::step::{self, Stepper};
use crate::turn_law::{
    median_step, omni_turn_ratio, turn_ratio, SideMotion, Sides, TurnLaw, Turning, ARC_RHO,
};
use calib_core::correction::{Corrections, LawRange};
use calib_core::diff_laws::DiffLawOdometry;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{integrate_arc, Odometry, Pose};
use calib_core::omni_laws::OmniLawOdometry;
use calib_core::robot::{Robot, RobotKind};
use fitkit::series::unwrap_angles;
use formats::recording::Recording;
use serde::Serialize;

/// Smallest 99th-percentile increment the encoder-glitch threshold scales from (rad): a
/// wheel that never moves has none, and any count is then a glitch candidate.
const MIN_INCREMENT_RAD: f64 = 1e-9;
/// Least pose samples per recording.
pub const MIN_POSES: usize = 20;
/// The dead-reckoning objective compares positions every this much travel (m), turns in
/// place counted as the arc the wheels' lever arm sweeps: standstill and slow corners do
/// not outweigh distance (OptiOdom compares every 0.5 m).
pub const SAMPLE_STEP_M: f64 = 0.05;

/// A recording reduced to what calibration replays: wheel angles per row and poses.
#[derive(Debug, Clone)]
pub struct Series {
    /// The recording's name as given.
    pub name: String,
    /// Time of each row, s.
    pub t: Vec<f64>,
    /// Per row, per wheel: angle increment to the next row (rad), row after row
    /// ([`Series::wheels`] values a row).
    pub(super) inc: Vec<f64>,
    /// Wheels per row of `inc`.
    pub(super) wheels: usize,
    pub(crate) pose_row: Vec<usize>,
    pub(crate) px: Vec<f64>,
    pub(crate) py: Vec<f64>,
    pub(crate) pth: Vec<f64>,
    /// Wheeled-legged robots: (front, rear) leg angles per row, rad; they move the wheel
    /// contacts along x, so the kinematics follow them.
    pub(super) legs: Option<Vec<(f64, f64)>>,
    /// Robots with sides: turn ratio rho per increment ([`turn_ratio`]).
    pub(super) rho: Option<Vec<f64>>,
    /// Robots with sides: how the left and right sides move per increment, at nominal
    /// radii ([`turn_ratio`]).
    pub(super) motion: Option<Vec<SideMotion>>,
    /// Pose samples (indices into px...) the dead-reckoning objective compares: one every
    /// [`SAMPLE_STEP_M`] of travel (turns in place counted at the wheels' lever arm).
    pub(crate) samples: Vec<usize>,
    /// Pose samples where dead reckoning restarts from the measured pose (the first one,
    /// and the end of every event one geometry cannot explain), sorted.
    pub(crate) anchors: Vec<Anchor>,
    /// Single-sample glitches and pose jumps found while reading (reported as events).
    pub(crate) glitches: Vec<Event>,
    /// Pose noise per sample (m) the poses' steps show against the wheels', from their
    /// median departure; `None` when too few samples.
    pub pose_noise_m: Option<f64>,
    /// Pose indices where the pose stream jumps (the first sample after each).
    pub(crate) jumps: Vec<usize>,
}

/// Separates a recording's name from the number of its part after a pose jump.
pub const PART_SEP: &str = "#";

/// Poses scattering more than this per sample (m) are SLAM-like (motion capture scatters
/// well under a millimetre): calibrate then fits each recording's start pose, because dead
/// reckoning from one noisy pose would tilt the whole recording.
pub const NOISY_POSES_M: f64 = 0.002;

/// A pose jump's position step, in medians of the windowed steps (a Rayleigh median is
/// 1.18 sigma: about 7 sigma).
pub const JUMP_SIGMAS: f64 = 6.0;
/// Pose samples averaged on each side of a candidate jump.
pub const JUMP_WINDOW: usize = 10;
/// Share of a jump's windowed step its single step must carry (a slip spreads it).
pub const JUMP_ONE_STEP: f64 = 0.5;
/// Smallest position jump, m: keeps a sub-millimetre motion-capture stream from
/// flagging its own noise.
pub const JUMP_MIN_M: f64 = 0.01;

/// Pose samples one every `step` of travel (|dp| + lever |dtheta| between samples), the
/// first and last included.
fn distance_samples(px: &[f64], py: &[f64], pth: &[f64], lever: f64, step: f64) -> Vec<usize> {
    let n = px.len();
    let mut v = vec![0];
    let mut d = 0.0;
    let mut next = step;
    for j in 1..n {
        d += (px[j] - px[j - 1]).hypot(py[j] - py[j - 1]) + lever * (pth[j] - pth[j - 1]).abs();
        if d >= next {
            v.push(j);
            next = d + step;
        }
    }
    if n > 1 && *v.last().unwrap_or(&0) != n - 1 {
        v.push(n - 1);
    }
    v
}

impl Series {
    /// Checks the recording has encoders for every wheel and ground truth.
    pub fn new(name: &str, robot: &Robot, rec: &Recording) -> Result<Series, CalibrateError> {
        let err = |m: String| CalibrateError {
            recording: Some(name.to_string()),
            message: m,
        };
        if rec.wheels.len() != robot.wheels.len() {
            return Err(err(format!(
                "the recording has {} wheels, the robot {}",
                rec.wheels.len(),
                robot.wheels.len()
            )));
        }
        let rpc = robot
            .drive
            .rad_per_count()
            .ok_or_else(|| err("the robot file gives no encoder resolution".into()))?;
        let n = rec.len();
        let mut angles = Vec::new();
        for (w, s) in robot.wheels.iter().zip(&rec.wheels) {
            let cells = s.enc.as_ref().ok_or_else(|| {
                err(format!(
                    "no encoder column for wheel '{}' (calibrate replays encoders)",
                    w.name
                ))
            })?;
            let counts = fitkit::series::fill(cells)
                .ok_or_else(|| err(format!("the encoder column of wheel '{}' is empty", w.name)))?;
            let c0 = counts[0];
            angles.push(
                counts
                    .iter()
                    .map(|c| (c - c0) as f64 * rpc)
                    .collect::<Vec<f64>>(),
            );
        }
        if n < MIN_POSES {
            return Err(err(format!(
                "{n} row(s): calibrate needs a recording of motion, at least {MIN_POSES} rows with encoders and poses"
            )));
        }
        let mut inc: Vec<Vec<f64>> = (0..n.saturating_sub(1))
            .map(|k| angles.iter().map(|a| a[k + 1] - a[k]).collect())
            .collect();
        let mut glitches = Vec::new();
        // One increment no motor makes (20 times the 99th percentile of the wheel's
        // increments): a counter glitch, replaced by its neighbours' mean and reported.
        for (w, wheel) in robot.wheels.iter().enumerate() {
            let mut a: Vec<f64> = inc.iter().map(|v| v[w].abs()).collect();
            a.sort_by(|x, y| x.total_cmp(y));
            let q = a.get(a.len() * 99 / 100).copied().unwrap_or(0.0);
            let thr = 20.0 * q.max(MIN_INCREMENT_RAD);
            let bad: Vec<usize> = (0..inc.len())
                .filter(|&k| inc[k][w].abs() > thr || inc[k][w].is_nan())
                .collect();
            for &k in &bad {
                let good = |k: Option<usize>| k.filter(|k| !bad.contains(k)).map(|k| inc[k][w]);
                let nb: Vec<f64> = [k.checked_sub(1), Some(k + 1).filter(|&k| k < inc.len())]
                    .into_iter()
                    .filter_map(good)
                    .collect();
                let v = inc[k][w];
                inc[k][w] = nb.iter().sum::<f64>() / nb.len().max(1) as f64;
                glitches.push(Event {
                    recording: name.to_string(),
                    kind: "encoder_glitch",
                    t_s: rec.t[k + 1] - rec.t[0],
                    duration_s: 0.0,
                    heading_rad: 0.0,
                    position_m: v * robot.wheels[w].radius_m,
                    handled: "replaced by its neighbours' mean".into(),
                });
                let _ = wheel;
            }
        }
        let (mut pose_row, mut px, mut py, mut pth) = (vec![], vec![], vec![], vec![]);
        for (i, x, y, th) in rec.pose_rows() {
            pose_row.push(i);
            px.push(x);
            py.push(y);
            pth.push(th);
        }
        // One pose sample far from both neighbours (which agree): a motion-capture glitch,
        // dropped and reported.
        let mut j = 1;
        while j + 1 < px.len() {
            let dev = (px[j] - 0.5 * (px[j - 1] + px[j + 1]))
                .hypot(py[j] - 0.5 * (py[j - 1] + py[j + 1]));
            let gap = (px[j + 1] - px[j - 1]).hypot(py[j + 1] - py[j - 1]);
            if dev > 0.05 && dev > 5.0 * gap || dev.is_nan() {
                glitches.push(Event {
                    recording: name.to_string(),
                    kind: "pose_glitch",
                    t_s: rec.t[pose_row[j]] - rec.t[0],
                    duration_s: 0.0,
                    heading_rad: 0.0,
                    position_m: dev,
                    handled: "the sample is dropped".into(),
                });
                for v in [&mut px, &mut py, &mut pth] {
                    v.remove(j);
                }
                pose_row.remove(j);
            } else {
                j += 1;
            }
        }
        let moved: f64 = px
            .windows(2)
            .zip(py.windows(2))
            .map(|(a, b)| (a[1] - a[0]).hypot(b[1] - b[0]))
            .sum();
        if moved > 0.1 && angles.iter().all(|a| a.iter().all(|v| *v == 0.0)) {
            return Err(err(format!(
                "the poses move {moved:.2} m and no encoder moves: calibrate needs the wheels' counts"
            )));
        }
        if pose_row.len() < MIN_POSES {
            return Err(err(format!(
                "{} ground-truth pose samples (x, y, theta), calibrate needs at least {MIN_POSES}: record with motion capture",
                pose_row.len()
            )));
        }
        unwrap_angles(&mut pth);
        let legs = if robot.kind == RobotKind::WheeledLegged {
            let fill = |col: &Option<Vec<Option<f64>>>, which: &str| {
                let cells = col.as_ref().ok_or_else(|| {
                    err(format!("no {which} leg angle column (a wheeled-legged robot's wheels move with its legs)"))
                })?;
                fitkit::series::fill(cells)
                    .ok_or_else(|| err(format!("the {which} leg angle column is empty")))
            };
            let (f, r) = (fill(&rec.leg_front, "front")?, fill(&rec.leg_rear, "rear")?);
            Some(f.into_iter().zip(r).collect())
        } else {
            None
        };
        let samples =
            distance_samples(&px, &py, &pth, robot.mean_wheel_distance_m(), SAMPLE_STEP_M);
        let (rho, motion) = match robot.kind {
            RobotKind::SkidSteer | RobotKind::DiffDrive => {
                let (r, v) = turn_ratio(robot, &inc, &rec.t);
                (Some(r), Some(v))
            }
            // An omni robot's turn law acts on its twist: its turn ratio, no sides.
            RobotKind::Omni => (omni_turn_ratio(robot, &inc, &rec.t), None),
            RobotKind::WheeledLegged => (None, None),
        };
        let wheels = robot.wheels.len();
        let first = Anchor::first(&px, &py, &pth);
        let mut s = Series {
            name: name.to_string(),
            t: rec.t.clone(),
            inc: inc.concat(),
            wheels,
            pose_row,
            px,
            py,
            pth,
            legs,
            rho,
            motion,
            samples,
            anchors: vec![first],
            glitches,
            pose_noise_m: None,
            jumps: vec![],
        };
        s.find_pose_jumps(robot);
        Ok(s)
    }

    /// Pose jumps (a SLAM trajectory closing a loop or relocalising): the poses' position
    /// offset from the wheels (accumulated over the pose steps) steps by more than the
    /// noise allows. The offset's mean over the [`JUMP_WINDOW`] samples after each sample
    /// is compared with its mean over the ones before (averaging beats the per-sample
    /// noise down; geometry drifts far less within a few samples); a step larger than
    /// [`JUMP_SIGMAS`] times the median step (about 7 sigma) and than [`JUMP_MIN_M`], at
    /// its local maximum, made mostly in one sample step ([`JUMP_ONE_STEP`]), is a jump.
    /// Only in SLAM-like pose streams (noisier than [`NOISY_POSES_M`]). It is reported, and dead reckoning restarts from the measured
    /// pose after it, so a jump weighs as one sample, not as an offset on everything after
    /// it. Also estimates the pose noise per sample from single steps of the poses
    /// against the wheels'.
    fn find_pose_jumps(&mut self, robot: &Robot) {
        let Ok(kin) = Kinematics::<f64>::new(robot, &Corrections::None) else {
            return;
        };
        let mut path = Path::default();
        let n = self.pose_row.len();
        if !self.path(robot, &kin, &mut path) || n < 2 * JUMP_WINDOW + 2 {
            return;
        }
        // Offset of the poses from the wheels, accumulated step by step: each step of the
        // wheels turned into the frame of the measured heading at its start, so a heading
        // error of the geometry does not swing the offset around.
        let mut off = vec![(0.0, 0.0, 0.0); n];
        for j in 1..n {
            let (k0, k1) = (self.pose_row[j - 1], self.pose_row[j]);
            let rot = self.pth[j - 1] - path.th[k0];
            let (c, sn) = (rot.cos(), rot.sin());
            let (ox, oy) = (path.x[k1] - path.x[k0], path.y[k1] - path.y[k0]);
            off[j] = (
                off[j - 1].0 + self.px[j] - self.px[j - 1] - (c * ox - sn * oy),
                off[j - 1].1 + self.py[j] - self.py[j - 1] - (sn * ox + c * oy),
                off[j - 1].2 + (self.pth[j] - self.pth[j - 1]) - (path.th[k1] - path.th[k0]),
            );
        }
        let median = |mut a: Vec<f64>| {
            a.sort_by(|x, y| x.total_cmp(y));
            a[a.len() / 2]
        };
        // Per-sample noise: a single step's departure is the difference of two samples'
        // noise, per axis sqrt(2) sigma, its length Rayleigh with median sqrt(2 ln 2) x that.
        let steps: Vec<f64> = (1..n)
            .map(|j| (off[j].0 - off[j - 1].0).hypot(off[j].1 - off[j - 1].1))
            .collect();
        let noise = median(steps) / (2.0 * std::f64::consts::LN_2).sqrt() / 2f64.sqrt();
        self.pose_noise_m = Some(noise);
        if noise <= NOISY_POSES_M {
            // Motion capture does not close loops. What looks like a jump in it is the
            // end of a turn giving back the heading the poses led by (the real squares'
            // run 02 at 17.5 s), which the event detection handles.
            return;
        }
        let w = JUMP_WINDOW;
        let mut pre = vec![(0.0, 0.0, 0.0); n + 1];
        for j in 0..n {
            pre[j + 1] = (
                pre[j].0 + off[j].0,
                pre[j].1 + off[j].1,
                pre[j].2 + off[j].2,
            );
        }
        let mean = |a: usize, b: usize| {
            let k = (b - a) as f64;
            (
                (pre[b].0 - pre[a].0) / k,
                (pre[b].1 - pre[a].1) / k,
                (pre[b].2 - pre[a].2) / k,
            )
        };
        // step[j]: mean of samples j..j+w minus mean of j-w..j.
        let mut dp = vec![0.0; n];
        let mut dh = vec![0.0; n];
        for j in w..=n - w {
            let (a, b) = (mean(j - w, j), mean(j, j + w));
            dp[j] = (b.0 - a.0).hypot(b.1 - a.1);
            dh[j] = b.2 - a.2;
        }
        let lim_p = (JUMP_SIGMAS * median(dp[w..=n - w].to_vec())).max(JUMP_MIN_M);
        // A jump happens between two samples: its single step carries at least
        // JUMP_ONE_STEP of the windowed step. A wheel slip (or a pose stream lagging the
        // wheels) spreads the same offset over the many steps of a turn.
        let one = |j: usize| {
            (
                (off[j].0 - off[j - 1].0).hypot(off[j].1 - off[j - 1].1),
                (off[j].2 - off[j - 1].2).abs(),
            )
        };
        // Position only: a heading step of a degree or two between two samples is what a
        // turn in place does to any pose stream that leads or lags the wheels a little
        // (the real squares show several per turn); a map correction moves the position.
        let score = |j: usize| {
            if one(j).0 >= JUMP_ONE_STEP * dp[j] {
                dp[j] / lim_p
            } else {
                0.0
            }
        };
        for j in w..=n - w {
            let sj = score(j);
            let local_max = (j.saturating_sub(w).max(w)..=(j + w).min(n - w))
                .all(|k| k == j || score(k) < sj || (score(k) == sj && k > j));
            if sj <= 1.0 || !local_max {
                continue;
            }
            self.glitches.push(Event {
                recording: self.name.clone(),
                kind: "pose_jump",
                t_s: self.t[self.pose_row[j]] - self.t[0],
                duration_s: self.t[self.pose_row[j]] - self.t[self.pose_row[j - 1]],
                heading_rad: dh[j],
                position_m: dp[j],
                handled: "the recording is split there and each part fitted from its own start"
                    .into(),
            });
            self.jumps.push(j);
        }
    }

    /// The recording cut at its pose jumps: each part has its own start (an anchor in
    /// the dead-reckoning objective, a fitted start pose with `--free-start`). The rows
    /// between a jump's two pose samples belong to neither. Parts after the first are
    /// named `<name>#2`, `<name>#3`... ([`CvBy::group`](crate::CvBy::group) keeps them with the first); a part
    /// with fewer than [`MIN_POSES`] pose samples is dropped.
    pub(crate) fn split_at_jumps(self, robot: &Robot) -> Vec<Series> {
        if self.jumps.is_empty() {
            return vec![self];
        }
        let mut cuts = vec![(0usize, 0usize)]; // (first pose index, first row)
        for &j in &self.jumps {
            cuts.push((j, self.pose_row[j]));
        }
        let n_pose = self.pose_row.len();
        let mut out = Vec::new();
        for (k, &(p0, r0)) in cuts.iter().enumerate() {
            let (p1, r1) = match cuts.get(k + 1) {
                // This part ends at the pose sample before the jump.
                Some(&(pj, _)) => (pj, self.pose_row[pj - 1] + 1),
                None => (n_pose, self.t.len()),
            };
            if p1 - p0 < MIN_POSES {
                continue;
            }
            let rows = r0..r1;
            let (px, py, pth) = (
                self.px[p0..p1].to_vec(),
                self.py[p0..p1].to_vec(),
                self.pth[p0..p1].to_vec(),
            );
            let samples =
                distance_samples(&px, &py, &pth, robot.mean_wheel_distance_m(), SAMPLE_STEP_M);
            let first = Anchor::first(&px, &py, &pth);
            out.push(Series {
                name: if k == 0 {
                    self.name.clone()
                } else {
                    format!("{}{PART_SEP}{}", self.name, k + 1)
                },
                t: self.t[rows.clone()].to_vec(),
                inc: self.inc[r0 * self.wheels..(r1 - 1) * self.wheels].to_vec(),
                wheels: self.wheels,
                pose_row: self.pose_row[p0..p1].iter().map(|r| r - r0).collect(),
                px,
                py,
                pth,
                legs: self.legs.as_ref().map(|l| l[rows.clone()].to_vec()),
                rho: self.rho.as_ref().map(|r| r[r0..r1 - 1].to_vec()),
                motion: self.motion.as_ref().map(|v| v[r0..r1 - 1].to_vec()),
                samples,
                anchors: vec![first],
                glitches: if k == 0 {
                    self.glitches.clone()
                } else {
                    vec![]
                },
                pose_noise_m: self.pose_noise_m,
                jumps: vec![],
            });
        }
        if out.is_empty() {
            // Every part too short: fitted whole, the jump reported.
            return vec![self];
        }
        out
    }

    /// The start the dead-reckoning objective uses: the first measured pose, clocks as
    /// recorded.
    pub fn first_pose(&self) -> Nuisance {
        Nuisance {
            x0_m: self.px[0],
            y0_m: self.py[0],
            theta0_rad: self.pth[0],
            time_offset_s: 0.0,
            clock_ratio: 1.0,
        }
    }

    /// How the recording turns, from the wheels (nominal geometry): [`Turning`]. An omni
    /// robot's turn counts as 2 |omega| L (a differential drive's |d_r - d_l|, L the
    /// wheels' mean distance from the centre; no speed terms). All zero for a
    /// wheeled-legged robot.
    pub(crate) fn turning(&self, robot: &Robot) -> Turning {
        let mut t = Turning::default();
        let Some(rho) = &self.rho else {
            return t;
        };
        if robot.kind == RobotKind::Omni {
            let Ok(kin) = Kinematics::<f64>::new(robot, &Corrections::None) else {
                return t;
            };
            let lever = robot.mean_wheel_distance_m();
            for (inc, &rho) in self.incs().zip(rho) {
                let d = 2.0 * (kin.forward(inc).omega * lever).abs();
                t.all += d;
                t.arc_term += d * calib_core::kinematics::turn_law_share(rho);
                if (ARC_RHO.0..=ARC_RHO.1).contains(&rho) {
                    t.arcs += d;
                }
            }
            return t;
        }
        let sides = Sides::new(robot);
        for (k, (inc, &rho)) in self.incs().zip(rho).enumerate() {
            let (l, r) = sides.travel(inc);
            if let Some(v) = self.motion.as_ref().map(|m| m[k].speed) {
                t.travel += l.abs() + r.abs();
                t.speed_term += l.abs() * v[0] + r.abs() * v[1];
            }
            let d = (r - l).abs();
            t.all += d;
            t.arc_term += d * sides.law_share(rho);
            if (ARC_RHO.0..=ARC_RHO.1).contains(&rho) {
                t.arcs += d;
            }
        }
        t
    }

    /// The motion a law fitted on this recording covers ([`LawRange`]): the turn ratios
    /// of its moving rows and its fastest side (m/s), as the stepping sees them (smoothed over 0.1 s either side). A
    /// recording that never moves covers nothing ([`empty_range`]); one without turn
    /// ratios (a wheeled-legged robot) everything.
    pub(crate) fn law_range(&self) -> LawRange {
        let Some(rho) = &self.rho else {
            return LawRange::UNBOUNDED;
        };
        let mut g = empty_range();
        for (k, (inc, &r)) in self.incs().zip(rho).enumerate() {
            let moving = match &self.motion {
                Some(m) => m[k].speed[0] + m[k].speed[1] > 0.0,
                None => inc.iter().any(|d| *d != 0.0),
            };
            if !moving {
                continue;
            }
            g.rho_min = g.rho_min.min(r as f32);
            g.rho_max = g.rho_max.max(r as f32);
            if let Some(m) = &self.motion {
                let m = m[k];
                let v = m.speed[0].max(m.speed[1]) as f32;
                g.speed_max_m_s = g.speed_max_m_s.max(v);
            }
        }
        if self.motion.is_none() {
            g.speed_max_m_s = f32::INFINITY;
        }
        g
    }

    /// The wheel increments, row after row.
    pub(super) fn incs(&self) -> std::slice::ChunksExact<'_, f64> {
        self.inc.chunks_exact(self.wheels.max(1))
    }

    /// Number of ground-truth pose samples.
    pub fn pose_samples(&self) -> usize {
        self.pose_row.len()
    }

    /// Dead-reckoned path (x, y, theta per row from the origin) of `robot`, whose
    /// kinematics at its described geometry are `kin`. On a wheeled-legged robot the
    /// kinematics follow the leg angles (rebuilt only when they move). False when the
    /// wheels cannot resolve the body twist at some leg pose.
    pub(crate) fn path(&self, robot: &Robot, kin: &Kinematics<f64>, out: &mut Path) -> bool {
        self.path_with(robot, kin, &TurnLaw::default(), out)
    }

    /// [`Series::path`] with a skid-steer robot's turn-radius law.
    pub(crate) fn path_with(
        &self,
        robot: &Robot,
        kin: &Kinematics<f64>,
        law: &TurnLaw,
        out: &mut Path,
    ) -> bool {
        self.path_by(robot, &Stepper::new(robot, kin, law), out)
    }

    /// [`Series::path_with`] with the stepping of `robot` at its geometry prepared.
    pub(crate) fn path_by(&self, robot: &Robot, stepper: &Stepper, out: &mut Path) -> bool {
        out.clear();
        let rows = self.t.len();
        out.x.reserve(rows);
        out.y.reserve(rows);
        out.th.reserve(rows);
        let mut p = Pose::new(0.0, 0.0, 0.0);
        out.push(p);
        let (mut x, mut y, mut h) = (0.0, 0.0, step::Heading::new());
        if let (Some(rho), Some(motion), Some((sides, law))) =
            (&self.rho, &self.motion, stepper.sides())
        {
            for ((inc, &rho), &v) in self.incs().zip(rho).zip(motion) {
                step::arc_step(&mut x, &mut y, &mut h, &sides.step(law, rho, v, inc));
                out.push(Pose::new(x, y, h.th));
            }
            return true;
        }
        if let (Some(rho), true) = (&self.rho, stepper.omni_arc() != 0.0) {
            for (inc, &rho) in self.incs().zip(rho) {
                step::arc_step(&mut x, &mut y, &mut h, &stepper.forward_at(inc, rho));
                out.push(Pose::new(x, y, h.th));
            }
            return true;
        }
        let Some(legs) = &self.legs else {
            for inc in self.incs() {
                step::arc_step(&mut x, &mut y, &mut h, &stepper.forward(inc));
                out.push(Pose::new(x, y, h.th));
            }
            return true;
        };
        let mut at: Option<((f64, f64), Kinematics<f64>)> = None;
        for (k, inc) in self.incs().enumerate() {
            let l = legs[k];
            if at
                .as_ref()
                .is_none_or(|(a, _)| (a.0 - l.0).abs() > 1e-6 || (a.1 - l.1).abs() > 1e-6)
            {
                let r = fitkit::geometry::geometry_at(robot, &[], 1.0, Some(l));
                let Ok(kl) = Kinematics::<f64>::new(&r, &Corrections::None) else {
                    return false;
                };
                at = Some((l, kl));
            }
            let kl = &at.as_ref().expect("set above").1;
            p = integrate_arc(p, &kl.forward(inc));
            out.push(p);
        }
        true
    }
}

/// Where dead reckoning restarts: a pose sample and the pose it restarts from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Anchor {
    /// The pose sample (index into px...).
    pub(crate) sample: usize,
    /// The body pose (x, y, theta) dead reckoning restarts from: the measured one at the
    /// first sample (motion capture in the robot's start frame), an estimate from the
    /// samples after a slip ([`detect_events`](crate::events)).
    pub(crate) pose: [f64; 3],
}

impl Anchor {
    /// At the first pose sample, from its measured pose (zeros when there is none).
    pub(crate) fn first(px: &[f64], py: &[f64], pth: &[f64]) -> Anchor {
        let at = |v: &[f64]| v.first().copied().unwrap_or(0.0);
        Anchor {
            sample: 0,
            pose: [at(px), at(py), at(pth)],
        }
    }
}

#[derive(Debug, Clone, Default)]
pub(crate) struct Path {
    pub(crate) x: Vec<f64>,
    pub(crate) y: Vec<f64>,
    pub(crate) th: Vec<f64>,
}

impl Path {
    #[inline]
    fn clear(&mut self) {
        self.x.clear();
        self.y.clear();
        self.th.clear();
    }
    #[inline]
    fn push(&mut self, p: Pose<f64>) {
        self.x.push(p.x);
        self.y.push(p.y);
        self.th.push(p.theta);
    }
}

/// Per-recording nuisance: start pose and recording parameters.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Nuisance {
    /// Start pose x in the motion-capture frame, m.
    pub x0_m: f64,
    /// Start pose y in the motion-capture frame, m.
    pub y0_m: f64,
    /// Start heading in the motion-capture frame, rad.
    pub theta0_rad: f64,
    /// How much later the poses are stamped than the encoders, s.
    pub time_offset_s: f64,
    /// Pose clock rate over encoder clock rate.
    pub clock_ratio: f64,
}

pub(super) const NUIS: usize = 5;

impl Nuisance {
    pub(super) fn from(v: &[f64]) -> Nuisance {
        Nuisance {
            x0_m: v[0],
            y0_m: v[1],
            theta0_rad: v[2],
            time_offset_s: v[3],
            clock_ratio: v[4],
        }
    }
}

/// Dead reckoning from the first measured pose with the given robot and no fitted
/// nuisance: the prediction a user gets (OptiOdom's held-out measure). Position RMSE, m.
pub fn dead_reckoning_rmse(robot: &Robot, s: &Series) -> Option<f64> {
    dead_reckoning_errors(robot, &TurnLaw::default(), s).map(|(rms, _)| rms)
}

/// [`dead_reckoning_rmse`] of a robot whose separation follows `law` (its `robot` the
/// separation of a turn in place: [`Calibration::law_base_robot`](crate::Calibration::law_base_robot)).
pub fn dead_reckoning_rmse_law(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<f64> {
    dead_reckoning_errors(robot, law, s).map(|(rms, _)| rms)
}

/// [`dead_reckoning_rmse`] of the geometry `values` (in `specs` order) of `base`, a
/// skid-steer robot's turn-radius law included.
pub fn fitted_dead_reckoning_rmse(
    base: &Robot,
    specs: &[ParamSpec],
    values: &[f64],
    known: TurnLaw,
    s: &Series,
) -> f64 {
    let r = robot_with(base, specs, values);
    dead_reckoning_errors(&r, &TurnLaw::of(specs, values, known), s)
        .map_or(f64::NAN, |(rms, _)| rms)
}

/// [`fitted_dead_reckoning_rmse`] with the law held at the edges of `range` (the motion
/// of the recordings it was fitted on).
pub(crate) fn fitted_dead_reckoning_rmse_within(
    base: &Robot,
    specs: &[ParamSpec],
    values: &[f64],
    known: TurnLaw,
    range: LawRange,
    s: &Series,
) -> f64 {
    let r = robot_with(base, specs, values);
    dead_reckoning_errors(&r, &TurnLaw::of(specs, values, known).within(range), s)
        .map_or(f64::NAN, |(rms, _)| rms)
}

/// The position RMS of [`dead_reckoning_rmse_law`] and the position error at the last
/// pose sample, m.
pub fn dead_reckoning_errors(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<(f64, f64)> {
    file_path(robot, law, s).map(|path| errors_along(s, &path))
}

/// The poses [`dead_reckoning_errors`] judges: `robot` (its separation following `law`)
/// dead-reckoning `s` from its first measured pose, one `(t s, x m, y m, theta rad)` per
/// pose sample. `None` when the kinematics do not solve.
pub fn dead_reckoned_poses(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<Vec<Stamped>> {
    file_path(robot, law, s).map(|path| placed_poses(s, &path))
}

/// A robot file's dead-reckoned pose per row of `s`, started at the origin.
fn file_path(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<Path> {
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let mut path = Path::default();
    s.path_with(robot, &kin, law, &mut path).then_some(path)
}

/// [`dead_reckoning_errors`] of a board holding `corrections` (its factors and laws) for
/// `robot`, its nominal robot: the recording's wheel increments go through calib-core's
/// own odometry, the firmware's ([`Kinematics`] with the factors, [`DiffLawOdometry`] and
/// [`OmniLawOdometry`] for the laws, [`Odometry`]'s integration), in f64 and ticking at the median row step.
/// `None` when the factors' kinematics do not solve, and for wheeled-legged robots (the
/// board's odometry has no legs).
pub fn board_dead_reckoning_errors(
    robot: &Robot,
    corrections: &Corrections,
    s: &Series,
) -> Option<(f64, f64)> {
    board_path(robot, corrections, s).map(|path| errors_along(s, &path))
}

/// The poses [`board_dead_reckoning_errors`] judges, as [`dead_reckoned_poses`] gives a
/// robot file's.
pub fn board_dead_reckoned_poses(
    robot: &Robot,
    corrections: &Corrections,
    s: &Series,
) -> Option<Vec<Stamped>> {
    board_path(robot, corrections, s).map(|path| placed_poses(s, &path))
}

/// The board's dead-reckoned pose per row of `s`, started at the origin.
fn board_path(robot: &Robot, corrections: &Corrections, s: &Series) -> Option<Path> {
    if s.legs.is_some() {
        return None;
    }
    let kin = Kinematics::<f64>::new(robot, corrections).ok()?;
    let tick = median_step(&s.t)?;
    let mut laws = DiffLawOdometry::<f64>::new(robot, corrections, tick);
    let mut omni = OmniLawOdometry::<f64>::new(robot, corrections, tick);
    let mut odo = Odometry::<f64>::new(Pose::new(0.0, 0.0, 0.0));
    let mut path = Path::default();
    path.push(odo.pose());
    for inc in s.incs() {
        odo.update(&omni.apply(inc, |p| laws.apply(p, |q| kin.forward(q))));
        path.push(odo.pose());
    }
    Some(path)
}

/// One planar pose at a time: (t s, x m, y m, theta rad).
pub type Stamped = (f64, f64, f64, f64);

/// `path` (a dead-reckoned pose per row started at row 0) at each pose sample, placed at
/// the first measured pose as [`errors_along`] places it.
fn placed_poses(s: &Series, path: &Path) -> Vec<Stamped> {
    let k0 = s.pose_row[0];
    let dth = s.pth[0] - path.th[k0];
    let (c, sn) = (dth.cos(), dth.sin());
    s.pose_row
        .iter()
        .map(|&k| {
            let (dx, dy) = (path.x[k] - path.x[k0], path.y[k] - path.y[k0]);
            (
                s.t[k],
                s.px[0] + c * dx - sn * dy,
                s.py[0] + sn * dx + c * dy,
                path.th[k] + dth,
            )
        })
        .collect()
}

/// The position RMS over every pose sample and the error at the last of `path`, a
/// dead-reckoned pose per row started at row 0, placed at the first measured pose.
fn errors_along(s: &Series, path: &Path) -> (f64, f64) {
    let k0 = s.pose_row[0];
    let dth = s.pth[0] - path.th[k0];
    let (c, sn) = (dth.cos(), dth.sin());
    let (mut acc, mut last) = (0.0, 0.0);
    for j in 0..s.pose_row.len() {
        let k = s.pose_row[j];
        let (dx, dy) = (path.x[k] - path.x[k0], path.y[k] - path.y[k0]);
        let ex = s.px[0] + c * dx - sn * dy - s.px[j];
        let ey = s.py[0] + sn * dx + c * dy - s.py[j];
        last = ex * ex + ey * ey;
        acc += last;
    }
    ((acc / s.pose_row.len() as f64).sqrt(), last.sqrt())
}

/// What a recording's poses and wheels show before any fit, for the refusals of
/// broken input ([`crate::refusals`]): how far the poses spread, and how the measured
/// heading follows the nominal wheels' heading.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Shape {
    /// RMS distance of the measured positions from their mean, m.
    pub(crate) spread_m: f64,
    /// RMS of the measured heading about its mean (unwrapped by its steps, each wrapped
    /// to half a turn), in the file's units.
    pub(crate) heading_spread: f64,
    /// Least-squares slope of the measured heading over the nominal wheels' (both about
    /// their means): 1 / E_b-like, about 1.
    pub(crate) heading_ratio: f64,
    /// Correlation of the measured heading and the nominal wheels' (NaN when the wheels
    /// do not turn at all).
    pub(crate) heading_follow: f64,
}

/// [`Shape`] of `s` for the nominal `robot`; `None` when its kinematics do not solve.
/// The headings themselves are compared, not their steps: a pose's heading noise
/// stays its own size in the heading, while it adds up over the steps.
pub(crate) fn shape(robot: &Robot, s: &Series) -> Option<Shape> {
    let path = file_path(robot, &TurnLaw::default(), s)?;
    let n = s.pose_row.len() as f64;
    let mean = |v: &mut dyn Iterator<Item = f64>| v.sum::<f64>() / n;
    let (mx, my) = (
        mean(&mut s.px.iter().copied()),
        mean(&mut s.py.iter().copied()),
    );
    let spread = mean(
        &mut s
            .px
            .iter()
            .zip(&s.py)
            .map(|(x, y)| (x - mx).powi(2) + (y - my).powi(2)),
    )
    .sqrt();
    let wrap = |a: f64| a - std::f64::consts::TAU * (a / std::f64::consts::TAU).round();
    let mut hm = Vec::with_capacity(s.pose_row.len());
    let mut h = s.pth[0];
    hm.push(h);
    for j in 1..s.pose_row.len() {
        h += wrap(s.pth[j] - s.pth[j - 1]);
        hm.push(h);
    }
    let hw: Vec<f64> = s.pose_row.iter().map(|&k| path.th[k]).collect();
    let (am, aw) = (mean(&mut hm.iter().copied()), mean(&mut hw.iter().copied()));
    let (mut cmw, mut cww, mut cmm) = (0.0, 0.0, 0.0);
    for (m, w) in hm.iter().zip(&hw) {
        cmw += (m - am) * (w - aw);
        cww += (w - aw) * (w - aw);
        cmm += (m - am) * (m - am);
    }
    Some(Shape {
        spread_m: spread,
        heading_spread: (cmm / n).sqrt(),
        heading_ratio: cmw / cww,
        heading_follow: cmw / (cww * cmm).sqrt(),
    })
}

/// The range of no motion at all: the hull with any range is that range.
pub(crate) fn empty_range() -> LawRange {
    LawRange {
        rho_min: 1.0,
        rho_max: 0.0,
        speed_max_m_s: 0.0,
    }
}

/// The motion `series` cover together ([`Series::law_range`]); unbounded when none of
/// them moves.
pub(crate) fn range_of<'a>(series: impl IntoIterator<Item = &'a Series>) -> LawRange {
    let g = series
        .into_iter()
        .fold(empty_range(), |g, s| g.hull(s.law_range()));
    if g.rho_min > g.rho_max {
        LawRange::UNBOUNDED
    } else {
        g
    }
}

/// A fitted time offset beyond this (s) is reported implausible: loggers of one rig are
/// synchronised to well under half a second.
pub const PLAUSIBLE_TIME_OFFSET_S: f64 = 0.5;
/// A clock ratio further than this from 1 is reported implausible (crystals agree to
/// 1e-4; 5 % means resampled or mis-stamped poses).
pub const PLAUSIBLE_CLOCK_DRIFT: f64 = 0.05;

/// An event one geometry cannot explain.
#[derive(Debug, Clone, Serialize)]
pub struct Event {
    /// The recording.
    pub recording: String,
    /// `slip` (odometry and motion capture part for good), `time_lead` (they part and
    /// meet again: one clock leads the other for a moment), `pose_glitch` (one pose
    /// sample far from its neighbours), `encoder_glitch` (one increment no motor makes),
    /// `pose_jump` (the pose stream jumps against the wheels: a SLAM loop closure).
    pub kind: &'static str,
    /// Start, s since the recording's first row.
    pub t_s: f64,
    /// Duration, s.
    pub duration_s: f64,
    /// Heading odometry minus motion capture over the event, rad.
    pub heading_rad: f64,
    /// Position size of the event (a glitch's jump), m.
    pub position_m: f64,
    /// What the fit did with it.
    pub handled: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Travel counts |dp| + lever |dtheta|, a sample every `step` of it: steps of 0.25 m
    /// (exact in binary, so the sums are exact) give a sample every fourth pose; the last
    /// pose is always kept; a turn in place counts at the lever arm, back and forth alike.
    #[test]
    fn distance_samples_fall_every_step_of_travel() {
        let line = |n: usize| -> Vec<f64> { (0..n).map(|j| 0.25 * j as f64).collect() };
        let zeros = |n: usize| vec![0.0; n];
        assert_eq!(
            distance_samples(&line(21), &zeros(21), &zeros(21), 0.1, 1.0),
            [0, 4, 8, 12, 16, 20]
        );
        assert_eq!(
            distance_samples(&line(19), &zeros(19), &zeros(19), 0.1, 1.0),
            [0, 4, 8, 12, 16, 18]
        );
        // In place, 0.125 rad a sample at a 2 m lever (0.25 m), out and back.
        let th = [0.0, 0.125, 0.25, 0.375, 0.5, 0.375, 0.25, 0.125, 0.0];
        assert_eq!(
            distance_samples(&zeros(9), &zeros(9), &th, 2.0, 1.0),
            [0, 4, 8]
        );
        // Standing still: the first and the last pose.
        assert_eq!(
            distance_samples(&zeros(5), &zeros(5), &zeros(5), 2.0, 1.0),
            [0, 4]
        );
    }

    /// A recording too short to calibrate is refused, naming it and the least it needs.
    #[test]
    fn a_recording_shorter_than_min_poses_is_refused_by_name() {
        let robot = crate::synth::robot("mobolab");
        let rec = crate::synth::recording(
            &robot,
            MIN_POSES - 1,
            50.0,
            Pose::new(0.0, 0.0, 0.0),
            crate::synth::wander(&robot),
        );
        let e = Series::new("short", &robot, &rec).unwrap_err();
        assert_eq!(e.recording.as_deref(), Some("short"));
        assert!(
            e.message.contains(&format!("at least {MIN_POSES} rows")),
            "{e}"
        );
        let rec = crate::synth::recording(
            &robot,
            MIN_POSES,
            50.0,
            Pose::new(0.0, 0.0, 0.0),
            crate::synth::wander(&robot),
        );
        let s = Series::new("long enough", &robot, &rec).unwrap();
        assert_eq!(s.pose_samples(), MIN_POSES);
    }
}
