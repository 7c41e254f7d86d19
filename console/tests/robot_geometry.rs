//! `wheelcal robot get|set|save` on a virtual board, through the binary: a calibrated
//! geometry (here omni3's wheels 2 % further out and one wheel turned 0.5 degree) reaches
//! the board to the bit, survives a restart once saved, and a robot file of another kind
//! is refused by name without changing anything.

mod common;

use common::{json_of, robot, scratch, Board};

#[test]
fn a_fitted_geometry_reaches_the_board_and_survives_a_restart() {
    let dir = scratch("robot-geometry");
    let flash = dir.join("flash.bin");
    let flash_s = flash.to_str().unwrap().to_string();
    let extra = ["--flash", flash_s.as_str()];
    let board = Board::start_with("omni3", &dir, "max", &extra);
    let nominal = json_of(&board.run(&["--json", "robot", "get"]));
    assert_eq!(nominal["kind"], "omni", "{nominal}");
    assert_eq!(nominal["wheels"][1]["l_m"], 0.15, "{nominal}");
    // A fitted file: every wheel 2 % further out, w2 turned 0.5 degree.
    let text = std::fs::read_to_string(robot("omni3"))
        .unwrap()
        .replace("l_m = 0.15", "l_m = 0.153")
        .replace("alpha_deg = 180.0", "alpha_deg = 180.5");
    assert_ne!(text, std::fs::read_to_string(robot("omni3")).unwrap());
    let fitted = dir.join("fitted.toml");
    std::fs::write(&fitted, &text).unwrap();
    let (o, out, err) = board.run_text(&["robot", "set", fitted.to_str().unwrap()]);
    assert!(o.status.success(), "{err}");
    assert!(out.contains("not yet saved"), "{out}");
    let set = json_of(&board.run(&["--json", "robot", "get"]));
    for w in set["wheels"].as_array().unwrap() {
        assert_eq!(w["l_m"], 0.153, "{set}");
    }
    let alpha = set["wheels"][1]["alpha_deg"].as_f64().unwrap();
    assert!((alpha - 180.5).abs() < 1e-12, "{set}");
    // Another kind of robot: refused by name, nothing changed.
    let other = robot("mobolab");
    let (o, _, err) = board.run_text(&["robot", "set", other.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains(
            "mobolab.toml: a robot of kind diff_drive; the board's robot ('omni3') is of kind omni"
        ),
        "{err}"
    );
    assert_eq!(json_of(&board.run(&["--json", "robot", "get"])), set);
    // Saved, it is the board's robot after a restart; written back as a robot file, it
    // reads as the same geometry.
    assert!(board.run(&["robot", "save"]).status.success());
    drop(board);
    // A link of its own: the first board's may point at a pseudo-terminal now reused.
    let dir2 = scratch("robot-geometry-restart");
    let board = Board::start_with("omni3", &dir2, "max", &extra);
    let back = dir.join("back.toml");
    let again = json_of(&board.run(&["--json", "robot", "get", "--out", back.to_str().unwrap()]));
    assert_eq!(again, set);
    let read = formats::robot_file::load(&back).unwrap();
    assert!(read.wheels.iter().all(|w| w.l_m == 0.153), "{read:?}");
}
