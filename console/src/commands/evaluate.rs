//! `wheelcal evaluate`: how well robot files dead-reckon recordings they were not fitted
//! to. A thin shell over `calibrate::evaluate`: gathers the recordings as
//! `calibrate` does ([`crate::recordings`]), reads the calibrations judged on the board
//! ([`crate::calibration::saved`]), refuses robot files with other wheels, prints or
//! writes the table.

use crate::args::EvaluateArgs;
use crate::calibration::saved::SavedCalibration;
use crate::output::Output;
use crate::recordings::{load_all, refuse_mixed_robots};
use crate::tum::Stamped;
use anyhow::{anyhow, Result};
use calibrate::{evaluate, same_wheels, Candidate};
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
    // Name the file, not only the short name.
    let named =
        |e: calibrate::CalibrateError| match e.recording.as_deref().and_then(|r| got.file_of(r)) {
            Some(file) => anyhow!("{}: {}", file.display(), e.message),
            None => anyhow!("{e}"),
        };
    let ev = evaluate(&candidates, &got.recs).map_err(&named)?;
    if let Some(dir) = &a.tum {
        let mut files = Vec::new();
        for (name, rec) in &got.recs {
            let measured: Vec<Stamped> = rec
                .pose_rows()
                .map(|(k, x, y, th)| (rec.t[k], x, y, th))
                .collect();
            files.push((format!("{name}__measured"), measured));
            for (i, c) in candidates.iter().enumerate() {
                let stem = std::path::Path::new(&c.label)
                    .file_stem()
                    .map_or_else(|| c.label.clone(), |s| s.to_string_lossy().into_owned());
                let label = format!("{name}__{}_{stem}", i + 1);
                // The very replay evaluate judges: a board through its own odometry.
                files.push((label, c.dead_reckoned(name, rec).map_err(&named)?));
            }
        }
        for f in crate::tum::write_dir(dir, &files)? {
            out.note(&format!("TUM trajectory: {f}"));
        }
    }
    out.emit(&ev, || ev.to_string())
}
