//! The robot geometry a board holds (`wheelcal robot get|set|save`): the wheels'
//! radii, positions and angles its kinematics and odometry use. A calibration's full
//! geometry (an omni robot's wheel distances, angles and centre, which no correction
//! factor carries) reaches the board this way, from `calibrate --write-board-robot`.

use anyhow::{bail, Result};
use calib_core::protocol::Params;
use calib_core::robot::Robot;
use serde::Serialize;
use std::path::Path;

/// One wheel of a board's robot, in the robot file's units.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct WheelView {
    /// The wheel's name.
    pub name: String,
    /// Radius, m.
    pub radius_m: f64,
    /// Distance of the wheel's centre from the body origin, m.
    pub l_m: f64,
    /// Polar angle of the wheel's centre, degrees.
    pub alpha_deg: f64,
    /// Wheel plane angle, degrees.
    pub beta_deg: f64,
    /// Roller angle, degrees.
    pub gamma_deg: f64,
}

/// A board's robot as `robot get` shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RobotView {
    /// The robot's name.
    pub name: String,
    /// Its kind, as in the robot file.
    pub kind: String,
    /// The wheels, in the robot's order.
    pub wheels: Vec<WheelView>,
}

impl From<&Robot> for RobotView {
    fn from(r: &Robot) -> Self {
        RobotView {
            name: r.name.to_string(),
            kind: r.kind.as_str().into(),
            wheels: r
                .wheels
                .iter()
                .map(|w| WheelView {
                    name: w.name.to_string(),
                    radius_m: w.radius_m,
                    l_m: w.l_m,
                    alpha_deg: w.alpha_rad.to_degrees(),
                    beta_deg: w.beta_rad.to_degrees(),
                    gamma_deg: w.gamma_rad.to_degrees(),
                })
                .collect(),
        }
    }
}

impl RobotView {
    /// One line for the robot, one per wheel.
    pub fn human(&self) -> String {
        let mut s = format!("robot '{}' ({})\n", self.name, self.kind);
        for w in &self.wheels {
            s.push_str(&format!(
                "  {:<8} radius {:.6} m, l {:.6} m, alpha {:.4} deg, beta {:.4} deg, gamma {:.4} deg\n",
                w.name, w.radius_m, w.l_m, w.alpha_deg, w.beta_deg, w.gamma_deg
            ));
        }
        s
    }
}

/// The board's parameters `current` with the robot of the file `file` (`robot`) in place
/// of its own; its gains, limits and safety settings kept. The board's motors and
/// encoders are wired per wheel, so the file must describe the same kind of robot with
/// the same wheels in the same order; refused otherwise, naming the file. The board
/// itself then validates the geometry and that its factors still fit.
pub fn with_robot(current: &Params, robot: Robot, file: &Path) -> Result<Params> {
    let board = &current.robot;
    if robot.kind != board.kind {
        bail!(
            "{}: a robot of kind {}; the board's robot ('{}') is of kind {}",
            file.display(),
            robot.kind.as_str(),
            board.name,
            board.kind.as_str()
        );
    }
    let names = |r: &Robot| {
        r.wheels
            .iter()
            .map(|w| w.name.to_string())
            .collect::<Vec<_>>()
    };
    if names(&robot) != names(board) {
        bail!(
            "{}: wheels {}; the board's motors and encoders are wired as {} (the same wheels, in the same order)",
            file.display(),
            names(&robot).join(", "),
            names(board).join(", ")
        );
    }
    Ok(Params {
        robot,
        ..current.clone()
    })
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A robot file of `robots/` (the board commands' tests share it).
    pub(crate) fn robot(name: &str) -> Robot {
        let p = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(format!("{name}.toml"));
        formats::robot_file::load(&p).unwrap()
    }

    /// The file's geometry replaces the board's, to the bit, and nothing else changes;
    /// another kind of robot, or other wheels, is refused naming the file.
    #[test]
    fn a_robot_file_of_the_same_wheels_replaces_the_boards_geometry_only() {
        let board = crate::virtual_board::board_params(&robot("omni3"));
        let mut fitted = robot("omni3");
        fitted.wheels[1].l_m *= 1.02;
        fitted.wheels[2].alpha_rad += 0.01;
        let p = with_robot(&board, fitted.clone(), Path::new("fit.toml")).unwrap();
        assert_eq!(p.robot, fitted);
        assert_eq!(
            (p.gains, p.limits, p.safety),
            (board.gains, board.limits, board.safety)
        );
        let e = with_robot(&board, robot("mobolab"), Path::new("m.toml")).unwrap_err();
        assert_eq!(
            e.to_string(),
            "m.toml: a robot of kind diff_drive; the board's robot ('omni3') is of kind omni"
        );
        let mut renamed = robot("omni3");
        renamed.wheels.swap(0, 1);
        let e = with_robot(&board, renamed, Path::new("r.toml")).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("r.toml: wheels w2, w1, w3; the board's motors"),
            "{e}"
        );
        let v = RobotView::from(&fitted);
        assert_eq!(v.wheels[1].l_m, fitted.wheels[1].l_m);
        assert!(v.human().contains("alpha"), "{}", v.human());
    }
}
