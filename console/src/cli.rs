//! Entry point and dispatcher of `wheelcal`: parses the command line ([`crate::args`])
//! and hands each subcommand to its module in [`crate::commands`]. Nothing imports this
//! module but the binary, so the command modules never depend on their dispatcher.

use crate::args::{Cli, Command};
use crate::output::Output;
use crate::session::{name_the_port, Ctx};
use anyhow::Result;
use clap::Parser;
use std::process::ExitCode;

/// Entry point of the binary: runs the command, prints errors to stderr.
pub fn main() -> ExitCode {
    crate::stop::install();
    let cli = Cli::parse();
    let mut ctx = Ctx {
        port: cli.port.clone(),
        baud: cli.baud,
        client: None,
        relay: None,
    };
    match run(cli, &mut ctx) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) if e.is::<crate::stop::Interrupted>() => {
            eprintln!("{e}");
            ExitCode::from(130)
        }
        Err(e) => {
            let e = name_the_port(e, &ctx);
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs a parsed command line: dispatch only, each command is a module of
/// [`crate::commands`].
pub fn run(cli: Cli, ctx: &mut Ctx) -> Result<()> {
    use crate::commands::{
        apply, board, calibrate, diagnose, evaluate, factors, log, omni, program, robot, sim,
        umbmark,
    };
    let out = Output::from_flag(cli.json);
    formats::safe_write::set_force(cli.force);
    match cli.command {
        Command::Info => board::info(ctx, out),
        Command::Factors(cmd) => factors::run(cmd, ctx, out),
        Command::Robot(cmd) => robot::run(cmd, ctx, out),
        Command::Apply(a) => apply::run(&a, ctx, out),
        Command::Drive(a) => board::drive(a, ctx, out),
        Command::Run(cmd) => program::run(cmd, ctx, out),
        Command::Status {
            follow,
            period_ms,
            foxglove,
        } => board::status_live(follow, period_ms, foxglove.as_deref(), ctx, out),
        Command::Log(cmd) => log::run(cmd, ctx, out),
        Command::Stop => board::stop(ctx, out),
        Command::Estop => board::estop(ctx, out),
        Command::ClearFault => board::clear_fault(ctx, out),
        Command::Console => crate::repl::run(ctx, cli.json, run),
        Command::Umbmark(cmd) => umbmark::run(cmd, ctx, out),
        Command::Omni(cmd) => omni::run(cmd, ctx, out),
        Command::SimBoard(a) => sim::sim_board(a, out),
        Command::Demo(a) => sim::demo(a, out),
        Command::Diagnose(a) => diagnose::run(a, out),
        Command::Calibrate(a) => calibrate::run(&a, out),
        Command::Evaluate(a) => evaluate::run(&a, out),
        Command::Sim(cmd) => sim::run(cmd, out),
        Command::Import(cmd) => crate::commands::import::run(cmd, out),
    }
}

#[cfg(test)]
mod tests {
    /// Errors keep their causes (`source()`), so `{:#}` shows the chain once and a
    /// caller can still find the OS error under it.
    #[test]
    fn causes_are_kept_not_flattened_into_text() {
        use std::io;
        let e =
            crate::client::ClientError::Io(io::Error::new(io::ErrorKind::BrokenPipe, "pipe gone"));
        let a = anyhow::Error::from(e).context("log transfer of trial 3 failed");
        assert_eq!(
            format!("{a:#}"),
            "log transfer of trial 3 failed: serial I/O error: pipe gone"
        );
        assert!(a.chain().any(|c| c.downcast_ref::<io::Error>().is_some()));
        let s = sim::SimError::Io {
            path: "out/recording.csv".into(),
            error: io::Error::new(io::ErrorKind::PermissionDenied, "denied"),
        };
        let a = anyhow::Error::from(s);
        assert_eq!(format!("{a:#}"), "cannot write out/recording.csv: denied");
        assert!(a.chain().any(|c| c.downcast_ref::<io::Error>().is_some()));
    }
}
