//! Several recordings of one robot at once: the geometry is shared (fitted jointly by
//! [`calibrate`](mod@calibrate) as it fits by default, dead reckoning from each first
//! pose; each recording's start pose and clocks from its own aligned fit), then each
//! recording is diagnosed against that shared geometry for what is left. Every finding says which
//! recordings carry it: a finding present in only some recordings is reported as such,
//! not as a property of the robot.

use crate::{diagnose, Finding, Options};
use calib_core::robot::Robot;
use calibrate::{calibrate, CalOptions, CalibrateError, Calibration};
use formats::recording::Recording;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// One recording's part of a joint diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct RecordingResult {
    /// The recording's name.
    pub name: String,
    /// Rows in the recording.
    pub rows: usize,
    /// Ground RMSE with the nominal geometry, its start pose and clocks fitted, m.
    pub rmse_nominal_m: f64,
    /// Ground RMSE with the shared geometry, its start pose and clocks fitted, m.
    pub rmse_shared_geometry_m: f64,
    /// Diagnosis of what the shared geometry leaves in this recording.
    pub verdict: crate::Verdict,
    /// The effects found against the shared geometry.
    pub findings: Vec<Finding>,
    /// Ground RMSE with the shared geometry and those findings, m.
    pub rmse_final_m: f64,
    /// Geometry parameters this recording alone moves away from nominal (more than three
    /// of its own sigmas, and separable in it).
    pub geometry_evidence: Vec<String>,
}

/// The joint diagnosis.
#[derive(Debug, Clone, Serialize)]
pub struct MultiReport {
    /// The robot's name.
    pub robot: String,
    /// The shared geometry as `calibrate` fits it by default (dead reckoning from each
    /// recording's first pose), its identifiability, plausibility and cross-validation.
    pub geometry: Calibration,
    /// Each recording's diagnosis, in the order given.
    pub recordings: Vec<RecordingResult>,
    /// Finding id or geometry parameter -> recordings that carry it.
    pub carried_by: BTreeMap<String, Vec<String>>,
    /// Ground RMSE of all recordings together with the nominal geometry (each its start
    /// pose and clocks fitted; pose samples weighted alike), m.
    pub joint_rmse_nominal_m: f64,
    /// The same with the shared geometry, m.
    pub joint_rmse_shared_geometry_m: f64,
}

/// Diagnoses `recordings` of `robot` jointly.
pub fn diagnose_many(
    robot: &Robot,
    recordings: &[(String, Recording)],
    options: &Options,
) -> Result<MultiReport, CalibrateError> {
    // The shared geometry as `calibrate` fits it by default (dead reckoning from each
    // recording's first pose, cross-validated by run), so that the two commands agree.
    // Its cost follows the rows: the aligned fit of every recording at once (a start
    // pose and clocks per recording) holds a Jacobian of all rows by five columns per
    // recording, n^2 in memory (issue 52: 48 real recordings took 3.7 GB).
    let cal = calibrate(
        robot,
        recordings,
        None,
        &CalOptions {
            leave_one_out: recordings.len() >= 3,
            ..CalOptions::default()
        },
    )?;
    let mut carried_by: BTreeMap<String, Vec<String>> = BTreeMap::new();
    let mut out = Vec::new();
    let (mut sum_n, mut sum_before, mut sum_after) = (0.0, 0.0, 0.0);
    for (i, (name, rec)) in recordings.iter().enumerate() {
        // Its part of the joint fit (the first part when a pose jump split it).
        let part = format!("{name}{}", calibrate::PART_SEP);
        let per = cal
            .per_recording
            .iter()
            .find(|p| p.name == *name || p.name.starts_with(&part))
            .ok_or_else(|| CalibrateError {
                recording: Some(name.clone()),
                message: "the joint fit has no result for it".into(),
            })?;
        // Which geometry parameters this recording shows on its own, and its start pose
        // and clocks (aligned: one recording's Jacobian, linear in its rows).
        let own_opts = CalOptions {
            free_start: true,
            ..CalOptions::default()
        };
        let own = calibrate(robot, &recordings[i..=i], None, &own_opts)?;
        let Some(own_fit) = own.per_recording.first() else {
            return Err(CalibrateError {
                recording: Some(name.clone()),
                message: "its own fit has no result".into(),
            });
        };
        let geometry_evidence: Vec<String> = own
            .params
            .iter()
            .filter(|p| (p.value - p.spec.nominal).abs() > 3.0 * p.sigma)
            .filter(|p| !own.inseparable.involves(&p.spec.name))
            .map(|p| p.spec.name.clone())
            .collect();
        for g in &geometry_evidence {
            carried_by.entry(g.clone()).or_default().push(name.clone());
        }
        // Recording artefacts (late or fast pose clock) are removed before physics.
        let rec = &crate::recording_stage::on_encoder_clock(rec, &own_fit.nuisance);
        let rep = diagnose(&cal.fitted_robot, rec, options).map_err(|e| CalibrateError {
            recording: Some(name.clone()),
            message: e.to_string(),
        })?;
        for f in &rep.findings {
            // A finding outside its physical range is not evidence for the effect: it is
            // listed apart so the table does not count it as one.
            let implausible =
                f.implausible_sign || rep.implausible.iter().any(|i| i.effect == f.effect);
            let key = if implausible {
                format!("{} (implausible)", f.effect)
            } else {
                f.effect.clone()
            };
            carried_by.entry(key).or_default().push(name.clone());
        }
        let n = per.pose_samples as f64;
        sum_n += n;
        sum_before += n * per.aligned_before_m.powi(2);
        sum_after += n * per.aligned_after_m.powi(2);
        out.push(RecordingResult {
            name: name.clone(),
            rows: rec.len(),
            rmse_nominal_m: per.aligned_before_m,
            rmse_shared_geometry_m: per.aligned_after_m,
            verdict: rep.verdict.clone(),
            findings: rep.findings.clone(),
            rmse_final_m: rep.rmse.ground.after_m,
            geometry_evidence,
        });
    }
    Ok(MultiReport {
        robot: robot.name.to_string(),
        joint_rmse_nominal_m: (sum_before / sum_n).sqrt(),
        joint_rmse_shared_geometry_m: (sum_after / sum_n).sqrt(),
        geometry: cal,
        recordings: out,
        carried_by,
    })
}

impl fmt::Display for MultiReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.recordings.len();
        writeln!(
            f,
            "diagnose {}: {n} recordings jointly (geometry shared, as calibrate fits it; start pose and clocks per recording)",
            self.robot
        )?;
        writeln!(
            f,
            "joint ground RMSE: {:.2} mm nominal -> {:.2} mm with the shared geometry",
            self.joint_rmse_nominal_m * 1e3,
            self.joint_rmse_shared_geometry_m * 1e3
        )?;
        write!(f, "{}", self.geometry)?;
        writeln!(f, "per recording (against the shared geometry):")?;
        for r in &self.recordings {
            writeln!(
                f,
                "  {:<24} {:.2} -> {:.2} mm (shared geometry) -> {:.2} mm; verdict {}; findings {}",
                r.name,
                r.rmse_nominal_m * 1e3,
                r.rmse_shared_geometry_m * 1e3,
                r.rmse_final_m * 1e3,
                r.verdict,
                if r.findings.is_empty() {
                    "none".to_string()
                } else {
                    r.findings
                        .iter()
                        .map(|x| x.effect.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                }
            )?;
        }
        writeln!(f, "which recordings carry each finding:")?;
        for (k, v) in &self.carried_by {
            let all = if v.len() == n {
                "all".to_string()
            } else {
                format!("only {} of {n}", v.len())
            };
            writeln!(f, "  {k:<24} {all}: {}", v.join(", "))?;
        }
        Ok(())
    }
}
