//! `wheelcal evaluate`: how well robot files dead-reckon recordings they were not fitted
//! to. A thin shell over `diagnose::calibrate::evaluate`: gathers the recordings as
//! `calibrate` does ([`crate::recordings`]), reads the calibrations judged on the board
//! ([`crate::calibration::saved`]), refuses robot files with other wheels, prints or
//! writes the table.

use crate::args::EvaluateArgs;
use crate::calibration::saved::SavedCalibration;
use crate::output::Output;
use crate::recordings::{load_all, refuse_mixed_robots};
use anyhow::{anyhow, Result};
use diagnose::calibrate::{evaluate, same_wheels, Candidate};
use formats::robot_file;

/// Runs `wheelcal evaluate`.
pub fn run(a: &EvaluateArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    // Every calibration and robot file is checked before any recording is read.
    let mut candidates = Vec::new();
    let board_robot = match &a.board_robot {
        Some(p) => {
            let geometry = robot_file::load(p)?;
            same_wheels(&robot, &geometry).map_err(|m| {
                anyhow!(
                    "{}: cannot be the board's robot for --robot {}: {m}",
                    p.display(),
                    a.robot.display()
                )
            })?;
            Some((geometry, p))
        }
        None => None,
    };
    for p in &a.board {
        let saved = SavedCalibration::read(p, &robot, "--board")?;
        candidates.push(match &board_robot {
            Some((geometry, file)) => saved.laws_candidate(geometry, file)?,
            None => saved.board_candidate(&robot, &a.robot)?,
        });
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
