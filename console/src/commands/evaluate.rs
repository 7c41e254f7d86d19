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
        // The factors correct the robot they were fitted from: on the robot file the
        // calibration wrote, any that change the geometry would count twice.
        if saved.is_fitted_robot(&robot) && !saved.is_fitted_robot(&factors.apply_to(&robot)) {
            bail!(
                "{}: --robot {} has this calibration's fitted geometry (the robot file it wrote): --board applies the calibration's factors to the robot it was fitted from, so they would count twice; give that robot (the nominal) as --robot, and the fitted file as --against",
                saved.file.display(),
                a.robot.display()
            );
        }
        let lost = saved.without_factor();
        let lost = if lost.is_empty() {
            String::new()
        } else {
            format!(
                " (no firmware factor for {}: the board's odometry goes without)",
                lost.join(", ")
            )
        };
        let board = Candidate::board(
            format!("{} on the board{lost}", saved.file.display()),
            robot.clone(),
            factors,
        );
        board
            .check()
            .map_err(|e| anyhow!("{e} (--robot {})", a.robot.display()))?;
        candidates.push(board);
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
