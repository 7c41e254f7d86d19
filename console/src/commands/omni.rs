//! `wheelcal omni compute|run`.

use crate::args::{OmniCmd, OmniComputeArgs};
use crate::calibration::{omni, procedure};
use crate::output::Output;
use crate::report;
use crate::session::Ctx;
use anyhow::{bail, Context, Result};
use formats::robot_file;
use formats::runs_file::RunsFile;

/// Dispatches `omni` subcommands.
pub fn run(cmd: OmniCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    match cmd {
        OmniCmd::Compute(a) => compute(a, out),
        OmniCmd::Run(a) => super::procedure::run(&a, procedure::Kind::Omni, ctx, out),
    }
}

/// F_lat and F_lon from measured end errors (composed with --previous).
fn compute(a: OmniComputeArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.common.robot)?;
    let runs = RunsFile::load(&a.common.runs)?;
    let idle = omni::idle_wheels_for(
        a.idle.idle_wheels.map(Into::into),
        &a.common.runs,
        &a.common.robot,
    )?;
    let mut rep = omni::compute_limited(&robot, &runs, idle, a.common.max_length)?;
    let previous = a
        .previous
        .as_deref()
        .map(omni::factors_from_json)
        .transpose()?;
    if let Some(p) = &previous {
        rep = omni::compose_with(rep, p)?;
    }
    rep = omni::with_circles(rep, &robot, &runs, previous.as_ref())?;
    // Outputs only once everything succeeded (as `calibrate`): the board robot is
    // computed and its target checked, the report written, and only then the file.
    let board_robot = match &a.write_board_robot {
        Some(file) => {
            let Some(board) = rep.board_robot(&robot)? else {
                bail!(
                    "--write-board-robot {}: {} has no circle rows: the board robot carries the wheels' distance the circles show (drive a turn in place and circles: `omni run --circle-radius R`)",
                    file.display(),
                    a.common.runs.display()
                );
            };
            let text = format!(
                "# {} with the wheel sizes of omni compute's factors and the wheel distance of its circle test ({}), for a board holding factors of one and the turn law\n{}",
                robot.name,
                a.common.runs.display(),
                robot_file::to_toml(&board)
            );
            formats::safe_write::check_target(file, "robot description", robot_file::is_robot_file)
                .with_context(|| format!("cannot write {}", file.display()))?;
            Some((file, text))
        }
        None => None,
    };
    let index = match &a.common.report {
        Some(dir) => Some(report::omni::write(&rep, dir)?),
        None => None,
    };
    if let Some((file, text)) = board_robot {
        robot_file::write(file, &text)
            .with_context(|| format!("cannot write {}", file.display()))?;
        out.note(&format!(
            "board robot: {} (put it on the board with this result's JSON: `wheelcal apply RESULT.json --board-robot {} --save`)",
            file.display(),
            file.display()
        ));
    }
    if let Some(index) = index {
        out.note(&format!("report: {}", index.display()));
    }
    out.emit(&rep, || rep.human())
}
