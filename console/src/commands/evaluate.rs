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
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{integrate_arc, Pose};
use calib_core::robot::RobotKind;
use calibrate::{evaluate, same_wheels, Candidate};
use formats::recording::Recording;
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
                match dead_reckoning(c, rec) {
                    Some(p) => files.push((label, p)),
                    None => out.note(&format!(
                        "--tum: [{}] {} on {name}: not written ({})",
                        i + 1,
                        c.label,
                        if c.board.is_some() {
                            "a board's factors and laws are replayed by evaluate only"
                        } else {
                            "its wheels have legs or sides, whose replay evaluate keeps to itself"
                        }
                    )),
                }
            }
        }
        for f in crate::tum::write_dir(dir, &files)? {
            out.note(&format!("TUM trajectory: {f}"));
        }
    }
    out.emit(&ev, || ev.to_string())
}

/// A robot file's dead reckoning of `rec` at its pose rows, started at its first measured
/// pose: the encoder counts (missing cells carry the last count) as wheel angles, each
/// row's increment through the robot's forward kinematics, integrated as an arc
/// (calib-core's odometry). This is how `evaluate` replays a robot file (bar its mending
/// of encoder glitches and pose jumps, which it reports as events). `None` for a board's
/// calibration, a wheeled-legged or a skid-steer robot (their replay is evaluate's own),
/// and for a recording without encoders or poses.
pub fn dead_reckoning(c: &Candidate, rec: &Recording) -> Option<Vec<Stamped>> {
    if c.board.is_some()
        || matches!(
            c.robot.kind,
            RobotKind::WheeledLegged | RobotKind::SkidSteer
        )
    {
        return None;
    }
    let rpc = c.robot.drive.rad_per_count()?;
    let kin = Kinematics::<f64>::new(&c.robot, &Corrections::None).ok()?;
    let n = c.robot.wheels.len();
    if rec.wheels.len() != n {
        return None;
    }
    // Counts per wheel, missing cells carrying the last (the first known before it).
    let mut counts: Vec<Vec<i64>> = Vec::with_capacity(n);
    for w in &rec.wheels {
        counts.push(fitkit::series::fill(w.enc.as_ref()?)?);
    }
    let mut rows = rec.pose_rows().peekable();
    let &(k0, x0, y0, th0) = rows.peek()?;
    let mut pose = Pose::new(x0, y0, th0);
    let mut out = Vec::new();
    let mut inc = vec![0.0; n];
    let mut k = k0;
    for (row, ..) in rows {
        while k < row {
            for (w, c) in counts.iter().enumerate() {
                inc[w] = (c[k + 1] as f64 - c[k] as f64) * rpc;
            }
            pose = integrate_arc(pose, &kin.forward(&inc));
            k += 1;
        }
        out.push((rec.t[row], pose.x, pose.y, pose.theta));
    }
    Some(out)
}
