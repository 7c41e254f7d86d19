//! The diagnosis as data: serialised for `--json` (formats.md §4 field names), printed
//! as a human summary, and applied to a robot file for `--write-robot`.

use crate::effects::{Model, Stage};
use crate::finding::{Finding, Verdict};
use crate::residuals::Noise;
use crate::select::Candidate;
use crate::windows::Window;
use calib_core::robot::Robot;
use calibrate::Inseparables;
use serde::ser::SerializeMap;
use serde::{Serialize, Serializer};
use std::fmt;
use std::path::Path;

/// RMSE of one stage before and after the findings.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct StageRmse {
    /// RMSE of the nominal model, m.
    pub before_m: f64,
    /// RMSE of the final model (nominal plus the findings), m.
    pub after_m: f64,
}

/// Both stages' RMSE before and after, stored once. The JSON gives them as objects
/// (`ground_rmse`, `actuator_rmse`) and, as it always has, flat (`rmse_nominal_m`,
/// `rmse_final_m`, `actuator_rmse_nominal_m`, `actuator_rmse_final_m`).
#[derive(Debug, Clone, Copy)]
pub struct Rmses {
    /// The ground stage: position error at the pose samples.
    pub ground: StageRmse,
    /// The actuator stage (only with commands and encoders): wheel-surface error.
    pub actuator: Option<StageRmse>,
}

impl Serialize for Rmses {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(6))?;
        m.serialize_entry("rmse_nominal_m", &self.ground.before_m)?;
        m.serialize_entry("rmse_final_m", &self.ground.after_m)?;
        m.serialize_entry(
            "actuator_rmse_nominal_m",
            &self.actuator.map(|a| a.before_m),
        )?;
        m.serialize_entry("actuator_rmse_final_m", &self.actuator.map(|a| a.after_m))?;
        m.serialize_entry("ground_rmse", &self.ground)?;
        m.serialize_entry("actuator_rmse", &self.actuator)?;
        m.end()
    }
}

/// Geometry pairs the recording cannot separate (from the whole-geometry fit of its
/// recording stage). The JSON gives the pairs (`not_separable`) and, for each, what
/// would separate them (`separation_advice`: `a / b: advice`).
#[derive(Debug, Clone, Default)]
pub struct Separability(pub Inseparables);

impl Serialize for Separability {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let advice: Vec<String> = self.0.advice().collect();
        let mut m = s.serialize_map(Some(2))?;
        m.serialize_entry("not_separable", &self.0.pairs())?;
        m.serialize_entry("separation_advice", &advice)?;
        m.end()
    }
}

/// Series kept for plots (not serialised).
#[derive(Debug, Clone, Default)]
pub struct PlotData {
    /// Time of each pose sample, s.
    pub pose_t: Vec<f64>,
    /// Measured (x, y) per pose sample, m.
    pub measured: Vec<(f64, f64)>,
    /// The nominal model's (x, y) at the pose samples, its start pose fitted, m.
    pub nominal: Vec<(f64, f64)>,
    /// The final model's (x, y) at the pose samples, its start pose fitted, m.
    pub fitted: Vec<(f64, f64)>,
    /// The nominal model's position error per pose sample, m.
    pub err_nominal: Vec<f64>,
    /// The final model's position error per pose sample, m.
    pub err_fitted: Vec<f64>,
    /// The nominal model's heading error (measured - predicted) per pose sample, rad.
    pub heading_nominal: Vec<f64>,
    /// The final model's heading error (measured - predicted) per pose sample, rad.
    pub heading_fitted: Vec<f64>,
    /// Time of each row compared in the actuator stage, s.
    pub act_t: Vec<f64>,
    /// (wheel name, nominal error, fitted error) in m.
    pub act: Vec<(String, Vec<f64>, Vec<f64>)>,
}

/// The whole diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The robot's name.
    pub robot: String,
    /// Rows in the recording.
    pub rows: usize,
    /// Rows with a measured pose.
    pub pose_samples: usize,
    /// Time from the first to the last row, s.
    pub duration_s: f64,
    /// A catalogue id, `none` or `unexplained`.
    pub verdict: Verdict,
    /// How far the verdict's family explains the excess: `full`, or `partial` when what
    /// is left is still far outside the noise (`depends_on` says what it follows);
    /// `null` for `none` and `unexplained`.
    pub fit: Option<crate::finding::Fit>,
    /// The effects found, the one explaining the largest share of the excess first.
    pub findings: Vec<Finding>,
    /// Where the residual leaves the noise band.
    pub windows: Vec<Window>,
    /// Heading RMSE of the nominal model, rad.
    pub heading_rmse_nominal_rad: f64,
    /// Heading RMSE of the final model, rad.
    pub heading_rmse_final_rad: f64,
    /// Noise levels estimated from the data.
    pub noise: Noise,
    /// Fraction of the residual beyond the noise that the findings explain (0..1).
    pub explained_fraction: f64,
    /// The stage on which the verdict's improvement is measured: the
    /// verdict's evidence stage; `rmse_nominal_m`/`rmse_final_m` are the ground stage's.
    pub rmse_stage: Stage,
    /// Both stages' RMSE before and after.
    #[serde(flatten)]
    pub rmse: Rmses,
    /// Estimated start pose (x, y, theta) of the final model.
    pub start_pose: [f64; 3],
    /// Every effect tried, for transparency.
    pub candidates: Vec<Candidate>,
    /// Remarks for the reader (missing encoders or commands, inseparable geometry...).
    pub notes: Vec<String>,
    /// How many times each stage's model was run (cost of the diagnosis).
    pub model_runs_ground: usize,
    /// How many times the actuator stage's model was run.
    pub model_runs_actuator: usize,
    /// The final model: the nominal one plus the effects the selection accepted.
    #[serde(skip)]
    pub model: Model,
    /// Series for the plots.
    #[serde(skip)]
    pub plot: PlotData,
    /// The recording stage: logging artefacts (not physics), removed before the physics
    /// was judged.
    pub recording_artefacts: Vec<crate::recording_stage::Artefact>,
    /// Findings whose parameters leave their physical range (never the verdict).
    pub implausible: Vec<crate::plausibility::Implausible>,
    /// Geometry parameter pairs this recording cannot separate, and what would.
    #[serde(flatten)]
    pub separability: Separability,
    /// Identification of the nominal model's residual: the terms of the
    /// physical regressor library that survive sparse selection on held-out blocks.
    pub identification: Vec<crate::identify::Term>,
    /// What the residual left after the findings depends on, in words (or, when nothing
    /// explains it, what the nominal residual depends on): better than `unexplained`.
    pub depends_on: Vec<String>,
    /// Windows found (merged) before the list was bounded to the strongest
    /// (`windows::MAX_LISTED`).
    pub windows_total: usize,
}

impl Report {
    /// The JSON object for `--json`.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}"))
    }

    /// The robot with the fitted geometry (radii, wheel distances) applied.
    pub fn fitted_robot(&self, robot: &Robot) -> Robot {
        self.model.apply_geometry(robot)
    }
}

/// Writes `robot` with the report's fitted geometry applied as formats.md §1 TOML.
pub fn write_robot(robot: &Robot, report: &Report, out: &Path) -> std::io::Result<()> {
    let fitted = report.fitted_robot(robot);
    let mut text = format!(
        "# {} with geometry fitted by wheelcal diagnose (verdict: {})\n",
        robot.name, report.verdict
    );
    text.push_str(&formats::robot_file::to_toml(&fitted));
    formats::robot_file::write(out, &text)
}

fn fmt_param(v: f64, s: Option<f64>) -> String {
    match s {
        Some(s) if s.is_finite() => format!("{v:.6} ± {s:.2e}"),
        _ => format!("{v:.6} (unconstrained)"),
    }
}

impl fmt::Display for Report {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "diagnose {}: {} rows, {} pose samples, {:.1} s",
            self.robot, self.rows, self.pose_samples, self.duration_s
        )?;
        match self.fit {
            Some(crate::finding::Fit::Partial) => writeln!(
                f,
                "verdict: {} (partial: it explains {:.0} % of the excess; what is left is below)",
                self.verdict,
                self.explained_fraction * 100.0
            )?,
            _ => writeln!(f, "verdict: {}", self.verdict)?,
        }
        let lead = if self.fit == Some(crate::finding::Fit::Partial) {
            "what is left depends on"
        } else {
            "depends on"
        };
        for d in &self.depends_on {
            writeln!(f, "{lead}: {d}")?;
        }
        for a in self.separability.0.advice() {
            writeln!(f, "not separable: {a}")?;
        }
        for i in &self.implausible {
            writeln!(
                f,
                "implausible: {} {} = {:.5} outside {:.4}..{:.4}, most likely stands in for {}",
                i.effect, i.parameter, i.value, i.plausible.0, i.plausible.1, i.stands_for
            )?;
        }
        if !self.recording_artefacts.is_empty() {
            writeln!(
                f,
                "recording artefacts (how the run was logged, not physics):"
            )?;
            for a in &self.recording_artefacts {
                writeln!(f, "  {a}")?;
            }
        }
        writeln!(
            f,
            "ground RMSE: {:.2} mm nominal -> {:.2} mm fitted (noise {:.2} mm, {:.4} rad)",
            self.rmse.ground.before_m * 1e3,
            self.rmse.ground.after_m * 1e3,
            self.noise.pose_sigma_m * 1e3,
            self.noise.heading_sigma_rad
        )?;
        if let Some(a) = self.rmse.actuator {
            writeln!(
                f,
                "actuator RMSE: {:.3} mm nominal -> {:.3} mm fitted (noise {:.3} mm)",
                a.before_m * 1e3,
                a.after_m * 1e3,
                self.noise.actuator_sigma_m * 1e3
            )?;
        }
        if self.findings.is_empty() {
            writeln!(f, "findings: none")?;
        }
        for (i, x) in self.findings.iter().enumerate() {
            writeln!(
                f,
                "{}. {} by {} ({} stage, {:.0} % of the excess, {} fit{}): RMSE {:.3} -> {:.3} mm, dBIC {:.0}, held-out ratio {:.3}",
                i + 1,
                x.effect,
                x.mechanism,
                x.stage,
                x.explained_share * 100.0,
                x.fit,
                if x.implausible_sign { ", implausible sign" } else { "" },
                x.rmse_before_m * 1e3,
                x.rmse_after_m * 1e3,
                x.delta_bic,
                x.heldout_ratio
            )?;
            for (name, v) in &x.parameters {
                let s = x.uncertainties.get(name).copied().flatten();
                writeln!(f, "     {name} = {}", fmt_param(*v, s))?;
            }
            if let Some(sig) = &x.signature {
                writeln!(f, "     signature: {sig}")?;
            }
        }
        writeln!(
            f,
            "windows: {} ({} listed)",
            self.windows_total,
            self.windows.len()
        )?;
        for w in self.windows.iter().take(20) {
            writeln!(
                f,
                "  {:8.2} .. {:8.2} s  {:8} {:12} {:12} {:5.1} sigma{}{}",
                w.t_start_s,
                w.t_end_s,
                w.stage.as_str(),
                w.axis.as_str(),
                w.wheel.as_deref().unwrap_or("-"),
                w.peak_sigma,
                if w.explained_by_fit {
                    ", explained"
                } else {
                    ""
                },
                w.related_signal
                    .as_deref()
                    .map(|s| format!(", with high {s}"))
                    .unwrap_or_default()
            )?;
        }
        if self.windows.len() > 20 {
            writeln!(f, "  ... {} more", self.windows.len() - 20)?;
        }
        for n in &self.notes {
            writeln!(f, "note: {n}")?;
        }
        Ok(())
    }
}
