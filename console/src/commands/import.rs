//! `wheelcal import ros2`: a ROS 2 bag to a formats.md recording folder (the work is in
//! the `ros2bag` crate; this only reads the flags and writes the files).

use crate::args::{ImportCmd, Ros2Args};
use crate::output::Output;
use anyhow::{bail, Context, Result};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// What `import ros2` wrote (its `--json`).
#[derive(Debug, Serialize)]
pub struct ImportReport {
    /// The recording written.
    pub recording: PathBuf,
    /// Rows (joint samples).
    pub rows: usize,
    /// Rows with an interpolated pose.
    pub rows_with_pose: usize,
    /// Pose samples read.
    pub pose_samples: usize,
    /// Joint names, in the robot's wheel order.
    pub joints: Vec<String>,
    /// The frame the poses were in (the recording is in the robot's start frame).
    pub pose_frame: String,
    /// Unix time of the first row, s.
    pub t0_unix_s: f64,
    /// Time covered, s.
    pub duration_s: f64,
    /// Whether wheel commands were written.
    pub commands: bool,
    /// Largest distance of a joint position from a whole count.
    pub max_count_residual: f64,
    /// Remarks.
    pub notes: Vec<String>,
}

/// `wheelcal import ...`.
pub fn run(cmd: ImportCmd, out: Output) -> Result<()> {
    match cmd {
        ImportCmd::Ros2(a) => ros2(&a, out),
    }
}

fn ros2(a: &Ros2Args, out: Output) -> Result<()> {
    let robot = formats::robot_file::load(&a.robot)?;
    let opts = a.bag_flags.options()?;
    let rec_path = a.out.join("recording.csv");
    let robot_path = a.out.join("robot.toml");
    for p in [&rec_path, &robot_path] {
        if p.exists() && !a.force {
            bail!(
                "{} exists: give another --out, or --force to replace it",
                p.display()
            );
        }
    }
    let imp = ros2bag::import(&a.bag, &robot, &opts)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    write_via_temp(&rec_path, |p| imp.recording.save(p))?;
    let robot_text = crate::input::read_text(
        &a.robot,
        formats::robot_file::MAX_FILE_BYTES,
        "robot description",
    )?;
    if !same_file(&a.robot, &robot_path) {
        write_via_temp(&robot_path, |p| std::fs::write(p, &robot_text))?;
    }
    for n in &imp.notes {
        out.note(n);
    }
    let r = &imp.recording;
    let rep = ImportReport {
        recording: rec_path,
        rows: r.len(),
        rows_with_pose: imp.rows_with_pose,
        pose_samples: imp.pose_samples,
        joints: imp.joints.clone(),
        pose_frame: imp.pose_frame.clone(),
        t0_unix_s: imp.t0_ns as f64 * 1e-9,
        duration_s: r.t.last().copied().unwrap_or(0.0),
        commands: r.wheels.iter().any(|w| w.cmd.is_some()),
        max_count_residual: imp.max_count_residual,
        notes: imp.notes.clone(),
    };
    out.emit(&rep, || {
        format!(
            "{}: {} rows over {:.2} s ({} with a pose, from {} samples in frame {}, put in the robot's start frame); joints {}{}\n",
            rep.recording.display(),
            rep.rows,
            rep.duration_s,
            rep.rows_with_pose,
            rep.pose_samples,
            rep.pose_frame,
            rep.joints.join(", "),
            if rep.commands { "; wheel commands from cmd_vel" } else { "" }
        )
    })
}

/// Writes `path` through a temporary file beside it, renamed into place, so a failed
/// import never leaves half a recording.
fn write_via_temp(path: &Path, write: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<()> {
    let tmp = path.with_extension("partial");
    write(&tmp).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
