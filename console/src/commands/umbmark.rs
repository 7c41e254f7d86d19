//! `wheelcal umbmark compute|run`.

use crate::args::{ComputeArgs, UmbmarkCmd};
use crate::calibration::{procedure, umbmark};
use crate::output::Output;
use crate::report;
use crate::session::Ctx;
use anyhow::Result;
use formats::robot_file;
use formats::runs_file::RunsFile;

/// Dispatches `umbmark` subcommands.
pub fn run(cmd: UmbmarkCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    match cmd {
        UmbmarkCmd::Compute(a) => compute(a, out),
        UmbmarkCmd::Run(a) => super::procedure::run(&a, procedure::Kind::Umbmark, ctx, out),
    }
}

/// E_d, E_b, c_L, c_R from measured end errors.
fn compute(a: ComputeArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    let runs = RunsFile::load(&a.runs)?;
    let rep = umbmark::compute_limited(&robot, &runs, a.max_length)?;
    if let Some(dir) = &a.report {
        let index = report::umbmark::write(&rep, dir)?;
        out.note(&format!("report: {}", index.display()));
    }
    out.emit(&rep, || rep.human())
}
