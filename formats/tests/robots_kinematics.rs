//! Every robot in `robots/`: parses, and forward kinematics inverts inverse kinematics.

use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::{Robot, RobotKind};
use calib_core::Corrections;
use formats::robot_file;
use proptest::prelude::*;
use std::path::PathBuf;

fn robots() -> Vec<(PathBuf, Robot)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../robots");
    let mut out: Vec<_> = std::fs::read_dir(&dir)
        .expect("robots/ next to calib-core")
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| {
            let r = robot_file::load(&p).unwrap_or_else(|e| panic!("{e}"));
            (p, r)
        })
        .collect();
    out.sort_by(|a, b| a.0.cmp(&b.0));
    out
}

#[test]
fn all_seven_robots_parse() {
    let names: Vec<String> = robots().iter().map(|(_, r)| r.name.to_string()).collect();
    assert_eq!(
        names,
        ["mobolab", "omni3", "omni4", "robotest", "rover4", "sweeper", "wlr"]
    );
}

/// rover4.toml is the skid4 preset written out: the same wheel rows to the file's ten
/// decimals of a degree.
#[test]
fn rover4_file_is_the_skid4_preset() {
    let file = robots()
        .into_iter()
        .find(|(_, r)| r.name == "rover4")
        .expect("robots/rover4.toml")
        .1;
    assert_eq!(file.kind, RobotKind::SkidSteer);
    let preset = calib_core::robot::presets::skid4("rover4", 0.1, 0.40, 0.31, file.drive);
    for (a, b) in file.wheels.iter().zip(&preset.wheels) {
        assert_eq!(a.name, b.name);
        for (x, y) in a.rolling_row().iter().zip(b.rolling_row()) {
            assert!((x - y).abs() < 1e-9, "{}: {x} vs {y}", a.name);
        }
    }
}

proptest! {
    /// Standard-wheeled robots cannot move sideways, so their twists have vy = 0; omni
    /// robots take any twist. The round trip is exact up to f64 rounding, except the
    /// skid-steered robots (wheeled-legged and skid_steer), whose contradicting sliding constraints are
    /// weighted 1e-3 and so perturb a turn by ~1e-6 relative.
    #[test]
    fn forward_inverts_inverse(vx in -1.0f64..1.0, vy in -1.0f64..1.0, w in -3.0f64..3.0) {
        for (path, robot) in robots() {
            let k = Kinematics::<f64>::new(&robot, &Corrections::None).unwrap();
            let vy = if robot.kind == RobotKind::Omni { vy } else { 0.0 };
            let t = Twist::new(vx, vy, w);
            let back = k.forward(&k.inverse(&t));
            let skids = matches!(robot.kind, RobotKind::WheeledLegged | RobotKind::SkidSteer);
            let tol = if skids { 1e-5 } else { 1e-9 };
            prop_assert!((back.vx - vx).abs() < tol, "{}: vx {} vs {}", path.display(), back.vx, vx);
            prop_assert!((back.vy - vy).abs() < tol, "{}: vy {} vs {}", path.display(), back.vy, vy);
            prop_assert!((back.omega - w).abs() < tol * 3.0, "{}: omega {} vs {}", path.display(), back.omega, w);
        }
    }

    /// The same in f32, as the firmware runs it: relative error at f32 precision.
    #[test]
    fn forward_inverts_inverse_f32(vx in -1.0f32..1.0, vy in -1.0f32..1.0, w in -3.0f32..3.0) {
        for (_, robot) in robots() {
            let k = Kinematics::<f32>::new(&robot, &Corrections::None).unwrap();
            let vy = if robot.kind == RobotKind::Omni { vy } else { 0.0 };
            let back = k.forward(&k.inverse(&Twist::new(vx, vy, w)));
            prop_assert!((back.vx - vx).abs() < 2e-5 && (back.vy - vy).abs() < 2e-5 && (back.omega - w).abs() < 1e-4);
        }
    }
}
