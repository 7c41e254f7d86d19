//! Finding and reading the recordings a command is given: a CSV file, a run folder
//! holding recording.csv, a directory of run folders, or a ROS 2 bag. Shared by
//! `calibrate`, `evaluate` and `diagnose`, so all accept the same paths in the same way,
//! and a set of recordings of one robot is gathered and checked once ([`load_all`],
//! [`refuse_mixed_robots`]).

use crate::args::BagFlags;
use crate::output::Output;
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
        match std::fs::metadata(p) {
            Ok(m) => bail!(
                "{}: {}, not a recording file or folder",
                p.display(),
                crate::input::kind_of(&m)
            ),
            Err(_) => bail!("{}: no such recording file or folder", p.display()),
        }
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

/// [`expand`], each recording once: a file given twice (by any path) or a byte-identical
/// copy of one given before is dropped with a note naming both files (counted twice, a
/// recording would weigh twice in a shared geometry).
pub fn expand_distinct(paths: &[PathBuf], out: Output) -> Result<Vec<PathBuf>> {
    let mut kept: Vec<PathBuf> = Vec::new();
    for f in expand(paths)? {
        if let Some(prev) = kept.iter().find(|q| same_recording(q, &f)) {
            out.note(&twice_note(&f, prev));
            continue;
        }
        kept.push(f);
    }
    Ok(kept)
}

/// The note for `f`, the same recording as `prev`: the same file given twice, or a copy.
fn twice_note(f: &Path, prev: &Path) -> String {
    let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    if canon(f) == canon(prev) {
        format!(
            "warning: {} is given twice (also as {}): read once",
            f.display(),
            prev.display()
        )
    } else {
        format!(
            "warning: {} holds the same recording as {} (byte-identical contents): read once",
            f.display(),
            prev.display()
        )
    }
}

/// Whether `a` and `b` hold the same recording: the same file (by any path) or files
/// of equal contents (compared in blocks, after their sizes; a bag folder by path only).
pub fn same_recording(a: &Path, b: &Path) -> bool {
    let canon = |p: &Path| std::fs::canonicalize(p).unwrap_or_else(|_| p.to_path_buf());
    if canon(a) == canon(b) {
        return true;
    }
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    if !ma.is_file() || !mb.is_file() || ma.len() != mb.len() {
        return false;
    }
    let (Ok(fa), Ok(fb)) = (std::fs::File::open(a), std::fs::File::open(b)) else {
        return false;
    };
    use std::io::Read;
    let (mut ra, mut rb) = (
        std::io::BufReader::new(fa.take(ma.len())),
        std::io::BufReader::new(fb.take(mb.len())),
    );
    let (mut ba, mut bb) = (vec![0u8; 1 << 16], vec![0u8; 1 << 16]);
    loop {
        let n = match ra.read(&mut ba) {
            Ok(n) => n,
            Err(_) => return false,
        };
        if n == 0 {
            return true;
        }
        if rb.read_exact(&mut bb[..n]).is_err() || ba[..n] != bb[..n] {
            return false;
        }
    }
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
/// error naming both files. A file whose time goes back is refused (formats.md §2: the
/// calibration trusts the file's times; `wheelcal diagnose` reads it, see
/// [`load_for_diagnosis`]).
pub fn load(
    f: &Path,
    robot: &Robot,
    robot_path: &Path,
    bag: &BagFlags,
) -> Result<(String, Recording)> {
    let r = load_for_diagnosis(f, robot, robot_path, bag)?;
    refuse_time_back(f, &r.1)?;
    Ok(r)
}

/// [`load`] for `wheelcal diagnose`: a file whose time goes back is read, its rows
/// re-timed by the reader, and the places reported by the diagnosis (`time_backwards`).
pub fn load_for_diagnosis(
    f: &Path,
    robot: &Robot,
    robot_path: &Path,
    bag: &BagFlags,
) -> Result<(String, Recording)> {
    load_checked(f, robot, robot_path)?;
    let rec = load_recording(f, robot, bag)?;
    Ok((short_name(f), rec))
}

/// The reader re-times rows whose time goes back (formats.md §2); the commands that
/// calibrate refuse such a file, naming the first place.
pub fn refuse_time_back(f: &Path, rec: &Recording) -> Result<()> {
    let tf = &rec.time_faults;
    if let Some(b) = tf.back.first() {
        bail!(
            "{}:{}: column 't': time must increase strictly: {} s lies {:.4} s behind the clock ({} such place{} in the file); `wheelcal diagnose` reads such a file, lists the places (time_backwards) and re-times the rows",
            f.display(),
            b.line,
            b.written_s,
            b.back_s,
            tf.count,
            if tf.count == 1 { "" } else { "s" }
        );
    }
    Ok(())
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
    let rec = Recording::load_into(f, robot, &mut PosesUnread)?;
    refuse_time_back(f, &rec)?;
    Ok((short_name(f), rec))
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

/// Travel by motion capture over travel by the nominal odometry of `robot`: about 1 (the
/// robot's scale, within a few percent) for a recording of this robot, far from it for a
/// recording of another robot given without its robot.toml. `None` where it cannot tell:
/// legs (the kinematics follow them), mecanum rollers (the real mecanum sessions' ratio
/// ranges from 1.37 to 2.01 with the motion: roller slip), no encoder scale, or under 1 m
/// of travel.
fn travel_ratio(robot: &Robot, rec: &Recording) -> Option<f64> {
    let rollers = robot
        .wheels
        .iter()
        .any(|w| w.gamma_rad.abs() > 1f64.to_radians());
    if robot.legs.is_some() || rollers {
        return None;
    }
    let rpc = robot.drive.rad_per_count()?;
    let kin = calib_core::kinematics::Kinematics::<f64>::new(robot, &calib_core::Corrections::None)
        .ok()?;
    let counts_at = |k: usize| -> Option<Vec<i64>> {
        rec.wheels
            .iter()
            .map(|w| w.enc.as_ref().and_then(|e| e.get(k).copied().flatten()))
            .collect()
    };
    let (mut odo, mut mocap) = (0.0, 0.0);
    let mut prev: Option<Vec<i64>> = None;
    let mut prev_pose: Option<(f64, f64)> = None;
    let mut dphi = vec![0.0; rec.wheels.len()];
    for k in 0..rec.t.len() {
        if let Some(c) = counts_at(k) {
            if let Some(p) = &prev {
                for (i, d) in dphi.iter_mut().enumerate() {
                    *d = (c[i] - p[i]) as f64 * rpc;
                }
                let d = kin.forward(&dphi);
                odo += d.vx.hypot(d.vy);
            }
            prev = Some(c);
        }
        if let (Some(x), Some(y)) = (rec.x[k], rec.y[k]) {
            if let Some((px, py)) = prev_pose {
                mocap += (x - px).hypot(y - py);
            }
            prev_pose = Some((x, y));
        }
    }
    (odo >= 1.0 && mocap >= 1.0).then(|| mocap / odo)
}

/// Recordings of this robot agree on [`travel_ratio`] within this fraction of their
/// median: twice the plausible scale range (+-5 %), above what slip or path kind change
/// (all 164 real runs of the differential robot and all 67 of the three-wheel omni, squares,
/// circles and Ivanjko paths together, pass).
const MIXED_ROBOT_TOLERANCE: f64 = 0.10;

/// Refuses a set of recordings one of which moves a different distance per encoder count
/// than the others: another robot's bare CSV (no robot.toml beside it to compare) would
/// otherwise be fitted as this robot's, with a confident, wrong geometry.
pub fn refuse_mixed_robots(robot: &Robot, recs: &[(&Path, &Recording)]) -> Result<()> {
    let ratios: Vec<(&Path, f64)> = recs
        .iter()
        .filter_map(|(p, r)| travel_ratio(robot, r).map(|q| (*p, q)))
        .collect();
    if ratios.len() < 2 {
        return Ok(());
    }
    let mut sorted: Vec<f64> = ratios.iter().map(|(_, q)| *q).collect();
    sorted.sort_by(f64::total_cmp);
    let m = sorted.len();
    let median = if m % 2 == 1 {
        sorted[m / 2]
    } else {
        0.5 * (sorted[m / 2 - 1] + sorted[m / 2])
    };
    let odd: Vec<String> = ratios
        .iter()
        .filter(|(_, q)| (q / median - 1.0).abs() > MIXED_ROBOT_TOLERANCE)
        .map(|(p, q)| format!("{} ({q:.3})", p.display()))
        .collect();
    if !odd.is_empty() {
        bail!(
            "{}: motion capture over odometry travel differs by more than {:.0} % from the \
             recordings' median {median:.3}: a recording of another robot (give it with its \
             robot.toml beside it), or encoder counts of another resolution; refused",
            odd.join(", "),
            MIXED_ROBOT_TOLERANCE * 100.0
        );
    }
    Ok(())
}

/// The recordings [`load_all`] gathered, in the order given.
pub struct Gathered {
    /// Each recording's file.
    pub paths: Vec<PathBuf>,
    /// Each recording's short name and contents.
    pub recs: Vec<(String, Recording)>,
}

impl Gathered {
    /// (file, recording) pairs, as [`refuse_mixed_robots`] takes them.
    pub fn by_file(&self) -> Vec<(&Path, &Recording)> {
        self.paths
            .iter()
            .map(PathBuf::as_path)
            .zip(self.recs.iter().map(|(_, r)| r))
            .collect()
    }

    /// The file of the recording named `name` (its short name).
    pub fn file_of(&self, name: &str) -> Option<&Path> {
        self.recs
            .iter()
            .position(|(n, _)| n == name)
            .map(|i| self.paths[i].as_path())
    }
}

/// Loads every recording `args` name (files, run folders, directories of them, bags)
/// against `robot`, in order: a recording given twice (by another path, or a byte-identical
/// copy: [`same_recording`]) is read once, with a warning naming both files; a
/// robot.toml beside one naming another robot is an error.
pub fn load_all(
    args: &[PathBuf],
    robot: &Robot,
    robot_path: &Path,
    bag: &BagFlags,
    out: Output,
) -> Result<Gathered> {
    let mut recs = Vec::new();
    let mut paths: Vec<PathBuf> = Vec::new();
    for p in args {
        for f in recording_files(p)? {
            if let Some(prev) = paths.iter().find(|q| same_recording(q, &f)) {
                out.note(&twice_note(&f, prev));
                continue;
            }
            let r = load(&f, robot, robot_path, bag)?;
            for n in &r.1.notes {
                out.note(&format!("{}: {n}", f.display()));
            }
            recs.push(r);
            paths.push(f);
        }
    }
    Ok(Gathered { paths, recs })
}
