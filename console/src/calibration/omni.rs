//! `wheelcal omni compute`: [Redundant omni]'s lateral (F_lat) and longitudinal (F_lon) factors from
//! straight-path runs, with the radial error statistics of [Redundant omni]'s Table II.

use super::omni_circles::OmniCircleReport;
use anyhow::{anyhow, bail, Result};
use calib_core::motion::OmniPath;
use calib_core::omni_cal::{self, DrivenWheel, IdleWheels, OmniRun, PathRuns};
use calib_core::robot::{Robot, RobotKind};
use calib_core::stats;
use calib_core::Corrections;
use formats::runs_file::{OmniPathRuns, Phase, RunsFile};
use serde::Serialize;
use std::fmt::Write;
use std::path::{Path, PathBuf};

/// Statistics of one path's runs in one phase ([Redundant omni] Table II, Fig. 5).
#[derive(Debug, Clone, Serialize)]
pub struct PathStats {
    /// Path name as in the runs file.
    pub path: String,
    /// Commanded length of the straight path, m.
    pub length_m: f64,
    /// Number of runs on this path.
    pub runs: usize,
    /// Mean radial end error, m.
    pub mean_radial_error_m: f64,
    /// Sample standard deviation of the radial end errors, m.
    pub std_dev_radial_m: f64,
    /// Skewness of the radial errors (absent with too few runs).
    pub skewness: Option<f64>,
    /// Excess kurtosis of the radial errors (absent with too few runs).
    pub kurtosis: Option<f64>,
    /// Radial error of each run.
    pub radial_errors_m: Vec<f64>,
}

/// The result of `omni compute`.
#[derive(Debug, Clone, Serialize)]
pub struct OmniReport {
    /// Robot name from the robot description.
    pub robot: String,
    /// How the idle wheels were modelled: `released` or `held`.
    pub idle_wheels: &'static str,
    /// Wheel names, in the robot description's order (the order of `f_lat` and `wheel_ratio`).
    pub wheels: Vec<String>,
    /// Multiplier on each wheel's command that makes the robot go straight.
    pub f_lat: Vec<f64>,
    /// Common multiplier that makes it go the full length.
    pub f_lon: f64,
    /// [Redundant omni]'s eq. 5 per path (with formats.md's sign convention), for comparison.
    pub f_lon_eq5: Vec<f64>,
    /// Effective velocity ratio of each wheel (actual / nominal travel); `null` for wheels
    /// no path drives.
    pub wheel_ratio: Vec<Option<f64>>,
    /// Mean radial error of the 'before' runs ([Redundant omni] eq. 7).
    pub mean_radial_error_m: f64,
    /// Statistics of each path's `before` runs.
    pub before: Vec<PathStats>,
    /// Statistics of each path's `after` runs (empty when there are none).
    pub after: Vec<PathStats>,
    /// Mean radial error of the 'after' runs, m, when there are any.
    pub mean_radial_error_after_m: Option<f64>,
    /// [Redundant omni] eq. 8, percent.
    pub improvement_index_percent: Option<f64>,
    /// Second pass: the factors in force while these runs were measured, and the
    /// secondary factors the runs give; `f_lat`/`f_lon` above are then their composition.
    pub previous: Option<OmniFactors>,
    /// The secondary factors computed from these runs alone, on a second pass.
    pub secondary: Option<OmniFactors>,
    /// The omni circle test, when the runs file has circle rows: the turn in place (the
    /// wheels' distance from the centre) and the turn law.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub circles: Option<OmniCircleReport>,
    /// The turn law the board applies (`factors set --l-arc`): the circles' when kept,
    /// added to a previous pass's; absent when there is none.
    #[serde(skip_serializing_if = "is_zero")]
    pub l_arc: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// A pair of omni factors.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OmniFactors {
    /// Multiplier on each wheel's command (lateral factor).
    pub f_lat: Vec<f64>,
    /// Common multiplier on all wheel commands (longitudinal factor).
    pub f_lon: f64,
}

/// A second pass ([Redundant omni]): runs measured with `previous` factors in force give secondary
/// factors; the board then needs their composition ([`Corrections::compose`]).
pub fn compose_with(mut rep: OmniReport, previous: &Corrections) -> Result<OmniReport> {
    // With or without a turn law: the paths are straight, so the law neither shows in
    // them nor changes; the composition keeps it.
    let Some((p_lat, p_lon)) = previous.omni_factors() else {
        bail!(
            "the previous factors are not omni factors: {}",
            crate::board::factors_text(previous)
        );
    };
    let secondary = Corrections::Omni {
        f_lat: heapless::Vec::from_slice(&rep.f_lat)
            .map_err(|_| anyhow::anyhow!("too many wheels"))?,
        f_lon: rep.f_lon,
    };
    let composed = previous.compose(&secondary);
    let Some((f_lat, f_lon)) = composed.as_ref().and_then(Corrections::omni_factors) else {
        bail!(
            "previous F_lat has {} factors, the robot {} wheels",
            p_lat.len(),
            rep.f_lat.len()
        );
    };
    rep.previous = Some(OmniFactors {
        f_lat: p_lat.to_vec(),
        f_lon: p_lon,
    });
    rep.secondary = Some(OmniFactors {
        f_lat: rep.f_lat.clone(),
        f_lon: rep.f_lon,
    });
    // The composition is what the board gets: refuse it as the board would.
    for (i, v) in f_lat.iter().enumerate() {
        calib_core::correction::check("f_lat", Some(i), *v).map_err(|e| {
            anyhow::anyhow!("composed with the previous pass, {e}: not recommended")
        })?;
    }
    calib_core::correction::check("f_lon", None, f_lon)
        .map_err(|e| anyhow::anyhow!("composed with the previous pass, {e}: not recommended"))?;
    rep.f_lat = f_lat.to_vec();
    rep.f_lon = f_lon;
    Ok(rep)
}

/// The omni circle test of `runs`' circle rows ([`super::omni_circles`]), measured with
/// `previous` in force (a first pass's factors and law; none on a first pass), added to
/// `rep` (whose factors are then the board's): the wheels' distance for the board robot
/// and the law, a previous pass's law added to the circles' (laws compose by adding).
pub fn with_circles(
    mut rep: OmniReport,
    robot: &Robot,
    runs: &RunsFile,
    previous: Option<&Corrections>,
) -> Result<OmniReport> {
    let measured_with = previous.cloned().unwrap_or(Corrections::None);
    let new = rep.corrections()?;
    rep.circles = super::omni_circles::compute(robot, runs, &measured_with, &new)?;
    rep.l_arc = measured_with.l_arc() + rep.circles.as_ref().map_or(0.0, |c| c.l_arc_kept());
    Ok(rep)
}

/// Reads the previous pass's factors (`f_lat`, `f_lon`, and a turn law `l_arc` when
/// `factors get` shows one) from a `--json` result of `omni compute` or `factors get`.
pub fn factors_from_json(path: &std::path::Path) -> Result<Corrections> {
    use anyhow::Context;
    // A FIFO or device would be waited on or read without end.
    crate::input::check_regular(path, "JSON result")?;
    let text = crate::ros2::read_json_text(path)?;
    let v: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    corrections_from_value(&v, &path.display(), "")
}

/// An omni robot's factors as the JSON results give them (`f_lat`, `f_lon`, and `l_arc`
/// when a turn law was kept; absent or null is none), checked against the board's
/// ranges so that a pass the board would refuse is neither composed with nor applied.
/// Errors name `shown` (the file) and end with `hint` (what the option takes).
pub fn corrections_from_value(
    v: &serde_json::Value,
    shown: &dyn std::fmt::Display,
    hint: &str,
) -> Result<Corrections> {
    let missing = |what: &str| anyhow::anyhow!("{shown}: no {what}{hint}");
    let f_lat: Vec<f64> = v
        .get("f_lat")
        .and_then(|a| a.as_array())
        .and_then(|a| a.iter().map(|x| x.as_f64()).collect())
        .ok_or_else(|| missing("numeric array f_lat"))?;
    let f_lon = v
        .get("f_lon")
        .and_then(|x| x.as_f64())
        .ok_or_else(|| missing("number f_lon"))?;
    let l_arc = match v.get("l_arc") {
        None | Some(serde_json::Value::Null) => 0.0,
        Some(x) => x.as_f64().ok_or_else(|| missing("number l_arc"))?,
    };
    let at = |e: calib_core::correction::CorrectionError| anyhow::anyhow!("{shown}: {e}");
    for (i, v) in f_lat.iter().enumerate() {
        calib_core::correction::check("f_lat", Some(i), *v).map_err(at)?;
    }
    calib_core::correction::check("f_lon", None, f_lon).map_err(at)?;
    calib_core::correction::check_within(
        "l_arc",
        l_arc,
        -calib_core::correction::E_B_ARC_MAX,
        calib_core::correction::E_B_ARC_MAX,
    )
    .map_err(at)?;
    let n = f_lat.len();
    let f_lat = heapless::Vec::from_slice(&f_lat).map_err(|_| {
        anyhow::anyhow!(
            "{shown}: {n} f_lat factors; a board holds at most {}",
            calib_core::robot::MAX_WHEELS
        )
    })?;
    Ok(Corrections::omni(f_lat, f_lon, l_arc))
}

/// Direction of a named path in the body frame (radians from body x).
fn path_direction(p: &OmniPathRuns) -> Result<f64> {
    match p.omni_path {
        Some(OmniPath::W1) => Ok(0.0),
        Some(OmniPath::W2) => Ok(core::f64::consts::FRAC_PI_2),
        None => bail!("unknown omni path '{}' (expected 4W-1 or 4W-2)", p.path),
    }
}

fn path_stats(p: &OmniPathRuns) -> PathStats {
    let radial: Vec<f64> = p.runs.iter().map(|r| r.0.hypot(r.1)).collect();
    PathStats {
        path: p.path.clone(),
        length_m: p.length_m,
        runs: p.runs.len(),
        mean_radial_error_m: stats::mean(&radial).unwrap_or(f64::NAN),
        std_dev_radial_m: stats::sample_std_dev(&radial).unwrap_or(f64::NAN),
        skewness: stats::skewness(&radial).ok(),
        kurtosis: stats::excess_kurtosis(&radial).ok(),
        radial_errors_m: radial,
    }
}

/// Where `omni run` writes the idle-wheel mode its runs were measured with.
pub fn idle_sidecar(runs_file: &Path) -> PathBuf {
    let mut s = runs_file.as_os_str().to_owned();
    s.push(".idle_wheels");
    PathBuf::from(s)
}

/// The mode written beside a runs file, if any.
pub fn read_idle_sidecar(runs_file: &Path) -> Result<Option<IdleWheels>> {
    let f = idle_sidecar(runs_file);
    match crate::input::read_text(&f, crate::input::MAX_SIDECAR_BYTES, "idle-wheel mode file") {
        Err(e) if crate::input::is_not_found(&e) => Ok(None),
        Err(e) => Err(e),
        Ok(t) => parse_idle(t.trim()).map(Some).ok_or_else(|| {
            anyhow!(
                "{}:1:1: expected `held` or `released`, found `{}`",
                f.display(),
                t.trim()
            )
        }),
    }
}

/// Writes the mode beside a runs file.
pub fn write_idle_sidecar(runs_file: &Path, idle: IdleWheels) -> Result<()> {
    let f = idle_sidecar(runs_file);
    std::fs::write(&f, format!("{}\n", idle.as_str()))
        .map_err(|e| anyhow!("cannot write {}: {e}", f.display()))
}

fn parse_idle(s: &str) -> Option<IdleWheels> {
    match s {
        "held" => Some(IdleWheels::Held),
        "released" => Some(IdleWheels::Released),
        _ => None,
    }
}

/// The idle-wheel mode in force: the flag, else what `omni run` wrote beside the runs,
/// else the robot file's `[procedure] idle_wheels` (when a robot file is given), else
/// released.
pub fn idle_wheels_for(
    flag: Option<IdleWheels>,
    runs_file: &Path,
    robot_file: &Path,
) -> Result<IdleWheels> {
    if let Some(f) = flag {
        return Ok(f);
    }
    if let Some(s) = read_idle_sidecar(runs_file)? {
        return Ok(s);
    }
    if robot_file.as_os_str().is_empty() {
        return Ok(IdleWheels::Released);
    }
    Ok(formats::robot_file::load_procedure(robot_file)?
        .idle_wheels
        .unwrap_or_default())
}

/// Computes F_lat and F_lon from a runs file (paths up to the default length limit), with
/// the idle wheels modelled as `idle`.
pub fn compute(robot: &Robot, runs: &RunsFile, idle: IdleWheels) -> Result<OmniReport> {
    compute_limited(robot, runs, idle, super::plausible::DEFAULT_MAX_LENGTH_M)
}

/// Computes F_lat and F_lon from a runs file whose rows are first checked against
/// physical bounds (paths up to `max_length_m`); factors the board would refuse are an
/// error, never a recommendation.
pub fn compute_limited(
    robot: &Robot,
    runs: &RunsFile,
    idle: IdleWheels,
    max_length_m: f64,
) -> Result<OmniReport> {
    super::plausible::check_runs(runs, max_length_m)?;
    let rep = compute_unchecked(robot, runs, idle)?;
    let mut factors: Vec<(&'static str, Option<usize>, f64)> = rep
        .f_lat
        .iter()
        .enumerate()
        .map(|(i, &f)| ("f_lat", Some(i), f))
        .collect();
    factors.push(("f_lon", None, rep.f_lon));
    super::plausible::check_factors(runs, &factors)?;
    Ok(rep)
}

fn compute_unchecked(robot: &Robot, runs: &RunsFile, idle: IdleWheels) -> Result<OmniReport> {
    if robot.kind != RobotKind::Omni {
        bail!(
            "omni calibration needs an omni robot; '{}' is {} (use `wheelcal umbmark compute`)",
            robot.name,
            robot.kind.as_str()
        );
    }
    let before = runs.omni(Phase::Before)?;
    if before.is_empty() {
        bail!(
            "{}: no omni 'before' runs (rows with test = omni)",
            runs.path.display()
        );
    }
    let mut driven_sets: Vec<Vec<DrivenWheel>> = Vec::new();
    let mut held_sets: Vec<Vec<[f64; 3]>> = Vec::new();
    let mut run_sets: Vec<Vec<OmniRun>> = Vec::new();
    let mut dirs = Vec::new();
    for p in &before {
        let dir = path_direction(p).map_err(|e| anyhow!("{}: {e}", runs.path.display()))?;
        let driven: Vec<DrivenWheel> = robot
            .wheels
            .iter()
            .enumerate()
            .map(|(i, w)| DrivenWheel::on_straight_path(i, w.rolling_row(), dir, p.length_m))
            .filter(|d| d.nominal_travel_m.abs() > 1e-9 * p.length_m)
            .collect();
        // Held idle wheels: every wheel of the robot this path does not drive.
        let held: Vec<[f64; 3]> = match idle {
            IdleWheels::Released => Vec::new(),
            IdleWheels::Held => robot
                .wheels
                .iter()
                .enumerate()
                .filter(|(i, _)| !driven.iter().any(|d| d.index == *i))
                .map(|(_, w)| w.rolling_row())
                .collect(),
        };
        held_sets.push(held);
        driven_sets.push(driven);
        run_sets.push(
            p.runs
                .iter()
                .map(|&(x, y, th)| OmniRun {
                    x_err_m: x,
                    y_err_m: y,
                    theta_err_rad: th,
                })
                .collect(),
        );
        dirs.push(dir);
    }
    let paths: Vec<PathRuns<'_>> = before
        .iter()
        .enumerate()
        .map(|(i, p)| PathRuns {
            length_m: p.length_m,
            direction_rad: dirs[i],
            driven: &driven_sets[i],
            runs: &run_sets[i],
            held: &held_sets[i],
        })
        .collect();
    let cal = omni_cal::calibrate(&paths, robot.wheel_count())
        .map_err(|e| anyhow!("{}: {e}", runs.path.display()))?;
    let n = robot.wheel_count();
    let before_stats: Vec<PathStats> = before.iter().map(path_stats).collect();
    let after_stats: Vec<PathStats> = runs.omni(Phase::After)?.iter().map(path_stats).collect();
    let mean_all = |ps: &[PathStats]| {
        let all: Vec<f64> = ps
            .iter()
            .flat_map(|p| p.radial_errors_m.iter().copied())
            .collect();
        stats::mean(&all).ok()
    };
    let before_mean = mean_all(&before_stats).unwrap_or(cal.mean_radial_error_m);
    let after_mean = if after_stats.is_empty() {
        None
    } else {
        mean_all(&after_stats)
    };
    Ok(OmniReport {
        robot: robot.name.to_string(),
        idle_wheels: idle.as_str(),
        wheels: robot.wheels.iter().map(|w| w.name.to_string()).collect(),
        f_lat: cal.correction.f_lat[..n].to_vec(),
        f_lon: cal.correction.f_lon,
        f_lon_eq5: cal.paths.iter().flatten().map(|p| p.f_lon_eq5).collect(),
        wheel_ratio: cal.k[..n].to_vec(),
        mean_radial_error_m: before_mean,
        before: before_stats,
        after: after_stats,
        mean_radial_error_after_m: after_mean,
        improvement_index_percent: after_mean
            .and_then(|a| stats::improvement_index_percent(before_mean, a).ok()),
        previous: None,
        secondary: None,
        circles: None,
        l_arc: 0.0,
    })
}

impl OmniReport {
    /// The factors (and law) the board takes.
    pub fn corrections(&self) -> Result<Corrections> {
        let f_lat = heapless::Vec::from_slice(&self.f_lat)
            .map_err(|_| anyhow!("{} wheels: a board holds at most 8", self.f_lat.len()))?;
        Ok(Corrections::omni(f_lat, self.f_lon, self.l_arc))
    }

    /// The geometry a board takes with the circles (`omni compute --write-board-robot`):
    /// `robot` with the factors' wheel sizes and the circles' wheel distances, to go with
    /// factors of one and the law (`wheelcal apply --board-robot`). None without circles.
    pub fn board_robot(&self, robot: &Robot) -> Result<Option<Robot>> {
        let Some(c) = &self.circles else {
            return Ok(None);
        };
        Ok(Some(c.board_robot(&self.corrections()?.apply_to(robot))))
    }

    /// The human-readable summary printed without `--json`.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "Omni calibration (lateral and longitudinal factors, [Redundant omni]): robot {}",
            self.robot
        );
        let _ = writeln!(s, "  {:<10} {:>12} {:>10}", "wheel", "ratio k", "F_lat");
        for (i, w) in self.wheels.iter().enumerate() {
            let k = self.wheel_ratio[i].map_or("-".to_string(), |k| format!("{k:.5}"));
            let _ = writeln!(s, "  {:<10} {:>12} {:>10.5}", w, k, self.f_lat[i]);
        }
        let _ = writeln!(
            s,
            "  F_lon = {:.5} ([Redundant omni] eq. 5, per path: {:?})",
            self.f_lon,
            self.f_lon_eq5
                .iter()
                .map(|v| (v * 1e5).round() / 1e5)
                .collect::<Vec<_>>()
        );
        let _ = writeln!(
            s,
            "  wheel command = F_lon * F_lat[i] * (J twist)_i  ([Redundant omni] eq. 6)"
        );
        if let (Some(p), Some(q)) = (&self.previous, &self.secondary) {
            let _ = writeln!(
                s,
                "  second pass: previous F_lat {:?} F_lon {:.5} x secondary F_lat {:?} F_lon {:.5}",
                p.f_lat, p.f_lon, q.f_lat, q.f_lon
            );
        }
        for (phase, ps) in [("before", &self.before), ("after", &self.after)] {
            for p in ps.iter() {
                let _ = writeln!(
                    s,
                    "  {phase:<6} {:<5} {} runs, mean radial error {:.2} mm, sd {:.2} mm, skewness {}, kurtosis {}",
                    p.path,
                    p.runs,
                    p.mean_radial_error_m * 1e3,
                    p.std_dev_radial_m * 1e3,
                    p.skewness.map_or("-".into(), |v| format!("{v:.3}")),
                    p.kurtosis.map_or("-".into(), |v| format!("{v:.3}")),
                );
            }
        }
        if let (Some(a), Some(i)) = (
            self.mean_radial_error_after_m,
            self.improvement_index_percent,
        ) {
            let _ = writeln!(
                s,
                "  mean radial error {:.2} mm -> {:.2} mm: improvement {:.1} % ([Redundant omni] eq. 8)",
                self.mean_radial_error_m * 1e3,
                a * 1e3,
                i
            );
        }
        if let Some(c) = &self.circles {
            s.push_str(&c.human());
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::presets;
    use std::path::Path;

    #[test]
    fn short_robot_gets_f_lon_above_one() {
        // Every run stops 5 % short on 0.6 m with no sideways error: k = 0.95 on every
        // driven wheel, F_lon = 1/0.95, F_lat = 1.
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\n");
        for p in ["4W-1", "4W-2"] {
            for _ in 0..3 {
                text.push_str(&format!("omni,{p},0.6,-0.03,0,,\n"));
            }
        }
        text.push_str("omni,4W-1,0.6,-0.003,0,,after\nomni,4W-1,0.6,-0.002,0,,after\n");
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        let rep = compute(&presets::omni4(), &runs, IdleWheels::Released).unwrap();
        assert!((rep.f_lon - 1.0 / 0.95).abs() < 1e-9, "{}", rep.f_lon);
        for f in &rep.f_lat {
            assert!((f - 1.0).abs() < 1e-9);
        }
        assert!((rep.mean_radial_error_m - 0.03).abs() < 1e-12);
        // after 2.5 mm mean: (30 - 2.5) / 30 = 91.67 %.
        assert!((rep.improvement_index_percent.unwrap() - 91.666_666).abs() < 1e-3);
    }

    #[test]
    fn second_pass_report_composes() {
        // Secondary runs stopping 2 % short: secondary F_lon = 1/0.98; the first pass had
        // F_lat [1.02, 1, 0.98, 1], F_lon 1.01; the report's factors are the products.
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\n");
        for p in ["4W-1", "4W-2"] {
            for _ in 0..2 {
                text.push_str(&format!("omni,{p},0.5,-0.01,0,,\n"));
            }
        }
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        let rep = compute(&presets::omni4(), &runs, IdleWheels::Released).unwrap();
        let first = Corrections::Omni {
            f_lat: heapless::Vec::from_slice(&[1.02, 1.0, 0.98, 1.0]).unwrap(),
            f_lon: 1.01,
        };
        let rep = compose_with(rep, &first).unwrap();
        assert!((rep.f_lon - 1.01 / 0.98).abs() < 1e-9, "{}", rep.f_lon);
        for (got, want) in rep.f_lat.iter().zip([1.02, 1.0, 0.98, 1.0]) {
            assert!((got - want).abs() < 1e-9);
        }
        assert!((rep.secondary.as_ref().unwrap().f_lon - 1.0 / 0.98).abs() < 1e-9);
        let diff = Corrections::DiffDrive {
            c_l: 1.0,
            c_r: 1.0,
            e_b: 1.0,
        };
        assert!(compose_with(rep.clone(), &diff).is_err());
        // A previous pass with a turn law composes alike (the straight paths neither show
        // nor change it).
        let lawful = Corrections::omni(
            heapless::Vec::from_slice(&[1.02, 1.0, 0.98, 1.0]).unwrap(),
            1.01,
            0.019,
        );
        let rep = compose_with(rep, &lawful).unwrap();
        assert!((rep.previous.as_ref().unwrap().f_lon - 1.01).abs() < 1e-12);
    }

    /// One reader for every omni result (`omni compute`, `factors get`, `apply`'s input):
    /// the factors come back to the bit, and each refusal names the file, what is wrong
    /// and what the option takes.
    #[test]
    fn omni_factors_are_read_and_refused_in_one_place() {
        let read = |text: &str| {
            let v: serde_json::Value = serde_json::from_str(text).unwrap();
            corrections_from_value(&v, &"c.json", ": apply takes ...")
        };
        let c = read(r#"{"f_lat": [1.01, 0.99, 1.0], "f_lon": 1.02, "l_arc": null}"#).unwrap();
        let (f_lat, f_lon) = c.omni_factors().unwrap();
        assert_eq!(
            (f_lat, f_lon, c.l_arc()),
            (&[1.01, 0.99, 1.0][..], 1.02, 0.0)
        );
        let e = |text: &str| read(text).unwrap_err().to_string();
        assert_eq!(
            e(r#"{"f_lat": [1, 1, 1]}"#),
            "c.json: no number f_lon: apply takes ..."
        );
        assert_eq!(
            e(r#"{"f_lat": [1, "x", 1], "f_lon": 1}"#),
            "c.json: no numeric array f_lat: apply takes ..."
        );
        assert_eq!(
            e(r#"{"f_lat": [1, 1, 1, 1, 1, 1, 1, 1, 1], "f_lon": 1}"#),
            "c.json: 9 f_lat factors; a board holds at most 8"
        );
        assert!(e(r#"{"f_lat": [1, 3, 1], "f_lon": 1}"#).starts_with("c.json: f_lat[1] = 3"));
    }

    /// `--previous` from `factors get --json` on a board with a turn law keeps the law
    /// (to the bit), and one the board would refuse is refused by name.
    #[test]
    fn a_previous_pass_keeps_its_turn_law() {
        let dir = std::env::temp_dir().join(format!("omni-prev-law-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let prev = dir.join("prev.json");
        std::fs::write(
            &prev,
            r#"{"kind": "omni", "f_lat": [1.01, 0.99, 1.0], "f_lon": 1.02, "l_arc": 0.019}"#,
        )
        .unwrap();
        let c = factors_from_json(&prev).unwrap();
        assert_eq!((c.l_arc(), c.omni_factors().unwrap().1), (0.019, 1.02));
        std::fs::write(&prev, r#"{"f_lat": [1, 1, 1], "f_lon": 1, "l_arc": 0.3}"#).unwrap();
        let e = factors_from_json(&prev).unwrap_err().to_string();
        assert!(e.contains("l_arc = 0.3 is outside [-0.1, 0.1]"), "{e}");
        std::fs::write(&prev, r#"{"f_lat": [1, 1, 1], "f_lon": 1, "l_arc": "x"}"#).unwrap();
        assert!(factors_from_json(&prev).is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn implausible_inputs_are_refused() {
        // 30 mm typed as 30 on a 0.6 m path: refused before any fit, with the hint.
        let text = "test,path,length_m,x_err_m,y_err_m\nomni,4W-1,0.6,-30,2\nomni,4W-1,0.6,-29,2\nomni,4W-2,0.6,-28,0\nomni,4W-2,0.6,-27,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = compute(&presets::omni4(), &runs, IdleWheels::Released)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("r.csv:2: radial end error") && e.contains("millimetres"),
            "{e}"
        );
        // 0.45 m short on 0.6 m passes the bounds but needs F_lon = 4: not recommended.
        let text =
            "test,path,length_m,x_err_m,y_err_m\nomni,4W-1,0.6,-0.45,0\nomni,4W-1,0.6,-0.45,0\nomni,4W-2,0.6,-0.45,0\nomni,4W-2,0.6,-0.45,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = compute(&presets::omni4(), &runs, IdleWheels::Released)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("f_lon = 4") && e.contains("not recommended"),
            "{e}"
        );
        // A previous pass with f_lon: -1 is refused, not composed.
        let dir = std::env::temp_dir().join(format!("omni-prev-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let prev = dir.join("prev.json");
        std::fs::write(&prev, r#"{"f_lat": [1, 1, 1, 1], "f_lon": -1}"#).unwrap();
        let e = factors_from_json(&prev).unwrap_err().to_string();
        assert!(e.contains("f_lon = -1 is outside [0.5, 2]"), "{e}");
        std::fs::write(&prev, r#"{"f_lat": [1, 1, 1.2, 1], "f_lon": 1.9}"#).unwrap();
        let first = factors_from_json(&prev).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // A composition past the board's range (1.9 / 0.9 = 2.11) is refused too.
        let text =
            "test,path,length_m,x_err_m,y_err_m\nomni,4W-1,0.6,-0.06,0\nomni,4W-1,0.6,-0.06,0\nomni,4W-2,0.6,-0.06,0\nomni,4W-2,0.6,-0.06,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let rep = compute(&presets::omni4(), &runs, IdleWheels::Released).unwrap();
        let e = compose_with(rep, &first).unwrap_err().to_string();
        assert!(
            e.contains("f_lon = 2.11") && e.contains("not recommended"),
            "{e}"
        );
    }

    #[test]
    fn unknown_path_is_named() {
        let text = "test,path,length_m,x_err_m,y_err_m\nomni,diag,0.6,0,0\nomni,diag,0.6,0,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = compute(&presets::omni4(), &runs, IdleWheels::Released)
            .unwrap_err()
            .to_string();
        assert!(e.contains("unknown omni path 'diag'"), "{e}");
    }
}
