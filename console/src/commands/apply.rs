//! `wheelcal apply CALIBRATION [--board-robot FILE] [--save]`: a calibration put on the
//! board in one step. With `--board-robot` (`calibrate --write-board-robot`'s file) the
//! board gets that geometry and factors of one with the calibration's laws; without it,
//! the calibration's factors for the robot the board holds, or, when the calibration
//! fitted geometry no factor carries (an omni robot's wheel distances, angles, centre or
//! roller angle), its own fitted geometry as with `--board-robot` (`--factors-only` keeps
//! the board's). Set together or not at all ([`board::apply_settings`]), read back, and
//! saved with `--save`.

use crate::args::ApplyArgs;
use crate::board::{self, FactorsView, RobotView, Target};
use crate::calibration::saved::SavedCalibration;
use crate::output::Output;
use crate::session::Ctx;
use anyhow::{anyhow, bail, Result};
use serde::Serialize;
use std::path::PathBuf;

/// What `apply` did, as printed and in the JSON.
#[derive(Serialize)]
struct Applied {
    calibration: PathBuf,
    /// The robot file whose geometry the board now holds (none: its own was kept).
    board_robot: Option<PathBuf>,
    saved: bool,
    robot: RobotView,
    factors: FactorsView,
    /// The board took the calibration's own fitted geometry (its `board_geometry`): no
    /// factor carries some of what was fitted.
    geometry_from_calibration: bool,
    /// Fitted parameters no factor carries, left out (`--factors-only`, or a result that
    /// carries no geometry).
    without_factor: Vec<String>,
}

/// Runs `wheelcal apply`.
pub fn run(a: &ApplyArgs, ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    let current = client.params()?;
    // Refused, naming the file, before anything is sent: another kind of robot, numbers
    // missing, another robot's wheels.
    let saved = SavedCalibration::read(&a.calibration, &current.robot, "apply")?;
    if saved.robot_name() != current.robot.name.as_str() {
        bail!(
            "{}: a calibration of robot '{}'; the board holds robot '{}': apply a calibration of the board's robot (if it is the same robot under another name, give the board its robot file first: `wheelcal robot set FILE.toml`)",
            a.calibration.display(),
            saved.robot_name(),
            current.robot.name
        );
    }
    let fitted = if a.board_robot.is_none() && !a.factors_only {
        saved.board_geometry(&current.robot)?
    } else {
        None
    };
    let geometry_from_calibration = fitted.is_some();
    let (target, without_factor) = match (&a.board_robot, fitted) {
        (None, Some(robot)) => {
            let params = board::with_robot(&current, robot, &a.calibration)?;
            let corrections = saved.law_corrections(params.robot.wheels.len())?;
            let t = Target {
                params: Some(params),
                corrections,
            };
            (t, Vec::new())
        }
        (Some(file), _) => {
            let robot = formats::robot_file::load(file).map_err(|e| anyhow!("{e}"))?;
            saved.check_board_robot(&robot, file, &current.robot)?;
            let params = board::with_robot(&current, robot, file)?;
            let corrections = saved.law_corrections(params.robot.wheels.len())?;
            let t = Target {
                params: Some(params),
                corrections,
            };
            (t, Vec::new())
        }
        (None, None) => {
            let corrections = saved
                .factors_for(&current.robot)
                .map_err(|e| anyhow!("{e}: the board already holds the geometry they correct"))?;
            let t = Target {
                params: None,
                corrections,
            };
            (t, saved.without_factor())
        }
    };
    board::apply_settings(client, &target)
        .map_err(|e| anyhow!("{}: {e}", a.calibration.display()))?;
    if a.save {
        if target.params.is_some() {
            client.save_params()?;
        }
        client.save_corrections()?;
    }
    let applied = Applied {
        calibration: a.calibration.clone(),
        board_robot: a.board_robot.clone(),
        geometry_from_calibration,
        saved: a.save,
        robot: RobotView::from(&client.params()?.robot),
        factors: FactorsView::from(&client.corrections()?),
        without_factor,
    };
    out.emit(&applied, || human(&applied))
}

fn human(a: &Applied) -> String {
    let mut s = format!("applied {}", a.calibration.display());
    if let Some(f) = &a.board_robot {
        s += &format!(" with the geometry of {}", f.display());
    }
    if a.geometry_from_calibration {
        s += " with its fitted geometry (no factor carries all of it)";
    }
    s += if a.saved {
        " (saved to flash)\n"
    } else {
        " (not yet saved: `wheelcal robot save` and `wheelcal factors save`, or apply again with --save)\n"
    };
    s += &format!("robot: {}", a.robot.human());
    s += &format!("factors: {}", a.factors.human());
    if !a.without_factor.is_empty() {
        s += &format!(
            "note: no factor carries {}, so the board goes without them: apply without --factors-only to give the board the calibration's fitted geometry, or write the board robot (`calibrate --write-board-robot FILE`, or `omni compute --write-board-robot FILE` after an omni circle test) and apply with `--board-robot FILE`\n",
            a.without_factor.join(", ")
        );
    }
    s
}
