//! Issue 23 §4's physical bounds (poses within 500 m, speeds at most 30 m/s, no step in
//! `t` over an hour, moving encoders) must never refuse a real recording: every recording
//! of `data/real` and of the OptiOdom sessions (diff drive, omni3, mecanum) reads.

use formats::recording::Recording;
use std::path::Path;

fn recordings(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    let Ok(rd) = std::fs::read_dir(dir) else {
        return;
    };
    for e in rd.flatten() {
        let p = e.path();
        if p.is_dir() {
            recordings(&p, out);
        } else if p.file_name().is_some_and(|n| n == "recording.csv") {
            out.push(p);
        }
    }
}

/// Reads every recording below `dir` (with the robot file beside it); returns how many.
fn all_within_the_bounds(dir: &Path) -> usize {
    let mut files = Vec::new();
    recordings(dir, &mut files);
    assert!(
        !files.is_empty(),
        "no recording.csv below {}",
        dir.display()
    );
    for f in &files {
        let robot_file = f.with_file_name("robot.toml");
        let robot = formats::robot_file::load(&robot_file)
            .unwrap_or_else(|e| panic!("a real robot file refused: {e}"));
        if let Err(e) = Recording::load(f, &robot) {
            panic!("a real recording refused: {e}");
        }
    }
    println!("{} real recordings within the bounds", files.len());
    files.len()
}

/// The seven runs kept in the repository.
#[test]
fn the_repositorys_real_recordings_are_within_the_bounds() {
    assert_eq!(all_within_the_bounds(&testdata::real_dir()), 7);
}

/// Every run of the OptiOdom sessions (299 in the converted folder of 2026-12-07).
#[test]
#[ignore = "needs the OptiOdom sessions: WHEELCAL_SESSIONS (data/real/README.md)"]
fn sessions_every_real_recording_is_within_the_bounds() {
    let n = all_within_the_bounds(&testdata::sessions_dir());
    assert!(n >= 275, "{n} recordings");
}
