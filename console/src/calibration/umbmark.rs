//! `wheelcal umbmark compute`: Borenstein's closed form and the exact-model fit, with the
//! statistics of [Measuring errors] (centroids, spreads, probability of ending within 3 cm),
//! and the circle test's turn law when the runs file has circle rows.

use super::circles::CircleReport;
use crate::output::PointM;
use anyhow::{bail, Context, Result};
use calib_core::robot::{Robot, RobotKind};
use calib_core::stats;
use calib_core::umbmark::{self, Run, UmbmarkResult};
use calibrate::BoardFactors;
use formats::runs_file::{Phase, RunsFile, UmbmarkRuns};
use serde::Serialize;
use std::fmt::Write;

/// Radius of [Measuring errors]'s convergence measure: probability of ending within 3 cm of the centroid.
pub const CONVERGENCE_RADIUS_M: f64 = 0.03;

/// Factors of one estimator.
#[derive(Debug, Clone, Serialize)]
pub struct Estimate {
    /// Wheel-diameter ratio E_d = D_R / D_L.
    pub ed: f64,
    /// Wheelbase ratio E_b = actual / nominal wheelbase.
    pub eb: f64,
    /// Left wheel radius multiplier c_L (mean diameter kept nominal).
    pub c_l: f64,
    /// Right wheel radius multiplier c_R (mean diameter kept nominal).
    pub c_r: f64,
    /// Corrected wheelbase E_b * nominal, m.
    pub wheelbase_m: f64,
    /// Type A error: under-rotation per nominal 90-degree turn, rad.
    pub alpha_rad: f64,
    /// Type B error: heading change along each straight leg, positive to the left, rad.
    pub beta_rad: f64,
}

impl From<&UmbmarkResult> for Estimate {
    fn from(r: &UmbmarkResult) -> Self {
        Estimate {
            ed: r.ed,
            eb: r.eb,
            c_l: r.c_l,
            c_r: r.c_r,
            wheelbase_m: r.wheelbase_m,
            alpha_rad: r.alpha_rad,
            beta_rad: r.beta_rad,
        }
    }
}

/// Statistics of one direction's runs.
#[derive(Debug, Clone, Serialize)]
pub struct DirectionStats {
    /// Number of runs in this direction.
    pub runs: usize,
    /// Centroid of the end errors (x, y), m.
    pub centroid: PointM,
    /// Distance of the centroid from the origin (r_c.g.), m.
    pub r_cg_m: f64,
    /// Sample standard deviation of the end errors in x and y, m.
    pub std_dev: PointM,
    /// Probability (normal model) of ending within 3 cm of the centroid.
    pub p_within_3cm: f64,
    /// The measured end errors themselves, for plots.
    pub points: Vec<PointM>,
}

/// The evaluation of one phase (before or after).
#[derive(Debug, Clone, Serialize)]
pub struct PhaseStats {
    /// Statistics of the clockwise runs.
    pub cw: DirectionStats,
    /// Statistics of the counter-clockwise runs.
    pub ccw: DirectionStats,
    /// E_max,sys = the larger of the two directions' r_c.g., m.
    pub e_max_sys_m: f64,
}

/// The result of `umbmark compute`.
#[derive(Debug, Clone, Serialize)]
pub struct UmbmarkReport {
    /// Robot name from the robot description.
    pub robot: String,
    /// Side of the square driven, m.
    pub side_m: f64,
    /// Nominal wheelbase from the robot description, m.
    pub wheelbase_nominal_m: f64,
    // The recommended (exact-model) estimate, at top level as formats.md's consumers expect.
    /// Wheel-diameter ratio E_d = D_R / D_L (exact-model fit).
    pub ed: f64,
    /// Wheelbase ratio E_b = actual / nominal (exact-model fit).
    pub eb: f64,
    /// Left wheel radius multiplier c_L (exact-model fit).
    pub c_l: f64,
    /// Right wheel radius multiplier c_R (exact-model fit).
    pub c_r: f64,
    /// Corrected wheelbase, m (exact-model fit).
    pub wheelbase_m: f64,
    /// Type A error per 90-degree turn, rad (exact-model fit).
    pub alpha_rad: f64,
    /// Type B error per straight leg, rad (exact-model fit).
    pub beta_rad: f64,
    /// E_max,sys of the runs the factors were computed from, m.
    pub e_max_sys_m: f64,
    /// Centroid of the clockwise end errors, m.
    pub centroid_cw: PointM,
    /// Centroid of the counter-clockwise end errors, m.
    pub centroid_ccw: PointM,
    /// r_c.g. of the clockwise runs, m.
    pub r_cg_cw_m: f64,
    /// r_c.g. of the counter-clockwise runs, m.
    pub r_cg_ccw_m: f64,
    /// Which estimator the top-level factors come from (always "exact").
    pub recommended: &'static str,
    /// Borenstein's closed-form estimate ([Measuring errors]), for comparison.
    pub closed_form: Estimate,
    /// The exact-model fit's estimate (the recommended one).
    pub exact: Estimate,
    /// RMS of the exact fit's four centroid residuals, m.
    pub exact_fit_residual_m: f64,
    /// Statistics of the `before` runs.
    pub before: PhaseStats,
    /// Present when the runs file has `after` rows.
    pub after: Option<PhaseStats>,
    /// E_max,sys of the `before` runs, m.
    pub e_max_sys_before_m: f64,
    /// E_max,sys of the `after` runs, m, when there are any.
    pub e_max_sys_after_m: Option<f64>,
    /// E_max,sys before / after ([Measuring errors] Table 1's "improvement").
    pub improvement: Option<f64>,
    /// [Measuring errors] eq. 19: (before - after) / before.
    pub p_e: Option<f64>,
    /// The circle test, when the runs file has circle rows: the turn law.
    pub circles: Option<CircleReport>,
    /// With a kept turn law, the board's factors and law as calibrate's JSON gives them
    /// (`factors.board`), so `factors export --ros2 --from` names the law.
    pub factors: Option<BoardSection>,
}

/// The board's factors with a law.
#[derive(Debug, Clone, Serialize)]
pub struct BoardSection {
    /// c_L, c_R, E_b in a turn in place, and the law.
    pub board: BoardFactors,
}

fn runs_of(v: &[(f64, f64)]) -> Vec<Run> {
    v.iter()
        .map(|&(x, y)| Run {
            x_err_m: x,
            y_err_m: y,
        })
        .collect()
}

fn direction_stats(runs: &[(f64, f64)]) -> Result<DirectionStats> {
    let r = runs_of(runs);
    let c = umbmark::centroid(&r)?;
    let sx = stats::sample_std_dev_by(&r, |p| p.x_err_m)?;
    let sy = stats::sample_std_dev_by(&r, |p| p.y_err_m)?;
    // A zero spread (identical runs) means every run is at the centroid.
    let p = if sx > 0.0 && sy > 0.0 {
        stats::probability_within_radius(sx, sy, CONVERGENCE_RADIUS_M).unwrap_or(f64::NAN)
    } else {
        1.0
    };
    Ok(DirectionStats {
        runs: r.len(),
        centroid: c.into(),
        r_cg_m: umbmark::r_cg(c),
        std_dev: PointM { x_m: sx, y_m: sy },
        p_within_3cm: p,
        points: runs.iter().map(|&p| p.into()).collect(),
    })
}

fn phase_stats(u: &UmbmarkRuns) -> Result<PhaseStats> {
    let cw = direction_stats(&u.cw)?;
    let ccw = direction_stats(&u.ccw)?;
    let e = cw.r_cg_m.max(ccw.r_cg_m);
    Ok(PhaseStats {
        cw,
        ccw,
        e_max_sys_m: e,
    })
}

/// Nominal wheel separation of a differential drive.
pub fn nominal_wheelbase(robot: &Robot) -> f64 {
    robot.wheels.iter().map(|w| w.l_m).sum()
}

/// Computes the UMBmark factors from a runs file (sides up to the default length limit).
pub fn compute(robot: &Robot, runs: &RunsFile) -> Result<UmbmarkReport> {
    compute_limited(robot, runs, super::plausible::DEFAULT_MAX_LENGTH_M)
}

/// Computes the UMBmark factors from a runs file whose rows are first checked against
/// physical bounds (sides up to `max_length_m`); factors the board would refuse are an
/// error, never a recommendation.
pub fn compute_limited(robot: &Robot, runs: &RunsFile, max_length_m: f64) -> Result<UmbmarkReport> {
    super::plausible::check_runs(runs, max_length_m)?;
    let rep = compute_unchecked(robot, runs)?;
    super::plausible::check_factors(
        runs,
        &[
            ("c_l", None, rep.c_l),
            ("c_r", None, rep.c_r),
            ("e_b", None, rep.eb),
        ],
    )?;
    Ok(rep)
}

fn compute_unchecked(robot: &Robot, runs: &RunsFile) -> Result<UmbmarkReport> {
    if robot.kind == RobotKind::SkidSteer {
        bail!(
            "UMBmark's closed form assumes errors of a few per cent; robot '{}' is skid_steer, whose effective separation is 1.5-2 times its track: use `wheelcal calibrate` on recordings with poses",
            robot.name
        );
    }
    if robot.kind != RobotKind::DiffDrive {
        bail!(
            "UMBmark calibrates differential drives; robot '{}' is {} (use `wheelcal omni compute` for omni robots)",
            robot.name,
            robot.kind.as_str()
        );
    }
    let before = runs.umbmark(Phase::Before)?.with_context(|| {
        let circles = if runs.circles(Phase::Before).is_empty() {
            ""
        } else {
            "; the circle rows need them beside them: the circle test measures the arcs against the squares' E_b"
        };
        format!(
            "{}: no UMBmark 'before' runs (rows with test = umbmark){circles}",
            runs.path.display()
        )
    })?;
    let b = nominal_wheelbase(robot);
    let (cw, ccw) = (runs_of(&before.cw), runs_of(&before.ccw));
    let closed = umbmark::closed_form(&cw, &ccw, before.side_m, b)
        .map_err(|e| anyhow::anyhow!("{}: {e}", runs.path.display()))?;
    let fit = umbmark::exact_fit(&cw, &ccw, before.side_m, b)
        .map_err(|e| anyhow::anyhow!("{}: {e}", runs.path.display()))?;
    let r = &fit.result;
    let before_stats = phase_stats(&before)?;
    let after = runs.umbmark(Phase::After)?;
    if let Some(a) = &after {
        if (a.side_m - before.side_m).abs() > 1e-9 {
            bail!(
                "{}: 'after' runs use a {} m square, 'before' runs {} m: compare like with like",
                runs.path.display(),
                a.side_m,
                before.side_m
            );
        }
    }
    let after_stats = after.as_ref().map(phase_stats).transpose()?;
    let xs = |v: &[(f64, f64)]| v.iter().map(|p| p.0).collect::<Vec<_>>();
    let circles = super::circles::compute(
        runs,
        (&xs(&before.cw), &xs(&before.ccw)),
        before.side_m,
        r.eb,
        b,
    )?;
    let factors = circles
        .as_ref()
        .and_then(|c| c.board(r.c_l, r.c_r, r.eb))
        .map(|board| BoardSection { board });
    let e_before = before_stats.e_max_sys_m;
    let e_after = after_stats.as_ref().map(|a| a.e_max_sys_m);
    Ok(UmbmarkReport {
        robot: robot.name.to_string(),
        side_m: before.side_m,
        wheelbase_nominal_m: b,
        ed: r.ed,
        eb: r.eb,
        c_l: r.c_l,
        c_r: r.c_r,
        wheelbase_m: r.wheelbase_m,
        alpha_rad: r.alpha_rad,
        beta_rad: r.beta_rad,
        e_max_sys_m: r.e_max_sys_m,
        centroid_cw: r.centroid_cw_m.into(),
        centroid_ccw: r.centroid_ccw_m.into(),
        r_cg_cw_m: r.r_cg_cw_m,
        r_cg_ccw_m: r.r_cg_ccw_m,
        recommended: "exact",
        closed_form: (&closed).into(),
        exact: r.into(),
        exact_fit_residual_m: fit.residual_rms_m,
        before: before_stats,
        after: after_stats,
        e_max_sys_before_m: e_before,
        e_max_sys_after_m: e_after,
        improvement: e_after.map(|a| e_before / a),
        p_e: e_after.and_then(|a| stats::error_decrease_pe(e_before, a).ok()),
        circles,
        factors,
    })
}

impl UmbmarkReport {
    /// The human summary.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "UMBmark: robot {}, {} m square, nominal wheelbase {:.4} m",
            self.robot, self.side_m, self.wheelbase_nominal_m
        );
        let d = |s: &mut String, name: &str, st: &DirectionStats| {
            let _ = writeln!(
                s,
                "  {name:>3}: {} runs, centroid ({:+.4}, {:+.4}) m, r_cg {:.4} m, sd ({:.4}, {:.4}) m, P(within 3 cm) {:.3}",
                st.runs, st.centroid.x_m, st.centroid.y_m, st.r_cg_m, st.std_dev.x_m, st.std_dev.y_m, st.p_within_3cm
            );
        };
        d(&mut s, "cw", &self.before.cw);
        d(&mut s, "ccw", &self.before.ccw);
        let _ = writeln!(s, "  E_max,sys = {:.4} m", self.e_max_sys_before_m);
        let _ = writeln!(
            s,
            "\n                 {:>10} {:>10} {:>10} {:>10} {:>12} {:>11} {:>11}",
            "E_d", "E_b", "c_L", "c_R", "wheelbase m", "alpha rad", "beta rad"
        );
        for (name, e) in [
            ("closed form", &self.closed_form),
            ("exact (use)", &self.exact),
        ] {
            let _ = writeln!(
                s,
                "  {name:<14} {:>10.6} {:>10.6} {:>10.6} {:>10.6} {:>12.5} {:>11.6} {:>11.6}",
                e.ed, e.eb, e.c_l, e.c_r, e.wheelbase_m, e.alpha_rad, e.beta_rad
            );
        }
        let _ = writeln!(s, "  exact-model fit residual {:.2e} m; recommended: exact (Borenstein's closed form drifts when E_b is off by a few percent)", self.exact_fit_residual_m);
        if let (Some(a), Some(ea), Some(imp)) =
            (&self.after, self.e_max_sys_after_m, self.improvement)
        {
            let _ = writeln!(s, "\nAfter calibration:");
            d(&mut s, "cw", &a.cw);
            d(&mut s, "ccw", &a.ccw);
            let _ = writeln!(
                s,
                "  E_max,sys before {:.4} m, after {:.4} m: improvement {:.1}x (P_e = {:.1} %)",
                self.e_max_sys_before_m,
                ea,
                imp,
                self.p_e.unwrap_or(f64::NAN) * 100.0
            );
        }
        if let Some(c) = &self.circles {
            s.push_str(&c.human(self.ed, self.factors.as_ref().map(|f| &f.board)));
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
    fn millimetre_errors_are_not_recommended() {
        // End errors of 5-10 mm typed as millimetres into the metre columns: 10 m off on
        // a 4 m side (their fit gave E_b 0.90 with a 4 m fit residual, "recommended").
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m\n");
        for (d, x, y) in [("cw", 8.0, -5.0), ("ccw", -6.0, 7.0)] {
            for k in 0..3 {
                text.push_str(&format!("umbmark,{d},4,{},{y}\n", x + k as f64));
            }
        }
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        let e = compute(&presets::mobolab(), &runs).unwrap_err().to_string();
        assert!(e.starts_with("r.csv:2: radial end error"), "{e}");
        assert!(
            e.contains("larger than the 4 m side") && e.contains("millimetres"),
            "{e}"
        );
        // 1e300 in a cell: refused with a sane number, not `inf mm`.
        let text = "test,path,length_m,x_err_m,y_err_m\numbmark,cw,4,1e300,0\n";
        let runs = RunsFile::parse(text, Path::new("r.csv")).unwrap();
        let e = compute(&presets::mobolab(), &runs).unwrap_err().to_string();
        assert!(
            e.contains("1.000e300 m is larger than") && !e.contains("inf"),
            "{e}"
        );
    }

    #[test]
    fn computes_from_synthetic_runs() {
        // Runs generated by the exact model with E_d = 1.01, E_b = 1.04 on MoboLab (b = 0.4 m),
        // 4 m square, +-2 mm of alternating scatter: the fit must return the truth within
        // what 2 mm over 4 m allows (~1e-3 relative).
        let robot = presets::mobolab();
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m\n");
        for (dir, name) in [
            (umbmark::Direction::Cw, "cw"),
            (umbmark::Direction::Ccw, "ccw"),
        ] {
            let (x, y, _) = umbmark::square_end_error(1.01, 1.04, 4.0, 0.4, dir).unwrap();
            for k in 0..5 {
                let n = if k % 2 == 0 { 0.002 } else { -0.002 };
                let n = if k == 4 { 0.0 } else { n };
                text.push_str(&format!("umbmark,{name},4,{},{}\n", x + n, y - n));
            }
        }
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        let rep = compute(&robot, &runs).unwrap();
        assert!(
            (rep.ed - 1.01).abs() < 1e-3 && (rep.eb - 1.04).abs() < 1e-3,
            "{} {}",
            rep.ed,
            rep.eb
        );
        assert!((rep.closed_form.eb - 1.04).abs() > (rep.eb - 1.04).abs());
        assert!((rep.c_l - 2.0 / (rep.ed + 1.0)).abs() < 1e-12);
        assert!(rep.after.is_none() && rep.improvement.is_none());
        let json = serde_json::to_value(&rep).unwrap();
        for key in [
            "ed",
            "eb",
            "c_l",
            "c_r",
            "wheelbase_m",
            "alpha_rad",
            "beta_rad",
            "e_max_sys_m",
        ] {
            assert!(json[key].is_f64(), "{key}");
        }
        assert!(json["closed_form"]["ed"].is_f64() && json["centroid_ccw"]["y_m"].is_f64());
    }

    #[test]
    fn refuses_omni_robots() {
        let runs =
            RunsFile::parse("test,path,length_m,x_err_m,y_err_m\n", Path::new("r.csv")).unwrap();
        let e = compute(&presets::omni4(), &runs).unwrap_err();
        assert!(e.to_string().contains("omni compute"));
    }
}
