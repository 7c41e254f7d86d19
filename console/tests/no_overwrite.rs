//! Issue 23 §2 through the `wheelcal` binary: no writing command overwrites or empties a
//! file it did not make. Each command is pointed at a folder of the user's files (a real
//! run folder: recording.csv and its nominal robot.toml, plus notes) and at its own
//! inputs; every file must come out byte for byte as it went in, and the command must
//! fail naming the path. Then the same command into a new folder works, and again into
//! the folder it made.

mod common;

use common::{robot, scratch, wheelcal};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Output, Stdio};
use std::time::{Duration, Instant};

/// A user's run folder: a simulated recording, its nominal robot and a note.
fn run_folder(dir: &Path) -> PathBuf {
    let tmp = dir.join("made");
    let o = wheelcal()
        .args([
            "sim",
            "record",
            "--seed",
            "2",
            "--umbmark-side",
            "1",
            "--robot",
        ])
        .arg(robot("mobolab"))
        .arg("--out")
        .arg(&tmp)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Copied by hand into a folder wheelcal did not make, as a user's run folder is.
    let run = dir.join("run-01");
    std::fs::create_dir_all(&run).unwrap();
    for f in ["recording.csv", "robot.toml"] {
        std::fs::copy(tmp.join(f), run.join(f)).unwrap();
    }
    for f in ["index.html", "paths.mcap", "notes.txt"] {
        std::fs::write(run.join(f), format!("the user's {f}\n")).unwrap();
    }
    run
}

/// Every file under `dir` with its bytes.
fn snapshot(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut m = BTreeMap::new();
    for e in std::fs::read_dir(dir).unwrap().flatten() {
        let p = e.path();
        if p.is_file() {
            m.insert(p.clone(), std::fs::read(&p).unwrap());
        }
    }
    m
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Runs wheelcal with `args`; asserts it failed naming `names` and left `dir` untouched.
fn refused(args: &[&str], dir: &Path, names: &str) {
    let before = snapshot(dir);
    let o = wheelcal().args(args).stdin(Stdio::null()).output().unwrap();
    let all = text(&o);
    assert_eq!(o.status.code(), Some(1), "{args:?}:\n{all}");
    assert!(
        all.contains(names),
        "{args:?}: expected {names:?} in:\n{all}"
    );
    assert_eq!(snapshot(dir), before, "{args:?} changed {}", dir.display());
}

fn ok(args: &[&str]) -> Output {
    let o = wheelcal().args(args).stdin(Stdio::null()).output().unwrap();
    assert!(o.status.success(), "{args:?}:\n{}", text(&o));
    o
}

fn s(p: &Path) -> String {
    p.display().to_string()
}

#[test]
fn reports_go_only_into_new_or_wheelcal_folders() {
    let dir = scratch("reports");
    let run = run_folder(&dir);
    let (rob, rec) = (s(&run.join("robot.toml")), s(&run.join("recording.csv")));
    // Pointed at the run folder (an easy mistake): its nominal robot.toml is the input.
    refused(
        &[
            "calibrate",
            "--robot",
            &rob,
            "--recording",
            &rec,
            "--report",
            &s(&run),
        ],
        &run,
        &s(&run),
    );
    refused(
        &[
            "diagnose",
            "--robot",
            &rob,
            "--recording",
            &rec,
            "--report",
            &s(&run),
        ],
        &run,
        &s(&run),
    );
    // A folder of other files, without the inputs in it.
    let mine = dir.join("mine");
    std::fs::create_dir_all(&mine).unwrap();
    std::fs::write(mine.join("index.html"), "my page").unwrap();
    refused(
        &[
            "diagnose",
            "--robot",
            &rob,
            "--recording",
            &rec,
            "--report",
            &s(&mine),
        ],
        &mine,
        "index.html",
    );
    // A new folder, then the same folder again (wheelcal made it).
    let fresh = dir.join("fresh");
    for _ in 0..2 {
        ok(&[
            "diagnose",
            "--robot",
            &rob,
            "--recording",
            &rec,
            "--report",
            &s(&fresh),
        ]);
        assert!(fresh.join("index.html").exists() && fresh.join("paths.mcap").exists());
    }
    // --force writes into the user's folder, but still not over an input.
    ok(&[
        "--force",
        "diagnose",
        "--robot",
        &rob,
        "--recording",
        &rec,
        "--report",
        &s(&mine),
    ]);
    assert_ne!(std::fs::read(mine.join("index.html")).unwrap(), b"my page");
    refused(
        &[
            "--force",
            "calibrate",
            "--robot",
            &rob,
            "--recording",
            &rec,
            "--report",
            &s(&run),
        ],
        &run,
        "input",
    );
}

#[test]
fn write_robot_never_replaces_an_input_or_another_kind_of_file() {
    let dir = scratch("write-robot");
    let run = run_folder(&dir);
    let (rob, rec) = (s(&run.join("robot.toml")), s(&run.join("recording.csv")));
    for cmd in ["diagnose", "calibrate"] {
        for force in [false, true] {
            let mut args = vec![];
            if force {
                args.push("--force");
            }
            args.extend([
                cmd,
                "--robot",
                &rob,
                "--recording",
                &rec,
                "--write-robot",
                &rob,
            ]);
            refused(&args, &run, "input");
        }
        let notes = s(&run.join("notes.txt"));
        refused(
            &[
                cmd,
                "--robot",
                &rob,
                "--recording",
                &rec,
                "--write-robot",
                &notes,
            ],
            &run,
            "notes.txt",
        );
        // A new file, then replacing the robot file it wrote.
        let out = dir.join(format!("{cmd}-fitted.toml"));
        for _ in 0..2 {
            ok(&[
                cmd,
                "--robot",
                &rob,
                "--recording",
                &rec,
                "--write-robot",
                &s(&out),
            ]);
            formats::robot_file::load(&out).expect("a robot file");
        }
    }
}

#[test]
fn sim_record_never_writes_into_a_run_folder() {
    let dir = scratch("sim-record");
    let run = run_folder(&dir);
    let m = s(&robot("mobolab"));
    refused(
        &[
            "sim",
            "record",
            "--robot",
            &m,
            "--duration",
            "5",
            "--out",
            &s(&run),
        ],
        &run,
        "recording.csv",
    );
    let fresh = dir.join("sim");
    for _ in 0..2 {
        ok(&[
            "sim",
            "record",
            "--robot",
            &m,
            "--duration",
            "5",
            "--out",
            &s(&fresh),
        ]);
    }
}

/// Starts sim-board with `args`; returns its exit status and output if it ended within
/// 5 s, else kills it (it started) and returns None.
fn sim_board(args: &[&str]) -> Option<Output> {
    let mut child = wheelcal()
        .arg("sim-board")
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while t0.elapsed() < Duration::from_secs(5) {
        if child.try_wait().unwrap().is_some() {
            return Some(child.wait_with_output().unwrap());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
    None
}

#[test]
fn sim_board_never_empties_or_replaces_the_users_files() {
    let dir = scratch("sim-board");
    let m = s(&robot("mobolab"));
    let notes = dir.join("notes.txt");
    std::fs::write(&notes, "my notes\n").unwrap();
    let link = dir.join("board");
    let check = |args: &[&str], name: &str| {
        let before = snapshot(&dir);
        let o = sim_board(args).unwrap_or_else(|| panic!("{args:?} started"));
        let all = text(&o);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {all}");
        assert!(all.contains(name), "{args:?}: {all}");
        assert_eq!(snapshot(&dir), before, "{args:?}");
    };
    // --truth at the user's file, and the default LINK.truth.jsonl being the user's file.
    check(
        &["--robot", &m, "--link", &s(&link), "--truth", &s(&notes)],
        "notes.txt",
    );
    std::fs::write(dir.join("board.truth.jsonl"), "my data\n").unwrap();
    check(&["--robot", &m, "--link", &s(&link)], "board.truth.jsonl");
    std::fs::remove_file(dir.join("board.truth.jsonl")).unwrap();
    // --flash at the user's file: refused at start, not overwritten by a save.
    check(
        &["--robot", &m, "--link", &s(&link), "--flash", &s(&notes)],
        "notes.txt",
    );
    // --flash in a folder that does not exist: an error now, not "saved" and nothing.
    let missing = dir.join("no-such-folder").join("flash.img");
    check(
        &["--robot", &m, "--link", &s(&link), "--flash", &s(&missing)],
        "no-such-folder",
    );
    // --link at the user's symlink: not replaced, not deleted on exit.
    let users_link = dir.join("mylink");
    std::os::unix::fs::symlink(&notes, &users_link).unwrap();
    check(&["--robot", &m, "--link", &s(&users_link)], "mylink");
    assert_eq!(std::fs::read_link(&users_link).unwrap(), notes);
    // A dangling link of the user's (not a pseudo-terminal) stays too.
    let dangling = dir.join("dangling");
    std::os::unix::fs::symlink(dir.join("gone"), &dangling).unwrap();
    check(&["--robot", &m, "--link", &s(&dangling)], "dangling");
    assert!(std::fs::symlink_metadata(&dangling).is_ok());
}
