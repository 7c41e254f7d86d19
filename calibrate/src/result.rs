//! What [`calibrate`](crate::calibrate) returns ([`Calibration`]): the fitted
//! parameters with their uncertainty, each wheel's geometry, the firmware factors,
//! per-recording and held-out errors, the pairs the data do not separate and the values
//! outside their plausible range; its JSON layout and its text report.

use crate::params::{ParamSpec, MECANUM_MIN_GAMMA};
use crate::series::{Event, Nuisance};
use crate::turn_law::TurnLaw;
use calib_core::robot::Robot;
use serde::{Deserialize, Serialize};
use std::fmt;

/// Where a law's one geometry sits with `--e-b-for`, in the notes' words.
pub(crate) const E_B_FOR: &str = "for --e-b-for's driving";

/// One fitted geometry parameter.
#[derive(Debug, Clone, Serialize)]
pub struct FittedParam {
    /// What the parameter is: name, effect, nominal value, plausible range.
    #[serde(flatten)]
    pub spec: ParamSpec,
    /// Fitted value.
    pub value: f64,
    /// One standard deviation: the larger of `sigma_fit` and `sigma_between`.
    pub sigma: f64,
    /// The fit's own standard deviation, from its residuals (their autocorrelation
    /// counted): what the data at hand fix.
    pub sigma_fit: f64,
    /// The spread between the recordings (or cross-validation's groups), each left out in
    /// turn (delete-one jackknife): what calibrating again on other runs would move the
    /// parameter by. Absent with fewer than three, with `--free-start` or a robust loss.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_between: Option<f64>,
    /// When the data alone do not fix it ([`FittedParam::sigma_exceeds_range`]): its
    /// standard deviation with the priors the fit used (the plausible range, and alike
    /// wheels held alike), on which the directions the data leave free rest.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sigma_with_priors: Option<f64>,
}

impl FittedParam {
    /// Whether the 1-sigma uncertainty is wider than the whole plausible range: the
    /// data then fix the parameter no better than the range itself (the covariance takes
    /// the prior at a millionth of its weight, so such a sigma is the data's alone).
    pub fn sigma_exceeds_range(&self) -> bool {
        self.sigma_fit > self.spec.plausible.1 - self.spec.plausible.0
    }
}

/// Events listed one a line up to this many; more are summarised by kind.
pub const EVENT_LINES: usize = 10;

fn event_line(e: &Event) -> String {
    format!(
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
    )
}

/// The events of the text report: each on a line when there are at most [`EVENT_LINES`],
/// else one line a kind (how many, in how many recordings, the range of their sizes and
/// times, the largest, what was done): a session of many turns can hold a hundred clock
/// leads, which would bury the geometry. The JSON keeps every one.
pub(crate) fn events_text(events: &[Event]) -> String {
    let mut out = String::new();
    if events.len() <= EVENT_LINES {
        for e in events {
            out.push_str(&event_line(e));
            out.push('\n');
        }
        return out;
    }
    let recordings = |v: &[&Event]| {
        let mut n: Vec<&str> = v.iter().map(|e| e.recording.as_str()).collect();
        n.sort_unstable();
        n.dedup();
        n.len()
    };
    let all: Vec<&Event> = events.iter().collect();
    let n = recordings(&all);
    out.push_str(&format!(
        "events: {} in {n} recording{}, by kind (each one in the JSON's events):\n",
        events.len(),
        if n == 1 { "" } else { "s" }
    ));
    let mut kinds: Vec<&str> = Vec::new();
    for e in events {
        if !kinds.contains(&e.kind) {
            kinds.push(e.kind);
        }
    }
    for kind in kinds {
        let group: Vec<&Event> = events.iter().filter(|e| e.kind == kind).collect();
        let by_heading = group.iter().any(|e| e.heading_rad != 0.0);
        let size = |e: &Event| {
            if by_heading {
                e.heading_rad.abs()
            } else {
                e.position_m.abs()
            }
        };
        let range = |f: &dyn Fn(&Event) -> f64| {
            group
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), e| {
                    (lo.min(f(e)), hi.max(f(e)))
                })
        };
        let (s0, s1) = range(&size);
        let (t0, t1) = range(&|e: &Event| e.t_s);
        let largest = group
            .iter()
            .copied()
            .reduce(|a, b| if size(b) > size(a) { b } else { a })
            .expect("a kind has an event");
        let n = recordings(&group);
        let (what, signed) = if by_heading {
            (
                format!("|heading| {s0:.3}-{s1:.3} rad"),
                format!("{:+.3} rad", largest.heading_rad),
            )
        } else {
            (
                format!("size {s0:.4}-{s1:.4} m"),
                format!("{:+.4} m", largest.position_m),
            )
        };
        out.push_str(&format!(
            "  {kind}: {} in {n} recording{}, {what}, at {t0:.2}-{t1:.2} s; largest {} at {:.2} s, {signed}; {}\n",
            group.len(),
            if n == 1 { "" } else { "s" },
            largest.recording,
            largest.t_s,
            largest.handled
        ));
    }
    out
}

/// One geometry line of the text report.
fn param_line(p: &FittedParam, implausible: bool) -> String {
    let flag = if implausible {
        "  (unbounded: implausible, see below)"
    } else {
        ""
    };
    let value = if p.sigma_exceeds_range() {
        // The figure is in the JSON; printed it reads as a +-795 % error.
        let priors = p
            .sigma_with_priors
            .map(|s| format!("; ± {s:.5} with the priors the fit used"))
            .unwrap_or_default();
        format!(
            "{:.5} (not fixed by the data: its sigma is wider than the plausible range{priors})",
            p.value
        )
    } else if p.sigma_between.is_some_and(|b| b > p.sigma_fit) {
        format!(
            "{:.5} ± {:.5} (the spread between runs; the fit's own ± {:.5})",
            p.value, p.sigma, p.sigma_fit
        )
    } else {
        format!("{:.5} ± {:.5}", p.value, p.sigma)
    };
    format!(
        "  {:<24} {value}  (nominal {}, plausible {:.4}..{:.4}){flag}",
        p.spec.name, p.spec.nominal, p.spec.plausible.0, p.spec.plausible.1
    )
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
    /// The wheel plane's angle to the chassis, degrees (moved with `alpha_deg` when the
    /// wheels' centre is fitted, so the wheel keeps its heading).
    pub beta_deg: f64,
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
        /// With any law kept (turn, speed or acceleration): everything a board that
        /// applies the law takes (`factors set` in full: E_b in a turn in place, c_L and
        /// c_R at standstill, the laws). The constant factors above are for consumers
        /// that cannot apply it.
        #[serde(skip_serializing_if = "Option::is_none")]
        board: Option<BoardFactors>,
    },
    /// Per wheel: the command multiplier f_lat (1 / radius scale), f_lon = 1. Wheel
    /// angle and position errors have no firmware factor: use the fitted robot file.
    Wheels {
        /// Command multiplier per wheel, in the robot's wheel order.
        f_lat: Vec<f64>,
        /// Common multiplier (always 1 here).
        f_lon: f64,
        /// The turn law a board applies to its odometry (`factors set --l-arc`): the
        /// wheels' distance from the centre this much longer on arcs than in a turn in
        /// place; absent when none was kept.
        #[serde(skip_serializing_if = "is_zero")]
        l_arc: f64,
    },
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// A differential drive's factors with its laws, as a board that applies them takes them
/// (`factors set --c-l --c-r --e-b --e-b-arc --speed-rel --accel-slip-s`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct BoardFactors {
    /// c_L (at standstill, with a speed law).
    pub c_l: f64,
    /// c_R (likewise).
    pub c_r: f64,
    /// E_b (in a turn in place, with a turn law).
    pub e_b: f64,
    /// The laws (0: none).
    #[serde(flatten)]
    pub laws: calib_core::correction::DiffLaws,
    /// The motion the laws were fitted on: beyond it the board holds each law at its
    /// edge (absent in the JSON: unbounded, as calibrations before protocol v9).
    #[serde(
        default,
        skip_serializing_if = "calib_core::correction::LawRange::is_unbounded"
    )]
    pub range: calib_core::correction::LawRange,
}

impl BoardFactors {
    /// The board's corrections.
    pub fn corrections(&self) -> calib_core::Corrections {
        calib_core::Corrections::diff_drive_within(
            self.c_l, self.c_r, self.e_b, self.laws, self.range,
        )
    }

    /// The `factors set` options that give the board these factors.
    pub fn command(&self) -> String {
        let mut s = format!(
            "factors set --c-l {:.6} --c-r {:.6} --e-b {:.6}",
            self.c_l, self.c_r, self.e_b
        );
        let l = &self.laws;
        for (flag, v) in [
            ("--e-b-arc", l.e_b_arc),
            ("--speed-rel", l.speed_rel),
            ("--accel-slip-s", l.accel_slip_s),
        ] {
            if v != 0.0 {
                s.push_str(&format!(" {flag} {v:.6}"));
            }
        }
        let g = self.range.for_laws(l);
        if *l != calib_core::correction::DiffLaws::default() && !g.is_unbounded() {
            s.push_str(&format!(
                " --law-range {:.6},{:.6},{:.6}",
                g.rho_min, g.rho_max, g.speed_max_m_s
            ));
        }
        s
    }
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

/// One law a two-sided robot was tested for, on its own against the constant model
/// (the held-out comparison the notes give in words); or, as `pose lead`, the
/// acceleration term tested again on top of the law kept.
#[derive(Debug, Clone, Serialize)]
pub struct LawTest {
    /// `turn`, `speed`, `acceleration`, or `pose lead` (the poses stamped early, a
    /// negative acceleration term, on top of the law kept: the logger's, not a rival);
    /// when the lead is chosen because no law qualified alone, `turn on the pose lead`
    /// and `speed on the pose lead` (each law again on top of it).
    pub law: &'static str,
    /// Its parameter (`eb_arc`, `speed_rel`, `accel_slip_s`).
    pub parameter: String,
    /// Fitted on all the recordings: the turn law as eb_arc / eb, the speed law per m/s,
    /// the acceleration law in s.
    pub value: f64,
    /// One standard deviation of `value`.
    pub sigma: f64,
    /// Mean held-out dead-reckoning RMSE with the law, m.
    pub heldout_m: f64,
    /// The same with the constant model (no law; for `pose lead`, the law kept alone;
    /// for a law on the pose lead, the lead alone), m.
    pub constant_heldout_m: f64,
    /// Folds (by recording) of the held-out comparison.
    pub folds: usize,
    /// Significant, within its range, told from the geometry, and held out enough.
    pub qualifies: bool,
    /// Kept (at most one law is, and a pose lead beside it).
    pub kept: bool,
    /// Two sessions or more and two kinds of motion or more: held out by each, the data
    /// can decide whether the law carries to motion it was not fitted on (else it is not
    /// kept).
    pub decided: bool,
    /// Each session left out in turn: the constant model's and the law's held-out error
    /// (empty when the data cannot decide).
    pub by_session: Vec<GroupHeldout>,
    /// Each kind of motion left out in turn (likewise).
    pub by_kind: Vec<GroupHeldout>,
}

/// One session or kind of motion left out: the recordings' mean dead-reckoned RMSE with
/// the model fitted without them, with and without the law (the law held at the edges of
/// the motion the other recordings cover).
#[derive(Debug, Clone, Serialize)]
pub struct GroupHeldout {
    /// The session (`<robot>-<path>-<session>`) or kind (`<path>`) left out.
    pub group: String,
    /// Its recordings.
    pub recordings: usize,
    /// Mean held-out RMSE with the constant model (no law), m.
    pub constant_m: f64,
    /// Mean held-out RMSE with the law, m.
    pub law_m: f64,
}

/// The result of [`calibrate`](crate::calibrate).
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
    /// The fitted geometry parameters (in [`param_specs`](crate::param_specs) order), each with its
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
    /// `"clockwise"` or `"counter-clockwise"` when every recording turns that way (what
    /// follows the turning direction then goes into the geometry unseen: a note says
    /// so), `null` when they turn both ways.
    pub turning_one_way: Option<&'static str>,
    /// Model evaluations the whole fit took.
    pub model_runs: usize,
    /// The robot with the fitted geometry applied; the JSON gives each wheel's fitted
    /// geometry (`geometry`).
    #[serde(rename = "geometry", serialize_with = "serialize_geometry")]
    pub fitted_robot: Robot,
    /// The turn law the geometry was fitted with (fitted, given, or none: zero).
    pub turn_law: TurnLaw,
    /// A differential or skid-steer robot's laws tested (none when a law was given or
    /// the recordings are too few): each with its fit and held-out figures.
    pub law_tests: Vec<LawTest>,
    /// With a turn law: the fitted robot with the separation of a turn in place, which
    /// the law widens on arcs ([`dead_reckoning_rmse_law`](crate::dead_reckoning_rmse_law)); else `fitted_robot`.
    /// The JSON gives each wheel's geometry as `board_geometry`: what `wheelcal apply`
    /// puts on a board when no factor carries the fitted geometry (an omni robot's wheel
    /// distances, angles, centre or roller angle).
    #[serde(rename = "board_geometry", serialize_with = "serialize_geometry")]
    pub law_base_robot: Robot,
    /// What `--e-b-for` placed in the robot file and ROS 2 (its notes give the values).
    #[serde(skip)]
    pub placed_for_log: PlacedForLog,
}

/// Which of the robot file's constants `--e-b-for` placed for the driving logged,
/// instead of at the fitted recordings' mean turn and mean speed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PlacedForLog {
    /// E_b, on a turn law.
    pub e_b: bool,
    /// The wheel size, on a speed law.
    pub wheel_size: bool,
}

impl Calibration {
    /// E_b of a differential drive's factors (with a law: at the recordings' mean turn, or
    /// for `--e-b-for`'s driving), else 1.
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
            beta_deg: w.beta_rad.to_degrees(),
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

    /// The geometry a board takes with the laws it applies ([`Calibration::law_base_robot`]:
    /// a turn law's separation or wheel distance of a turn in place, a speed law's wheel
    /// size at standstill; the robot file's geometry when the board applies no law, as on
    /// a skid-steer robot), as TOML for `wheelcal robot set`.
    pub fn board_robot_toml(&self) -> String {
        format!(
            "# {} with geometry fitted by wheelcal calibrate from {}, for a board that applies its laws\n{}",
            self.robot,
            self.recordings.join(", "),
            formats::robot_file::to_toml(self.board_robot())
        )
    }

    /// [`Calibration::board_robot_toml`]'s robot.
    fn board_robot(&self) -> &Robot {
        let laws = match &self.factors {
            Factors::Diff { board, .. } => board.is_some(),
            Factors::Wheels { l_arc, .. } => *l_arc != 0.0,
        };
        if laws {
            &self.law_base_robot
        } else {
            &self.fitted_robot
        }
    }

    /// The `factors set` line of a board holding [`Calibration::board_robot_toml`]'s
    /// geometry: ones, and the laws the board applies.
    pub fn board_robot_factors(&self) -> String {
        match &self.factors {
            Factors::Wheels { f_lat, l_arc, .. } => {
                let ones = vec!["1"; f_lat.len()].join(",");
                let law = if *l_arc != 0.0 {
                    format!(" --l-arc {l_arc:.6}")
                } else {
                    String::new()
                };
                format!("factors set --f-lat {ones} --f-lon 1{law}")
            }
            Factors::Diff { board, .. } => {
                let laws = board.map(|b| b.laws).unwrap_or_default();
                BoardFactors {
                    c_l: 1.0,
                    c_r: 1.0,
                    e_b: 1.0,
                    laws,
                    range: board.map(|b| b.range).unwrap_or_default(),
                }
                .command()
            }
        }
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
            let implausible = self.implausible.iter().any(|i| i.name == p.spec.name);
            writeln!(f, "{}", param_line(p, implausible))?;
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
                board: Some(b),
                e_b,
                ..
            } => writeln!(
                f,
                "firmware factors: {} (the board applies the law; ROS 2 and the robot file get the constant factors: {}E_b {e_b:.6} {})",
                b.command(),
                if b.laws.speed_rel == 0.0 {
                    String::new()
                } else if self.placed_for_log.wheel_size {
                    format!("c_L and c_R {}, ", E_B_FOR)
                } else {
                    "c_L and c_R at the recordings' mean speed, ".into()
                },
                if self.placed_for_log.e_b {
                    E_B_FOR
                } else {
                    "at the recordings' mean turn"
                }
            )?,
            Factors::Diff { c_l, c_r, e_b, .. } => writeln!(
                f,
                "firmware factors: factors set --c-l {c_l:.6} --c-r {c_r:.6} --e-b {e_b:.6}"
            )?,
            Factors::Wheels { f_lat, f_lon, l_arc } => {
                let f_lat = f_lat
                    .iter()
                    .map(|v| format!("{v:.6}"))
                    .collect::<Vec<_>>()
                    .join(",");
                write!(f, "firmware factors: factors set --f-lat {f_lat} --f-lon {f_lon:.6}")?;
                if *l_arc != 0.0 {
                    write!(
                        f,
                        " --l-arc {l_arc:.6} (the board applies the turn law; the robot file gets the wheels' distance at the recordings' mean turn)"
                    )?;
                }
                writeln!(f)?
            }
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
        f.write_str(&events_text(&self.events))?;
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
            match self.turning_one_way {
                None => writeln!(
                    f,
                    "identifiability: every parameter is separable from these recordings"
                )?,
                Some(sense) => writeln!(
                    f,
                    "identifiability: the model's parameters are separable from these recordings, but every one turns {sense}: what follows the turning direction is not (see the notes)"
                )?,
            }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::GeomKind;

    fn event(rec: &str, kind: &'static str, t_s: f64, heading_rad: f64) -> Event {
        Event {
            recording: rec.into(),
            kind,
            t_s,
            duration_s: 3.0,
            heading_rad,
            position_m: 0.0,
            handled: format!("handled as a {kind}"),
        }
    }

    /// Up to [`EVENT_LINES`] events are listed one a line; more are summarised by kind
    /// (how many, in how many recordings, the range of their sizes and times, what was
    /// done) with the largest of each kind named, so 170 clock leads of a mecanum session
    /// do not bury the geometry; the JSON keeps every one.
    #[test]
    fn many_events_are_summarised_by_kind_and_few_are_listed() {
        let few: Vec<Event> = (0..EVENT_LINES)
            .map(|i| event("run-01", "slip", i as f64, 0.05))
            .collect();
        let text = events_text(&few);
        assert_eq!(text.lines().count(), EVENT_LINES);
        assert!(text
            .lines()
            .all(|l| l.starts_with("event run-01 slip: at ")));
        let mut many = few.clone();
        many.extend((0..30).map(|i| {
            event(
                &format!("run-{:02}", 2 + i % 3),
                "time_lead",
                10.0 + i as f64,
                if i == 17 {
                    -0.452
                } else {
                    0.1 + 0.001 * i as f64
                },
            )
        }));
        let text = events_text(&many);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 3, "{text}");
        assert_eq!(
            lines[0],
            "events: 40 in 4 recordings, by kind (each one in the JSON's events):"
        );
        assert_eq!(
            lines[1],
            "  slip: 10 in 1 recording, |heading| 0.050-0.050 rad, at 0.00-9.00 s; largest run-01 at 0.00 s, +0.050 rad; handled as a slip"
        );
        assert_eq!(
            lines[2],
            "  time_lead: 30 in 3 recordings, |heading| 0.100-0.452 rad, at 10.00-39.00 s; largest run-04 at 27.00 s, -0.452 rad; handled as a time_lead"
        );
    }

    fn row(name: &str, v: [f64; 4]) -> Heldout {
        Heldout {
            name: name.into(),
            group: None,
            rmse_before_m: v[0],
            rmse_after_m: v[1],
            aligned_before_m: v[2],
            aligned_after_m: v[3],
        }
    }

    fn param(sigma: f64) -> FittedParam {
        FittedParam {
            spec: ParamSpec {
                kind: GeomKind::Radius(0),
                name: "radius_scale_w1".into(),
                effect: "wheel_diameter_mismatch",
                nominal: 1.0,
                plausible: (0.85, 1.15),
                stands_for: "",
                alike: None,
            },
            value: 1.10198,
            sigma,
            sigma_fit: sigma,
            sigma_between: None,
            sigma_with_priors: None,
        }
    }

    /// A sigma wider than the whole plausible range (0.30 here) says the data do not fix
    /// the parameter: the line says so in words instead of printing "± 7.95" (a mecanum
    /// square session's radius, whose directions only the prior holds). A sigma inside
    /// the range is printed as it is.
    #[test]
    fn a_sigma_wider_than_the_plausible_range_reads_as_not_fixed() {
        let loose = param_line(&param(7.95184), false);
        assert!(loose.contains("1.10198 (not fixed by the data"), "{loose}");
        assert!(!loose.contains("7.95"), "{loose}");
        let tight = param_line(&param(0.00213), false);
        assert!(tight.contains("1.10198 ± 0.00213"), "{tight}");
        // Just inside the range's width the data still say as much as the range does.
        let edge = param_line(&param(0.299), true);
        assert!(
            edge.contains("± 0.29900") && edge.contains("implausible"),
            "{edge}"
        );
        assert!(param(0.31).sigma_exceeds_range() && !param(0.29).sigma_exceeds_range());
        // With the sigma the priors give (the wheels held alike), the line says it too.
        let held = FittedParam {
            sigma_with_priors: Some(0.00812),
            ..param(7.95184)
        };
        let line = param_line(&held, false);
        assert!(
            line.contains("not fixed by the data") && line.contains("± 0.00812 with the priors"),
            "{line}"
        );
        assert!(!line.contains("7.95"), "{line}");
        // The spread between runs, when larger than the fit's own, is the figure, and the
        // line names both.
        let spread = FittedParam {
            sigma: 0.00155,
            sigma_between: Some(0.00155),
            ..param(0.00012)
        };
        let line = param_line(&spread, false);
        assert!(
            line.contains("1.10198 ± 0.00155 (the spread between runs; the fit's own ± 0.00012)"),
            "{line}"
        );
    }

    /// The column means of a hand-made table, each the sum of three values over 3 (a
    /// couple of roundings of numbers near 0.01: 1e-16 absolute), and the JSON carries
    /// them; without cross-validation there are none and the JSON says null.
    #[test]
    fn heldout_means_are_the_column_means() {
        let t = HeldoutTable(vec![
            row("a", [0.010, 0.004, 0.003, 0.002]),
            row("b", [0.020, 0.005, 0.006, 0.001]),
            row("c", [0.030, 0.009, 0.009, 0.003]),
        ]);
        let m = t.means().unwrap();
        let want = [0.020, 0.006, 0.006, 0.002];
        let got = [m.before_m, m.after_m, m.aligned_before_m, m.aligned_after_m];
        for (g, w) in got.iter().zip(want) {
            assert!((g - w).abs() < 1e-16, "{got:?}");
        }
        let j = serde_json::to_value(&t).unwrap();
        assert_eq!(j["leave_one_out"].as_array().unwrap().len(), 3);
        assert_eq!(j["leave_one_out_mean_before_m"], m.before_m);
        assert_eq!(j["leave_one_out_aligned_after_m"], m.aligned_after_m);
        let none = HeldoutTable::default();
        assert_eq!(none.means(), None);
        assert!(serde_json::to_value(&none).unwrap()["leave_one_out_mean_after_m"].is_null());
    }
}
