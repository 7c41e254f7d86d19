//! The guided procedures shared by `umbmark run` and `omni run`: options from the
//! command line, a measurer (a person or the virtual board's truth), the run itself.

use crate::args::ProcedureArgs;
use crate::calibration::procedure;
use crate::output::Output;
use crate::session::Ctx;
use crate::sim_board;
use anyhow::Result;

/// `umbmark run` / `omni run`: the guided procedure on a board.
pub fn run(a: &ProcedureArgs, kind: procedure::Kind, ctx: &mut Ctx, out: Output) -> Result<()> {
    let port = ctx.port.clone().unwrap_or_default();
    let opts = procedure_options(a, &port, kind)?;
    let rep = procedure::run(ctx.client()?, &opts, measure_for(&opts).as_mut())?;
    out.emit(&rep, || rep.human())
}

/// A person with a tape measure, or the virtual board's truth with --auto-measure.
fn measure_for(opts: &procedure::Options) -> Box<dyn procedure::Measure> {
    match &opts.auto_measure {
        Some(file) => Box::new(procedure::TruthFile {
            file: file.clone(),
            quiet: false,
        }),
        None => Box::new(procedure::Terminal),
    }
}

/// The procedure's options from the command line; the truth file defaults to the one
/// the virtual board on `port` writes.
fn procedure_options(
    a: &ProcedureArgs,
    port: &str,
    kind: procedure::Kind,
) -> Result<procedure::Options> {
    let idle_wheels = match kind {
        procedure::Kind::Omni => crate::calibration::omni::idle_wheels_for(
            a.idle.idle_wheels.map(Into::into),
            &a.runs_file,
            a.robot.as_deref().unwrap_or(std::path::Path::new("")),
        )?,
        procedure::Kind::Umbmark => Default::default(),
    };
    Ok(procedure::Options {
        idle_wheels,
        kind,
        side_m: a.side,
        length_m: a.length,
        runs: a.runs,
        after_runs: a.after_runs.unwrap_or(a.runs),
        runs_file: a.runs_file.clone(),
        auto_measure: a.auto_measure.then(|| {
            a.truth
                .clone()
                .unwrap_or_else(|| sim_board::truth_file_for(std::path::Path::new(port)))
        }),
        report: a.report.clone(),
        after: !a.no_after,
        second_pass: a.second_pass,
        circles: a.circle_radius.map(|r| (r, a.circle_laps)),
    })
}
