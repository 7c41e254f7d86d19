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

/// A simulated 40 s drive of mobolab in `dir/name` (recording.csv), without a robot file.
fn mobolab_drive(dir: &std::path::Path, name: &str, seed: u64) -> std::path::PathBuf {
    let truth = formats::robot_file::load(&robot("mobolab")).unwrap();
    let mut cfg = sim::RecordConfig {
        row_rate_hz: 50.0,
        ..sim::RecordConfig::default()
    };
    cfg.sim.seed = seed;
    let motion = sim::Motion::Random(sim::RandomMotion {
        duration_s: 40.0,
        ..sim::RandomMotion::default()
    });
    let r = sim::record(&truth, &[], sim::Surface::flat(), &motion, &cfg).unwrap();
    let run = dir.join(name);
    std::fs::create_dir_all(&run).unwrap();
    r.recording.save(&run.join("recording.csv")).unwrap();
    run
}

/// `diagnose` fitted the same recording twice when it was given twice, and a
/// byte-identical copy in another folder was fitted again by `diagnose` and `calibrate`:
/// a recording counted twice weighs twice in the shared geometry. Identical contents
/// (not paths) are read once, with a note naming both files.
#[test]
fn identical_recordings_are_read_once_with_a_note_naming_both() {
    let dir = scratch("identical");
    let a = mobolab_drive(&dir, "a", 31);
    let other = mobolab_drive(&dir, "other", 32);
    let copy = dir.join("copy");
    std::fs::create_dir_all(&copy).unwrap();
    std::fs::copy(a.join("recording.csv"), copy.join("recording.csv")).unwrap();
    for cmd in ["diagnose", "calibrate"] {
        for (twice, shown) in [(&a, "a/recording.csv"), (&copy, "copy/recording.csv")] {
            let mut c = wheelcal();
            c.args(["--json", cmd, "--robot"]).arg(robot("mobolab"));
            if cmd == "calibrate" {
                c.arg("--no-cross-validation");
            }
            for r in [&a, &other, twice] {
                c.arg("--recording").arg(r);
            }
            let o = c.output().unwrap();
            let err = String::from_utf8_lossy(&o.stderr);
            assert!(o.status.success(), "{cmd}: {err}");
            let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
            let list = if cmd == "calibrate" {
                &j["per_recording"]
            } else {
                &j["recordings"]
            };
            let names: Vec<&str> = list
                .as_array()
                .unwrap()
                .iter()
                .map(|r| r["name"].as_str().unwrap())
                .collect();
            assert_eq!(names, ["a", "other"], "{cmd} {shown}: {err}");
            assert!(
                err.contains(shown) && err.contains("a/recording.csv") && err.contains("read once"),
                "{cmd} {shown}: {err}"
            );
        }
    }
}

/// A flash image of the wrong size (grown or cut after the saved item) booted as
/// `loaded` with the saved factors: it is no flash of this board. It is reported
/// (`corrupted`, nominal values in use), never loaded and never written.
#[test]
fn a_wrong_size_flash_image_is_reported_not_loaded() {
    let dir = scratch("flash-size");
    let flash = dir.join("flash.img");
    let start = |dir: &std::path::Path| {
        Board::start_with("mobolab", dir, "max", &["--flash", flash.to_str().unwrap()])
    };
    {
        let board = start(&dir);
        for args in [
            &[
                "factors", "set", "--c-l", "1.01", "--c-r", "0.99", "--e-b", "1.02",
            ][..],
            &["factors", "save"],
        ] {
            let (o, _, err) = board.run_text(args);
            assert!(o.status.success(), "{args:?}: {err}");
        }
    }
    let good = std::fs::read(&flash).unwrap();
    for (what, bytes) in [
        ("double size", [good.clone(), good.clone()].concat()),
        ("cut after the data", good[..good.len() / 2].to_vec()),
        ("one byte more", [good.clone(), vec![0xFF]].concat()),
    ] {
        std::fs::write(&flash, &bytes).unwrap();
        let sub = dir.join(what.replace(' ', "-"));
        std::fs::create_dir_all(&sub).unwrap();
        let board = start(&sub);
        let (o, out, err) = board.run_text(&["--json", "info"]);
        assert!(o.status.success(), "{err}");
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_eq!(v["corrections_at_boot"], "corrupted", "{what}: {v}");
        let (_, out, _) = board.run_text(&["--json", "factors", "get"]);
        let f: serde_json::Value = serde_json::from_str(&out).unwrap();
        assert_ne!(f["c_l"], 1.01, "{what}: the saved factors were loaded: {f}");
        drop(board);
        assert_eq!(std::fs::read(&flash).unwrap(), bytes, "{what}: rewritten");
    }
}

/// The board keeps the last 8 trials; an older trial's pull said only "no trial N".
/// The error says the limit, and the README's command table documents it.
#[test]
fn a_trial_past_the_limit_says_the_board_keeps_8() {
    let dir = scratch("trial-limit");
    let board = Board::start("mobolab", &dir);
    let out = dir.join("t.csv");
    let (o, _, err) = board.run_text(&[
        "log",
        "pull",
        "--trial",
        "1",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let limit = format!("last {} trials", calib_core::protocol::MAX_TRIALS);
    assert!(err.contains(&limit), "{err}");
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../README.md")).unwrap();
    let row = readme
        .lines()
        .find(|l| l.starts_with("| `log list`"))
        .unwrap();
    assert!(row.contains(&limit), "{row}");
}
