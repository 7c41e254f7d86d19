//! Issue 13's polish list, through the `wheelcal` binary as a person types it: words
//! instead of Rust's debug text, arguments read as meant, errors in plain words.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

fn wheelcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wheelcal"))
}

fn robot(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"))
}

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wheelcal-polish-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// A `wheelcal sim-board` process at full speed; killed when dropped.
struct Board {
    child: Child,
    link: PathBuf,
}

impl Board {
    fn start(robot_name: &str, dir: &Path) -> Board {
        let link = dir.join("board");
        let child = wheelcal()
            .args(["sim-board", "--speed", "max", "--robot"])
            .arg(robot(robot_name))
            .arg("--link")
            .arg(&link)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("sim-board starts");
        let t0 = Instant::now();
        while !link.exists() {
            assert!(t0.elapsed() < Duration::from_secs(20), "no link after 20 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        Board { child, link }
    }

    fn run(&self, args: &[&str]) -> (Output, String, String) {
        let o = wheelcal()
            .arg("--port")
            .arg(&self.link)
            .args(args)
            .stdin(Stdio::null())
            .output()
            .expect("wheelcal runs");
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        (o, out, err)
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `--f-lat '1, 1, 1, 1'` was refused (`invalid value ' 1'`); diff-drive factors on an
/// omni board said "a omni robot"; `log list` showed `Omni { path: W1, length_m: 0.3 }`.
#[test]
fn factors_and_trials_read_as_words() {
    let dir = scratch("words");
    let board = Board::start("omni4", &dir);

    let (o, out, err) = board.run(&[
        "factors",
        "set",
        "--f-lat",
        "1.01, 0.99 ,1, 1.02",
        "--f-lon",
        "1",
    ]);
    assert!(o.status.success(), "{err}");
    assert!(
        out.contains("F_lat = [1.010000, 0.990000, 1.000000, 1.020000]"),
        "{out}"
    );

    let (o, _, err) = board.run(&["factors", "set", "--c-l", "1", "--c-r", "1", "--e-b", "1"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("do not fit this omni robot"), "{err}");
    assert!(!err.contains("a omni"), "{err}");

    let (o, _, err) = board.run(&["factors", "set", "--f-lat", "1,x,1,1", "--f-lon", "1"]);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("'x' is not a number"), "{err}");

    for args in [
        ["run", "omni", "--path", "4W-1", "--length", "0.3"],
        ["run", "umbmark", "--dir", "cw", "--side", "0.5"],
    ] {
        let (o, _, err) = board.run(&args);
        assert!(o.status.success(), "{args:?}: {err}");
    }
    let (o, out, err) = board.run(&["log", "list"]);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("omni 4W-1, 0.3 m"), "{out}");
    assert!(out.contains("umbmark cw, side 0.5 m"), "{out}");
    for debug in ["{", "}", "W1", "Cw", "None", "Some("] {
        assert!(!out.contains(debug), "debug text {debug:?} in:\n{out}");
    }
    let (_, out, _) = board.run(&["--json", "log", "list"]);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["trials"][0]["program"], "omni 4W-1, 0.3 m", "{v}");
}

/// `--baud 0` was accepted (and timed out talking to nothing).
#[test]
fn baud_zero_is_refused_by_the_parser() {
    let o = wheelcal()
        .args(["--port", "/dev/null", "--baud", "0", "info"])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("--baud"), "{err}");
    assert!(err.contains("50..=12000000"), "{err}");
}

/// `--port /dev/null` said `cannot open /dev/null: Not a typewriter`.
#[test]
fn a_port_that_is_not_a_terminal_is_named_so() {
    let dir = scratch("notatty");
    let file = dir.join("notes.txt");
    std::fs::write(&file, "x").unwrap();
    for port in [Path::new("/dev/null"), file.as_path()] {
        let o = wheelcal()
            .arg("--port")
            .arg(port)
            .arg("info")
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(err.contains("is not a serial port"), "{port:?}: {err}");
        assert!(!err.to_lowercase().contains("typewriter"), "{err}");
        assert!(!err.contains("ioctl"), "{err}");
    }
}
