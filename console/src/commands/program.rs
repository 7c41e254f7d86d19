//! `wheelcal run umbmark|omni|circle`: one test path on the board.

use crate::args::RunCmd;
use crate::board;
use crate::output::Output;
use crate::session::Ctx;
use anyhow::{bail, Result};

/// Starts the program (validated first) and, unless --no-wait, follows it to its end.
pub fn run(cmd: RunCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    let link_ms = match &cmd {
        RunCmd::Umbmark { run, .. } | RunCmd::Omni { run, .. } | RunCmd::Circle { run, .. } => {
            run.link_timeout_ms()?
        }
    };
    let client = ctx.client()?;
    let (no_wait, limit) = match cmd {
        RunCmd::Umbmark { dir, side, run } => {
            let limit = board::run_umbmark(client, dir.into(), side, run.log_rate, link_ms)?;
            (run.no_wait, limit)
        }
        RunCmd::Omni {
            path,
            length,
            run,
            idle,
        } => {
            let idle = idle.idle_wheels.map(Into::into).unwrap_or_default();
            let limit = board::run_omni(client, path.into(), length, idle, run.log_rate, link_ms)?;
            (run.no_wait, limit)
        }
        RunCmd::Circle {
            dir,
            radius,
            laps,
            run,
        } => {
            let limit = board::run_circle(client, dir.into(), radius, laps, run.log_rate, link_ms)?;
            (run.no_wait, limit)
        }
    };
    let s = if no_wait {
        client.status()?
    } else {
        let human = out == Output::Human;
        board::wait_program(client, limit, |s| {
            if human {
                eprint!("\r{}", board::status_line(s));
            }
        })?
    };
    if out == Output::Human {
        eprintln!();
    }
    out.emit(&s, || format!("{}\n", board::status_line(&s)))?;
    // The program must have run to its end: a script takes exit 0 for "driven".
    use calib_core::protocol::StopReason;
    match s.stop {
        _ if no_wait => Ok(()),
        StopReason::ProgramDone => Ok(()),
        StopReason::LinkLost => bail!(
            "the board cut the program short: it heard nothing from this console for {link_ms} ms (--link-timeout; the console was suspended or starved): the path was not driven to its end"
        ),
        other => bail!(
            "the program ended before the path's end ({}): the path was not driven to its end",
            crate::calibration::procedure::stop_words(other)
        ),
    }
}
