//! The geometry parameters calibration can fit, as data about the robot: what each one is
//! ([`GeomKind`], [`ParamSpec`]: name, nominal value, plausible range, what a value outside
//! it most likely stands in for), which ones a robot gets (the full model, a mecanum
//! robot's roller model, the turn law, the rungs of an omni robot's [`ladder`]), how a
//! set of values changes the robot ([`robot_with`]), and which motion separates two of
//! them ([`advice`]). Every other part of calibrate builds on this one.

use calib_core::robot::{Robot, RobotKind};
use formats::catalogue as cat;
use serde::Serialize;

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
    /// |d_r - d_l| / (|d_r| + |d_l|) (1 in place, 0 straight). A differential drive's
    /// tyre scrub likewise, in the share 1 - rho^2. An omni robot's (`l_arc`): its
    /// wheels' distance from the centre grows by l_arc (1 - rho^2) from a turn in place
    /// to an arc, rho = |omega| L / |v| of its twist.
    EbArc,
    /// Skid-steer: longitudinal position of the ICRs ([Mandow et al.]'s x_ICR), m; the
    /// body's sideways speed is -x_ICR omega.
    IcrX,
    /// Differential drive: growth of each side's effective wheel size per m/s of its
    /// rolling speed (a side rolling at v travels (1 + speed_rel |v|) times what its
    /// radius says; the speed from the counts at nominal radii, smoothed as rho is).
    SpeedRel,
    /// Differential drive: the ground's lag behind each side's speed, s (slip in
    /// proportion to acceleration: each side's travel less accel_slip_s times its change
    /// of speed).
    AccelSlip,
    /// Omni: where the wheels' centre is, body frame x, m: every wheel moved by it, its
    /// rolling direction kept (the odometry's origin, the point motion capture tracks,
    /// is not the centre the wheels were laid out about).
    CentreX,
    /// Omni: the wheels' centre, body frame y, m (see `CentreX`).
    CentreY,
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
    /// A per-wheel parameter of a symmetric robot: held to the mean of the same parameter
    /// of the other wheels with this sigma ([`alike_priors`]); `None`: free.
    #[serde(skip)]
    pub alike: Option<f64>,
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
        alike: None,
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
/// An omni wheel's radius (90-degree rollers): its contact moves across the rollers,
/// under their outer envelope, which the published diameter is. The real omni3's wheels
/// measure 0.940-0.982 of theirs (the OptiOdom authors' fits on squares and circles).
pub const OMNI_RADIUS_RANGE: f64 = 0.10;
/// The plausible half-range of a wheel's radius scale on `robot`: a mecanum wheel's
/// ([`MECANUM_RADIUS_RANGE`]), an omni wheel's ([`OMNI_RADIUS_RANGE`]), else a tyre's
/// ([`RADIUS_RANGE`]).
pub fn radius_range(robot: &Robot) -> f64 {
    if is_mecanum(robot) {
        MECANUM_RADIUS_RANGE
    } else if robot.kind == RobotKind::Omni {
        OMNI_RADIUS_RANGE
    } else {
        RADIUS_RANGE
    }
}
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
/// The wheels' centre from the odometry's origin, m.
pub const CENTRE_RANGE: f64 = 0.05;
const CENTRE_STANDS: &str =
    "the wheels laid out about another point than the one motion capture tracks";
/// Motion-capture marker offset from the kinematic centre, m.
pub const MARKER_RANGE: f64 = 0.02;
const MARKER_STANDS: &str =
    "a marker set far from the kinematic centre, or wheel slip in turns in place";
const L_STANDS: &str = "scrub in rotation or a radius error the motion does not separate";
const GAMMA_STANDS: &str =
    "rollers slipping along their axles, or wheels mounted at other angles (per-wheel alpha, l and radius)";

/// A value within this share of its plausible range from an edge sits on the edge: the
/// ladders do not keep a model that puts a parameter there (the model or the range is
/// wrong; issue 21's check counts the same 1 %).
pub const EDGE_SHARE: f64 = 0.01;

impl ParamSpec {
    /// Whether `v` is past this parameter's plausible range or within [`EDGE_SHARE`] of
    /// the range from one of its edges.
    pub fn on_edge_or_past(&self, v: f64) -> bool {
        let (lo, hi) = self.plausible;
        let margin = EDGE_SHARE * (hi - lo);
        !(v > lo + margin && v < hi - margin)
    }
}

/// The wheels of a symmetric robot are alike: in the ladder's per-wheel rungs each
/// wheel's radius and distance scale is held to the wheels' mean with this sigma (one
/// batch of wheels, one machined frame), so "within 3 % of each other" is three sigmas.
/// Real squares (forward legs and turns in place) fix a few combinations of a mecanum
/// robot's twelve per-wheel parameters; held only by their plausible ranges, the others
/// went to the ranges' edges (a radius at +15 %, a distance at +8 %).
pub const ALIKE_SCALE: f64 = 0.01;
/// A wheel's mounting angle offset is held to the wheels' mean with this sigma, rad
/// (1 degree: see [`ALIKE_SCALE`]).
pub const ALIKE_ANGLE: f64 = std::f64::consts::PI / 180.0;

/// The prior rows that hold alike wheels alike: for each family (radius, angle, distance)
/// with two or more members whose [`ParamSpec::alike`] is set, one row per member, its
/// value less the family's mean, target 0, sigma `alike` (weights over `specs`).
pub fn alike_priors(specs: &[ParamSpec]) -> Vec<(Vec<f64>, f64, f64)> {
    let family = |k: GeomKind| match k {
        GeomKind::Radius(_) => Some(0),
        GeomKind::Alpha(_) => Some(1),
        GeomKind::L(_) => Some(2),
        _ => None,
    };
    let mut rows = Vec::new();
    for f in 0..3 {
        let members: Vec<(usize, f64)> = specs
            .iter()
            .enumerate()
            .filter(|(_, s)| family(s.kind) == Some(f))
            .filter_map(|(i, s)| s.alike.map(|sigma| (i, sigma)))
            .collect();
        if members.len() < 2 {
            continue;
        }
        let share = 1.0 / members.len() as f64;
        for &(i, sigma) in &members {
            let mut w = vec![0.0; specs.len()];
            for &(j, _) in &members {
                w[j] = -share;
            }
            w[i] += 1.0;
            rows.push((w, 0.0, sigma));
        }
    }
    rows
}

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
    v.insert(at, roller_angle_spec());
    v
}

/// The roller angle offset shared by every mecanum wheel.
fn roller_angle_spec() -> ParamSpec {
    spec(
        GeomKind::Gamma,
        "roller_angle_offset_rad".into(),
        "roller_angle_error",
        0.0,
        GAMMA_RANGE,
        GAMMA_STANDS,
    )
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
        cat::WHEELBASE_ERROR,
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
        cat::WHEELBASE_ERROR,
        0.0,
        ICR_X_RANGE,
        ICR_X_STANDS,
    ));
    v
}

/// An omni robot's turn law ([`GeomKind::EbArc`], `l_arc`): its wheels' effective
/// distance from the centre longer on arcs than in a turn in place, by l_arc (1 - rho^2)
/// at turn ratio rho ([`calib_core::kinematics::turn_ratio`]), within ±[`DIFF_EB_ARC_RANGE`]
/// (the board's bound on any turn law). Fitted on top of a rung of the model ladder.
pub fn omni_turn_law_spec() -> ParamSpec {
    spec(
        GeomKind::EbArc,
        "l_arc".into(),
        cat::WHEELBASE_ERROR,
        0.0,
        DIFF_EB_ARC_RANGE,
        OMNI_L_ARC_STANDS,
    )
}

const OMNI_L_ARC_STANDS: &str =
    "wheels whose contact moves across their rollers with the turn, or slip the arcs do not share with a turn in place";

/// The speed model of a differential drive: [`param_specs`] plus the wheels' growth
/// with speed ([`GeomKind::SpeedRel`]).
pub fn speed_law_specs(robot: &Robot) -> Vec<ParamSpec> {
    let mut v = param_specs(robot, false);
    v.push(spec(
        GeomKind::SpeedRel,
        "speed_rel".into(),
        cat::WHEEL_SCALE,
        0.0,
        SPEED_REL_RANGE,
        SPEED_REL_STANDS,
    ));
    v
}

/// The acceleration model of a differential drive: [`param_specs`] plus the ground's
/// lag behind the wheels' speed ([`GeomKind::AccelSlip`]).
pub fn accel_law_specs(robot: &Robot) -> Vec<ParamSpec> {
    let mut v = param_specs(robot, false);
    v.push(spec(
        GeomKind::AccelSlip,
        "accel_slip_s".into(),
        cat::LONGITUDINAL_SLIP,
        0.0,
        ACCEL_SLIP_RANGE,
        ACCEL_SLIP_STANDS,
    ));
    v
}

/// The ground may lag a differential drive's wheels by this much (s): 0.2 s of slip
/// per change of speed is a wheel spinning on ice. The board's own limit, so a kept law
/// is one it takes.
pub const ACCEL_SLIP_RANGE: f64 = calib_core::correction::ACCEL_SLIP_MAX_S;
const ACCEL_SLIP_STANDS: &str =
    "a clock offset between the encoders and the poses rather than slip";

/// A differential drive's wheels may roll this much further (or shorter) per m/s of
/// their speed: 6 % at 0.3 m/s, more than tyre deflection or slip give a small robot.
/// The board's own limit, so a kept law is one it takes.
pub const SPEED_REL_RANGE: f64 = calib_core::correction::SPEED_REL_MAX;
const SPEED_REL_STANDS: &str =
    "slip that depends on acceleration or load rather than speed, or encoder counts lost at speed";

fn param_specs_left_right() -> Vec<ParamSpec> {
    vec![
        spec(
            GeomKind::Scale,
            "scale".into(),
            cat::WHEEL_SCALE,
            1.0,
            RADIUS_RANGE,
            SCALE_STANDS,
        ),
        spec(
            GeomKind::Ed,
            "ed".into(),
            cat::WHEEL_DIAMETER_MISMATCH,
            1.0,
            ED_RANGE,
            ED_STANDS,
        ),
        spec(
            GeomKind::Eb,
            "eb".into(),
            cat::WHEELBASE_ERROR,
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
            cat::WHEEL_DIAMETER_MISMATCH,
            1.0,
            if robot.kind == RobotKind::Omni && !is_mecanum(robot) {
                OMNI_RADIUS_RANGE
            } else {
                RADIUS_RANGE
            },
            SCALE_STANDS,
        ));
    }
    if robot.kind == RobotKind::Omni {
        for (i, w) in robot.wheels.iter().enumerate() {
            v.push(spec(
                GeomKind::Alpha(i),
                format!("alpha_offset_rad_{}", w.name),
                cat::WHEEL_ANGLE_ERROR,
                0.0,
                ALPHA_RANGE,
                ALPHA_STANDS,
            ));
        }
        for (i, w) in robot.wheels.iter().enumerate() {
            v.push(spec(
                GeomKind::L(i),
                format!("l_scale_{}", w.name),
                cat::WHEEL_POSITION_ERROR,
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
            cat::WHEELBASE_ERROR,
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
    let mut centre = (0.0, 0.0);
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
            GeomKind::CentreX => centre.0 = x,
            GeomKind::CentreY => centre.1 = x,
            GeomKind::MarkerX
            | GeomKind::MarkerY
            | GeomKind::EbArc
            | GeomKind::IcrX
            | GeomKind::SpeedRel
            | GeomKind::AccelSlip => {}
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
        if centre != (0.0, 0.0) {
            // Moved with its rolling direction (alpha + beta) kept.
            let (x, y) = w.position();
            let (x, y) = (x + centre.0, y + centre.1);
            let alpha = y.atan2(x);
            w.beta_rad += w.alpha_rad - alpha;
            w.alpha_rad = alpha;
            w.l_m = x.hypot(y);
        }
    }
    r
}

pub(super) fn advice(a: &ParamSpec, b: &ParamSpec) -> String {
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
    } else if matches!(a.kind, CentreX | CentreY) || matches!(b.kind, CentreX | CentreY) {
        "add turns in place and translations while turning: the wheels' centre moves only motion that turns".into()
    } else if matches!(a.kind, Alpha(_)) || matches!(b.kind, Alpha(_)) {
        "add pure translations in several directions without rotation, and a turn in place".into()
    } else {
        "add motion that moves them differently: straight runs both ways and turns in place both ways".into()
    }
}

/// A mecanum wheel's effective radius: the rollers' contact moves with the direction of
/// travel, and real mecanum robots dead-reckon with radii 5-16 % off the hub's (the
/// real mecanum squares want 67 mm on a 60 mm wheel; whole sessions fit up to 1.161).
pub const MECANUM_RADIUS_RANGE: f64 = 0.20;
/// A mecanum wheel's effective radius fitted on one recording (the BIC ladder, and
/// `--free-start`'s models there): the narrower range of before. One square cannot tell
/// the rollers' effective radius from the wheel distance and the roller angle (a 0.999
/// correlation), and the range's edge is what holds them: trained on one square per
/// session, the real mecanum robot dead-reckons the other sessions' squares at 1.269 of
/// the authors with this range and 1.658 with [`MECANUM_RADIUS_RANGE`].
pub const MECANUM_RADIUS_RANGE_ONE_RECORDING: f64 = 0.15;

/// `specs` with a mecanum robot's wheel sizes given [`MECANUM_RADIUS_RANGE`] (the
/// ladder's models); unchanged on other robots. [`param_specs`] keeps a tyre's range for
/// them: the first fit that finds events uses it (with the mecanum range there, the real
/// mecanum proxy went from 0.934 to 0.947 of the authors, and one square from 1.269 to
/// 1.326, at ±15 %).
pub(crate) fn with_wheel_radius_range(robot: &Robot, specs: Vec<ParamSpec>) -> Vec<ParamSpec> {
    with_mecanum_radius_range(robot, specs, MECANUM_RADIUS_RANGE)
}

/// `specs` with a mecanum robot's wheel sizes given
/// [`MECANUM_RADIUS_RANGE_ONE_RECORDING`]: the models fitted on one recording.
pub(crate) fn with_one_recording_radius_range(
    robot: &Robot,
    specs: Vec<ParamSpec>,
) -> Vec<ParamSpec> {
    with_mecanum_radius_range(robot, specs, MECANUM_RADIUS_RANGE_ONE_RECORDING)
}

/// `specs` with a mecanum robot's wheel sizes (the common scale and the per-wheel radii)
/// plausible within ±`r`; unchanged on other robots.
fn with_mecanum_radius_range(robot: &Robot, mut specs: Vec<ParamSpec>, r: f64) -> Vec<ParamSpec> {
    if is_mecanum(robot) {
        for s in specs.iter_mut() {
            if matches!(s.kind, GeomKind::Radius(_) | GeomKind::Scale) {
                s.plausible = (1.0 - r, 1.0 + r);
            }
        }
    }
    specs
}

/// The models an omni robot's calibration climbs, by parameter count: one common scale;
/// a common scale and wheel distance; on a mecanum robot a common scale, wheel distance
/// and roller angle; per-wheel radii and a common distance; on a mecanum robot per-wheel
/// radii and one roller angle, then per-wheel radii, a common distance and one roller
/// angle, on another omni robot per-wheel radii, a common distance and the wheels'
/// centre; per-wheel radii, angles and distances.
pub fn ladder(robot: &Robot, marker: bool) -> Vec<(&'static str, Vec<ParamSpec>)> {
    let mecanum = is_mecanum(robot);
    let mut scale = spec(
        GeomKind::Scale,
        "scale".into(),
        cat::WHEEL_SCALE,
        1.0,
        radius_range(robot),
        SCALE_STANDS,
    );
    if mecanum {
        scale.stands_for = "the rollers' effective radius, or a wrong nominal diameter";
    }
    let distance = spec(
        GeomKind::Eb,
        "l_scale".into(),
        cat::WHEELBASE_ERROR,
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
    let full = with_wheel_radius_range(robot, full);
    let radii: Vec<ParamSpec> = full
        .iter()
        .filter(|s| matches!(s.kind, GeomKind::Radius(_)))
        .cloned()
        .collect();
    let with_markers = |mut v: Vec<ParamSpec>| {
        v.extend(markers.iter().cloned());
        v
    };
    let mut rungs = vec![
        ("common scale", with_markers(vec![scale.clone()])),
        (
            "common scale and wheel distance",
            with_markers(vec![scale.clone(), distance.clone()]),
        ),
        ("per-wheel radii and a common wheel distance", {
            let mut v = radii.clone();
            v.push(distance.clone());
            with_markers(v)
        }),
        ("per-wheel radii, angles and distances", full.clone()),
    ];
    if mecanum {
        // In the body frame: longitudinal, lateral and turning scales (the Jacobian's
        // F_lon, F_lat and the distance), as rollers that grip sideways otherwise than
        // along make them. A common roller angle moves the lateral gain against the
        // longitudinal one; the distance restores the turn.
        rungs.push((
            "common scale, wheel distance and roller angle",
            with_markers(vec![scale.clone(), distance.clone(), roller_angle_spec()]),
        ));
        rungs.push((
            "per-wheel radii and one roller angle",
            with_wheel_radius_range(robot, roller_specs(robot, marker)),
        ));
        // The three body-frame scales with the wheels' own sizes: without the distance,
        // the roller angle must also carry the turn (on the real September squares this
        // rung holds out at 26.0 and 26.4 mm against 29.9 and 29.3 mm for the next best).
        rungs.push((
            "per-wheel radii, a common wheel distance and one roller angle",
            {
                let mut v = radii.clone();
                v.push(distance.clone());
                v.push(roller_angle_spec());
                with_markers(v)
            },
        ));
    } else {
        // On the mecanum robot the centre does not hold out across sessions (trained on
        // one square session, tested on the other three's squares: 1.002 of the authors
        // where the per-wheel model gives 0.937).
        rungs.push((
            "per-wheel radii, a common wheel distance and the wheels' centre",
            {
                let mut v = radii.clone();
                v.push(distance.clone());
                v.push(spec(
                    GeomKind::CentreX,
                    "centre_x_m".into(),
                    cat::WHEELBASE_ERROR,
                    0.0,
                    CENTRE_RANGE,
                    CENTRE_STANDS,
                ));
                v.push(spec(
                    GeomKind::CentreY,
                    "centre_y_m".into(),
                    cat::WHEELBASE_ERROR,
                    0.0,
                    CENTRE_RANGE,
                    CENTRE_STANDS,
                ));
                with_markers(v)
            },
        ));
    }
    // Per-wheel parameters of the nominally alike wheels stay alike unless the data say
    // otherwise (ALIKE_SCALE).
    for (_, specs) in rungs.iter_mut() {
        for s in specs.iter_mut() {
            s.alike = match s.kind {
                GeomKind::Radius(_) | GeomKind::L(_) => Some(ALIKE_SCALE),
                GeomKind::Alpha(_) => Some(ALIKE_ANGLE),
                _ => None,
            };
        }
    }
    rungs.sort_by_key(|r| r.1.len());
    rungs
}

/// A differential drive's separation may depend on the turn by this much (tyre scrub):
/// the board's own limit.
pub const DIFF_EB_ARC_RANGE: f64 = calib_core::correction::E_B_ARC_MAX;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;

    /// Relative difference.
    fn rel(a: f64, b: f64) -> f64 {
        (a / b - 1.0).abs()
    }

    /// A differential drive's (scale, E_d, E_b) are Borenstein's: the right wheel's
    /// radius over the left's is E_d, their mean is scale x nominal (c_L + c_R = 2), the
    /// separation is E_b x nominal. A few roundings of numbers near 1: 1e-12.
    #[test]
    fn robot_with_applies_scale_ed_and_eb_as_borenstein_defines_them() {
        let base = synth::robot("mobolab");
        let specs = param_specs(&base, false);
        let names: Vec<&str> = specs.iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["scale", "ed", "eb"]);
        let r = robot_with(&base, &specs, &[1.02, 1.01, 1.05]);
        let (l, rt) = if r.wheels[0].is_left() {
            (&r.wheels[0], &r.wheels[1])
        } else {
            (&r.wheels[1], &r.wheels[0])
        };
        assert!(rel(rt.radius_m / l.radius_m, 1.01) < 1e-12);
        assert!(rel(0.5 * (l.radius_m + rt.radius_m), 1.02 * 0.05) < 1e-12);
        let separation = l.position().1 - rt.position().1;
        assert!(rel(separation, 1.05 * 0.40) < 1e-12, "{separation}");
        for (a, b) in r.wheels.iter().zip(&base.wheels) {
            assert_eq!((a.alpha_rad, a.gamma_rad), (b.alpha_rad, b.gamma_rad));
        }
        // The nominal values give the robot back, to the bit.
        let nominal: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
        assert_eq!(robot_with(&base, &specs, &nominal), base);
    }

    /// The ladder's per-wheel rungs hold alike wheels alike: one prior row per radius,
    /// angle and distance of the full omni4 rung, each the wheel's value less its
    /// family's mean (weights summing to zero within 1e-15), sigma 1 % or 1 degree; a
    /// common scale or one distance gets none, and neither does the full model outside
    /// the ladder (diagnose's recording stage).
    #[test]
    fn alike_wheels_are_held_to_their_family_mean() {
        let base = synth::robot("omni4");
        assert!(alike_priors(&param_specs(&base, false)).is_empty());
        let rungs = ladder(&base, false);
        let (_, full) = rungs
            .iter()
            .find(|(n, _)| *n == "per-wheel radii, angles and distances")
            .unwrap();
        let rows = alike_priors(full);
        assert_eq!(rows.len(), 12);
        let mut v: Vec<f64> = full.iter().map(|s| s.nominal).collect();
        let radii = [1.10, 1.11, 1.12, 1.15];
        for (w, r) in radii.iter().enumerate() {
            let i = full
                .iter()
                .position(|s| s.kind == GeomKind::Radius(w))
                .unwrap();
            v[i] = *r;
        }
        let mean = radii.iter().sum::<f64>() / 4.0;
        for (w, target, sigma) in &rows {
            assert!(w.iter().sum::<f64>().abs() < 1e-15);
            assert_eq!(*target, 0.0);
            let own = w.iter().position(|x| *x > 0.0).unwrap();
            let value: f64 = w.iter().zip(&v).map(|(a, b)| a * b).sum();
            match full[own].kind {
                GeomKind::Radius(k) => {
                    assert!((value - (radii[k] - mean)).abs() < 1e-12);
                    assert_eq!(*sigma, ALIKE_SCALE);
                }
                GeomKind::L(_) => {
                    assert!(value.abs() < 1e-12);
                    assert_eq!(*sigma, ALIKE_SCALE);
                }
                GeomKind::Alpha(_) => assert_eq!(*sigma, ALIKE_ANGLE),
                k => panic!("a row for {k:?}"),
            }
        }
        for (name, specs) in &rungs {
            let n = alike_priors(specs).len();
            if name.starts_with("common scale") {
                assert_eq!(n, 0, "{name}");
            }
        }
    }

    /// Wheel sizes a mecanum robot's ladder may fit: ±20 % on several recordings, ±15 %
    /// on one (the common scale and the per-wheel radii alike); other parameters and a
    /// plain omni robot's ±10 % are left as they were. Exact: the ranges are set, not
    /// computed.
    #[test]
    fn a_mecanum_wheel_size_has_the_range_of_the_recordings_given() {
        let plain = synth::robot("omni4");
        let mut mecanum = plain.clone();
        for (i, w) in mecanum.wheels.iter_mut().enumerate() {
            w.gamma_rad = if i % 2 == 0 { 0.25 } else { -0.25 } * std::f64::consts::PI;
        }
        assert!(is_mecanum(&mecanum) && !is_mecanum(&plain));
        let size = |s: &ParamSpec| matches!(s.kind, GeomKind::Radius(_) | GeomKind::Scale);
        for (robot, several, one) in [
            (&mecanum, (0.8, 1.2), (0.85, 1.15)),
            (&plain, (0.9, 1.1), (0.9, 1.1)),
        ] {
            for (name, specs) in ladder(robot, false) {
                let narrowed = with_one_recording_radius_range(robot, specs.clone());
                for (s, n) in specs.iter().zip(&narrowed) {
                    if size(s) {
                        let r = (s.plausible.0, s.plausible.1);
                        assert!(
                            rel(r.0, several.0) < 1e-12 && rel(r.1, several.1) < 1e-12,
                            "{name}: {} {r:?}",
                            s.name
                        );
                        let r = (n.plausible.0, n.plausible.1);
                        assert!(
                            rel(r.0, one.0) < 1e-12 && rel(r.1, one.1) < 1e-12,
                            "{name}: {} {r:?}",
                            s.name
                        );
                    } else {
                        assert_eq!(s.plausible, n.plausible, "{name}: {}", s.name);
                    }
                }
            }
        }
    }

    /// A per-wheel parameter moves its own wheel only; the roller angle offset widens
    /// every mecanum wheel's |gamma| by its value, the sign (roller hand) kept, and leaves
    /// a wheel without angled rollers alone. Exact but for one multiplication or addition
    /// each: 1e-15 relative.
    #[test]
    fn robot_with_moves_only_the_named_wheel_and_widens_mecanum_rollers() {
        let base = synth::robot("omni4");
        let specs = param_specs(&base, false);
        let at = |k: GeomKind| specs.iter().position(|s| s.kind == k).unwrap();
        let mut v: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
        v[at(GeomKind::Radius(1))] = 1.03;
        v[at(GeomKind::Alpha(2))] = 0.01;
        v[at(GeomKind::L(3))] = 0.95;
        let r = robot_with(&base, &specs, &v);
        for (i, (a, b)) in r.wheels.iter().zip(&base.wheels).enumerate() {
            let want = (
                b.radius_m * if i == 1 { 1.03 } else { 1.0 },
                b.alpha_rad + if i == 2 { 0.01 } else { 0.0 },
                b.l_m * if i == 3 { 0.95 } else { 1.0 },
            );
            assert!(rel(a.radius_m, want.0) < 1e-15, "wheel {i} radius");
            assert!((a.alpha_rad - want.1).abs() < 1e-15, "wheel {i} alpha");
            assert!(rel(a.l_m, want.2) < 1e-15, "wheel {i} l");
        }

        let mut mecanum = base.clone();
        let g45 = std::f64::consts::FRAC_PI_4;
        for (i, w) in mecanum.wheels.iter_mut().enumerate() {
            // Alternating hands, and wheel 3 a plain omni wheel (0.5 deg: not mecanum).
            w.gamma_rad = match i {
                3 => 0.5f64.to_radians(),
                _ if i % 2 == 0 => g45,
                _ => -g45,
            };
        }
        assert!(is_mecanum(&mecanum));
        let specs = roller_specs(&mecanum, false);
        let mut v: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
        v[specs
            .iter()
            .position(|s| s.kind == GeomKind::Gamma)
            .unwrap()] = 0.02;
        let r = robot_with(&mecanum, &specs, &v);
        for (i, (a, b)) in r.wheels.iter().zip(&mecanum.wheels).enumerate() {
            let want = if i == 3 {
                b.gamma_rad
            } else {
                b.gamma_rad + b.gamma_rad.signum() * 0.02
            };
            assert!(rel(a.gamma_rad, want) < 1e-15, "wheel {i} gamma");
            assert_eq!(a.radius_m, b.radius_m);
        }
    }

    /// The wheels' centre moved by d: each wheel's position moves by d and its rolling
    /// direction stays, so under a body twist (v, omega) at the origin every wheel rolls as
    /// the nominal wheel does under (v + omega x d, omega), the twist carried to the
    /// wheels' centre (rigid-body transport). Trigonometry of numbers near 1: 1e-12.
    #[test]
    fn the_wheels_centre_moves_every_wheel_and_keeps_its_rolling_direction() {
        let base = synth::robot("omni3");
        let specs: Vec<ParamSpec> = ladder(&base, false)
            .into_iter()
            .find(|(_, v)| v.iter().any(|s| s.kind == GeomKind::CentreX))
            .unwrap()
            .1;
        let (dx, dy) = (0.03, -0.02);
        let v: Vec<f64> = specs
            .iter()
            .map(|s| match s.kind {
                GeomKind::CentreX => dx,
                GeomKind::CentreY => dy,
                _ => s.nominal,
            })
            .collect();
        let r = robot_with(&base, &specs, &v);
        let twist = [0.3, -0.2, 0.7];
        let carried = [twist[0] - twist[2] * dy, twist[1] + twist[2] * dx, twist[2]];
        let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        for (a, b) in r.wheels.iter().zip(&base.wheels) {
            let (p, q) = (a.position(), b.position());
            assert!((p.0 - q.0 - dx).abs() < 1e-12 && (p.1 - q.1 - dy).abs() < 1e-12);
            let turn = a.alpha_rad + a.beta_rad - b.alpha_rad - b.beta_rad;
            assert!(
                turn.sin().abs() < 1e-12,
                "rolling direction turned by {turn}"
            );
            let (moved, nominal) = (dot(a.rolling_row(), twist), dot(b.rolling_row(), carried));
            assert!((moved - nominal).abs() < 1e-12, "{moved} vs {nominal}");
        }
    }

    /// The ladder climbs by parameter count (the simplest adequate model is the first
    /// adequate one): on the three-wheel omni, the four-wheel omni and the mecanum robot.
    /// The wheels' centre is a rung of the omni robots, not of the mecanum one.
    #[test]
    fn the_ladder_climbs_by_parameter_count() {
        for name in ["omni3", "omni4", "mecanum"] {
            let robot = if name == "mecanum" {
                let mut r = synth::robot("omni4");
                for w in r.wheels.iter_mut() {
                    w.gamma_rad = std::f64::consts::FRAC_PI_4;
                }
                r
            } else {
                synth::robot(name)
            };
            let rungs = ladder(&robot, false);
            let counts: Vec<usize> = rungs.iter().map(|r| r.1.len()).collect();
            assert!(
                counts.windows(2).all(|w| w[0] <= w[1]),
                "{name}: {counts:?}"
            );
            let centre = rungs
                .iter()
                .any(|r| r.1.iter().any(|s| s.kind == GeomKind::CentreX));
            assert_eq!(centre, name != "mecanum", "{name}");
        }
    }
}
