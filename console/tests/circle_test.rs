//! The circle test through the binary: `umbmark run --circle-radius` on a `sim-board`
//! whose tyres scrub, measured by the board's truth as a person would measure the ends.

mod common;
use common::{json_of, scratch, Board};

/// `wheelcal umbmark run --side 1 --runs 3 --circle-radius 0.5 --circle-laps 2
/// --auto-measure` on a virtual MoboLab (0.4 m wheelbase) with wheels E_d 1.004 and a
/// wheelbase 2 % wide hidden, a 4 % tyre scrub (`--turn-scrub 0.04`) and a rough floor
/// (0.2 mm per square-root metre): it drives the squares and the circles each way,
/// computes, uploads the factors with the law, and runs the after trials with them.
/// Tolerances: the law within 3 sigma plus 0.002 of 0.04 (5 % for the board's ramps and
/// whole steps, as `calib_core::circle_test`'s virtual-board test); E_b within 0.002 of
/// 1.02 (UMBmark on 1 m squares); the board holds exactly the JSON's law; the after
/// circles, measured with the law in force, leave under 3 sigma plus 0.002 of it; the runs
/// file keeps every run with its laps.
#[test]
fn the_guided_circle_test_finds_and_uploads_the_turn_law() {
    let dir = scratch("circle-test");
    let board = Board::start_with(
        "mobolab",
        &dir,
        "max",
        &[
            "--turn-scrub",
            "0.04",
            "--effect",
            "wheel_diameter_mismatch=ed:1.004",
            "--effect",
            "wheelbase_error=eb:1.02",
            "--roughness",
            "0.0002",
        ],
    );
    let runs = dir.join("runs.csv");
    let out = board.run(&[
        "--json",
        "umbmark",
        "run",
        "--side",
        "1",
        "--runs",
        "3",
        "--circle-radius",
        "0.5",
        "--circle-laps",
        "2",
        "--auto-measure",
        "--runs-file",
        runs.to_str().unwrap(),
    ]);
    let rep = json_of(&out);
    let c = &rep["circles"];
    let (k, s) = (
        c["e_b_arc"].as_f64().unwrap(),
        c["e_b_arc_sigma"].as_f64().unwrap(),
    );
    eprintln!("law {k:.5} ± {s:.5}, E_b {}", rep["eb"]);
    assert!((k - 0.04).abs() <= 3.0 * s + 0.002, "{c}");
    assert_eq!(c["kept"], true, "{c}");
    assert!((rep["eb"].as_f64().unwrap() - 1.02).abs() < 0.002, "{rep}");
    let held = json_of(&board.run(&["--json", "factors", "get"]));
    let law = held["e_b_arc"]
        .as_f64()
        .or_else(|| held["laws"]["e_b_arc"].as_f64())
        .unwrap_or_else(|| panic!("no law on the board: {held}"));
    assert!((law - k).abs() < 1e-9, "{held}");
    let after = &c["after"];
    let (ka, sa) = (
        after["e_b_arc"].as_f64().unwrap(),
        after["e_b_arc_sigma"].as_f64().unwrap(),
    );
    assert!(ka.abs() <= 3.0 * sa + 0.002, "{after}");
    let text = std::fs::read_to_string(&runs).unwrap();
    assert!(
        text.starts_with("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase,laps\n"),
        "{text}"
    );
    assert_eq!(
        text.lines().filter(|l| l.starts_with("circle,")).count(),
        12,
        "{text}"
    );
    assert!(
        text.lines()
            .filter(|l| l.starts_with("circle,"))
            .all(|l| l.ends_with(",2")),
        "{text}"
    );
}

/// `wheelcal demo --circle-radius 0.5`: a tyre scrub drawn at random (0.5-3 %) is hidden
/// beside the wheels' errors, and the circle test finds it within 3 sigma plus 0.002 (the
/// tolerance above), for three seeds.
#[test]
fn the_demo_hides_a_tyre_scrub_and_the_circle_test_finds_it() {
    for seed in [1, 2, 3] {
        let out = common::wheelcal()
            .args([
                "--json",
                "demo",
                "--runs",
                "3",
                "--side",
                "1",
                "--circle-radius",
                "0.5",
            ])
            .args(["--seed", &seed.to_string()])
            .output()
            .unwrap();
        let rep = json_of(&out);
        let hidden = rep["true_e_b_arc"].as_f64().unwrap();
        let (k, s) = (
            rep["estimated_e_b_arc"][0].as_f64().unwrap(),
            rep["estimated_e_b_arc"][1].as_f64().unwrap(),
        );
        eprintln!("seed {seed}: hidden {hidden:.5}, found {k:.5} ± {s:.5}");
        assert!((0.005..0.03).contains(&hidden), "{rep}");
        assert!((k - hidden).abs() <= 3.0 * s + 0.002, "{rep}");
    }
}

/// A runs file begun without circles has no laps column: circles of two laps could be
/// driven but not recorded, so the procedure refuses before anything moves, and the file
/// is left as it was.
#[test]
fn circles_are_refused_before_moving_when_the_runs_file_cannot_hold_their_laps() {
    let dir = scratch("circle-no-laps");
    let board = Board::start("mobolab", &dir);
    let runs = dir.join("runs.csv");
    let text =
        "test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\numbmark,cw,1,0.01,0.02,,before\n";
    std::fs::write(&runs, text).unwrap();
    let (o, _, err) = board.run_text(&[
        "umbmark",
        "run",
        "--side",
        "1",
        "--runs",
        "2",
        "--circle-radius",
        "0.5",
        "--auto-measure",
        "--runs-file",
        runs.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(
        err.contains("has no laps column for circles of 2 laps"),
        "{err}"
    );
    assert_eq!(std::fs::read_to_string(&runs).unwrap(), text);
    let (x, y) = common::pose_of(&board.status());
    assert!(x.hypot(y) < 1e-9, "the robot moved to ({x}, {y})");
}
