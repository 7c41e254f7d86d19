//! `wheelcal evaluate`: how well robot files dead-reckon recordings they were not fitted
//! to. A thin shell over `diagnose::calibrate::evaluate`: gathers the recordings as
//! `calibrate` does ([`crate::recordings`]), reads the calibrations judged on the board
//! ([`crate::calibration::saved`]), refuses robot files with other wheels, prints or
//! writes the table.

use crate::args::EvaluateArgs;
use crate::calibration::saved::SavedCalibration;
use crate::output::Output;
use crate::recordings::{load_all, refuse_mixed_robots};
use anyhow::{anyhow, bail, Result};
use calib_core::correction::Corrections;
use diagnose::calibrate::{evaluate, same_wheels, Candidate};
use formats::robot_file;

/// Runs `wheelcal evaluate`.
pub fn run(a: &EvaluateArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    // Every calibration and robot file is checked before any recording is read.
    let mut candidates = Vec::new();
    for p in &a.board {
        let saved = SavedCalibration::read(p, &robot, "--board")?;
        let factors = saved.board_corrections()?;
        // The factors correct the robot they were fitted from; on the robot file the
        // calibration wrote they would apply twice.
        if !factors_are_one(&factors) && saved.is_fitted_robot(&robot) {
            bail!(
                "{}: --robot {} has this calibration's fitted geometry (the robot file it wrote): --board applies the calibration's factors to the robot it was fitted from, so they would count twice; give that robot (the nominal) as --robot, and the fitted file as --against",
                saved.file.display(),
                a.robot.display()
            );
        }
        factors.validate(&robot).map_err(|e| {
            anyhow!(
                "{}: a board with --robot {} refuses its factors: {e}",
                saved.file.display(),
                a.robot.display()
            )
        })?;
        let lost = saved.without_factor();
        let lost = if lost.is_empty() {
            String::new()
        } else {
            format!(
                " (no firmware factor for {}: the board's odometry goes without)",
                lost.join(", ")
            )
        };
        candidates.push(Candidate::board(
            format!("{} on the board{lost}", saved.file.display()),
            robot.clone(),
            factors,
        ));
    }
    candidates.push(Candidate::file(
        a.robot.display().to_string(),
        robot.clone(),
    ));
    for p in &a.against {
        let other = robot_file::load(p)?;
        same_wheels(&robot, &other).map_err(|m| {
            anyhow!(
                "{}: cannot be compared with --robot {}: {m}",
                p.display(),
                a.robot.display()
            )
        })?;
        candidates.push(Candidate::file(p.display().to_string(), other));
    }
    let got = load_all(&a.recording, &robot, &a.robot, &a.bag, out)?;
    refuse_mixed_robots(&robot, &got.by_file())?;
    let ev = evaluate(&candidates, &got.recs).map_err(|e| {
        // Name the file, not only the short name.
        match e.recording.as_deref().and_then(|r| got.file_of(r)) {
            Some(file) => anyhow!("{}: {}", file.display(), e.message),
            None => anyhow!("{e}"),
        }
    })?;
    out.emit(&ev, || ev.to_string())
}

/// Factors that change nothing (all 1, no law): on them the nominal and the fitted robot
/// are the same.
fn factors_are_one(c: &Corrections) -> bool {
    match c {
        Corrections::None => true,
        Corrections::DiffDrive { c_l, c_r, e_b } => [c_l, c_r, e_b].iter().all(|v| **v == 1.0),
        Corrections::Omni { f_lat, f_lon } => *f_lon == 1.0 && f_lat.iter().all(|v| *v == 1.0),
        _ => false,
    }
}
