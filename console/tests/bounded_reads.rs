//! Issue 52.4: `apply FILE`, `evaluate --board FILE` and `calibrate --laws-from FILE`
//! read `/dev/zero` or a FIFO until memory ran out (or forever). Every user file is read
//! only if it is a regular file, and at most a stated size; the error names the file and
//! says what it is. Each command runs under a 1 GiB address-space limit and a 10 s clock,
//! so the old behaviour fails the test instead of the machine.

mod common;

use common::{robot, scratch, wheelcal, Board};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Runs `wheelcal args...` (after `--port LINK` if given) with at most 1 GiB of address
/// space; kills it after 10 s. (exit code, stderr); `None` for the code if it was killed
/// or ended by a signal.
fn bounded(port: Option<&Path>, args: &[&str]) -> (Option<i32>, String) {
    let mut cmd = Command::new("sh");
    cmd.arg("-c")
        .arg("ulimit -v 1048576; exec \"$@\"")
        .arg("sh")
        .arg(wheelcal().get_program());
    if let Some(p) = port {
        cmd.arg("--port").arg(p);
    }
    let mut child = cmd
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let code = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s.code();
        }
        if t0.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            let _ = child.wait();
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut err = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut err).unwrap();
    (code, err)
}

fn fifo(dir: &Path) -> std::path::PathBuf {
    let f = dir.join("pipe.json");
    let ok = Command::new("mkfifo").arg(&f).status().unwrap();
    assert!(ok.success(), "mkfifo");
    f
}

fn refused(got: (Option<i32>, String), file: &Path, what: &str) {
    let (code, err) = got;
    assert_eq!(code, Some(1), "not refused ({code:?}): {err}");
    let shown = file.display().to_string();
    assert!(
        err.contains(&shown) && err.contains(what),
        "{shown:?} and {what:?} not in: {err}"
    );
}

#[test]
fn calibrate_laws_from_reads_only_a_regular_file() {
    let dir = scratch("bounded-laws");
    let mobolab = robot("mobolab");
    let m = mobolab.to_str().unwrap();
    let args = |f: &Path| {
        vec![
            "calibrate".to_string(),
            "--robot".into(),
            m.into(),
            "--recording".into(),
            dir.join("none").display().to_string(),
            "--laws-from".into(),
            f.display().to_string(),
        ]
    };
    let run = |f: &Path| {
        let a = args(f);
        bounded(None, &a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    refused(
        run(Path::new("/dev/zero")),
        Path::new("/dev/zero"),
        "character device",
    );
    let p = fifo(&dir);
    refused(run(&p), &p, "FIFO");
    // Over the stated cap (16 MiB): refused by size, without parsing.
    let big = dir.join("big.json");
    std::fs::write(&big, " ".repeat(17 << 20)).unwrap();
    refused(run(&big), &big, "16777216 bytes");
}

#[test]
fn evaluate_board_reads_only_a_regular_file() {
    let dir = scratch("bounded-evaluate");
    let mobolab = robot("mobolab");
    let none = dir.join("none");
    let run = |f: &Path| {
        bounded(
            None,
            &[
                "evaluate",
                "--robot",
                mobolab.to_str().unwrap(),
                "--recording",
                none.to_str().unwrap(),
                "--board",
                f.to_str().unwrap(),
            ],
        )
    };
    refused(
        run(Path::new("/dev/zero")),
        Path::new("/dev/zero"),
        "character device",
    );
    let p = fifo(&dir);
    refused(run(&p), &p, "FIFO");
}

#[test]
fn apply_reads_only_a_regular_file() {
    let dir = scratch("bounded-apply");
    let board = Board::start("mobolab", &dir);
    let run = |f: &Path| bounded(Some(&board.link), &["apply", f.to_str().unwrap()]);
    refused(
        run(Path::new("/dev/zero")),
        Path::new("/dev/zero"),
        "character device",
    );
    let p = fifo(&dir);
    refused(run(&p), &p, "FIFO");
}

/// `/dev/zero: no such recording file or folder` was wrong: it exists. Say what it is.
#[test]
fn a_device_given_as_a_recording_is_named_for_what_it_is() {
    let mobolab = robot("mobolab");
    let got = bounded(
        None,
        &[
            "calibrate",
            "--robot",
            mobolab.to_str().unwrap(),
            "--recording",
            "/dev/zero",
        ],
    );
    assert!(!got.1.contains("no such"), "{}", got.1);
    refused(got, Path::new("/dev/zero"), "character device");
}

/// The other JSON inputs: `factors export --from` (and `omni compute --previous`, read
/// by the same kind of reader) refuse a FIFO instead of waiting for a writer forever.
#[test]
fn factors_export_from_reads_only_a_regular_file() {
    let dir = scratch("bounded-export");
    let p = fifo(&dir);
    let out = dir.join("out.yaml");
    let got = bounded(
        None,
        &[
            "factors",
            "export",
            "--from",
            p.to_str().unwrap(),
            "--ros2",
            out.to_str().unwrap(),
        ],
    );
    refused(got, &p, "FIFO");
    assert!(!out.exists());
}

/// The files formats reads itself (robot file, runs file): a FIFO given as `--robot` or
/// `--runs` waited for a writer forever; refused by name at once, as a FIFO.
#[test]
fn robot_and_runs_files_read_only_regular_files() {
    let dir = scratch("bounded-robot");
    let p = fifo(&dir);
    let mobolab = robot("mobolab");
    for args in [
        vec![
            "diagnose",
            "--robot",
            p.to_str().unwrap(),
            "--recording",
            mobolab.to_str().unwrap(),
        ],
        vec![
            "evaluate",
            "--robot",
            p.to_str().unwrap(),
            "--recording",
            mobolab.to_str().unwrap(),
        ],
        vec![
            "umbmark",
            "compute",
            "--robot",
            mobolab.to_str().unwrap(),
            "--runs",
            p.to_str().unwrap(),
        ],
    ] {
        refused(bounded(None, &args), &p, "FIFO");
    }
}
