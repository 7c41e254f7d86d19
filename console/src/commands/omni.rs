//! `wheelcal omni compute|run`.

use crate::args::{OmniCmd, OmniComputeArgs};
use crate::calibration::{omni, procedure};
use crate::output::Output;
use crate::report;
use crate::session::Ctx;
use anyhow::Result;
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
    if let Some(p) = &a.previous {
        rep = omni::compose_with(rep, &omni::factors_from_json(p)?)?;
    }
    if let Some(dir) = &a.common.report {
        let index = report::omni::write(&rep, dir)?;
        out.note(&format!("report: {}", index.display()));
    }
    out.emit(&rep, || rep.human())
}
