//! Finding and reading the recordings a command is given: a CSV file, a run folder
//! holding recording.csv, a directory of run folders, or a ROS 2 bag. Shared by
//! `calibrate` and `diagnose`, so both accept the same paths in the same way.

use crate::args::BagFlags;
use anyhow::{bail, Context, Result};
use calib_core::robot::Robot;
use formats::recording::Recording;
use formats::robot_file;
use std::path::{Path, PathBuf};

/// Whether `p` is a ROS 2 bag: an `.mcap` file or a folder with `metadata.yaml`.
pub fn is_bag(p: &Path) -> bool {
    (p.is_file() && p.extension().is_some_and(|e| e == "mcap"))
        || (p.is_dir() && p.join("metadata.yaml").is_file())
}

/// A recording from a formats.md CSV file or a ROS 2 bag (read with `flags`): for the
/// commands that take either (`calibrate`, `diagnose`). The import's notes go to stderr.
pub fn load_recording(p: &Path, robot: &Robot, flags: &BagFlags) -> Result<Recording> {
    load_recording_at(p, robot, flags, None)
}

/// [`load_recording`], a CSV file's rows merged to about `max_rate_hz` per second as it
/// is read (formats::decimate; `Recording::merged` says so). A bag is read whole (the
/// diagnosis merges its rows).
pub fn load_recording_at(
    p: &Path,
    robot: &Robot,
    flags: &BagFlags,
    max_rate_hz: Option<f64>,
) -> Result<Recording> {
    if is_bag(p) {
        return Ok(ros2bag::load_bag_recording(p, robot, &flags.options()?)?);
    }
    Ok(match max_rate_hz {
        Some(rate) => formats::decimate::load(p, robot, rate)?,
        None => Recording::load(p, robot)?,
    })
}

/// Recording CSV files named by `p`: the file itself, `p/recording.csv`, or every
/// `recording.csv` one level down (sorted).
pub fn recording_files(p: &Path) -> Result<Vec<PathBuf>> {
    if p.is_file() || is_bag(p) {
        return Ok(vec![p.to_path_buf()]);
    }
    if !p.is_dir() {
        bail!("{}: no such recording file or folder", p.display());
    }
    let own = p.join("recording.csv");
    if own.is_file() {
        return Ok(vec![own]);
    }
    let mut v: Vec<PathBuf> = std::fs::read_dir(p)
        .with_context(|| format!("cannot read {}", p.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter_map(|d| {
            if d.is_dir() && d.join("recording.csv").is_file() {
                Some(d.join("recording.csv"))
            } else if d.extension().is_some_and(|x| x == "csv") {
                Some(d)
            } else {
                None
            }
        })
        .collect();
    v.sort();
    if v.is_empty() {
        bail!("{}: holds no recording.csv", p.display());
    }
    Ok(v)
}

/// Every recording file named by `paths` (see [`recording_files`]).
pub fn expand(paths: &[PathBuf]) -> Result<Vec<PathBuf>> {
    let mut v = Vec::new();
    for p in paths {
        v.extend(recording_files(p)?);
    }
    Ok(v)
}

/// A short name: the run folder for `.../run/recording.csv`, else the file name.
pub fn short_name(f: &Path) -> String {
    let file = f
        .file_name()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    match f.parent().and_then(|d| d.file_name()) {
        Some(d) if file == "recording.csv" => d.to_string_lossy().to_string(),
        _ => file,
    }
}

/// Loads a recording against `robot`; a robot.toml beside it naming another robot is an
/// error naming both files.
pub fn load(
    f: &Path,
    robot: &Robot,
    robot_path: &Path,
    bag: &BagFlags,
) -> Result<(String, Recording)> {
    load_checked(f, robot, robot_path)?;
    let rec = load_recording(f, robot, bag)?;
    Ok((short_name(f), rec))
}

/// [`load`] for a log whose poses are not read (`calibrate --e-b-for`): a CSV file's pose
/// cells may all be blank (each row's pose is taken as the origin). A bag is read as by
/// [`load`].
pub fn load_encoders(
    f: &Path,
    robot: &Robot,
    robot_path: &Path,
    bag: &BagFlags,
) -> Result<(String, Recording)> {
    if is_bag(f) {
        return load(f, robot, robot_path, bag);
    }
    /// Every row as read, its pose the origin.
    struct PosesUnread;
    impl formats::recording::RowSink for PosesUnread {
        fn push(&mut self, rec: &mut Recording, mut row: formats::recording::Cells) {
            row.pose = Some((0.0, 0.0, 0.0));
            row.push_to(rec);
        }
        fn finish(&mut self, _: &mut Recording) {}
    }
    load_checked(f, robot, robot_path)?;
    Ok((
        short_name(f),
        Recording::load_into(f, robot, &mut PosesUnread)?,
    ))
}

/// Refuses `f` when a robot.toml beside it names another robot than `robot`.
fn load_checked(f: &Path, robot: &Robot, robot_path: &Path) -> Result<()> {
    if let Some(beside) = f
        .parent()
        .map(|d| d.join("robot.toml"))
        .filter(|p| p.is_file())
    {
        if let Ok(other) = robot_file::load(&beside) {
            if other.name != robot.name {
                bail!(
                    "{}: recorded with robot '{}' ({}), but --robot {} is '{}'",
                    f.display(),
                    other.name,
                    beside.display(),
                    robot_path.display(),
                    robot.name
                );
            }
        }
    }
    Ok(())
}
