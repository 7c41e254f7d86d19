//! Issue 52.5, the smaller defects: outputs written before a later step failed, an
//! option's absurd value printed as 300 digits, a refused factor printed rounded into
//! its own bound, help that did not say what a command writes or keeps.

mod common;

use common::{robot, scratch, wheelcal, Board};

/// `calibrate --write-robot F --report R` wrote F, then failed on R: a script saw a
/// fitted robot file beside an error. Nothing is written unless everything succeeds.
#[test]
fn no_robot_file_is_written_when_the_report_fails() {
    let dir = scratch("write-after-report");
    let nominal_file = robot("mobolab");
    let mut truth = formats::robot_file::load(&nominal_file).unwrap();
    truth.wheels.iter_mut().for_each(|w| w.l_m *= 1.02);
    let runs = common::random_runs(&dir, &truth, 0.04, 60);
    let report = dir.join("report-is-a-file");
    std::fs::write(&report, "my notes\n").unwrap();
    let (fitted, board) = (dir.join("fitted.toml"), dir.join("board.toml"));
    let o = wheelcal()
        .args(["calibrate", "--no-cross-validation", "--robot"])
        .arg(&nominal_file)
        .arg("--recording")
        .arg(&runs[0])
        .arg("--recording")
        .arg(&runs[1])
        .arg("--write-robot")
        .arg(&fitted)
        .arg("--write-board-robot")
        .arg(&board)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("report-is-a-file"), "{err}");
    eprintln!("{err}");
    assert!(!fitted.exists(), "--write-robot was written: {err}");
    assert!(!board.exists(), "--write-board-robot was written: {err}");
    assert_eq!(std::fs::read_to_string(&report).unwrap(), "my notes\n");
}

/// `sim record --vision-noise 1e300` printed 300-digit numbers. The noise is a camera's
/// standard deviation in metres: refused outside [0, 1] m, before anything is written.
#[test]
fn vision_noise_out_of_range_is_refused() {
    let dir = scratch("vision-noise");
    for bad in ["1e300", "-0.01", "NaN", "inf", "1.5"] {
        let out = dir.join(format!("rec-{bad}"));
        let o = wheelcal()
            .args(["sim", "record", "--robot"])
            .arg(robot("mobolab"))
            .arg("--out")
            .arg(&out)
            .arg(format!("--vision-noise={bad}"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{bad} accepted");
        assert!(
            err.contains("--vision-noise") && err.contains("[0, 1]"),
            "{bad}: {err}"
        );
        assert!(err.len() < 400, "{bad}: {err}");
        assert!(!out.exists(), "{bad}: output written");
    }
}

/// `factors set --c-l 2.0000001` was refused as `2 is outside [0.5, 2]`: the value is
/// printed with the digits that show why it is outside.
#[test]
fn a_factor_just_outside_its_range_is_printed_with_its_digits() {
    let dir = scratch("factor-digits");
    let board = Board::start("mobolab", &dir);
    for (v, shown) in [
        ("2.0000001", "2.0000001"),
        ("0.49999999999", "0.49999999999"),
    ] {
        let (o, _, err) =
            board.run_text(&["factors", "set", "--c-l", v, "--c-r", "1", "--e-b", "1"]);
        assert_eq!(o.status.code(), Some(1), "{err}");
        assert!(
            err.contains(&format!("c_l = {shown} is outside [0.5, 2]")),
            "{v}: {err}"
        );
    }
}

/// `log pull --help` said CSV only; it also writes MCAP. The board's log keeps 8 trials,
/// which no help said.
#[test]
fn log_help_says_mcap_and_the_trial_limit() {
    let help = |args: &[&str]| {
        let o = wheelcal().args(args).output().unwrap();
        assert!(o.status.success());
        String::from_utf8_lossy(&o.stdout).into_owned()
    };
    let pull = help(&["log", "pull", "--help"]);
    assert!(pull.contains(".mcap") && pull.contains(".csv"), "{pull}");
    for args in [&["log", "--help"][..], &["log", "list", "--help"][..]] {
        let h = help(args);
        let limit = format!("{} trials", calib_core::protocol::MAX_TRIALS);
        assert!(h.contains(&limit), "{args:?}: {h}");
    }
}
