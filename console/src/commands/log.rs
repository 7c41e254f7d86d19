//! `wheelcal log list|pull|clear`.

use crate::args::LogCmd;
use crate::board;
use crate::output::Output;
use crate::session::Ctx;
use anyhow::Result;
use std::path::PathBuf;

/// Dispatches `log` subcommands.
pub fn run(cmd: LogCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    match cmd {
        LogCmd::List => list(ctx, out),
        LogCmd::Pull {
            trial,
            out: file,
            tum,
        } => pull(trial, file, tum, ctx, out),
        LogCmd::Clear => clear(ctx, out),
    }
}

/// The trials on the board.
fn list(ctx: &mut Ctx, out: Output) -> Result<()> {
    let t = board::trial_list(&ctx.client()?.trials()?);
    out.emit(&t, || t.human())
}

/// Downloads a trial as a recording, with a progress bar on stderr.
fn pull(trial: u16, file: PathBuf, tum: Option<PathBuf>, ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    // Ctrl-C ends the transfer between chunks; nothing is written (the file only
    // appears when the whole trial is in).
    let _guard = crate::stop::Guard::new();
    let bar = indicatif::ProgressBar::new(0);
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{msg} [{bar:40}] {bytes}/{total_bytes} {bytes_per_sec}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_message(format!("trial {trial}"));
    let r =
        board::trial_log::pull_trial_with(client, trial, &file, tum.as_deref(), |done, total| {
            bar.set_length(total);
            bar.set_position(done);
        });
    bar.finish_and_clear();
    let r = r?;
    out.emit(&r, || {
        format!(
            "trial {} -> {}: {} records ({} bytes) in {:.2} s, {} retries{}\n",
            r.trial,
            r.file,
            r.records,
            r.bytes,
            r.seconds,
            r.retries,
            r.warnings()
        ) + &r
            .tum
            .iter()
            .map(|f| format!("TUM trajectory: {f}\n"))
            .collect::<String>()
    })
}

/// Deletes all trials.
fn clear(ctx: &mut Ctx, out: Output) -> Result<()> {
    ctx.client()?.clear_logs()?;
    out.emit(&serde_json::json!({"cleared": true}), || {
        "trial logs cleared\n".into()
    })
}
