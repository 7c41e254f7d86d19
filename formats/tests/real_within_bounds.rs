//! Issue 23 §4's physical bounds (poses within 500 m, speeds at most 30 m/s, no step in
//! `t` over an hour, moving encoders) must never refuse a real recording: every recording
//! of `../shared/real` (OptiOdom sessions, diff drive and omni) reads.

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

#[test]
fn every_real_recording_is_within_the_bounds() {
    // shared/ beside the checkout, or where WHEELCAL_SHARED says (a worktree elsewhere).
    let base = std::env::var_os("WHEELCAL_SHARED").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
        std::path::PathBuf::from,
    );
    let base = base.join("real");
    let mut files = Vec::new();
    recordings(&base, &mut files);
    if files.is_empty() {
        return; // shared/ sits beside the checkout in CI and on developer machines
    }
    let mut read = 0;
    for f in &files {
        let robot_file = f.with_file_name("robot.toml");
        let Ok(robot) = formats::robot_file::load(&robot_file) else {
            continue;
        };
        if let Err(e) = Recording::load(f, &robot) {
            panic!("a real recording refused: {e}");
        }
        read += 1;
    }
    assert!(read >= files.len() / 2, "{read} of {}", files.len());
    println!("{read} real recordings within the bounds");
}
