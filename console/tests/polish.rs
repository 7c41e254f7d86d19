//! Issue 13's polish list, through the `wheelcal` binary as a person types it: words
//! instead of Rust's debug text, arguments read as meant, errors in plain words.

mod common;

use common::{scratch, wheelcal, Board};
use std::path::Path;

/// `--f-lat '1, 1, 1, 1'` was refused (`invalid value ' 1'`); diff-drive factors on an
/// omni board said "a omni robot"; `log list` showed `Omni { path: W1, length_m: 0.3 }`.
#[test]
fn factors_and_trials_read_as_words() {
    let dir = scratch("words");
    let board = Board::start("omni4", &dir);

    let (o, out, err) = board.run_text(&[
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

    let (o, _, err) = board.run_text(&["factors", "set", "--c-l", "1", "--c-r", "1", "--e-b", "1"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("do not fit this omni robot"), "{err}");
    assert!(!err.contains("a omni"), "{err}");

    let (o, _, err) = board.run_text(&["factors", "set", "--f-lat", "1,x,1,1", "--f-lon", "1"]);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("'x' is not a number"), "{err}");

    for args in [
        ["run", "omni", "--path", "4W-1", "--length", "0.3"],
        ["run", "umbmark", "--dir", "cw", "--side", "0.5"],
    ] {
        let (o, _, err) = board.run_text(&args);
        assert!(o.status.success(), "{args:?}: {err}");
    }
    let (o, out, err) = board.run_text(&["log", "list"]);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("omni 4W-1, 0.3 m"), "{out}");
    assert!(out.contains("umbmark cw, side 0.5 m"), "{out}");
    for debug in ["{", "}", "W1", "Cw", "None", "Some("] {
        assert!(!out.contains(debug), "debug text {debug:?} in:\n{out}");
    }
    let (_, out, _) = board.run_text(&["--json", "log", "list"]);
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

/// A differential drive's speed and acceleration laws through the binary, as typed at a
/// mobolab board: negative values read as numbers, the board stores them beside the
/// factors and the text says each in words; a speed law past ±0.2 per m/s is refused in
/// words naming it, and the stored factors do not change.
#[test]
fn speed_and_acceleration_laws_are_set_in_words() {
    let dir = scratch("laws");
    let board = Board::start("mobolab", &dir);
    let (o, out, err) = board.run_text(&[
        "factors",
        "set",
        "--c-l",
        "0.995",
        "--speed-rel",
        "-0.035",
        "--accel-slip-s",
        "0.047",
    ]);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("-3.500 % larger per m/s"), "{out}");
    assert!(out.contains("47.0 ms"), "{out}");
    let (o, _, err) = board.run_text(&["factors", "set", "--speed-rel", "0.5"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("speed_rel = 0.5 is outside [-0.2, 0.2]"),
        "{err}"
    );
    let (_, out, _) = board.run_text(&["--json", "factors", "get"]);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["speed_rel"], -0.035, "{v}");
    assert_eq!(v["accel_slip_s"], 0.047, "{v}");
    assert_eq!(v["c_l"], 0.995, "{v}");
}

/// `wheelcal run circle` on the virtual board: the board drives the circle (mobolab's
/// steppers follow the profile step by step, so its own odometry ends where it started,
/// having turned +2 pi: within 1 mm and 5 mrad, a few steps at the ends; measured
/// 0.005 mm and under 1e-6 rad),
/// the trial reads as words, and a circle wider than the arena or of no laps is refused
/// before anything is sent, naming the number.
#[test]
fn a_circle_runs_on_the_board_and_a_bad_one_is_not_sent() {
    let dir = scratch("circle");
    let board = Board::start("mobolab", &dir);
    let (o, out, err) =
        board.run_text(&["--json", "run", "circle", "--dir", "ccw", "--radius", "0.3"]);
    assert!(o.status.success(), "{err}");
    let s: serde_json::Value = serde_json::from_str(&out).expect("status JSON");
    let pose = &s["pose"];
    let (x, y, th) = (
        pose["x"].as_f64().unwrap(),
        pose["y"].as_f64().unwrap(),
        pose["theta"].as_f64().unwrap(),
    );
    // Not wrapped: one lap counter-clockwise is +2 pi.
    let off = th - std::f64::consts::TAU;
    eprintln!(
        "after the circle: {:.3} mm from the start, {off:+.5} rad off one lap",
        x.hypot(y) * 1e3
    );
    assert!(x.hypot(y) < 1e-3 && off.abs() < 5e-3, "{s}");
    let (o, out, err) = board.run_text(&["log", "list"]);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("circle ccw, radius 0.3 m, 1 lap"), "{out}");
    for (args, word) in [
        (["--radius", "6", "--laps", "1"], "radius_m = 6"),
        (["--radius", "0.5", "--laps", "0"], "laps"),
    ] {
        let mut all = vec!["run", "circle", "--dir", "cw"];
        all.extend(args);
        let (o, _, err) = board.run_text(&all);
        assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("not sent") && err.contains(word),
            "{args:?}: {err}"
        );
    }
}
