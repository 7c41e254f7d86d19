//! Calibration from whole trajectories: the robot's geometry fitted to one or more
//! recordings with motion-capture ground truth (what OptiOdom does), not only to end
//! points as UMBmark does.
//!
//! Shared by all recordings: the geometry (differential drive: mean wheel scale, E_d,
//! E_b; any other wheel set: per wheel radius scale, mounting-angle offset and distance
//! scale). Per recording (nuisance): the start pose and the recording parameters
//! `time_offset_s` (poses later than encoders when positive) and `clock_ratio` (pose
//! clock over encoder clock).
//!
//! What the data cannot tell is said, not guessed: the covariance of the fit (with the
//! residuals' autocorrelation counted, since drift residuals are not independent
//! samples) gives correlations; pairs that move together are reported `not_separable`
//! with the recording that would separate them, and only their identifiable combination
//! is fitted. Every parameter has a plausible range; a value outside is listed
//! `implausible` with what it most likely stands in for.

pub mod proxy;
mod sens;
mod step;

use crate::replay::unwrap_angles;
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{integrate_arc, Pose};
use calib_core::robot::{Robot, RobotKind};
use formats::recording::Recording;
use nalgebra::{DMatrix, SymmetricEigen};
use serde::Serialize;
use std::cell::RefCell;
use std::fmt;
use step::Stepper;

/// Unit of the position residuals (m): only scales the cost, uncertainties use the
/// observed scatter.
pub(crate) const RES_UNIT_M: f64 = 1e-3;
/// Heading residuals count as position errors at this lever arm (m).
const HEADING_LEVER_M: f64 = 0.1;
/// Default lever arm (m) of the heading residuals in the dead-reckoning objective (as the
/// aligned fit's). On the held-out proxy a longer lever transfers better (geometric mean
/// ratio to OptiOdom for 0.1, 0.3, 1, 3, 10 m: 1.004, 0.997, 0.964, 0.940, 0.934), but at
/// 3 m the heading gain dominates and scale/eb are reported not separable even on
/// two-direction squares (sim and real): [`CalOptions::heading_lever_m`] sets it.
pub const DR_HEADING_LEVER_M: f64 = 0.1;
/// Smallest 99th-percentile increment the encoder-glitch threshold scales from (rad): a
/// wheel that never moves has none, and any count is then a glitch candidate.
const MIN_INCREMENT_RAD: f64 = 1e-9;
/// Least pose samples per recording.
pub const MIN_POSES: usize = 20;
/// The dead-reckoning objective compares positions every this much travel (m), turns in
/// place counted as the arc the wheels' lever arm sweeps: standstill and slow corners do
/// not outweigh distance (OptiOdom compares every 0.5 m).
pub const SAMPLE_STEP_M: f64 = 0.05;
/// |correlation| above which two parameters are reported not separable.
pub const CORR_LIMIT: f64 = 0.95;
/// Two parameters correlated above this whose uncertainty exceeds their value (and
/// [`MATERIAL_SHARE`] of the plausible half-range) are reported not separable too.
pub const WEAK_CORR: f64 = 0.5;
/// Share of a parameter's plausible half-range below which an uncertainty is immaterial:
/// a parameter fitted 0 ± 0.0002 is known, not lost.
pub const MATERIAL_SHARE: f64 = 0.1;

/// One geometry parameter of the fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GeomKind {
    /// Differential drive: mean actual / nominal wheel diameter (catalogue `wheel_scale`).
    Scale,
    /// Differential drive: D_right / D_left with the mean kept (Borenstein's E_d).
    Ed,
    /// Actual / nominal wheelbase (Borenstein's E_b).
    Eb,
    /// Actual / nominal radius of one wheel.
    Radius(usize),
    /// Mounting angle offset of one wheel, rad (position and rolling direction turn).
    Alpha(usize),
    /// Actual / nominal distance of one wheel from the centre.
    L(usize),
    /// Mecanum: roller angle offset shared by every mecanum wheel, rad; each wheel's
    /// |gamma| grows by it (left- and right-handed rollers mirror each other).
    Gamma,
    /// Where motion capture tracks, body frame, m (a recording parameter shared by the
    /// recordings of one rig: a marker set not at the kinematic centre).
    MarkerX,
    /// Where motion capture tracks, body frame y, m (see `MarkerX`).
    MarkerY,
    /// Skid-steer: how much E_b grows from a turn in place to a wide arc, the tracks'
    /// ICRs moving with the turn radius: E_b(rho) = eb + eb_arc (1 - rho)^2, rho =
    /// |d_r - d_l| / (|d_r| + |d_l|) (1 in place, 0 straight).
    EbArc,
    /// Skid-steer: longitudinal position of the ICRs ([Mandow et al.]'s x_ICR), m; the
    /// body's sideways speed is -x_ICR omega.
    IcrX,
}

/// A parameter's description: name, null value, plausible range and what a value
/// outside it most likely stands for.
#[derive(Debug, Clone, Serialize)]
pub struct ParamSpec {
    /// Which geometry parameter it is.
    pub kind: GeomKind,
    /// Its name in reports (`scale`, `ed`, `radius_scale_<wheel>`...).
    pub name: String,
    /// Catalogue effect the parameter belongs to.
    pub effect: &'static str,
    /// Its value in the nominal geometry (1 for a scale, 0 for an offset).
    pub nominal: f64,
    /// Physical range (low, high).
    pub plausible: (f64, f64),
    /// What a value outside the range most likely stands in for.
    #[serde(skip)]
    pub stands_for: &'static str,
}

fn spec(
    kind: GeomKind,
    name: String,
    effect: &'static str,
    nominal: f64,
    half: f64,
    stands_for: &'static str,
) -> ParamSpec {
    ParamSpec {
        kind,
        name,
        effect,
        nominal,
        plausible: (nominal - half, nominal + half),
        stands_for,
    }
}

/// A skid-steer robot's E_b: its effective separation is 1 to 3 times the track
/// ([`calib_core::correction::SKID_EB_MAX`]).
pub const SKID_EB_RANGE: (f64, f64) = (1.0, calib_core::correction::SKID_EB_MAX);
/// Skid-steer: change of E_b from a turn in place to a wide arc.
pub const EB_ARC_RANGE: f64 = 0.5;
/// Skid-steer: longitudinal ICR offset, m (a load far forward or back).
pub const ICR_X_RANGE: f64 = 0.05;
const EB_ARC_STANDS: &str =
    "tyres whose lateral grip builds up with the slip angle (ICRs that move with the turn radius)";
const ICR_X_STANDS: &str = "the load far forward or back of the wheels' centre";
const SKID_EB_STANDS: &str =
    "a wrong track in the robot file, or tracks that turn without skidding";

/// Tyre radius: within a few per cent of nominal (wear, pressure, load).
pub const RADIUS_RANGE: f64 = 0.05;
/// Left/right diameter ratio.
pub const ED_RANGE: f64 = 0.03;
/// Wheelbase and wheel distances: the contact patch moves across a tyre's width.
pub const BASE_RANGE: f64 = 0.08;
/// Mounting angle, rad (3 degrees).
pub const ALPHA_RANGE: f64 = 3.0 * std::f64::consts::PI / 180.0;
/// Roller angle of a mecanum wheel set, rad (3 degrees: moulding tolerance and roller wear).
pub const GAMMA_RANGE: f64 = 3.0 * std::f64::consts::PI / 180.0;
/// A wheel with |gamma| above this (rad, 1 degree) is a mecanum wheel.
pub const MECANUM_MIN_GAMMA: f64 = std::f64::consts::PI / 180.0;

const SCALE_STANDS: &str = "a wrong nominal diameter, gear ratio or encoder resolution (counts_per_rev_error), or longitudinal slip";
const ED_STANDS: &str =
    "slip on one side, a tilted floor or a drift the motion does not separate from wheel size";
const EB_STANDS: &str =
    "tyre scrub in turns (the effective wheelbase of a skidding robot) or castor drag";
const ALPHA_STANDS: &str =
    "rollers slipping sideways, or the motion-capture frame turned against the body";
/// Motion-capture marker offset from the kinematic centre, m.
pub const MARKER_RANGE: f64 = 0.02;
const MARKER_STANDS: &str =
    "a marker set far from the kinematic centre, or wheel slip in turns in place";
const L_STANDS: &str = "scrub in rotation or a radius error the motion does not separate";
const GAMMA_STANDS: &str =
    "rollers slipping along their axles, or wheels mounted at other angles (per-wheel alpha, l and radius)";

/// True when some wheel has angled rollers (mecanum), so a roller angle can be fitted.
pub fn is_mecanum(robot: &Robot) -> bool {
    robot.kind == RobotKind::Omni
        && robot
            .wheels
            .iter()
            .any(|w| w.gamma_rad.abs() > MECANUM_MIN_GAMMA)
}

/// The roller model of a mecanum robot: per-wheel radius scales and one shared roller
/// angle offset (with `marker`: the motion-capture marker offset too). In the kinematics a
/// wheel's roller angle is exactly a combination of its mounting angle, distance and
/// radius, so this is the parsimonious alternative to [`param_specs`]' full model, not an
/// addition to it.
pub fn roller_specs(robot: &Robot, marker: bool) -> Vec<ParamSpec> {
    let mut v: Vec<ParamSpec> = param_specs(robot, marker)
        .into_iter()
        .filter(|s| {
            matches!(
                s.kind,
                GeomKind::Radius(_) | GeomKind::MarkerX | GeomKind::MarkerY
            )
        })
        .collect();
    let at = robot.wheels.len().min(v.len());
    v.insert(
        at,
        spec(
            GeomKind::Gamma,
            "roller_angle_offset_rad".into(),
            "roller_angle_error",
            0.0,
            GAMMA_RANGE,
            GAMMA_STANDS,
        ),
    );
    v
}

/// The parameters fitted for `robot` (with `marker`: the motion-capture marker offset
/// too, for omni robots).
pub fn param_specs(robot: &Robot, marker: bool) -> Vec<ParamSpec> {
    // A wheeled-legged robot steers like a skid-steer pair: its encoders fix a left and a
    // right wheel size and a track, not four radii (consistent wheels are averaged).
    let left_right = (robot.kind == RobotKind::DiffDrive && robot.wheels.len() == 2)
        || robot.kind == RobotKind::WheeledLegged;
    if robot.kind == RobotKind::SkidSteer {
        let mut v = param_specs_left_right();
        v[2].plausible = SKID_EB_RANGE;
        v[2].stands_for = SKID_EB_STANDS;
        return v;
    }
    if left_right {
        return param_specs_left_right();
    }
    param_specs_wheels(robot, marker)
}

/// The turn-radius model of a robot with a left and a right side: [`param_specs`] plus
/// the E_b law; a skid-steer robot also gets the longitudinal ICR offset of
/// [Mandow et al.] (a two-wheel robot cannot slide sideways).
pub fn turn_law_specs(robot: &Robot) -> Vec<ParamSpec> {
    let mut v = param_specs(robot, false);
    v.push(spec(
        GeomKind::EbArc,
        "eb_arc".into(),
        "wheelbase_error",
        0.0,
        if robot.kind == RobotKind::SkidSteer {
            EB_ARC_RANGE
        } else {
            DIFF_EB_ARC_RANGE
        },
        EB_ARC_STANDS,
    ));
    if robot.kind != RobotKind::SkidSteer {
        return v;
    }
    v.push(spec(
        GeomKind::IcrX,
        "icr_x_m".into(),
        "wheelbase_error",
        0.0,
        ICR_X_RANGE,
        ICR_X_STANDS,
    ));
    v
}

fn param_specs_left_right() -> Vec<ParamSpec> {
    vec![
        spec(
            GeomKind::Scale,
            "scale".into(),
            "wheel_scale",
            1.0,
            RADIUS_RANGE,
            SCALE_STANDS,
        ),
        spec(
            GeomKind::Ed,
            "ed".into(),
            "wheel_diameter_mismatch",
            1.0,
            ED_RANGE,
            ED_STANDS,
        ),
        spec(
            GeomKind::Eb,
            "eb".into(),
            "wheelbase_error",
            1.0,
            BASE_RANGE,
            EB_STANDS,
        ),
    ]
}

fn param_specs_wheels(robot: &Robot, marker: bool) -> Vec<ParamSpec> {
    let marker_specs = [
        spec(
            GeomKind::MarkerX,
            "marker_x_m".into(),
            "marker_offset",
            0.0,
            MARKER_RANGE,
            MARKER_STANDS,
        ),
        spec(
            GeomKind::MarkerY,
            "marker_y_m".into(),
            "marker_offset",
            0.0,
            MARKER_RANGE,
            MARKER_STANDS,
        ),
    ];
    let mut v = Vec::new();
    for (i, w) in robot.wheels.iter().enumerate() {
        v.push(spec(
            GeomKind::Radius(i),
            format!("radius_scale_{}", w.name),
            "wheel_diameter_mismatch",
            1.0,
            RADIUS_RANGE,
            SCALE_STANDS,
        ));
    }
    if robot.kind == RobotKind::Omni {
        for (i, w) in robot.wheels.iter().enumerate() {
            v.push(spec(
                GeomKind::Alpha(i),
                format!("alpha_offset_rad_{}", w.name),
                "wheel_angle_error",
                0.0,
                ALPHA_RANGE,
                ALPHA_STANDS,
            ));
        }
        for (i, w) in robot.wheels.iter().enumerate() {
            v.push(spec(
                GeomKind::L(i),
                format!("l_scale_{}", w.name),
                "wheel_position_error",
                1.0,
                BASE_RANGE,
                L_STANDS,
            ));
        }
        if marker {
            v.extend(marker_specs);
        }
    } else {
        v.push(spec(
            GeomKind::Eb,
            "eb".into(),
            "wheelbase_error",
            1.0,
            BASE_RANGE,
            EB_STANDS,
        ));
    }
    v
}

/// The robot with geometry parameters `values` (in `specs` order) applied.
pub fn robot_with(base: &Robot, specs: &[ParamSpec], values: &[f64]) -> Robot {
    let n = base.wheels.len();
    let (mut rs, mut ls, mut da) = (vec![1.0; n], vec![1.0; n], vec![0.0; n]);
    let mut dg = 0.0;
    for (s, &x) in specs.iter().zip(values) {
        match s.kind {
            GeomKind::Scale => rs.iter_mut().for_each(|r| *r *= x),
            GeomKind::Ed => {
                for (i, w) in base.wheels.iter().enumerate() {
                    rs[i] *= calib_core::umbmark::wheel_factor(w, x);
                }
            }
            GeomKind::Eb => ls.iter_mut().for_each(|l| *l *= x),
            GeomKind::Radius(i) => rs[i] *= x,
            GeomKind::Alpha(i) => da[i] += x,
            GeomKind::L(i) => ls[i] *= x,
            GeomKind::Gamma => dg += x,
            GeomKind::MarkerX | GeomKind::MarkerY | GeomKind::EbArc | GeomKind::IcrX => {}
        }
    }
    let mut r = base.clone();
    for (i, w) in r.wheels.iter_mut().enumerate() {
        w.radius_m *= rs[i];
        w.l_m *= ls[i];
        w.alpha_rad += da[i];
        if w.gamma_rad.abs() > MECANUM_MIN_GAMMA {
            w.gamma_rad += w.gamma_rad.signum() * dg;
        }
    }
    r
}

/// A turn-radius law (zero when the separation does not depend on the turn).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TurnLaw {
    /// eb_arc / eb: relative growth of the separation from a turn in place to a wide arc.
    pub arc_rel: f64,
    /// Longitudinal ICR offset, m.
    pub icr_x_m: f64,
}

impl TurnLaw {
    /// The law in `values` (in `specs` order); `known_arc_rel` when the specs do not fit
    /// eb_arc ([`CalOptions::turn_law`], else 0).
    pub fn of(specs: &[ParamSpec], values: &[f64], known_arc_rel: f64) -> TurnLaw {
        let get = |k: GeomKind| specs.iter().position(|s| s.kind == k).map(|i| values[i]);
        let eb = get(GeomKind::Eb).unwrap_or(1.0);
        TurnLaw {
            arc_rel: get(GeomKind::EbArc).map_or(known_arc_rel, |a| a / eb),
            icr_x_m: get(GeomKind::IcrX).unwrap_or(0.0),
        }
    }
}

/// Time either side over which a recording's turn ratio rho is smoothed (s): one encoder
/// count makes a row's own ratio noisy at low speed (20 rows at 200 rows/s, 2 at 20).
const RHO_HALF_WINDOW_S: f64 = 0.1;

/// The median step between consecutive times, when positive.
fn median_step(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    (*m > 0.0).then_some(*m)
}

/// Per increment, rho = |d_r - d_l| / (|d_r| + |d_l|) of the sides' travel (nominal
/// radii), smoothed over [`RHO_HALF_WINDOW_S`] either side (in rows at the median row step).
fn turn_ratio(robot: &Robot, inc: &[Vec<f64>], t: &[f64]) -> Vec<f64> {
    let m = inc.len();
    let half = median_step(t).map_or(1, |dt| ((RHO_HALF_WINDOW_S / dt).round() as usize).max(1));
    let sides = Sides::new(robot);
    let (mut pl, mut pr) = (vec![0.0; m + 1], vec![0.0; m + 1]);
    for k in 0..m {
        let (l, r) = sides.travel(&inc[k]);
        pl[k + 1] = pl[k] + l;
        pr[k + 1] = pr[k] + r;
    }
    (0..m)
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(m));
            let (dl, dr) = (pl[b] - pl[a], pr[b] - pr[a]);
            let den = dl.abs() + dr.abs();
            if den > 0.0 {
                (dr - dl).abs() / den
            } else {
                0.0
            }
        })
        .collect()
}

/// A robot's sides as the stepping needs them, computed once per geometry (the wheels'
/// sides and the mean half separation take trigonometry): [`Sides::travel`] and
/// [`Sides::step`] give the same values, to the bit, as computing them per row.
#[derive(Debug, Clone)]
pub(crate) struct Sides {
    /// Per wheel: on the left side, and its radius (m).
    wheels: Vec<(bool, f64)>,
    /// Left and right wheel counts, at least 1.
    counts: (f64, f64),
    /// Mean |y| of the wheels (half the separation, E_b applied), m.
    half: f64,
    /// A skid-steer robot (the law's shape differs).
    skid: bool,
}

impl Sides {
    pub(crate) fn new(robot: &Robot) -> Sides {
        let wheels: Vec<(bool, f64)> = robot
            .wheels
            .iter()
            .map(|w| (w.is_left(), w.radius_m))
            .collect();
        let nl = wheels.iter().filter(|w| w.0).count() as f64;
        let nr = wheels.len() as f64 - nl;
        let half = robot
            .wheels
            .iter()
            .map(|w| w.position().1.abs())
            .sum::<f64>()
            / robot.wheels.len().max(1) as f64;
        Sides {
            wheels,
            counts: (f64::max(nl, 1.0), f64::max(nr, 1.0)),
            half,
            skid: robot.kind == RobotKind::SkidSteer,
        }
    }

    /// Share of the law's widening at turn ratio `rho`: a differential drive's turn slip
    /// ([`calib_core::kinematics::turn_law_share`]); a skid-steer robot's moving ICRs
    /// (1 - rho)^2, as measured on the simulator's independent tyres.
    #[inline]
    pub(crate) fn law_share(&self, rho: f64) -> f64 {
        if self.skid {
            (1.0 - rho).powi(2)
        } else {
            calib_core::kinematics::turn_law_share(rho)
        }
    }

    /// Mean travel of the left and the right wheels over one increment (m).
    #[inline]
    pub(crate) fn travel(&self, inc: &[f64]) -> (f64, f64) {
        let (mut l, mut r) = (0.0, 0.0);
        for (&(left, radius), d) in self.wheels.iter().zip(inc) {
            if left {
                l += radius * d;
            } else {
                r += radius * d;
            }
        }
        (l / self.counts.0, r / self.counts.1)
    }

    /// One step of a robot driven by its sides (skid-steer, or a differential drive with
    /// a turn law): each side's mean travel, the separation (E_b applied) widened by the
    /// law at this turn ratio, the sideways speed of the ICR offset.
    #[inline]
    pub(crate) fn step(
        &self,
        law: &TurnLaw,
        rho: f64,
        inc: &[f64],
    ) -> calib_core::kinematics::Twist<f64> {
        let (l, r) = self.travel(inc);
        let half = self.half * (1.0 + law.arc_rel * self.law_share(rho));
        let dth = (r - l) / (2.0 * half);
        calib_core::kinematics::Twist::new(0.5 * (l + r), -law.icr_x_m * dth, dth)
    }
}

/// How a recording turns: the side-travel difference |d_r - d_l| summed over all rows, over
/// the rows on arcs ([`ARC_RHO`]), and weighted by (1 - rho)^2 (what averages the E_b law
/// over the recording's turning).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Turning {
    pub(crate) all: f64,
    pub(crate) arcs: f64,
    pub(crate) arc_term: f64,
}

/// Why calibration cannot run.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateError {
    /// The recording at fault (its name as given), if one is.
    pub recording: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for CalibrateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.recording {
            Some(r) => write!(f, "{r}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for CalibrateError {}

/// A recording reduced to what calibration replays: wheel angles per row and poses.
#[derive(Debug, Clone)]
pub struct Series {
    /// The recording's name as given.
    pub name: String,
    /// Time of each row, s.
    pub t: Vec<f64>,
    /// Per row, per wheel: angle increment to the next row (rad), row after row
    /// ([`Series::wheels`] values a row).
    inc: Vec<f64>,
    /// Wheels per row of `inc`.
    wheels: usize,
    pub(crate) pose_row: Vec<usize>,
    pub(crate) px: Vec<f64>,
    pub(crate) py: Vec<f64>,
    pub(crate) pth: Vec<f64>,
    /// Wheeled-legged robots: (front, rear) leg angles per row, rad; they move the wheel
    /// contacts along x, so the kinematics follow them.
    legs: Option<Vec<(f64, f64)>>,
    /// Skid-steer robots: turn ratio rho per increment ([`turn_ratio`]).
    rho: Option<Vec<f64>>,
    /// Pose samples (indices into px...) the dead-reckoning objective compares: one every
    /// [`SAMPLE_STEP_M`] of travel (turns in place counted at the wheels' lever arm).
    pub(crate) samples: Vec<usize>,
    /// Pose samples where dead reckoning restarts from the measured pose (the first one,
    /// and the end of every event one geometry cannot explain).
    pub(crate) anchors: Vec<usize>,
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

/// The lever arm at which a turn in place counts as travel: the mean wheel distance from
/// the centre (half the separation of a differential drive).
fn turn_lever(robot: &Robot) -> f64 {
    let n = robot.wheels.len().max(1) as f64;
    robot.wheels.iter().map(|w| w.l_m).sum::<f64>() / n
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
            let counts = crate::replay::fill(cells)
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
                    handled: "replaced by its neighbours' mean",
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
                    handled: "the sample is dropped",
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
                crate::replay::fill(cells)
                    .ok_or_else(|| err(format!("the {which} leg angle column is empty")))
            };
            let (f, r) = (fill(&rec.leg_front, "front")?, fill(&rec.leg_rear, "rear")?);
            Some(f.into_iter().zip(r).collect())
        } else {
            None
        };
        let samples = distance_samples(&px, &py, &pth, turn_lever(robot), SAMPLE_STEP_M);
        let rho = matches!(robot.kind, RobotKind::SkidSteer | RobotKind::DiffDrive)
            .then(|| turn_ratio(robot, &inc, &rec.t));
        let wheels = robot.wheels.len();
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
            samples,
            anchors: vec![0],
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
                handled: "the recording is split there and each part fitted from its own start",
            });
            self.jumps.push(j);
        }
    }

    /// The recording cut at its pose jumps: each part has its own start (an anchor in
    /// the dead-reckoning objective, a fitted start pose with `--free-start`). The rows
    /// between a jump's two pose samples belong to neither. Parts after the first are
    /// named `<name>#2`, `<name>#3`... ([`CvBy::group`] keeps them with the first); a part
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
            let samples = distance_samples(&px, &py, &pth, turn_lever(robot), SAMPLE_STEP_M);
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
                samples,
                anchors: vec![0],
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

    /// How the recording turns, from the wheels (nominal geometry): [`Turning`]. All
    /// zero for robots without sides.
    pub(crate) fn turning(&self, robot: &Robot) -> Turning {
        let mut t = Turning::default();
        let Some(rho) = &self.rho else {
            return t;
        };
        let sides = Sides::new(robot);
        for (inc, &rho) in self.incs().zip(rho) {
            let (l, r) = sides.travel(inc);
            let d = (r - l).abs();
            t.all += d;
            t.arc_term += d * sides.law_share(rho);
            if (ARC_RHO.0..=ARC_RHO.1).contains(&rho) {
                t.arcs += d;
            }
        }
        t
    }

    /// The wheel increments, row after row.
    fn incs(&self) -> std::slice::ChunksExact<'_, f64> {
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
        if let (Some(rho), Some((sides, law))) = (&self.rho, stepper.sides()) {
            for (inc, &rho) in self.incs().zip(rho) {
                step::arc_step(&mut x, &mut y, &mut h, &sides.step(law, rho, inc));
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
                let r = crate::ground::geometry_at(robot, &[], 1.0, Some(l));
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

const NUIS: usize = 5;

impl Nuisance {
    fn from(v: &[f64]) -> Nuisance {
        Nuisance {
            x0_m: v[0],
            y0_m: v[1],
            theta0_rad: v[2],
            time_offset_s: v[3],
            clock_ratio: v[4],
        }
    }
}

/// Huber's loss on the Jacobian's data rows: d huber / dr is 1 within `c` and
/// c / |r| beyond (huber is monotone, = c at c), on the first `cols` columns.
fn huber_rows(jac: &mut DMatrix<f64>, r: &[f64], c: f64, cols: usize) {
    for (i, v) in r.iter().enumerate() {
        if v.abs() > c {
            let k = c / v.abs();
            for a in 0..cols {
                jac[(i, a)] *= k;
            }
        }
    }
}

/// Each pose sample on the encoders' clock: (sample j, its row time, its time tau on the
/// encoders' clock, the row segment k with t[k] <= tau < t[k + 1] where there is one).
fn pose_segments<'a>(
    s: &'a Series,
    nu: &Nuisance,
) -> impl Iterator<Item = (usize, f64, f64, usize)> + 'a {
    let (t0, n) = (s.t[0], s.t.len());
    let (offset, ratio) = (nu.time_offset_s, nu.clock_ratio);
    let mut k = 0usize;
    (0..s.pose_row.len()).map(move |j| {
        let tj = s.t[s.pose_row[j]];
        let tau = t0 + (tj - t0 - offset) / ratio;
        while k + 2 < n && s.t[k + 1] <= tau {
            k += 1;
        }
        while k > 0 && s.t[k] > tau {
            k -= 1;
        }
        (j, tj, tau, k)
    })
}

/// Residuals (ex, ey, lever * eth per pose sample, in RES_UNIT_M) of one recording.
pub(crate) fn residuals_into(
    s: &Series,
    path: &Path,
    nu: &Nuisance,
    marker: (f64, f64),
    out: &mut Vec<f64>,
) {
    let (c, sn) = (nu.theta0_rad.cos(), nu.theta0_rad.sin());
    let n = s.t.len();
    for (j, _, tau, k) in pose_segments(s, nu) {
        let (x, y, th) = if n < 2 || tau <= s.t[0] {
            (path.x[0], path.y[0], path.th[0])
        } else if tau >= s.t[n - 1] {
            (path.x[n - 1], path.y[n - 1], path.th[n - 1])
        } else {
            let f = (tau - s.t[k]) / (s.t[k + 1] - s.t[k]);
            let l = |v: &[f64]| v[k] + (v[k + 1] - v[k]) * f;
            (l(&path.x), l(&path.y), l(&path.th))
        };
        // The marker sits at `marker` in the body frame: it moves on a circle in a turn.
        let (mut wx, mut wy) = (nu.x0_m + c * x - sn * y, nu.y0_m + sn * x + c * y);
        if marker != (0.0, 0.0) {
            let (sm, cm) = (nu.theta0_rad + th).sin_cos();
            // Term by term, as the whole sum rounds.
            wx = wx + cm * marker.0 - sm * marker.1;
            wy = wy + sm * marker.0 + cm * marker.1;
        }
        out.push((wx - s.px[j]) / RES_UNIT_M);
        out.push((wy - s.py[j]) / RES_UNIT_M);
        out.push((nu.theta0_rad + th - s.pth[j]) * HEADING_LEVER_M / RES_UNIT_M);
    }
}

/// The Jacobian of [`residuals_into`] with respect to the recording's nuisance (x0, y0,
/// theta0, time offset, clock ratio: columns `col0..col0 + NUIS`) into `jac` from row
/// `row0`. The path is interpolated linearly between rows, so its slope in time is its
/// segment's (none before the first row or after the last).
fn nuisance_jacobian_into(
    s: &Series,
    path: &Path,
    nu: &Nuisance,
    marker: (f64, f64),
    jac: &mut DMatrix<f64>,
    row0: usize,
    col0: usize,
) {
    let t0 = s.t[0];
    let (c, sn) = (nu.theta0_rad.cos(), nu.theta0_rad.sin());
    let n = s.t.len();
    let u = 1.0 / RES_UNIT_M;
    let lever = HEADING_LEVER_M * u;
    for (j, tj, tau, k) in pose_segments(s, nu) {
        // The path at tau and its slope in tau.
        let ((x, y, th), (vx, vy, vth)) = if n < 2 || tau <= s.t[0] {
            ((path.x[0], path.y[0], path.th[0]), (0.0, 0.0, 0.0))
        } else if tau >= s.t[n - 1] {
            (
                (path.x[n - 1], path.y[n - 1], path.th[n - 1]),
                (0.0, 0.0, 0.0),
            )
        } else {
            let dt = s.t[k + 1] - s.t[k];
            let f = (tau - s.t[k]) / dt;
            let l = |v: &[f64]| v[k] + (v[k + 1] - v[k]) * f;
            let d = |v: &[f64]| (v[k + 1] - v[k]) / dt;
            (
                (l(&path.x), l(&path.y), l(&path.th)),
                (d(&path.x), d(&path.y), d(&path.th)),
            )
        };
        // d(wx, wy)/d theta_total of the marker's offset (zero without one).
        let (mx, my) = if marker != (0.0, 0.0) {
            let (sm, cm) = (nu.theta0_rad + th).sin_cos();
            (
                -sm * marker.0 - cm * marker.1,
                cm * marker.0 - sm * marker.1,
            )
        } else {
            (0.0, 0.0)
        };
        // d tau / d time offset, d tau / d clock ratio.
        let dtau = [
            -1.0 / nu.clock_ratio,
            -(tj - t0 - nu.time_offset_s) / (nu.clock_ratio * nu.clock_ratio),
        ];
        let wx_tau = c * vx - sn * vy + mx * vth;
        let wy_tau = sn * vx + c * vy + my * vth;
        let row = row0 + 3 * j;
        jac[(row, col0)] = u;
        jac[(row + 1, col0 + 1)] = u;
        jac[(row, col0 + 2)] = (-sn * x - c * y + mx) * u;
        jac[(row + 1, col0 + 2)] = (c * x - sn * y + my) * u;
        jac[(row + 2, col0 + 2)] = lever;
        for (q, dq) in dtau.iter().enumerate() {
            jac[(row, col0 + 3 + q)] = wx_tau * dq * u;
            jac[(row + 1, col0 + 3 + q)] = wy_tau * dq * u;
            jac[(row + 2, col0 + 3 + q)] = vth * dq * lever;
        }
    }
}

/// A path's (x, y, theta) at a row.
pub(crate) trait PathAt {
    fn at(&self, row: usize) -> [f64; 3];
}

impl PathAt for &Path {
    #[inline]
    fn at(&self, k: usize) -> [f64; 3] {
        [self.x[k], self.y[k], self.th[k]]
    }
}

impl PathAt for &sens::Sensitivity {
    /// At a kept row only.
    #[inline]
    fn at(&self, k: usize) -> [f64; 3] {
        self.values[self.need.binary_search(&k).expect("row kept")]
    }
}

/// Dead-reckoning residuals (ex, ey, lever * eth, in RES_UNIT_M) of one recording at its
/// distance samples: the path integrated from the measured pose at each anchor (the first
/// pose sample, and the end of each event), no start pose or clocks fitted.
pub(crate) fn dr_residuals_into(
    s: &Series,
    path: impl PathAt,
    marker: (f64, f64),
    lever: f64,
    out: &mut Vec<f64>,
) {
    let mut seg = 0usize;
    // The segment whose anchor quantities are set: the anchor's path row, the rotation
    // onto the measured heading there (angle, cos, sin) and the body's position.
    let mut set = usize::MAX;
    let (mut pa, mut dth, mut c, mut sn, mut bx, mut by) = ([0.0; 3], 0.0, 1.0, 0.0, 0.0, 0.0);
    for &j in &s.samples {
        while seg + 1 < s.anchors.len() && s.anchors[seg + 1] <= j {
            seg += 1;
        }
        if set != seg {
            set = seg;
            let a = s.anchors[seg];
            pa = path.at(s.pose_row[a]);
            dth = s.pth[a] - pa[2];
            (c, sn) = (dth.cos(), dth.sin());
            // Body position at the anchor from the measured marker position.
            let (ca, sa) = (s.pth[a].cos(), s.pth[a].sin());
            bx = s.px[a] - (ca * marker.0 - sa * marker.1);
            by = s.py[a] - (sa * marker.0 + ca * marker.1);
        }
        let pj = path.at(s.pose_row[j]);
        let (dx, dy) = (pj[0] - pa[0], pj[1] - pa[1]);
        let th = pj[2] + dth;
        let (mut wx, mut wy) = (bx + c * dx - sn * dy, by + sn * dx + c * dy);
        if marker != (0.0, 0.0) {
            let (cm, sm) = (th.cos(), th.sin());
            // Term by term, as the whole sum rounds.
            wx = wx + cm * marker.0 - sm * marker.1;
            wy = wy + sm * marker.0 + cm * marker.1;
        }
        out.push((wx - s.px[j]) / RES_UNIT_M);
        out.push((wy - s.py[j]) / RES_UNIT_M);
        out.push((th - s.pth[j]) * lever / RES_UNIT_M);
    }
}

/// Huber's loss as a residual: sign(r) sqrt(2 rho(r)), so a least-squares solver
/// minimises sum rho (quadratic within `c`, linear beyond).
fn huber(r: f64, c: f64) -> f64 {
    let a = r.abs();
    if a <= c {
        r
    } else {
        r.signum() * (c * (2.0 * a - c)).sqrt()
    }
}

/// Position RMSE (m) from residuals laid out by `residuals_into`.
fn position_rmse(r: &[f64]) -> f64 {
    let n = r.len() / 3;
    if n == 0 {
        return 0.0;
    }
    let s: f64 = r.chunks(3).map(|c| c[0] * c[0] + c[1] * c[1]).sum::<f64>();
    (s / n as f64).sqrt() * RES_UNIT_M
}

/// Dead reckoning from the first measured pose with the given robot and no fitted
/// nuisance: the prediction a user gets (OptiOdom's held-out measure). Position RMSE, m.
pub fn dead_reckoning_rmse(robot: &Robot, s: &Series) -> Option<f64> {
    dead_reckoning_rmse_with(robot, &TurnLaw::default(), s)
}

/// [`dead_reckoning_rmse`] of a robot whose separation follows `law` (its `robot` the
/// separation of a turn in place: [`Calibration::law_base_robot`]).
pub fn dead_reckoning_rmse_law(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<f64> {
    dead_reckoning_rmse_with(robot, law, s)
}

/// [`dead_reckoning_rmse`] of the geometry `values` (in `specs` order) of `base`, a
/// skid-steer robot's turn-radius law included.
pub fn fitted_dead_reckoning_rmse(
    base: &Robot,
    specs: &[ParamSpec],
    values: &[f64],
    known_arc_rel: f64,
    s: &Series,
) -> f64 {
    let r = robot_with(base, specs, values);
    dead_reckoning_rmse_with(&r, &TurnLaw::of(specs, values, known_arc_rel), s).unwrap_or(f64::NAN)
}

fn dead_reckoning_rmse_with(robot: &Robot, law: &TurnLaw, s: &Series) -> Option<f64> {
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let mut path = Path::default();
    if !s.path_with(robot, &kin, law, &mut path) {
        return None;
    }
    let k0 = s.pose_row[0];
    let dth = s.pth[0] - path.th[k0];
    let (c, sn) = (dth.cos(), dth.sin());
    let mut acc = 0.0;
    for j in 0..s.pose_row.len() {
        let k = s.pose_row[j];
        let (dx, dy) = (path.x[k] - path.x[k0], path.y[k] - path.y[k0]);
        let ex = s.px[0] + c * dx - sn * dy - s.px[j];
        let ey = s.py[0] + sn * dx + c * dy - s.py[j];
        acc += ex * ex + ey * ey;
    }
    Some((acc / s.pose_row.len() as f64).sqrt())
}

/// The joint problem: geometry shared, nuisance per recording.
struct Problem<'a> {
    robot: &'a Robot,
    specs: &'a [ParamSpec],
    /// The recordings, borrowed (a fold's problem holds some of them).
    series: Vec<&'a Series>,
    /// Prior rows: (weights over the geometry parameters, target, sigma).
    priors: Vec<(Vec<f64>, f64, f64)>,
    /// Prior rows are multiplied by this: sqrt(residual variance x autocorrelation
    /// inflation) once known, so the prior weighs against what the data really tell.
    prior_scale: f64,
    cache: RefCell<(Vec<f64>, Vec<Path>)>,
    /// The geometry and its paths at the dead-reckoning rows with their sensitivities
    /// ([`Problem::sensitivities`]).
    sens: RefCell<(Vec<f64>, Vec<sens::Sensitivity>)>,
    /// Residuals are evaluated with the sensitivities (dead reckoning only): set while a
    /// fit with the analytic Jacobian runs, whose next Jacobian is most likely at the point
    /// just evaluated (one pass over the rows then serves both).
    speculate: std::cell::Cell<bool>,
    /// Bound the geometry to the plausible ranges (else 10 times wider).
    plausible_bounds: bool,
    /// Fit each recording's start pose and clocks (else dead-reckon from the anchors).
    free_start: bool,
    /// Huber scale of the data residuals (residual units), when the loss is robust.
    huber: Option<f64>,
    /// Lever arm of the dead-reckoning heading residuals, m.
    dr_lever: f64,
    /// A known turn law (eb_arc / eb) when the specs do not fit one.
    known_law: f64,
    /// The Jacobian of a fit's solution (its covariance, the cross-validation's steps)
    /// by forward differences, as the iterations' used to be; else the analytic one.
    differences_at_solution: bool,
}

impl<'a> Problem<'a> {
    /// Where motion capture tracks on the body in `geom` ((0, 0) when not fitted).
    fn marker(&self, geom: &[f64]) -> (f64, f64) {
        let get = |k: GeomKind| {
            self.specs
                .iter()
                .position(|s| s.kind == k)
                .map_or(0.0, |i| geom[i])
        };
        (get(GeomKind::MarkerX), get(GeomKind::MarkerY))
    }

    fn new(
        robot: &'a Robot,
        specs: &'a [ParamSpec],
        series: impl IntoIterator<Item = &'a Series>,
    ) -> Self {
        let series: Vec<&'a Series> = series.into_iter().collect();
        let n = series.len();
        // A weak prior at nominal (one plausible half-range) keeps directions the data
        // do not constrain where they are; it is negligible against thousands of
        // millimetre residuals wherever the data speak.
        let g = specs.len();
        let priors = specs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let mut w = vec![0.0; g];
                w[i] = 1.0;
                (w, s.nominal, s.plausible.1 - s.nominal)
            })
            .collect();
        Problem {
            robot,
            specs,
            series,
            priors,
            prior_scale: 1.0,
            plausible_bounds: false,
            free_start: true,
            huber: None,
            dr_lever: DR_HEADING_LEVER_M,
            known_law: 0.0,
            differences_at_solution: true,
            cache: RefCell::new((vec![f64::NAN], vec![Path::default(); n])),
            sens: RefCell::new((vec![f64::NAN], Vec::new())),
            speculate: std::cell::Cell::new(false),
        }
    }

    fn paths(&self, geom: &[f64]) -> bool {
        let mut c = self.cache.borrow_mut();
        if c.0.as_slice() == geom {
            return true;
        }
        let r = robot_with(self.robot, self.specs, geom);
        let law = TurnLaw::of(self.specs, geom, self.known_law);
        let Ok(kin) = Kinematics::<f64>::new(&r, &Corrections::None) else {
            c.0 = vec![f64::NAN];
            return false;
        };
        let stepper = Stepper::new(&r, &kin, &law);
        let mut jobs: Vec<(&Series, &mut Path)> =
            self.series.iter().copied().zip(c.1.iter_mut()).collect();
        let ok = par_each(&mut jobs, |(s, p)| s.path_by(&r, &stepper, p));
        if ok.iter().all(|v| *v) {
            c.0 = geom.to_vec();
            true
        } else {
            c.0 = vec![f64::NAN];
            false
        }
    }

    /// The analytic Jacobian of [`Problem::residuals`] with the prior rows (dead
    /// reckoning only) at `geom`, the data rows through Huber's loss when robust (`r`:
    /// the residuals at `geom` as the fit sees them). False when it has none (fitted start
    /// poses, a wheeled-legged robot, a singular geometry).
    fn jacobian(&self, geom: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
        if !self.sensitivities(geom) {
            return false;
        }
        let g = self.specs.len();
        let m = self.data_len();
        let cached = self.sens.borrow();
        let cols = sens::split_params(self.specs);
        if jac.nrows() != m + self.priors.len() || jac.ncols() != g {
            *jac = DMatrix::zeros(m + self.priors.len(), g);
        }
        jac.fill(0.0);
        let marker = self.marker(geom);
        let mut row = 0;
        for (s, sens) in self.series.iter().zip(&cached.1) {
            s.dr_jacobian(sens, &cols, marker, self.dr_lever, jac, row);
            row += 3 * s.samples.len();
        }
        if let Some(c) = self.huber {
            huber_rows(jac, &r[..m], c, g);
        }
        for (i, (w, _, sigma)) in self.priors.iter().enumerate() {
            for a in 0..g {
                jac[(m + i, a)] = w[a] / sigma * self.prior_scale;
            }
        }
        true
    }

    /// The paths at the dead-reckoning rows and their sensitivities at `geom` into
    /// [`Problem::sens`] (kept while `geom` stays). False when there are none (fitted
    /// start poses, a wheeled-legged robot, a singular geometry).
    fn sensitivities(&self, geom: &[f64]) -> bool {
        if self.free_start {
            return false;
        }
        if self.sens.borrow().0.as_slice() == geom {
            return true;
        }
        let robot = robot_with(self.robot, self.specs, geom);
        let law = TurnLaw::of(self.specs, geom, self.known_law);
        let Ok(kin) = Kinematics::<f64>::new(&robot, &Corrections::None) else {
            return false;
        };
        let stepper = Stepper::new(&robot, &kin, &law);
        let cols = sens::split_params(self.specs);
        let sides = self.robot.kind == RobotKind::SkidSteer
            || self
                .specs
                .iter()
                .any(|s| matches!(s.kind, GeomKind::EbArc | GeomKind::IcrX));
        let Some(slopes) = sens::TwistSlopes::new(
            self.robot,
            self.specs,
            geom,
            self.known_law,
            &cols.path,
            sides,
        ) else {
            return false;
        };
        let mut jobs: Vec<(&Series, Option<sens::Sensitivity>)> =
            self.series.iter().map(|s| (*s, None)).collect();
        par_each(&mut jobs, |(s, out)| {
            *out = s.sensitivity(&stepper, &slopes, s.dr_rows());
        });
        let Some(all) = jobs.into_iter().map(|j| j.1).collect::<Option<Vec<_>>>() else {
            return false;
        };
        *self.sens.borrow_mut() = (geom.to_vec(), all);
        true
    }

    /// The analytic Jacobian of the data residuals with respect to every recording's
    /// nuisance at the geometry `geom` (fixed), through Huber's loss when robust (`r`:
    /// the residuals as the fit sees them). False when the start poses are not fitted or
    /// the geometry is singular.
    fn nuisance_jacobian(
        &self,
        geom: &[f64],
        nuis: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
    ) -> bool {
        if !self.free_start || !self.paths(geom) {
            return false;
        }
        let m = self.data_len();
        let np = nuis.len();
        if jac.nrows() != m || jac.ncols() != np {
            *jac = DMatrix::zeros(m, np);
        }
        jac.fill(0.0);
        let c = self.cache.borrow();
        let marker = self.marker(geom);
        let mut row = 0;
        for (i, s) in self.series.iter().enumerate() {
            let nu = Nuisance::from(&nuis[i * NUIS..(i + 1) * NUIS]);
            nuisance_jacobian_into(s, &c.1[i], &nu, marker, jac, row, i * NUIS);
            row += 3 * s.pose_samples();
        }
        if let Some(h) = self.huber {
            huber_rows(jac, &r[..m], h, np);
        }
        true
    }

    /// Data residuals of every recording, then prior rows.
    fn residuals(&self, geom: &[f64], nuis: &[f64], with_prior: bool) -> Vec<f64> {
        let mut out = Vec::new();
        let cached = !self.free_start && self.sens.borrow().0.as_slice() == geom;
        if cached || (self.speculate.get() && self.sensitivities(geom)) {
            // The paths at the dead-reckoning rows, as the sensitivities carry them.
            let c = self.sens.borrow();
            self.dr_residuals_all(c.1.iter().collect(), self.marker(geom), &mut out);
            if with_prior {
                self.prior_rows(geom, &mut out);
            }
            return out;
        }
        if !self.paths(geom) {
            let m = self.data_len();
            return vec![1e12; m + if with_prior { self.priors.len() } else { 0 }];
        }
        let c = self.cache.borrow();
        let marker = self.marker(geom);
        if self.free_start {
            for (i, s) in self.series.iter().enumerate() {
                let nu = Nuisance::from(&nuis[i * NUIS..(i + 1) * NUIS]);
                residuals_into(s, &c.1[i], &nu, marker, &mut out);
            }
        } else {
            self.dr_residuals_all(c.1.iter().collect(), marker, &mut out);
        }
        if with_prior {
            self.prior_rows(geom, &mut out);
        }
        out
    }

    /// The dead-reckoning residuals of every recording along `paths` (one per series):
    /// each recording's on its own (in parallel), then in order onto `out`.
    fn dr_residuals_all<P: Copy + PathAt + Send>(
        &self,
        paths: Vec<P>,
        marker: (f64, f64),
        out: &mut Vec<f64>,
    ) {
        let lever = self.dr_lever;
        let mut jobs: Vec<(&Series, P)> = self.series.iter().copied().zip(paths).collect();
        let parts = par_jobs(
            &mut jobs,
            |j| 20 * j.0.samples.len(),
            |(s, path)| {
                let mut v = Vec::with_capacity(3 * s.samples.len());
                dr_residuals_into(s, *path, marker, lever, &mut v);
                v
            },
        );
        out.reserve(parts.iter().map(|v| v.len()).sum());
        for v in parts {
            out.extend_from_slice(&v);
        }
    }

    /// The prior rows at `geom` onto `out`.
    fn prior_rows(&self, geom: &[f64], out: &mut Vec<f64>) {
        for (w, target, sigma) in &self.priors {
            let v: f64 = w.iter().zip(geom).map(|(a, b)| a * b).sum();
            out.push((v - target) / sigma * self.prior_scale);
        }
    }

    fn data_len(&self) -> usize {
        self.series
            .iter()
            .map(|s| {
                3 * if self.free_start {
                    s.pose_samples()
                } else {
                    s.samples.len()
                }
            })
            .sum()
    }
}

/// Rows below which one evaluation is not worth a second thread.
const PAR_MIN_ROWS: usize = 20_000;

/// Runs `f` on every job (a recording and its output), on up to
/// `available_parallelism` threads when the recordings are long enough to pay for them;
/// each job's result is the same as run alone. The jobs are split in contiguous runs of
/// about equal rows.
fn par_each<'s, J: Send, R: Send>(
    jobs: &mut [(&'s Series, J)],
    f: impl Fn(&mut (&'s Series, J)) -> R + Sync,
) -> Vec<R> {
    par_jobs(jobs, |j| j.0.t.len(), f)
}

thread_local! {
    /// Set on [`pool_map`]'s threads: what they run runs on one thread.
    static IN_POOL: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// `f` of every item, on up to `available_parallelism` threads taking the next item as
/// they finish one (each item on one thread, its own work not split further); results
/// in the items' order.
fn pool_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(items.len());
    if threads < 2 || IN_POOL.with(|p| p.get()) {
        return items.iter().map(f).collect();
    }
    let next = std::sync::atomic::AtomicUsize::new(0);
    let (f, next) = (&f, &next);
    let mut out: Vec<(usize, R)> = std::thread::scope(|sc| {
        let handles: Vec<_> = (0..threads)
            .map(|_| {
                sc.spawn(move || {
                    IN_POOL.with(|p| p.set(true));
                    let mut mine = Vec::new();
                    loop {
                        let i = next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                        let Some(item) = items.get(i) else {
                            break;
                        };
                        mine.push((i, f(item)));
                    }
                    mine
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a calibration thread panicked"))
            .collect()
    });
    out.sort_by_key(|r| r.0);
    out.into_iter().map(|r| r.1).collect()
}

/// Runs `f` on every job, weighed by `rows`, in contiguous runs of about equal weight on
/// up to `available_parallelism` threads (one thread under [`PAR_MIN_ROWS`]).
fn par_jobs<J: Send, R: Send>(
    jobs: &mut [J],
    rows: impl Fn(&J) -> usize,
    f: impl Fn(&mut J) -> R + Sync,
) -> Vec<R> {
    let total: usize = jobs.iter().map(&rows).sum();
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .min(jobs.len());
    if threads < 2 || total < PAR_MIN_ROWS || IN_POOL.with(|p| p.get()) {
        return jobs.iter_mut().map(&f).collect();
    }
    // Contiguous chunks of about total / threads each.
    let mut bounds = vec![0];
    let mut acc = 0;
    for (i, j) in jobs.iter().enumerate() {
        acc += rows(j);
        if bounds.len() < threads && acc * threads >= total * bounds.len() {
            bounds.push(i + 1);
        }
    }
    if bounds.last() != Some(&jobs.len()) {
        bounds.push(jobs.len());
    }
    let mut chunks = Vec::new();
    let mut rest = jobs;
    for w in bounds.windows(2) {
        let (a, b) = std::mem::take(&mut rest).split_at_mut(w[1] - w[0]);
        chunks.push(a);
        rest = b;
    }
    let f = &f;
    std::thread::scope(|sc| {
        let handles: Vec<_> = chunks
            .into_iter()
            .map(|c| sc.spawn(move || c.iter_mut().map(f).collect::<Vec<R>>()))
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().expect("a calibration thread panicked"))
            .collect()
    })
}

/// A fitted time offset beyond this (s) is reported implausible: loggers of one rig are
/// synchronised to well under half a second.
pub const PLAUSIBLE_TIME_OFFSET_S: f64 = 0.5;
/// A clock ratio further than this from 1 is reported implausible (crystals agree to
/// 1e-4; 5 % means resampled or mis-stamped poses).
pub const PLAUSIBLE_CLOCK_DRIFT: f64 = 0.05;
/// Search bounds of the per-recording nuisance (x0, y0, theta0 in m and rad, time offset
/// in s, clock ratio): far outside the plausible values, so an implausible one is seen
/// and reported rather than clamped.
const NUISANCE_LO: [f64; NUIS] = [-10.0, -10.0, -10.0, -2.0, 0.8];
/// Upper search bounds of the nuisance (see [`NUISANCE_LO`]).
const NUISANCE_HI: [f64; NUIS] = [10.0, 10.0, 10.0, 2.0, 1.25];

fn nuisance_bounds(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (lo, hi) = (NUISANCE_LO, NUISANCE_HI);
    (
        (0..n).flat_map(|_| lo).collect(),
        (0..n).flat_map(|_| hi).collect(),
    )
}

fn geom_bounds(specs: &[ParamSpec]) -> (Vec<f64>, Vec<f64>) {
    // Bounds far outside the plausible range: an implausible value must be seen to be
    // reported, not clamped away.
    specs
        .iter()
        .map(|s| {
            let h = 10.0 * (s.plausible.1 - s.nominal);
            (s.nominal - h, s.nominal + h)
        })
        .unzip()
}

/// The joint fit: geometry (free or fixed) and every recording's nuisance.
struct Solved {
    geom: Vec<f64>,
    nuis: Vec<f64>,
    /// Jacobian of the data residuals with respect to [geometry, nuisance] (free ones).
    jac: DMatrix<f64>,
    data_cost: f64,
    evaluations: usize,
}

fn solve(p: &Problem, geom0: &[f64], nuis0: &[f64], fit_geom: bool) -> Solved {
    solve_iter(p, geom0, nuis0, fit_geom, 60)
}

/// [`solve`] with at most `max_iter` iterations (none: the residuals and Jacobian at the
/// start, as a fit ending there returns them).
fn solve_iter(
    p: &Problem,
    geom0: &[f64],
    nuis0: &[f64],
    fit_geom: bool,
    max_iter: usize,
) -> Solved {
    let g = p.specs.len();
    let (nlo, nhi) = nuisance_bounds(p.series.len());
    let (glo, ghi) = if p.plausible_bounds {
        p.specs.iter().map(|s| s.plausible).unzip()
    } else {
        geom_bounds(p.specs)
    };
    let (x0, lo, hi) = if fit_geom {
        (
            [geom0, nuis0].concat(),
            [glo.as_slice(), &nlo].concat(),
            [ghi.as_slice(), &nhi].concat(),
        )
    } else {
        (nuis0.to_vec(), nlo, nhi)
    };
    let m = p.data_len();
    let mut f = |x: &[f64]| -> Vec<f64> {
        let mut r = if fit_geom {
            p.residuals(&x[..g], &x[g..], true)
        } else {
            p.residuals(geom0, x, false)
        };
        if let Some(c) = p.huber {
            r[..m].iter_mut().for_each(|v| *v = huber(*v, c));
        }
        r
    };
    if x0.is_empty() {
        // Nothing free (dead reckoning with the geometry given).
        let data = p.residuals(geom0, nuis0, false);
        return Solved {
            geom: geom0.to_vec(),
            nuis: nuis0.to_vec(),
            jac: DMatrix::zeros(m, 0),
            data_cost: data.iter().map(|v| v * v).sum(),
            evaluations: 1,
        };
    }
    /// The geometry's analytic Jacobian; whether the last one was (else differences).
    struct Analytic<'a, 'b>(&'b Problem<'a>, usize, bool);
    impl crate::fit::Jacobian for Analytic<'_, '_> {
        fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
            self.2 = self.0.jacobian(&x[..self.1], r, jac);
            self.2
        }
        fn runs(&self) -> usize {
            // One pass over the rows carrying the sensitivities: about three model runs.
            3
        }
        fn column_dots(&self) -> bool {
            true
        }
    }
    /// The start poses and clocks alone (the geometry given): their analytic Jacobian.
    struct Nuisances<'a, 'b>(&'b Problem<'a>, &'b [f64]);
    impl crate::fit::Jacobian for Nuisances<'_, '_> {
        fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
            self.0.nuisance_jacobian(self.1, x, r, jac)
        }
        fn runs(&self) -> usize {
            // One pass over the pose samples, the paths as they are: one model run.
            1
        }
        fn column_dots(&self) -> bool {
            true
        }
    }
    let analytic = fit_geom && !p.free_start;
    let r = if analytic {
        // Each point evaluated carries its sensitivities: the Jacobian that follows an
        // accepted step costs no pass over the rows.
        p.speculate.set(true);
        let mut jac_fn = Analytic(p, g, false);
        let mut r = crate::fit::levenberg_marquardt_with(
            &mut f,
            &mut jac_fn,
            &x0,
            &lo,
            &hi,
            max_iter,
            false,
        );
        p.speculate.set(false);
        if p.differences_at_solution && jac_fn.2 {
            // Forward differences at the solution, as the fit gives them (its analytic
            // Jacobian there is counted as its runs; the differences as one per parameter).
            let at = f(&r.x);
            crate::fit::forward_differences(&mut f, &r.x, &at, &hi, &mut r.jac);
            r.evaluations = r.evaluations - crate::fit::Jacobian::runs(&jac_fn) + r.x.len();
        }
        r
    } else {
        let mut jac_fn: Box<dyn crate::fit::Jacobian> = if !fit_geom && p.free_start {
            Box::new(Nuisances(p, geom0))
        } else {
            Box::new(crate::fit::Differences)
        };
        crate::fit::levenberg_marquardt_with(
            &mut f,
            jac_fn.as_mut(),
            &x0,
            &lo,
            &hi,
            max_iter,
            p.differences_at_solution,
        )
    };
    let jac = &r.jac;
    let (geom, nuis) = if fit_geom {
        (r.x[..g].to_vec(), r.x[g..].to_vec())
    } else {
        (geom0.to_vec(), r.x.clone())
    };
    let data = p.residuals(&geom, &nuis, false);
    let data_cost = data.iter().map(|v| v * v).sum();
    Solved {
        geom,
        nuis,
        jac: jac.rows(0, m).into_owned(),
        data_cost,
        evaluations: r.evaluations,
    }
}

/// The recordings borrowed one by one.
fn refs(series: &[Series]) -> Vec<&Series> {
    series.iter().collect()
}

/// Nuisance start: start pose at the first measured pose, clocks nominal (none when
/// dead-reckoning: nothing per recording is fitted).
fn nuisance_start(series: &[&Series], free_start: bool) -> Vec<f64> {
    if !free_start {
        return vec![];
    }
    series
        .iter()
        .flat_map(|s| {
            // The path starts at row 0; the first pose sample may come later, but the
            // fit moves the start from there.
            [s.px[0], s.py[0], s.pth[0], 0.0, 1.0]
        })
        .collect()
}

/// One fitted geometry parameter.
#[derive(Debug, Clone, Serialize)]
pub struct FittedParam {
    /// What the parameter is: name, effect, nominal value, plausible range.
    #[serde(flatten)]
    pub spec: ParamSpec,
    /// Fitted value.
    pub value: f64,
    /// One standard deviation, residual autocorrelation counted.
    pub sigma: f64,
}

/// Fitted geometry of one wheel.
#[derive(Debug, Clone, Serialize)]
pub struct WheelGeometry {
    /// The wheel's name.
    pub name: String,
    /// Fitted radius, m.
    pub radius_m: f64,
    /// Fitted distance from the body centre, m.
    pub l_m: f64,
    /// Fitted mounting angle (direction of the wheel's position), degrees.
    pub alpha_deg: f64,
    /// Roller angle, degrees (fitted for mecanum wheels in the roller model).
    pub gamma_deg: f64,
}

/// Firmware correction factors.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum Factors {
    /// `factors set` values of a differential drive.
    Diff {
        /// Left wheel's effective radius / nominal radius.
        c_l: f64,
        /// Right wheel's effective radius / nominal radius.
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase (with a turn law: at the recordings' mean
        /// turn, for consumers that apply one constant: ROS 2, the robot file).
        e_b: f64,
        /// A differential drive's turn law, for a board that applies it: E_b in a turn in
        /// place ...
        #[serde(skip_serializing_if = "Option::is_none")]
        e_b_turn_in_place: Option<f64>,
        /// ... and the law's e_b_arc (`factors set --e-b-arc`).
        #[serde(skip_serializing_if = "Option::is_none")]
        e_b_arc: Option<f64>,
    },
    /// Per wheel: the command multiplier f_lat (1 / radius scale), f_lon = 1. Wheel
    /// angle and position errors have no firmware factor: use the fitted robot file.
    Wheels {
        /// Command multiplier per wheel, in the robot's wheel order.
        f_lat: Vec<f64>,
        /// Common multiplier (always 1 here).
        f_lon: f64,
    },
}

/// RMSE of one recording.
#[derive(Debug, Clone, Serialize)]
pub struct PerRecording {
    /// The recording's name as given.
    pub name: String,
    /// Its ground-truth pose samples.
    pub pose_samples: usize,
    /// Pose samples the objective compared (every 5 cm of travel when dead-reckoning).
    pub compared_samples: usize,
    /// The fit's objective with the nominal geometry: position RMSE dead-reckoned from the
    /// first pose at the compared samples (or with the start pose and clocks fitted,
    /// `--free-start`), m.
    pub rmse_before_m: f64,
    /// The same with the fitted geometry, m.
    pub rmse_after_m: f64,
    /// Start pose and clocks fitted (geometry as given), nominal geometry, m.
    pub aligned_before_m: f64,
    /// Start pose and clocks fitted, fitted geometry, m.
    pub aligned_after_m: f64,
    /// Dead reckoning from the first measured pose, nominal and fitted geometry.
    pub dead_reckoning_before_m: f64,
    /// Dead reckoning from the first measured pose with the fitted geometry, m.
    pub dead_reckoning_after_m: f64,
    /// Its fitted start pose and clocks.
    pub nuisance: Nuisance,
    /// Its start pose and clocks fitted with the nominal geometry (the "before").
    pub nuisance_nominal: Nuisance,
    /// One standard deviation of `time_offset_s` and `clock_ratio` (autocorrelation
    /// counted).
    pub time_offset_sigma_s: f64,
    /// One standard deviation of `clock_ratio`.
    pub clock_ratio_sigma: f64,
}

/// RMSE on a recording the fit did not see (dead reckoning from its first pose).
#[derive(Debug, Clone, Serialize)]
pub struct Heldout {
    /// The recording's name as given.
    pub name: String,
    /// The cross-validation group it was held out with (run, session or path kind).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub group: Option<String>,
    /// Dead reckoning with the nominal geometry, m.
    pub rmse_before_m: f64,
    /// Dead reckoning with the fitted geometry, m.
    pub rmse_after_m: f64,
    /// With its start pose and clocks fitted (geometry as given): what the geometry
    /// explains without the start heading's noise, which dead reckoning carries to the end.
    pub aligned_before_m: f64,
    /// The same with the fitted geometry, m.
    pub aligned_after_m: f64,
}

/// Fit RMSE of `s` with the geometry fixed, only its start pose and clocks fitted.
fn aligned_rmse(robot: &Robot, specs: &[ParamSpec], geom: &[f64], s: &Series) -> f64 {
    let mut p = Problem::new(robot, specs, [s]);
    // Only the residuals are read: the analytic Jacobian at the solution too.
    p.differences_at_solution = false;
    let r = solve(&p, geom, &nuisance_start(&[s], true), false);
    position_rmse(&p.residuals(geom, &r.nuis, false))
}

/// Two parameters (or a parameter and the rest) the data do not separate.
#[derive(Debug, Clone, Serialize)]
pub struct Inseparable {
    /// The two parameters' names.
    pub params: [String; 2],
    /// Their correlation in the fit.
    pub correlation: f64,
    /// The combination the data do fix (unit vector over `params`).
    pub identifiable: [f64; 2],
    /// What recording would separate them.
    pub advice: String,
}

/// A parameter outside its physical range.
#[derive(Debug, Clone, Serialize)]
pub struct Implausible {
    /// The parameter's name (a recording's clocks: `<recording>: time_offset_s`...).
    pub name: String,
    /// The value the data ask for.
    pub value: f64,
    /// Physical range (low, high).
    pub plausible: (f64, f64),
    /// What the value most likely stands in for.
    pub stands_for: String,
}

/// The result of [`calibrate`].
#[derive(Debug, Clone, Serialize)]
pub struct Calibration {
    /// The robot's name.
    pub robot: String,
    /// The robot's kind (`diff_drive`, `skid_steer`...): which factors and ranges apply.
    pub kind: &'static str,
    /// What the fit minimised.
    pub objective: &'static str,
    /// True when each recording's start pose and clocks were fitted (`--free-start`);
    /// false when each was dead-reckoned from its first pose.
    pub free_start: bool,
    /// The robust loss and its scale (`None`: squared loss).
    pub robust_loss: Option<String>,
    /// Events one geometry cannot explain, found, reported and kept out of the fit.
    pub events: Vec<Event>,
    /// How cross-validation grouped the recordings (`run`, `session`, `path-kind`).
    pub cv_by: Option<&'static str>,
    /// The recordings' names, in the order given.
    pub recordings: Vec<String>,
    /// The fitted geometry parameters (in [`param_specs`] order), each with its
    /// description (which model was kept).
    pub params: Vec<FittedParam>,
    /// The fitted geometry as firmware correction factors.
    pub factors: Factors,
    /// Each recording's fit, in the order given.
    pub per_recording: Vec<PerRecording>,
    /// All recordings together, nuisance fitted: position RMSE with the nominal
    /// geometry, m.
    pub joint_rmse_before_m: f64,
    /// The same with the fitted geometry, m.
    pub joint_rmse_after_m: f64,
    /// The prediction of the held-out recording, when one was given.
    pub heldout: Option<Heldout>,
    /// Cross-validation: fit on the rest, dead-reckon each group left out.
    #[serde(flatten)]
    pub leave_one_out: HeldoutTable,
    /// Correlations between the geometry parameters (params order).
    pub correlations: Vec<Vec<f64>>,
    /// Pairs the data do not separate, with their correlation, identifiable combination
    /// and advice.
    #[serde(flatten)]
    pub inseparable: Inseparables,
    /// Directions over the geometry the data leave unconstrained (unit vectors).
    pub unconstrained: Vec<Vec<(String, f64)>>,
    /// Values the data ask for outside their physical range (the geometry is then
    /// refitted within the ranges), and implausible clocks of a recording.
    pub implausible: Vec<Implausible>,
    /// Remarks for the reader.
    pub notes: Vec<String>,
    /// Model evaluations the whole fit took.
    pub model_runs: usize,
    /// The robot with the fitted geometry applied; the JSON gives each wheel's fitted
    /// geometry (`geometry`).
    #[serde(rename = "geometry", serialize_with = "serialize_geometry")]
    pub fitted_robot: Robot,
    /// The turn law the geometry was fitted with (fitted, given, or none: zero).
    pub turn_law: TurnLaw,
    /// With a turn law: the fitted robot with the separation of a turn in place, which
    /// the law widens on arcs ([`dead_reckoning_rmse_law`]); else `fitted_robot`.
    #[serde(skip)]
    pub law_base_robot: Robot,
}

impl Calibration {
    /// E_b of a differential drive's factors (at the recordings' mean turn), else 1.
    pub fn factors_e_b(&self) -> f64 {
        match self.factors {
            Factors::Diff { e_b, .. } => e_b,
            Factors::Wheels { .. } => 1.0,
        }
    }

    /// Each wheel's fitted geometry, in the robot's wheel order.
    pub fn geometry(&self) -> Vec<WheelGeometry> {
        wheel_geometry(&self.fitted_robot)
    }

    /// The fitted parameters' descriptions, in `params` order.
    pub fn specs(&self) -> Vec<ParamSpec> {
        self.params.iter().map(|p| p.spec.clone()).collect()
    }

    /// The fitted parameter named `name`.
    pub fn param(&self, name: &str) -> Option<&FittedParam> {
        self.params.iter().find(|p| p.spec.name == name)
    }
}

/// Each wheel's geometry in `robot`, in its wheel order.
fn wheel_geometry(robot: &Robot) -> Vec<WheelGeometry> {
    robot
        .wheels
        .iter()
        .map(|w| WheelGeometry {
            name: w.name.to_string(),
            radius_m: w.radius_m,
            l_m: w.l_m,
            alpha_deg: w.alpha_rad.to_degrees(),
            gamma_deg: w.gamma_rad.to_degrees(),
        })
        .collect()
}

fn serialize_geometry<S: serde::Serializer>(robot: &Robot, s: S) -> Result<S::Ok, S::Error> {
    wheel_geometry(robot).serialize(s)
}

/// The held-out recordings of cross-validation. The JSON gives the table
/// (`leave_one_out`) and its column means (`leave_one_out_mean_before_m`,
/// `leave_one_out_mean_after_m`, `leave_one_out_aligned_before_m`,
/// `leave_one_out_aligned_after_m`; `null` without cross-validation).
#[derive(Debug, Clone, Default)]
pub struct HeldoutTable(pub Vec<Heldout>);

/// Column means of a [`HeldoutTable`], m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldoutMeans {
    /// Dead reckoning with the nominal geometry.
    pub before_m: f64,
    /// Dead reckoning with the fitted geometry.
    pub after_m: f64,
    /// Aligned (start pose and clocks fitted), nominal geometry.
    pub aligned_before_m: f64,
    /// Aligned, fitted geometry.
    pub aligned_after_m: f64,
}

impl HeldoutTable {
    /// The column means, `None` without cross-validation.
    pub fn means(&self) -> Option<HeldoutMeans> {
        let n = self.0.len() as f64;
        let mean = |f: fn(&Heldout) -> f64| self.0.iter().map(f).sum::<f64>() / n;
        (!self.0.is_empty()).then(|| HeldoutMeans {
            before_m: mean(|h| h.rmse_before_m),
            after_m: mean(|h| h.rmse_after_m),
            aligned_before_m: mean(|h| h.aligned_before_m),
            aligned_after_m: mean(|h| h.aligned_after_m),
        })
    }
}

impl Serialize for HeldoutTable {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let m = self.means();
        let mut map = s.serialize_map(Some(5))?;
        map.serialize_entry("leave_one_out", &self.0)?;
        map.serialize_entry("leave_one_out_mean_before_m", &m.map(|m| m.before_m))?;
        map.serialize_entry("leave_one_out_mean_after_m", &m.map(|m| m.after_m))?;
        map.serialize_entry(
            "leave_one_out_aligned_before_m",
            &m.map(|m| m.aligned_before_m),
        )?;
        map.serialize_entry(
            "leave_one_out_aligned_after_m",
            &m.map(|m| m.aligned_after_m),
        )?;
        map.end()
    }
}

/// Geometry pairs the data do not separate. The JSON gives the pairs by name
/// (`not_separable`) and in full (`inseparable`: correlation, the combination the data
/// fix, and what would separate them).
#[derive(Debug, Clone, Default)]
pub struct Inseparables(pub Vec<Inseparable>);

impl Inseparables {
    /// Whether `param` is one side of a pair the data cannot separate.
    pub fn involves(&self, param: &str) -> bool {
        self.0.iter().any(|i| i.params.iter().any(|p| p == param))
    }

    /// The pairs by name.
    pub fn pairs(&self) -> Vec<&[String; 2]> {
        self.0.iter().map(|i| &i.params).collect()
    }

    /// `a / b: what would separate them`, one line per pair.
    pub fn advice(&self) -> impl Iterator<Item = String> + '_ {
        self.0
            .iter()
            .map(|i| format!("{} / {}: {}", i.params[0], i.params[1], i.advice))
    }
}

impl Serialize for Inseparables {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeMap;
        let mut map = s.serialize_map(Some(2))?;
        map.serialize_entry("not_separable", &self.pairs())?;
        map.serialize_entry("inseparable", &self.0)?;
        map.end()
    }
}

/// Options of [`calibrate`].
#[derive(Debug, Clone, Default)]
pub struct CalOptions {
    /// Run leave-one-out cross-validation (when there are at least 2 recordings): the
    /// same as `cv: Some(CvBy::Run)`.
    pub leave_one_out: bool,
    /// Also fit where motion capture tracks on the body (omni robots).
    pub marker_offset: bool,
    /// Fit each recording's start pose, time offset and clock ratio (for recordings whose
    /// frame is not the robot's start frame); else dead-reckon from the first pose.
    pub free_start: bool,
    /// Huber's loss instead of least squares (dead-reckoning objective). Off by default:
    /// on the held-out proxy it transferred worse (geometric mean ratio 1.041 against
    /// 0.987 with squared loss, events kept out either way).
    pub robust: bool,
    /// Cross-validation: hold out whole runs, sessions or kinds of motion.
    pub cv: Option<CvBy>,
    /// Lever arm (m) of the heading residuals in the dead-reckoning objective (default
    /// [`DR_HEADING_LEVER_M`]).
    pub heading_lever_m: Option<f64>,
    /// A differential drive's known turn law, eb_arc / eb (the effective separation on
    /// arcs against a turn in place, [`calib_core::kinematics::turn_law_share`]), from an
    /// earlier calibration on runs with arcs: held fixed while the geometry is fitted.
    /// Squares turn in place and cannot find it (measured: it transfers across days on
    /// the OptiOdom robot).
    pub turn_law: Option<f64>,
}

/// How cross-validation groups recordings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CvBy {
    /// Each recording alone.
    Run,
    /// Recordings of one session (the name without its `-run-NN` suffix).
    Session,
    /// Recordings of one kind of motion (the name's second dash field:
    /// `<robot>-<path>-<session>-run-NN`, e.g. square, circular, ivanjko).
    PathKind,
}

impl CvBy {
    /// Its name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            CvBy::Run => "run",
            CvBy::Session => "session",
            CvBy::PathKind => "path-kind",
        }
    }

    /// Parses `run`, `session` or `path-kind`.
    pub fn parse(s: &str) -> Option<CvBy> {
        match s {
            "run" => Some(CvBy::Run),
            "session" => Some(CvBy::Session),
            "path-kind" | "path" => Some(CvBy::PathKind),
            _ => None,
        }
    }

    /// The group of a recording named `name` (a run folder's name, or a file name).
    pub fn group(self, name: &str) -> String {
        // The parts of a recording split at a pose jump stay together.
        let name = name.split(PART_SEP).next().unwrap_or(name);
        let base = name.trim_end_matches(".csv");
        match self {
            CvBy::Run => base.to_string(),
            CvBy::Session => match base.rfind("-run-") {
                Some(i) => base[..i].to_string(),
                None => base.to_string(),
            },
            CvBy::PathKind => base.split('-').nth(1).unwrap_or(base).to_string(),
        }
    }
}

/// A fit that makes a recording more than this many times worse than nominal (plus
/// [`WORSE_MARGIN_M`]) is refused, naming the recording.
pub const WORSE_FACTOR: f64 = 3.0;
/// See [`WORSE_FACTOR`], m.
pub const WORSE_MARGIN_M: f64 = 0.01;

/// Huber's loss switches from quadratic to linear at this many robust sigmas (1.345: 95 %
/// efficiency on Gaussian residuals).
pub const HUBER_K: f64 = 1.345;
/// Least heading step (rad) across [`EVENT_WINDOW_S`] reported as a slip.
pub const EVENT_MIN_RAD: f64 = 0.04;
/// ... and at least this many robust sigmas of the recording's discrepancies.
pub const EVENT_SIGMAS: f64 = 8.0;
/// Window over which encoders and motion capture are compared for events, s.
pub const EVENT_WINDOW_S: f64 = 3.0;
/// Time on either side of an event window whose mean discrepancy sets the step, s.
pub const EVENT_GUARD_S: f64 = 2.0;
/// A step must also exceed this fraction of the heading turned in its window (a geometry
/// error grows with the turn: 2 % is well beyond any fitted wheelbase's error).
pub const EVENT_PER_TURN: f64 = 0.02;
/// Least transient heading discrepancy (rad) reported as a clock leading for a moment
/// (0.1 s at 1 rad/s).
pub const EVENT_TRANSIENT_RAD: f64 = 0.08;

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
    pub handled: &'static str,
}

#[derive(Debug, Clone, Copy)]
struct Cfg {
    free_start: bool,
    huber: Option<f64>,
    dr_lever: f64,
    /// A known turn law (eb_arc / eb, [`CalOptions::turn_law`]).
    known_law: Option<f64>,
}

impl Cfg {
    /// The known turn law, 0 when none is given.
    fn law(&self) -> f64 {
        self.known_law.unwrap_or(0.0)
    }

    fn apply(&self, p: &mut Problem) {
        p.free_start = self.free_start;
        p.huber = self.huber;
        p.dr_lever = self.dr_lever;
        p.known_law = self.law();
    }
}

/// 1.4826 x the median absolute residual (a robust standard deviation).
fn robust_sigma(r: &[f64]) -> f64 {
    let mut a: Vec<f64> = r
        .iter()
        .map(|v| v.abs())
        .filter(|v| v.is_finite())
        .collect();
    if a.is_empty() {
        return f64::NAN;
    }
    a.sort_by(|x, y| x.total_cmp(y));
    1.4826 * a[a.len() / 2]
}

/// Heading discrepancies (odometry minus motion capture) over [`EVENT_WINDOW_S`] that no
/// geometry explains: reported, and kept out of the fit (a slip restarts dead reckoning
/// from the measured pose after it; a clock lead's samples are not compared).
fn detect_events(robot: &Robot, s: &mut Series) -> Vec<Event> {
    let Ok(kin) = Kinematics::<f64>::new(robot, &Corrections::None) else {
        return vec![];
    };
    let mut path = Path::default();
    if !s.path(robot, &kin, &mut path) {
        return vec![];
    }
    let n = s.pose_row.len();
    let e: Vec<f64> = (0..n)
        .map(|j| (path.th[s.pose_row[j]] - path.th[s.pose_row[0]]) - (s.pth[j] - s.pth[0]))
        .collect();
    let t = |j: usize| s.t[s.pose_row[j]];
    // Window ends.
    let mut end = vec![n - 1; n];
    let mut k = 0;
    for (j, e_j) in end.iter_mut().enumerate() {
        k = k.max(j);
        while k + 1 < n && t(k) - t(j) < EVENT_WINDOW_S {
            k += 1;
        }
        *e_j = k;
    }
    // Mean discrepancy over EVENT_GUARD_S before each window and after it: a slip is a
    // step that stays; one clock leading the other for a moment is a transient inside
    // the window that the means on either side do not see.
    let mut pre = vec![0.0; n + 1];
    for j in 0..n {
        pre[j + 1] = pre[j] + e[j];
    }
    let mean = |a: usize, b: usize| (pre[b + 1] - pre[a]) / (b + 1 - a) as f64;
    // What a geometry error makes of the same step: a wheelbase error grows with the
    // heading turned, a diameter ratio with the distance driven. Both are regressed out
    // (robustly) before a step counts as an event, so a geometry the event itself bent
    // in the first fit does not hide it.
    let mut dist = vec![0.0; n];
    for j in 1..n {
        dist[j] = dist[j - 1] + (s.px[j] - s.px[j - 1]).hypot(s.py[j] - s.py[j - 1]);
    }
    let (mut pth_pre, mut dist_pre) = (vec![0.0; n + 1], vec![0.0; n + 1]);
    for j in 0..n {
        pth_pre[j + 1] = pth_pre[j] + s.pth[j];
        dist_pre[j + 1] = dist_pre[j] + dist[j];
    }
    let mean_of = |v: &[f64], a: usize, b: usize| (v[b + 1] - v[a]) / (b + 1 - a) as f64;
    let mut reg = vec![(0.0, 0.0); n];
    // The first sample at or after t0: by bisection when the times never decrease (the
    // same sample as the scan, which is quadratic in the samples over the recording).
    let ordered = (1..n).all(|k| t(k - 1) <= t(k));
    let first_at = |t0: f64| {
        if ordered && !t0.is_nan() {
            let (mut lo, mut hi) = (0, n);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if t(mid) < t0 {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo.min(n - 1)
        } else {
            (0..n).find(|&k| t(k) >= t0).unwrap_or(n - 1)
        }
    };
    let mut step = vec![0.0; n];
    let mut transient = vec![0.0; n];
    let mut turned = vec![0.0; n];
    let mut after_end = vec![n - 1; n];
    for j in 0..n {
        let b = end[j];
        let a0 = first_at(t(j) - EVENT_GUARD_S);
        let b1 = first_at(t(b) + EVENT_GUARD_S).max(b);
        after_end[j] = b1;
        let (m0, m1) = (mean(a0, j), mean(b, b1));
        step[j] = m1 - m0;
        reg[j] = (
            mean_of(&pth_pre, b, b1) - mean_of(&pth_pre, a0, j),
            mean_of(&dist_pre, b, b1) - mean_of(&dist_pre, a0, j),
        );
        transient[j] = (j..=b)
            .map(|k| e[k] - m0 - (m1 - m0) * (t(k) - t(j)) / (t(b) - t(j)).max(crate::MIN_DT_S))
            .fold(0.0, |acc: f64, v| if v.abs() > acc.abs() { v } else { acc });
        turned[j] = (s.pth[b] - s.pth[j]).abs();
    }
    // Huber-weighted least squares of step on the two regressors, a few passes.
    let mut coef = (0.0, 0.0);
    for _ in 0..5 {
        let res: Vec<f64> = (0..n)
            .map(|j| step[j] - coef.0 * reg[j].0 - coef.1 * reg[j].1)
            .collect();
        let c = HUBER_K * robust_sigma(&res).max(1e-6);
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for j in 0..n {
            let w = if res[j].abs() <= c {
                1.0
            } else {
                c / res[j].abs()
            };
            let (x, y) = reg[j];
            a11 += w * x * x;
            a12 += w * x * y;
            a22 += w * y * y;
            b1 += w * x * step[j];
            b2 += w * y * step[j];
        }
        let det = a11 * a22 - a12 * a12;
        if det.abs() < 1e-12 * (a11 * a22).max(1e-300) {
            break;
        }
        coef = ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
    }
    for j in 0..n {
        step[j] -= coef.0 * reg[j].0 + coef.1 * reg[j].1;
    }
    let sigma = robust_sigma(&step);
    let thr = |j: usize| {
        EVENT_MIN_RAD
            .max(EVENT_SIGMAS * sigma)
            .max(EVENT_PER_TURN * turned[j])
    };
    let mut found: Vec<(usize, usize, f64, &'static str)> = vec![];
    for (vals, kind, limit) in [
        (&step, "slip", None),
        (&transient, "time_lead", Some(EVENT_TRANSIENT_RAD)),
    ] {
        let mut used = vec![false; n];
        for f in &found {
            for u in used.iter_mut().take(f.1 + 1).skip(f.0) {
                *u = true;
            }
        }
        loop {
            let best = (0..n)
                .filter(|&j| !used[j])
                .max_by(|&a, &b| vals[a].abs().total_cmp(&vals[b].abs()));
            let Some(j) = best.filter(|&j| vals[j].abs() > limit.unwrap_or_else(|| thr(j))) else {
                break;
            };
            let (a, b) = (j, end[j]);
            for (u, w) in used.iter_mut().enumerate() {
                if end[u] >= a && u <= b {
                    *w = true;
                }
            }
            found.push((a, b, vals[j], kind));
        }
    }
    found.sort_by_key(|f| f.0);
    // Two steps of opposite sign that undo each other within a few seconds: a clock
    // leading the other through a turn, not a slip.
    // (Transients between them belong to the same turn.)
    let mut merged: Vec<(usize, usize, f64, &'static str)> = vec![];
    let mut i = 0;
    while i < found.len() {
        let f = found[i];
        if f.3 == "slip" {
            let next = (i + 1..found.len()).find(|&j| found[j].3 == "slip");
            if let Some(j) = next {
                let g = found[j];
                if t(g.0) - t(f.1) < 2.0 * EVENT_WINDOW_S
                    && f.2 * g.2 < 0.0
                    && (f.2 + g.2).abs() < 0.3 * f.2.abs().max(g.2.abs())
                {
                    let h = found[i..=j].iter().map(|x| x.2).fold(0.0, |acc: f64, v| {
                        if v.abs() > acc.abs() {
                            v
                        } else {
                            acc
                        }
                    });
                    merged.push((f.0, g.1.max(f.1), h, "time_lead"));
                    i = j + 1;
                    continue;
                }
            }
        }
        merged.push(f);
        i += 1;
    }
    let mut out = vec![];
    let mut skip: Vec<(usize, usize)> = vec![];
    for (a, b, h, kind) in merged {
        let slip = kind == "slip";
        out.push(Event {
            recording: s.name.clone(),
            kind,
            t_s: t(a) - s.t[0],
            duration_s: t(b) - t(a),
            heading_rad: h,
            position_m: 0.0,
            handled: if slip {
                "dead reckoning restarts from the measured pose after it"
            } else {
                "reported only: the heading it leads by is given back when the turn ends"
            },
        });
        if slip {
            skip.push((a, b));
        }
        if slip && !s.anchors.contains(&b) {
            s.anchors.push(b);
        }
    }
    s.anchors.sort();
    s.samples
        .retain(|&j| !skip.iter().any(|&(a, b)| j > a && j < b));
    out
}

/// Inputs `calibrate` refuses before fitting: a held-out recording that is also fitted,
/// a marker offset on a drive without one.
fn check_inputs(
    robot: &Robot,
    recordings: &[(String, Recording)],
    holdout: Option<&(String, Recording)>,
    opts: &CalOptions,
) -> Result<(), CalibrateError> {
    if let Some((hn, hr)) = holdout {
        if let Some((n, _)) = recordings.iter().find(|(_, r)| {
            r.t == hr.t && r.x == hr.x && r.y == hr.y && r.theta == hr.theta && r.len() == hr.len()
        }) {
            return Err(CalibrateError {
                recording: Some(hn.clone()),
                message: format!(
                    "the held-out recording is also fitted (as {n}): a held-out error needs a recording the fit did not see"
                ),
            });
        }
    }
    if let Some(law) = opts.turn_law {
        if robot.kind != RobotKind::DiffDrive {
            return Err(CalibrateError {
                recording: None,
                message: "a known turn law (--turn-law) is for differential drives; a skid-steer robot's law is fitted from its recordings".into(),
            });
        }
        if !law.is_finite() || law.abs() > DIFF_EB_ARC_RANGE {
            return Err(CalibrateError {
                recording: None,
                message: format!(
                    "--turn-law {law} is outside the plausible -{r}..{r} (eb_arc / eb: the separation on arcs over that of a turn in place, minus 1)",
                    r = DIFF_EB_ARC_RANGE
                ),
            });
        }
    }
    if opts.marker_offset && robot.kind != RobotKind::Omni {
        return Err(CalibrateError {
            recording: None,
            message: "a marker offset is fitted for omni robots only: a differential drive's marker offset is not separable from its wheelbase and start heading (drop --marker-offset)".into(),
        });
    }
    Ok(())
}

/// Refuses a fit that makes a recording clearly worse than nominal, or whose
/// uncertainties are zero or infinite: the answer would be confident and wrong.
fn refuse_bad_fit(
    per: &[PerRecording],
    specs: &[ParamSpec],
    geom: &[f64],
    cov: &DMatrix<f64>,
) -> Result<(), CalibrateError> {
    for r in per {
        // One shared geometry need not help every recording (a run whose errors cancelled
        // with the nominal geometry gets worse: a note says so); several times worse is a
        // recording the geometry cannot explain (a glitch, another robot, other units).
        let limit = WORSE_FACTOR * r.rmse_before_m + WORSE_MARGIN_M;
        if r.rmse_after_m > limit || r.rmse_after_m.is_nan() {
            return Err(CalibrateError {
                recording: Some(r.name.clone()),
                message: format!(
                    "the fitted geometry makes this recording worse than nominal ({:.2} -> {:.2} mm): the recordings disagree, or this one holds an error no geometry explains; fit it apart or leave it out",
                    r.rmse_before_m * 1e3,
                    r.rmse_after_m * 1e3
                ),
            });
        }
    }
    for (i, sp) in specs.iter().enumerate() {
        let sg = cov[(i, i)].sqrt();
        if !geom[i].is_finite() || !sg.is_finite() || sg <= 0.0 {
            return Err(CalibrateError {
                recording: per.first().map(|r| r.name.clone()).filter(|_| per.len() == 1),
                message: format!(
                    "{} = {} with uncertainty {sg}: the recordings do not determine it (do the encoders move?)",
                    sp.name, geom[i]
                ),
            });
        }
    }
    Ok(())
}

fn advice(a: &ParamSpec, b: &ParamSpec) -> String {
    use GeomKind::*;
    let pair =
        |x: GeomKind, y: GeomKind| (a.kind == x && b.kind == y) || (a.kind == y && b.kind == x);
    if pair(Ed, Eb) {
        "drive the square the other way too (clockwise and counter-clockwise, as UMBmark does)"
            .into()
    } else if pair(Scale, Eb) || matches!((a.kind, b.kind), (Radius(_), L(_)) | (L(_), Radius(_))) {
        "add a straight run of known length and a turn in place".into()
    } else if a.kind == Gamma || b.kind == Gamma {
        "add sideways and diagonal translations: the roller angle moves them, wheel size moves all motion alike".into()
    } else if matches!(a.kind, Alpha(_)) || matches!(b.kind, Alpha(_)) {
        "add pure translations in several directions without rotation, and a turn in place".into()
    } else {
        "add motion that moves them differently: straight runs both ways and turns in place both ways".into()
    }
}

/// One joint fit of `specs` from nominal (nuisance first, then geometry with the prior
/// weighed by the data): the fit, its residual variance x autocorrelation inflation, and
/// its covariance (when `cov`, else empty: the fit's Jacobian is then the analytic one).
fn fit_specs(robot: &Robot, specs: &[ParamSpec], series: &[&Series], cfg: Cfg, cov: bool) -> Fit {
    let nominal: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
    let mut p = Problem::new(robot, specs, series.iter().copied());
    cfg.apply(&mut p);
    p.differences_at_solution = false;
    let before = solve(&p, &nominal, &nuisance_start(series, cfg.free_start), false);
    p.prior_scale = noise_scale(&p, &before);
    let first = solve(&p, &nominal, &before.nuis, true);
    p.prior_scale = noise_scale(&p, &first);
    p.differences_at_solution = cov;
    let f = solve(&p, &first.geom, &first.nuis, true);
    let var = noise_scale(&p, &f).powi(2);
    let cov = if cov {
        covariance(&p, &f).0
    } else {
        DMatrix::zeros(0, 0)
    };
    let runs = before.evaluations + first.evaluations + f.evaluations;
    Fit {
        f,
        var,
        cov,
        runs,
        first,
    }
}

/// A joint fit of [`fit_specs`].
struct Fit {
    /// The fit (the prior weighed by the first fit's residuals).
    f: Solved,
    /// Its residual variance x autocorrelation inflation.
    var: f64,
    /// Its covariance (empty unless asked for).
    cov: DMatrix<f64>,
    /// Model runs it took.
    runs: usize,
    /// The first fit (the prior weighed by the nominal residuals).
    first: Solved,
}

/// A fit of the chosen parameters on all the recordings that choosing them made: the
/// final fit repeats it (the same problem, the same steps) and takes it over.
struct Prefit {
    specs: Vec<ParamSpec>,
    first: Solved,
    f: Solved,
}

/// 0.999 quantile of chi-squared with `k` degrees of freedom (Wilson-Hilferty; within
/// 1 % of the tables for k >= 1).
fn chi2_999(k: usize) -> f64 {
    let k = k.max(1) as f64;
    let a = 2.0 / (9.0 * k);
    k * (1.0 - a + 3.0902 * a.sqrt()).powi(3)
}

/// The parameters to fit. For a mecanum robot the roller angle is fitted when the data
/// ask for it: the roller model (radii and one roller angle) is chosen when its angle is
/// significant (3 sigma) and it fits as well as the full per-wheel model (likelihood
/// ratio below the 0.999 quantile for the parameters it saves). Says which and why.
fn choose_specs(
    robot: &Robot,
    series: &[Series],
    marker: bool,
    cfg: Cfg,
    notes: &mut Vec<String>,
    runs: &mut usize,
    prefit: &mut Option<Prefit>,
) -> Vec<ParamSpec> {
    let full = param_specs(robot, marker);
    if robot.kind == RobotKind::SkidSteer
        || (robot.kind == RobotKind::DiffDrive && robot.wheels.len() == 2)
    {
        return choose_turn_law(robot, series, cfg, notes, runs, prefit);
    }
    if robot.kind == RobotKind::Omni && series.len() >= 2 {
        return climb_ladder(robot, series, marker, cfg, notes, runs, prefit);
    }
    if !is_mecanum(robot) {
        return full;
    }
    let roller = roller_specs(robot, marker);
    let Fit {
        f: f_full,
        var: var_full,
        runs: r1,
        ..
    } = fit_specs(robot, &full, &refs(series), cfg, false);
    let Fit {
        f: f_roller,
        cov: cov_roller,
        runs: r2,
        ..
    } = fit_specs(robot, &roller, &refs(series), cfg, true);
    *runs += r1 + r2;
    let gi = roller
        .iter()
        .position(|s| s.kind == GeomKind::Gamma)
        .unwrap_or(0);
    let (dg, sg) = (f_roller.geom[gi], cov_roller[(gi, gi)].max(0.0).sqrt());
    let k = full.len() - roller.len();
    let stat = (f_roller.data_cost - f_full.data_cost).max(0.0) / var_full.max(1e-300);
    let q = chi2_999(k);
    let significant = dg.abs() >= 3.0 * sg;
    let as_good = stat <= q;
    let deg = |v: f64| v.to_degrees();
    if significant && as_good {
        notes.push(format!(
            "mecanum: one roller angle offset ({:+.3} ± {:.3} deg) explains the data as well as per-wheel angles, distances and radii (likelihood ratio {stat:.1} <= {q:.1} for {k} fewer parameters): the roller model is fitted",
            deg(dg),
            deg(sg)
        ));
        roller
    } else {
        let why = if significant {
            format!("a roller angle alone ({:+.3} ± {:.3} deg) leaves a likelihood ratio of {stat:.1} > {q:.1} against per-wheel geometry", deg(dg), deg(sg))
        } else {
            format!(
                "the roller angle is not asked for by the data ({:+.3} ± {:.3} deg)",
                deg(dg),
                deg(sg)
            )
        };
        notes.push(format!(
            "mecanum: {why}; per-wheel angles, distances and radii are fitted (in the kinematics a wheel's roller angle is a combination of them)"
        ));
        full
    }
}

/// A rung of the ladder is adequate when its held-out error is within this share of the
/// best rung's: a model with more parameters must buy more than 3 % to be chosen.
pub const LADDER_TOLERANCE: f64 = 0.03;
/// Most folds the ladder's held-out comparison uses.
pub const LADDER_FOLDS: usize = 5;
/// A mecanum wheel's effective radius: the rollers' contact moves with the direction of
/// travel, and real mecanum robots dead-reckon with radii 5-12 % off the hub's (the
/// real mecanum squares want 67 mm on a 60 mm wheel).
pub const MECANUM_RADIUS_RANGE: f64 = 0.15;

/// The models an omni robot's calibration climbs, simplest first: one common scale; a
/// common scale and wheel distance; per-wheel radii and a common distance; per-wheel
/// radii, angles and distances; on a mecanum robot, per-wheel radii and one roller angle.
pub fn ladder(robot: &Robot, marker: bool) -> Vec<(&'static str, Vec<ParamSpec>)> {
    let mecanum = is_mecanum(robot);
    let mut scale = spec(
        GeomKind::Scale,
        "scale".into(),
        "wheel_scale",
        1.0,
        if mecanum {
            MECANUM_RADIUS_RANGE
        } else {
            RADIUS_RANGE
        },
        SCALE_STANDS,
    );
    if mecanum {
        scale.stands_for = "the rollers' effective radius, or a wrong nominal diameter";
    }
    let distance = spec(
        GeomKind::Eb,
        "l_scale".into(),
        "wheelbase_error",
        1.0,
        BASE_RANGE,
        L_STANDS,
    );
    let full = param_specs(robot, marker);
    let markers: Vec<ParamSpec> = full
        .iter()
        .filter(|s| matches!(s.kind, GeomKind::MarkerX | GeomKind::MarkerY))
        .cloned()
        .collect();
    let radii: Vec<ParamSpec> = full
        .iter()
        .filter(|s| matches!(s.kind, GeomKind::Radius(_)))
        .cloned()
        .map(|mut s| {
            if mecanum {
                s.plausible = (1.0 - MECANUM_RADIUS_RANGE, 1.0 + MECANUM_RADIUS_RANGE);
            }
            s
        })
        .collect();
    let with_markers = |mut v: Vec<ParamSpec>| {
        v.extend(markers.iter().cloned());
        v
    };
    let mut rungs = vec![
        ("common scale", with_markers(vec![scale.clone()])),
        (
            "common scale and wheel distance",
            with_markers(vec![scale, distance.clone()]),
        ),
        ("per-wheel radii and a common wheel distance", {
            let mut v = radii.clone();
            v.push(distance);
            with_markers(v)
        }),
        ("per-wheel radii, angles and distances", {
            let mut f = full.clone();
            for s in f.iter_mut() {
                if let Some(r) = radii.iter().find(|r| r.kind == s.kind) {
                    s.plausible = r.plausible;
                }
            }
            f
        }),
    ];
    if mecanum {
        rungs.push((
            "per-wheel radii and one roller angle",
            roller_specs(robot, marker)
                .into_iter()
                .map(|mut s| {
                    if let Some(r) = radii.iter().find(|r| r.kind == s.kind) {
                        s.plausible = r.plausible;
                    }
                    s
                })
                .collect(),
        ));
    }
    rungs
}

/// Mean held-out dead-reckoning RMSE of the model `specs`: the recordings split into at
/// most [`LADDER_FOLDS`] folds (recording j in fold j mod k; 44 recordings left out one
/// by one for five models took six minutes), the model fitted without each fold and
/// dead-reckoning it from each recording's first pose.
///
/// Of each model of `models`: the folds of all of them are fitted in parallel (each fit
/// on one thread), each model's errors summed in fold order.
fn heldout_errors(
    robot: &Robot,
    models: &[&[ParamSpec]],
    series: &[Series],
    cfg: Cfg,
    runs: &mut usize,
) -> Vec<f64> {
    let n = series.len();
    let k = n.min(LADDER_FOLDS);
    let mut jobs: Vec<(usize, usize)> = (0..models.len())
        .flat_map(|m| (0..k).map(move |fold| (m, fold)))
        .collect();
    // Largest models first: the threads finish together.
    jobs.sort_by_key(|&(m, _)| std::cmp::Reverse(models[m].len()));
    let done = pool_map(&jobs, |&(m, fold)| {
        let rest: Vec<&Series> = (0..n)
            .filter(|&j| j % k != fold)
            .map(|j| &series[j])
            .collect();
        let Fit { f, runs: r, .. } = fit_specs(robot, models[m], &rest, cfg, false);
        let errors: Vec<f64> = (0..n)
            .filter(|&j| j % k == fold)
            .map(|j| fitted_dead_reckoning_rmse(robot, models[m], &f.geom, cfg.law(), &series[j]))
            .collect();
        (errors, r)
    });
    let mut by_job: Vec<_> = jobs.into_iter().zip(done).collect();
    by_job.sort_by_key(|j| j.0);
    *runs += by_job.iter().map(|j| j.1 .1).sum::<usize>();
    (0..models.len())
        .map(|m| {
            let mut e = 0.0;
            for (_, (errors, _)) in by_job.iter().filter(|j| j.0 .0 == m) {
                for v in errors {
                    e += v;
                }
            }
            e / n as f64
        })
        .collect()
}

/// Parsimony for an omni robot: each model of [`ladder`] is judged by its held-out
/// dead reckoning ([`heldout_errors`]); the simplest model within
/// [`LADDER_TOLERANCE`] of the best held-out error is kept, unless its fit on all the data
/// leaves a parameter outside its plausible range (the model or the range is then
/// wrong: said, and the next adequate model tried). Says which and why, with figures.
fn climb_ladder(
    robot: &Robot,
    series: &[Series],
    marker: bool,
    cfg: Cfg,
    notes: &mut Vec<String>,
    runs: &mut usize,
    prefit: &mut Option<Prefit>,
) -> Vec<ParamSpec> {
    let rungs = ladder(robot, marker);
    let k = series.len().min(LADDER_FOLDS);
    let models: Vec<&[ParamSpec]> = rungs.iter().map(|(_, specs)| specs.as_slice()).collect();
    let errors = heldout_errors(robot, &models, series, cfg, runs);
    let best = errors
        .iter()
        .copied()
        .filter(|e| e.is_finite())
        .fold(f64::INFINITY, f64::min);
    let table = rungs
        .iter()
        .zip(&errors)
        .map(|((name, specs), e)| format!("{name} ({} parameters) {:.1} mm", specs.len(), e * 1e3))
        .collect::<Vec<_>>()
        .join("; ");
    let mut skipped = Vec::new();
    let mut fitted: Vec<(usize, Fit)> = Vec::new();
    for (rung, ((name, specs), e)) in rungs.iter().zip(&errors).enumerate() {
        if !(e.is_finite() && *e <= (1.0 + LADDER_TOLERANCE) * best) {
            continue;
        }
        let fit = fit_specs(robot, specs, &refs(series), cfg, false);
        *runs += fit.runs;
        let f = &fit.f;
        let edge: Vec<String> = specs
            .iter()
            .zip(&f.geom)
            .filter(|(s, v)| **v < s.plausible.0 || **v > s.plausible.1)
            .map(|(s, v)| format!("{} {v:.4}", s.name))
            .collect();
        if !edge.is_empty() {
            skipped.push(format!(
                "{name} wants {} outside the plausible range",
                edge.join(", ")
            ));
            fitted.push((rung, fit));
            continue;
        }
        let why = if skipped.is_empty() {
            String::new()
        } else {
            format!(" ({}: the next model is tried)", skipped.join("; "))
        };
        notes.push(format!(
            "model ladder, held-out dead reckoning by recording ({k} folds): {table}; kept: {name}, the simplest within {:.0} % of the best{why}",
            LADDER_TOLERANCE * 100.0
        ));
        *prefit = Some(Prefit {
            specs: specs.clone(),
            first: fit.first,
            f: fit.f,
        });
        return specs.clone();
    }
    // Every adequate model wants an implausible value: the best one is fitted, its
    // implausible values reported (the model or the range is wrong).
    let chosen = rungs
        .iter()
        .zip(&errors)
        .enumerate()
        .filter(|(_, (_, e))| e.is_finite())
        .min_by(|a, b| a.1 .1.total_cmp(b.1 .1))
        .map(|(i, (r, _))| (i, r.clone()));
    let (name, specs) = match chosen {
        Some((i, r)) => {
            if let Some((_, fit)) = fitted.into_iter().find(|(j, _)| *j == i) {
                *prefit = Some(Prefit {
                    specs: r.1.clone(),
                    first: fit.first,
                    f: fit.f,
                });
            }
            r
        }
        None => ("full", param_specs(robot, marker)),
    };
    notes.push(format!(
        "model ladder, held-out dead reckoning by recording ({k} folds): {table}; every adequate model wants values outside the plausible ranges ({}): the best, {name}, is fitted and its implausible values are listed",
        skipped.join("; ")
    ));
    specs
}

/// Turn ratios that count as arcs (rho = 1 is a turn in place, 0 a straight line).
pub const ARC_RHO: (f64, f64) = (0.1, 0.8);
/// A turn-radius law needs the recordings to turn on arcs for at least this share of
/// their turning: squares turn only in place, and a law fitted to them extrapolates
/// (measured: on one real square session, eb_arc 0.33 ± 0.08 held out on its squares
/// and made the circles nine times worse). Real squares turn 0-4 % on arcs (the starts
/// and ends of turns), the simulator's free motion 24 %.
pub const MIN_ARC_SHARE: f64 = 0.15;
/// A differential drive's separation may depend on the turn by this much (tyre scrub).
pub const DIFF_EB_ARC_RANGE: f64 = 0.1;

/// Held-out improvement a turn-radius law must bring to be kept: its mean held-out
/// dead-reckoning error at most this share of the constant-E_b model's.
pub const TURN_LAW_HOLDOUT_RATIO: f64 = 0.95;

/// A differential or skid-steer robot's model: constant E_b, or the turn-radius law
/// ([Mandow et al.]'s moving ICRs on a skid-steer robot, tyre scrub on a differential
/// drive) when it holds out. The recordings are split into at most [`LADDER_FOLDS`]
/// folds; both models are fitted without each fold and dead-reckon it; the law is kept
/// when its mean held-out error is at most [`TURN_LAW_HOLDOUT_RATIO`] of the constant
/// model's and one of its parameters is significant (3 sigma) on all the data. Says
/// which and why, with the figures.
fn choose_turn_law(
    robot: &Robot,
    series: &[Series],
    cfg: Cfg,
    notes: &mut Vec<String>,
    runs: &mut usize,
    prefit: &mut Option<Prefit>,
) -> Vec<ParamSpec> {
    let skid = robot.kind == RobotKind::SkidSteer;
    let who = if skid { "skid-steer" } else { "turn law" };
    let base = param_specs(robot, false);
    let law = turn_law_specs(robot);
    if let Some(known) = cfg.known_law {
        notes.push(format!(
            "turn law: given (--turn-law), held at eb_arc/eb {known:+.4}: the separation on arcs is {:.2} % wider than in a turn in place; the geometry is fitted with it",
            known * 100.0
        ));
        return base;
    }
    if series.len() < 2 {
        if skid {
            notes.push(format!(
                "{who}: one recording cannot cross-validate a turn-radius law; a constant effective separation (E_b) is fitted"
            ));
        }
        return base;
    }
    let (arcs, all) = series.iter().fold((0.0, 0.0), |(a, b), s| {
        let t = s.turning(robot);
        (a + t.arcs, b + t.all)
    });
    let share = if all > 0.0 { arcs / all } else { 0.0 };
    if share < MIN_ARC_SHARE {
        notes.push(format!(
            "{who}: the recordings turn on arcs for {:.0} % of their turning (the rest in place), under the {:.0} % a turn-radius law needs: a constant effective separation (E_b) is fitted; record arcs of several radii to test one",
            share * 100.0,
            MIN_ARC_SHARE * 100.0
        ));
        return base;
    }
    let fit_law = fit_specs(robot, &law, &refs(series), cfg, true);
    *runs += fit_law.runs;
    let (f_law, cov_law) = (&fit_law.f, &fit_law.cov);
    let k = series.len().min(LADDER_FOLDS);
    let e = heldout_errors(robot, &[&base, &law], series, cfg, runs);
    let (e_base, e_law) = (e[0], e[1]);
    let at = |k: GeomKind| law.iter().position(|s| s.kind == k);
    let sd = |i: usize| cov_law[(i, i)].max(0.0).sqrt();
    let ia = at(GeomKind::EbArc).unwrap_or(0);
    let (arc, s_arc) = (f_law.geom[ia], sd(ia));
    let mut significant = arc.abs() >= 3.0 * s_arc;
    let mut figures = format!("eb_arc {arc:+.4} ± {s_arc:.4}");
    if let Some(ix) = at(GeomKind::IcrX) {
        let (x, s_x) = (f_law.geom[ix], sd(ix));
        significant |= x.abs() >= 3.0 * s_x;
        figures.push_str(&format!(", icr_x {:+.1} ± {:.1} mm", x * 1e3, s_x * 1e3));
    }
    figures.push_str(&format!(
        "; held-out dead reckoning by recording ({k} folds) {:.1} mm with the law, {:.1} mm with a constant E_b",
        e_law * 1e3,
        e_base * 1e3
    ));
    let holds = e_law.is_finite() && e_law <= TURN_LAW_HOLDOUT_RATIO * e_base;
    let plausible = law[ia].plausible;
    let in_range = (plausible.0..=plausible.1).contains(&arc);
    if !in_range {
        figures.push_str(&format!(
            "; eb_arc is outside its plausible {:+.2}..{:+.2}",
            plausible.0, plausible.1
        ));
    }
    if significant && holds && in_range {
        let what = if skid {
            "the tracks' ICRs move with the turn radius"
        } else {
            "the effective wheelbase depends on how the robot turns (tyre scrub)"
        };
        let consumers = if skid {
            "ROS 2's diff_drive_controller and the board apply a constant E_b, the law's value at the recordings' mean turn"
        } else {
            "the board applies it (factors set --e-b-arc); ROS 2's diff_drive_controller and the robot file get E_b at the recordings' mean turn"
        };
        notes.push(format!(
            "{who}: {what} and the law holds out ({figures}): the law is fitted ({consumers})"
        ));
        *prefit = Some(Prefit {
            specs: law.clone(),
            first: fit_law.first,
            f: fit_law.f,
        });
        law
    } else {
        notes.push(format!(
            "{who}: a constant effective separation explains the data ({figures}; the law is kept only when significant and at most {:.0} % of the constant model's held-out error)",
            TURN_LAW_HOLDOUT_RATIO * 100.0
        ));
        base
    }
}

/// Fits the geometry of `robot` to `recordings` (name, recording) jointly.
pub fn calibrate(
    robot: &Robot,
    recordings: &[(String, Recording)],
    holdout: Option<&(String, Recording)>,
    opts: &CalOptions,
) -> Result<Calibration, CalibrateError> {
    if recordings.is_empty() {
        return Err(CalibrateError {
            recording: None,
            message: "no recording given".into(),
        });
    }
    if Kinematics::<f64>::new(robot, &Corrections::None).is_err() {
        return Err(CalibrateError {
            recording: None,
            message: "the robot's wheels cannot resolve the body twist".into(),
        });
    }
    check_inputs(robot, recordings, holdout, opts)?;
    let series = recordings
        .iter()
        .map(|(n, r)| Series::new(n, robot, r))
        .collect::<Result<Vec<_>, _>>()?;
    let mut series: Vec<Series> = series
        .into_iter()
        .flat_map(|s| s.split_at_jumps(robot))
        .collect();
    let held = holdout.map(|(n, r)| Series::new(n, robot, r)).transpose()?;
    let mut notes = Vec::new();
    let mut runs = 0;
    let mut cfg = Cfg {
        free_start: opts.free_start,
        huber: None,
        dr_lever: opts.heading_lever_m.unwrap_or(DR_HEADING_LEVER_M),
        known_law: opts.turn_law,
    };
    // SLAM-like poses: dead reckoning from one pose sample of centimetre noise tilts the
    // whole recording (measured on the simulator: scale, E_d and E_b 8-11 sigma off), so
    // the start pose is fitted from all samples instead.
    let mut noise: Vec<f64> = series.iter().filter_map(|s| s.pose_noise_m).collect();
    noise.sort_by(|a, b| a.total_cmp(b));
    if let Some(&median_noise) = noise.get(noise.len() / 2) {
        if median_noise > NOISY_POSES_M && !cfg.free_start {
            cfg.free_start = true;
            notes.push(format!(
                "the poses scatter {:.1} mm per sample (SLAM-like, above {:.0} mm): each recording's start pose and clocks are fitted (as --free-start), since dead reckoning from one noisy pose would tilt the whole recording",
                median_noise * 1e3,
                NOISY_POSES_M * 1e3
            ));
        }
    }
    // Events one geometry cannot explain (slips, motion capture leading the encoders,
    // glitches): found on a first squared-loss fit, reported, and kept out of the fit
    // (dead reckoning restarts from the measured pose after a slip; the samples inside an
    // event are not compared).
    let mut events: Vec<Event> = series.iter().flat_map(|s| s.glitches.clone()).collect();
    if !cfg.free_start {
        let specs0 = param_specs(robot, opts.marker_offset);
        let f0 = fit_specs(robot, &specs0, &refs(&series), cfg, false).f;
        let r0 = robot_with(robot, &specs0, &f0.geom);
        for s in series.iter_mut() {
            events.extend(detect_events(&r0, s));
        }
        if opts.robust {
            // Huber's scale: HUBER_K robust sigmas (MAD) of the squared-loss residuals.
            let f1 = fit_specs(robot, &specs0, &refs(&series), cfg, false).f;
            let mut p1 = Problem::new(robot, &specs0, &series);
            cfg.apply(&mut p1);
            let r = p1.residuals(&f1.geom, &f1.nuis, false);
            let sigma = robust_sigma(&r);
            if sigma.is_finite() && sigma > 0.0 {
                cfg.huber = Some(HUBER_K * sigma);
            }
        }
    }
    let mut prefit = None;
    let specs = choose_specs(
        robot,
        &series,
        opts.marker_offset,
        cfg,
        &mut notes,
        &mut runs,
        &mut prefit,
    );
    let nominal: Vec<f64> = specs.iter().map(|s| s.nominal).collect();

    // Nominal geometry (nuisance fitted when free): the "before".
    let mut p = Problem::new(robot, &specs, &series);
    cfg.apply(&mut p);
    let before = solve(
        &p,
        &nominal,
        &nuisance_start(&refs(&series), cfg.free_start),
        false,
    );
    let before_res = p.residuals(&nominal, &before.nuis, false);
    runs += before.evaluations;

    // Joint fit, the prior weighed by the nominal residuals first (directions the data
    // do not constrain must not wander off while the fit starts).
    // When choosing the model fitted it on all the recordings already (the same problem
    // and steps), that fit is taken over, its Jacobian at the solution by differences.
    p.prior_scale = noise_scale(&p, &before);
    let mut fitted = match prefit {
        Some(pre) => {
            debug_assert!(pre
                .specs
                .iter()
                .map(|s| &s.name)
                .eq(specs.iter().map(|s| &s.name)));
            p.prior_scale = noise_scale(&p, &pre.first);
            solve_iter(&p, &pre.f.geom, &pre.f.nuis, true, 0)
        }
        None => {
            p.differences_at_solution = false;
            let first = solve(&p, &nominal, &before.nuis, true);
            p.differences_at_solution = true;
            runs += first.evaluations;
            // Weigh the plausibility prior against the data's real information (MAP),
            // and refit.
            p.prior_scale = noise_scale(&p, &first);
            solve(&p, &first.geom, &first.nuis, true)
        }
    };
    runs += fitted.evaluations;
    let g = specs.len();
    let (mut cov, inflation) = covariance(&p, &fitted);
    let mut corr = correlations(&cov, g);
    // Not separable pairs: fit only the combination the data fix.
    let mut insep = Vec::new();
    for a in 0..g {
        for b in a + 1..g {
            let c = corr[a][b];
            let (sa, sb) = (cov[(a, a)].sqrt(), cov[(b, b)].sqrt());
            let (da, db) = (
                (fitted.geom[a] - specs[a].nominal).abs(),
                (fitted.geom[b] - specs[b].nominal).abs(),
            );
            // "Uncertainty larger than the value" counts only when the uncertainty is material
            // against the plausible range: a parameter fitted 0 ± 0.0002 is known, not lost.
            let (ra, rb) = (
                MATERIAL_SHARE * (specs[a].plausible.1 - specs[a].nominal),
                MATERIAL_SHARE * (specs[b].plausible.1 - specs[b].nominal),
            );
            let weak = c.abs() > WEAK_CORR && (sa > da.max(ra) || sb > db.max(rb));
            if c.abs() > CORR_LIMIT || weak {
                // Well-determined direction of the 2x2 block: the eigenvector with the
                // smaller variance.
                let blk =
                    nalgebra::Matrix2::new(cov[(a, a)], cov[(a, b)], cov[(a, b)], cov[(b, b)]);
                let e = SymmetricEigen::new(blk);
                let i_small = if e.eigenvalues[0] < e.eigenvalues[1] {
                    0
                } else {
                    1
                };
                let good = e.eigenvectors.column(i_small);
                let sgn = if good[0] < 0.0 { -1.0 } else { 1.0 };
                insep.push(Inseparable {
                    params: [specs[a].name.clone(), specs[b].name.clone()],
                    correlation: c,
                    identifiable: [sgn * good[0], sgn * good[1]],
                    advice: advice(&specs[a], &specs[b]),
                });
            }
        }
    }
    // What the uncertainties assume of the poses: motion capture is sub-millimetre, a
    // SLAM trajectory centimetres, and the stated sigmas scale with it.
    let noise: Vec<f64> = series.iter().filter_map(|s| s.pose_noise_m).collect();
    let pose_noise = if noise.is_empty() {
        String::new()
    } else {
        let mut v = noise.clone();
        v.sort_by(|a, b| a.total_cmp(b));
        format!(
            "; the poses scatter {:.1} mm per sample about the wheels' steps (median over the recordings), and the fit's residuals {:.1} mm RMS",
            1e3 * v[v.len() / 2],
            position_rmse(&p.residuals(&fitted.geom, &fitted.nuis, false)) * 1e3
        )
    };
    notes.push(format!(
        "uncertainties count the residuals' autocorrelation (variance x{inflation:.0}){pose_noise}"
    ));
    // What the data ask for outside the physical ranges is reported, and the geometry
    // is refitted within them: an implausible value stands in for something else and
    // must not be written to a robot.
    let implausible: Vec<Implausible> = specs
        .iter()
        .zip(&fitted.geom)
        .filter(|(s, v)| **v < s.plausible.0 || **v > s.plausible.1)
        .map(|(s, v)| Implausible {
            name: s.name.clone(),
            value: *v,
            plausible: s.plausible,
            stands_for: s.stands_for.to_string(),
        })
        .collect();
    if !implausible.is_empty() {
        let unbounded = p.residuals(&fitted.geom, &fitted.nuis, false);
        notes.push(format!(
            "geometry fitted within the plausible ranges; unbounded it reaches {:.2} mm (fit RMSE) with the implausible values listed",
            position_rmse(&unbounded) * 1e3
        ));
        p.plausible_bounds = true;
        fitted = solve(&p, &fitted.geom, &fitted.nuis, true);
        runs += fitted.evaluations;
        (cov, _) = covariance(&p, &fitted);
        corr = correlations(&cov, g);
    }
    let after_res = p.residuals(&fitted.geom, &fitted.nuis, false);
    let mut fitted_robot = robot_with(robot, &specs, &fitted.geom);
    // A turn-radius law is more than a robot file, the board or ROS 2's
    // diff_drive_controller express: they all get E_b at the recordings' mean turn,
    // weighted by how much each row turns.
    let turn_law = TurnLaw::of(&specs, &fitted.geom, cfg.law());
    let law_base_robot = fitted_robot.clone();
    let mut law_eb_shift = 0.0;
    if turn_law.arc_rel != 0.0 {
        let (mut sw, mut st) = (0.0, 0.0);
        for s in &series {
            let t = s.turning(robot);
            sw += t.all;
            st += t.arc_term;
        }
        let eb = specs
            .iter()
            .position(|s| s.kind == GeomKind::Eb)
            .map_or(1.0, |i| fitted.geom[i]);
        if sw > 0.0 {
            law_eb_shift = turn_law.arc_rel * eb * st / sw;
            for w in fitted_robot.wheels.iter_mut() {
                w.l_m *= (eb + law_eb_shift) / eb;
            }
        }
    }

    // Unconstrained directions: eigenvectors of the correlation matrix with tiny
    // eigenvalues.
    let mut unconstrained = Vec::new();
    if g > 1 {
        let cm = DMatrix::from_fn(g, g, |i, j| corr[i][j]);
        let e = SymmetricEigen::new(cm);
        for k in 0..g {
            if e.eigenvalues[k] < 1e-2 {
                let v = e.eigenvectors.column(k);
                let mut dir: Vec<(String, f64)> = (0..g)
                    .filter(|&i| v[i].abs() > 0.1)
                    .map(|i| (specs[i].name.clone(), v[i]))
                    .collect();
                if dir.first().is_some_and(|d| d.1 < 0.0) {
                    dir.iter_mut().for_each(|d| d.1 = -d.1);
                }
                unconstrained.push(dir);
            }
        }
    }

    // Per recording: its dead reckoning and aligned errors (independent: in parallel,
    // each thread taking the next recording, since the aligned fits' lengths vary).
    let replays = pool_map(&series, |s| {
        let (ab, aa) = if cfg.free_start {
            (f64::NAN, f64::NAN)
        } else {
            (
                aligned_rmse(robot, &specs, &nominal, s),
                aligned_rmse(robot, &specs, &fitted.geom, s),
            )
        };
        (
            dead_reckoning_rmse(robot, s).unwrap_or(f64::NAN),
            fitted_dead_reckoning_rmse(robot, &specs, &fitted.geom, cfg.law(), s),
            ab,
            aa,
        )
    });
    let mut per_recording = Vec::new();
    let mut offs = (0, 0);
    for (i, s) in series.iter().enumerate() {
        let (dr_before, dr_after, ab, aa) = replays[i];
        let m = 3 * if cfg.free_start {
            s.pose_samples()
        } else {
            s.samples.len()
        };
        offs.1 = offs.0 + m;
        let (rb, ra) = (
            position_rmse(&before_res[offs.0..offs.1]),
            position_rmse(&after_res[offs.0..offs.1]),
        );
        let (nu, nu_nom, sig_t, sig_c) = if cfg.free_start {
            (
                Nuisance::from(&fitted.nuis[i * NUIS..(i + 1) * NUIS]),
                Nuisance::from(&before.nuis[i * NUIS..(i + 1) * NUIS]),
                cov[(g + i * NUIS + 3, g + i * NUIS + 3)].max(0.0).sqrt(),
                cov[(g + i * NUIS + 4, g + i * NUIS + 4)].max(0.0).sqrt(),
            )
        } else {
            let a = s.first_pose();
            (a, a, f64::NAN, f64::NAN)
        };
        let (ab, aa) = if cfg.free_start { (rb, ra) } else { (ab, aa) };
        per_recording.push(PerRecording {
            name: s.name.clone(),
            pose_samples: s.pose_samples(),
            compared_samples: m / 3,
            rmse_before_m: rb,
            rmse_after_m: ra,
            dead_reckoning_before_m: dr_before,
            dead_reckoning_after_m: dr_after,
            aligned_before_m: ab,
            aligned_after_m: aa,
            nuisance: nu,
            nuisance_nominal: nu_nom,
            time_offset_sigma_s: sig_t,
            clock_ratio_sigma: sig_c,
        });
        offs.0 = offs.1;
    }
    refuse_bad_fit(&per_recording, &specs, &fitted.geom, &cov)?;
    let heldout = held.as_ref().map(|h| Heldout {
        name: h.name.clone(),
        group: None,
        rmse_before_m: dead_reckoning_rmse(robot, h).unwrap_or(f64::NAN),
        aligned_before_m: aligned_rmse(robot, &specs, &nominal, h),
        aligned_after_m: aligned_rmse(robot, &specs, &fitted.geom, h),
        rmse_after_m: fitted_dead_reckoning_rmse(robot, &specs, &fitted.geom, cfg.law(), h),
    });

    // Cross-validation: each group (run, session or path kind) held out in turn, the
    // geometry refitted on the rest from the full solution (the same objective, loss,
    // events and bounds), the held-out recordings dead-reckoned and aligned.
    let cv_by = opts.cv.or(opts.leave_one_out.then_some(CvBy::Run));
    let mut leave_one_out = Vec::new();
    if let Some(by) = cv_by {
        let groups: Vec<String> = series.iter().map(|s| by.group(&s.name)).collect();
        let mut distinct: Vec<String> = groups.clone();
        distinct.sort();
        distinct.dedup();
        if distinct.len() < 2 {
            notes.push(format!(
                "cross-validation by {} needs at least two groups, found {}",
                by.name(),
                distinct.len()
            ));
        }
        // Dead reckoning (squared loss): each fold is one Gauss-Newton step from the full
        // solution with the held-out recordings' rows taken out of the normal equations
        // (no refit: CV costs next to nothing). Otherwise a refit from the full solution.
        let gn = (!cfg.free_start && cfg.huber.is_none()).then(|| {
            let r = p.residuals(&fitted.geom, &fitted.nuis, false);
            let jac = &fitted.jac;
            let mut h = jac.transpose() * jac;
            let mut grad = jac.transpose() * nalgebra::DVector::from_column_slice(&r);
            for (w, target, sigma) in &p.priors {
                let v: f64 = w.iter().zip(&fitted.geom).map(|(a, b)| a * b).sum();
                let pr = (v - target) / sigma * p.prior_scale;
                for a in 0..g {
                    grad[a] += w[a] / sigma * p.prior_scale * pr;
                    for b in 0..g {
                        h[(a, b)] += w[a] * w[b] / (sigma * sigma) * p.prior_scale * p.prior_scale;
                    }
                }
            }
            let mut at = vec![0usize];
            for s in &series {
                at.push(at.last().copied().unwrap_or(0) + 3 * s.samples.len());
            }
            (h, grad, r, at)
        });
        let (blo, bhi) = if p.plausible_bounds {
            specs.iter().map(|s| s.plausible).unzip()
        } else {
            geom_bounds(&specs)
        };
        let t0 = std::time::Instant::now();
        // One-step folds: (recording, group, geometry without the group), replayed after.
        let mut stepped: Vec<(usize, &String, Vec<f64>)> = Vec::new();
        for (k, gname) in distinct.iter().enumerate().filter(|_| distinct.len() >= 2) {
            if let Some((h, grad, r, at)) = &gn {
                let (mut h, mut grad) = (h.clone(), grad.clone());
                for i in (0..series.len()).filter(|&j| &groups[j] == gname) {
                    let ji = fitted.jac.rows(at[i], at[i + 1] - at[i]);
                    h -= ji.transpose() * ji;
                    grad -=
                        ji.transpose() * nalgebra::DVector::from_column_slice(&r[at[i]..at[i + 1]]);
                }
                let step = h
                    .lu()
                    .solve(&(-grad))
                    .unwrap_or_else(|| nalgebra::DVector::zeros(g));
                let geom: Vec<f64> = (0..g)
                    .map(|a| (fitted.geom[a] + step[a]).clamp(blo[a], bhi[a]))
                    .collect();
                for i in (0..series.len()).filter(|&j| &groups[j] == gname) {
                    stepped.push((i, gname, geom.clone()));
                }
                continue;
            }
            if t0.elapsed().as_secs_f64() > 2.0 {
                eprintln!(
                    "calibrate: cross-validation {}/{} ({:.1} s)",
                    k + 1,
                    distinct.len(),
                    t0.elapsed().as_secs_f64()
                );
            }
            let keep: Vec<usize> = (0..series.len()).filter(|&j| &groups[j] != gname).collect();
            let rest: Vec<&Series> = keep.iter().map(|&j| &series[j]).collect();
            let mut q = Problem::new(robot, &specs, rest);
            cfg.apply(&mut q);
            q.priors = p.priors.clone();
            q.prior_scale = p.prior_scale;
            q.plausible_bounds = p.plausible_bounds;
            q.differences_at_solution = false;
            let nuis: Vec<f64> = if cfg.free_start {
                keep.iter()
                    .flat_map(|&j| fitted.nuis[j * NUIS..(j + 1) * NUIS].to_vec())
                    .collect()
            } else {
                vec![]
            };
            let f = solve(&q, &fitted.geom, &nuis, true);
            runs += f.evaluations;
            for i in (0..series.len()).filter(|&j| &groups[j] == gname) {
                leave_one_out.push(Heldout {
                    name: series[i].name.clone(),
                    group: Some(gname.clone()),
                    rmse_before_m: dead_reckoning_rmse(robot, &series[i]).unwrap_or(f64::NAN),
                    rmse_after_m: fitted_dead_reckoning_rmse(
                        robot,
                        &specs,
                        &f.geom,
                        cfg.law(),
                        &series[i],
                    ),
                    aligned_before_m: per_recording[i].aligned_before_m,
                    aligned_after_m: aligned_rmse(robot, &specs, &f.geom, &series[i]),
                });
            }
        }
        leave_one_out.extend(pool_map(&stepped, |(i, gname, geom)| {
            let s = &series[*i];
            Heldout {
                name: s.name.clone(),
                group: Some((*gname).clone()),
                rmse_before_m: per_recording[*i].dead_reckoning_before_m,
                rmse_after_m: fitted_dead_reckoning_rmse(robot, &specs, geom, cfg.law(), s),
                aligned_before_m: per_recording[*i].aligned_before_m,
                aligned_after_m: aligned_rmse(robot, &specs, geom, s),
            }
        }));
    }

    let params: Vec<FittedParam> = specs
        .iter()
        .enumerate()
        .map(|(i, s)| FittedParam {
            spec: s.clone(),
            value: fitted.geom[i],
            sigma: cov[(i, i)].max(0.0).sqrt(),
        })
        .collect();
    let mut implausible = implausible;
    for pr in &per_recording {
        let nu = pr.nuisance;
        if nu.time_offset_s.abs() > PLAUSIBLE_TIME_OFFSET_S {
            implausible.push(Implausible {
                name: format!("{}: time_offset_s", pr.name),
                value: nu.time_offset_s,
                plausible: (-PLAUSIBLE_TIME_OFFSET_S, PLAUSIBLE_TIME_OFFSET_S),
                stands_for:
                    "a t column that does not match the encoders (check the logger's clock)".into(),
            });
        }
        if (nu.clock_ratio - 1.0).abs() > PLAUSIBLE_CLOCK_DRIFT {
            implausible.push(Implausible {
                name: format!("{}: clock_ratio", pr.name),
                value: nu.clock_ratio,
                plausible: (1.0 - PLAUSIBLE_CLOCK_DRIFT, 1.0 + PLAUSIBLE_CLOCK_DRIFT),
                stands_for: "resampled or mis-stamped ground truth".into(),
            });
        }
    }

    let factors = if specs.iter().any(|s| s.kind == GeomKind::Ed) {
        let scale_or = |k: GeomKind, or: f64| {
            specs
                .iter()
                .position(|s| s.kind == k)
                .map_or(or, |i| fitted.geom[i])
        };
        let scale = |k: GeomKind| scale_or(k, 1.0);
        let (sc, ed, eb) = (
            scale(GeomKind::Scale),
            scale(GeomKind::Ed),
            scale(GeomKind::Eb),
        );
        // With a turn-radius law: E_b at the recordings' mean turn (as the robot file);
        // a differential drive's board applies the law itself, from a turn in place.
        let board_law = (robot.kind == RobotKind::DiffDrive && turn_law.arc_rel != 0.0)
            .then_some((eb, turn_law.arc_rel));
        let (c_l, c_r) = calib_core::umbmark::wheel_factors(ed);
        Factors::Diff {
            c_l: sc * c_l,
            c_r: sc * c_r,
            e_b: eb + law_eb_shift,
            e_b_turn_in_place: board_law.map(|l| l.0),
            e_b_arc: board_law.map(|l| l.1),
        }
    } else {
        if specs.iter().any(|s| {
            matches!(
                s.kind,
                GeomKind::Alpha(_) | GeomKind::L(_) | GeomKind::Gamma
            )
        }) {
            notes.push(
                "wheel angle, position and roller angle have no firmware factor: use --write-robot to carry them"
                    .into(),
            );
        }
        Factors::Wheels {
            f_lat: fitted_robot
                .wheels
                .iter()
                .zip(&robot.wheels)
                .map(|(f, n)| n.radius_m / f.radius_m)
                .collect(),
            f_lon: 1.0,
        }
    };

    let objective = if cfg.free_start {
        "aligned: start pose, time offset and clock ratio fitted per recording (--free-start)"
    } else {
        "dead reckoning from each recording's first measured pose, compared every 5 cm of travel (turns in place at the wheels' lever arm)"
    };
    let robust_loss = cfg.huber.map(|c| {
        format!(
            "Huber, quadratic within {:.2} mm ({HUBER_K} robust sigmas of the squared-loss residuals), linear beyond",
            c * RES_UNIT_M * 1e3
        )
    });
    Ok(Calibration {
        robot: robot.name.to_string(),
        kind: robot.kind.as_str(),
        objective,
        free_start: cfg.free_start,
        robust_loss,
        events,
        cv_by: cv_by.map(|c| c.name()),
        recordings: series.iter().map(|s| s.name.clone()).collect(),
        params,
        factors,
        joint_rmse_before_m: position_rmse(&before_res),
        joint_rmse_after_m: position_rmse(&after_res),
        per_recording,
        heldout,
        leave_one_out: HeldoutTable(leave_one_out),
        correlations: corr,
        inseparable: Inseparables(insep),
        unconstrained,
        implausible,
        notes,
        model_runs: runs,
        fitted_robot,
        turn_law,
        law_base_robot,
    })
}

/// sqrt(residual variance x autocorrelation inflation), in residual units.
fn noise_scale(p: &Problem, s: &Solved) -> f64 {
    let m = s.jac.nrows();
    let dof = m.saturating_sub(s.jac.ncols()).max(1) as f64;
    (s.data_cost / dof * autocorrelation_inflation(p, s)).sqrt()
}

/// Lag-1 autocorrelation of the residual series (per component): an AR(1) series' mean
/// has (1 + rho) / (1 - rho) times the variance of independent samples.
fn autocorrelation_inflation(p: &Problem, s: &Solved) -> f64 {
    let m = s.jac.nrows();
    let r = p.residuals(&s.geom, &s.nuis, false);
    let comps: Vec<Vec<f64>> = (0..3)
        .map(|c| r.iter().skip(c).step_by(3).copied().collect())
        .collect();
    let rho = crate::residuals::lag1_autocorrelation(comps.iter().map(|v| v.as_slice()), 0.999);
    crate::residuals::ar1_inflation(rho)
        .min(m as f64 / 10.0)
        .max(1.0)
}

/// Covariance of [geometry, nuisance] from what the data tell (the plausibility prior
/// enters only as a ridge 1000 ranges wide, so a direction the data do not constrain
/// shows as one), scaled by the residual variance and the autocorrelation inflation
/// (returned).
fn covariance(p: &Problem, s: &Solved) -> (DMatrix<f64>, f64) {
    let m = s.jac.nrows();
    let np = s.jac.ncols();
    let g = p.specs.len();
    let mut info = s.jac.transpose() * &s.jac;
    let dof = m.saturating_sub(np).max(1) as f64;
    let s2 = (s.data_cost / dof).max(1e-12);
    let inflation = autocorrelation_inflation(p, s);
    for (w, _, sigma) in &p.priors {
        for a in 0..g {
            for b in 0..g {
                info[(a, b)] += w[a] * w[b] / (sigma * sigma) * 1e-6 * s2 * inflation;
            }
        }
    }
    let cov = info
        .clone()
        .try_inverse()
        .unwrap_or_else(|| DMatrix::from_element(np, np, f64::INFINITY));
    (cov * (s2 * inflation), inflation)
}

fn correlations(cov: &DMatrix<f64>, g: usize) -> Vec<Vec<f64>> {
    (0..g)
        .map(|a| {
            (0..g)
                .map(|b| {
                    let d = (cov[(a, a)] * cov[(b, b)]).sqrt();
                    if a == b {
                        1.0
                    } else if d > 0.0 && d.is_finite() {
                        (cov[(a, b)] / d).clamp(-1.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

impl Calibration {
    /// The fitted robot file text (all geometry), with a header naming the recordings.
    pub fn robot_toml(&self) -> String {
        format!(
            "# {} with geometry fitted by wheelcal calibrate from {}\n{}",
            self.robot,
            self.recordings.join(", "),
            formats::robot_file::to_toml(&self.fitted_robot)
        )
    }
}

fn mm(v: f64) -> String {
    format!("{:.2} mm", v * 1e3)
}

impl fmt::Display for Calibration {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "calibrate {}: {} recording(s), geometry shared",
            self.robot,
            self.recordings.len()
        )?;
        writeln!(f, "minimised: {}", self.objective)?;
        if let Some(l) = &self.robust_loss {
            writeln!(f, "loss: {l}")?;
        }
        writeln!(f, "geometry:")?;
        for p in &self.params {
            let flag = if self.implausible.iter().any(|i| i.name == p.spec.name) {
                "  (unbounded: implausible, see below)"
            } else {
                ""
            };
            writeln!(
                f,
                "  {:<24} {:.5} ± {:.5}  (nominal {}, plausible {:.4}..{:.4}){flag}",
                p.spec.name,
                p.value,
                p.sigma,
                p.spec.nominal,
                p.spec.plausible.0,
                p.spec.plausible.1
            )?;
        }
        for w in &self.geometry() {
            write!(
                f,
                "  wheel {:<8} radius {:.5} m, l {:.5} m, alpha {:.3} deg",
                w.name, w.radius_m, w.l_m, w.alpha_deg
            )?;
            if w.gamma_deg.abs() > MECANUM_MIN_GAMMA.to_degrees() {
                write!(f, ", gamma {:.3} deg", w.gamma_deg)?;
            }
            writeln!(f)?;
        }
        match &self.factors {
            Factors::Diff {
                c_l,
                c_r,
                e_b_turn_in_place: Some(e_b),
                e_b_arc: Some(arc),
                ..
            } => writeln!(
                f,
                "firmware factors: factors set --c-l {c_l:.6} --c-r {c_r:.6} --e-b {e_b:.6} --e-b-arc {arc:.6} (the board applies the turn law; ROS 2 and the robot file get E_b {:.6} at the recordings' mean turn)",
                self.factors_e_b()
            )?,
            Factors::Diff { c_l, c_r, e_b, .. } => writeln!(
                f,
                "firmware factors: factors set --c-l {c_l:.6} --c-r {c_r:.6} --e-b {e_b:.6}"
            )?,
            Factors::Wheels { f_lat, f_lon } => writeln!(
                f,
                "firmware factors: f_lat {} f_lon {f_lon:.6}",
                f_lat
                    .iter()
                    .map(|v| format!("{v:.6}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            )?,
        }
        writeln!(
            f,
            "fit RMSE (what was minimised): joint {} -> {}",
            mm(self.joint_rmse_before_m),
            mm(self.joint_rmse_after_m)
        )?;
        writeln!(f, "per recording, nominal -> fitted: minimised; dead reckoning from the first pose (every pose sample); aligned (start pose and clocks fitted)")?;
        for r in &self.per_recording {
            write!(
                f,
                "  {:<24} {} -> {}   dead reckoning {} -> {}   aligned {} -> {}",
                r.name,
                mm(r.rmse_before_m),
                mm(r.rmse_after_m),
                mm(r.dead_reckoning_before_m),
                mm(r.dead_reckoning_after_m),
                mm(r.aligned_before_m),
                mm(r.aligned_after_m),
            )?;
            if r.nuisance.time_offset_s != 0.0 || r.nuisance.clock_ratio != 1.0 {
                write!(
                    f,
                    "   time_offset {:+.3} s, clock_ratio {:.4}",
                    r.nuisance.time_offset_s, r.nuisance.clock_ratio
                )?;
            }
            writeln!(f)?;
            if r.rmse_after_m > r.rmse_before_m {
                writeln!(
                    f,
                    "    worse than nominal with the shared geometry (its errors cancelled with the nominal one, or it disagrees with the others)"
                )?;
            }
        }
        for e in &self.events {
            writeln!(
                f,
                "event {} {}: at {:.2} s for {:.2} s, heading {:+.3} rad (odometry minus motion capture){}; {}",
                e.recording,
                e.kind,
                e.t_s,
                e.duration_s,
                e.heading_rad,
                if e.position_m != 0.0 {
                    format!(", size {:.4} m", e.position_m)
                } else {
                    String::new()
                },
                e.handled
            )?;
        }
        if let Some(h) = &self.heldout {
            writeln!(
                f,
                "held out {}: {} -> {} (dead reckoning, nominal -> fitted); {} -> {} with its start pose and clocks fitted",
                h.name,
                mm(h.rmse_before_m),
                mm(h.rmse_after_m),
                mm(h.aligned_before_m),
                mm(h.aligned_after_m)
            )?;
        }
        if !self.leave_one_out.0.is_empty() {
            writeln!(f, "cross-validation by {} (fit on the rest; the held-out recordings dead-reckoned from their first pose, nominal -> fitted, and aligned: start pose and clocks fitted):", self.cv_by.unwrap_or("run"))?;
            for h in &self.leave_one_out.0 {
                writeln!(
                    f,
                    "  {:<24} {} -> {}   aligned {} -> {}",
                    h.name,
                    mm(h.rmse_before_m),
                    mm(h.rmse_after_m),
                    mm(h.aligned_before_m),
                    mm(h.aligned_after_m)
                )?;
            }
            if let Some(m) = self.leave_one_out.means() {
                writeln!(
                    f,
                    "  mean                     {} -> {}   aligned {} -> {}",
                    mm(m.before_m),
                    mm(m.after_m),
                    mm(m.aligned_before_m),
                    mm(m.aligned_after_m)
                )?;
            }
        }
        if self.inseparable.0.is_empty() {
            writeln!(
                f,
                "identifiability: every parameter is separable from these recordings"
            )?;
        }
        // Many pairs (a 4-wheel per-wheel model) would bury the summary: the strongest
        // few in words, the rest named; the JSON keeps every one.
        const SHOWN: usize = 6;
        let mut order: Vec<&Inseparable> = self.inseparable.0.iter().collect();
        order.sort_by(|a, b| b.correlation.abs().total_cmp(&a.correlation.abs()));
        for i in order.iter().take(SHOWN) {
            writeln!(
                f,
                "not separable: {} and {} (correlation {:+.3}); the data fix only {:.3}*{} {:+.3}*{}, the rest rests on the plausibility prior; to separate them: {}",
                i.params[0], i.params[1], i.correlation, i.identifiable[0], i.params[0], i.identifiable[1], i.params[1], i.advice
            )?;
        }
        if order.len() > SHOWN {
            writeln!(
                f,
                "not separable, {} more pairs (all in --json): {}",
                order.len() - SHOWN,
                order[SHOWN..]
                    .iter()
                    .map(|i| format!("{}/{}", i.params[0], i.params[1]))
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
        for d in &self.unconstrained {
            writeln!(
                f,
                "unconstrained direction: {}",
                d.iter()
                    .map(|(n, v)| format!("{v:+.2} {n}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            )?;
        }
        for i in &self.implausible {
            writeln!(
                f,
                "implausible: {} = {:.5} outside {:.4}..{:.4}; most likely stands in for {}",
                i.name, i.value, i.plausible.0, i.plausible.1, i.stands_for
            )?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}
