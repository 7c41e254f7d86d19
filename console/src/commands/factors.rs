//! `wheelcal factors get|set|save|reset|export`.

use crate::board_cmds::{self, FactorsView};
use crate::cli::Ctx;
use crate::cli::{ExportArgs, FactorsCmd, SetArgs};
use crate::output::Output;
use crate::ros2;
use anyhow::{bail, Context, Result};

/// Dispatches `factors` subcommands.
pub fn run(cmd: FactorsCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    match cmd {
        FactorsCmd::Get => get(ctx, out),
        FactorsCmd::Set(a) => set(a, ctx, out),
        FactorsCmd::Save => save(ctx, out),
        FactorsCmd::Reset => reset(ctx, out),
        FactorsCmd::Export(a) => export(a, ctx, out),
    }
}

/// The active factors.
fn get(ctx: &mut Ctx, out: Output) -> Result<()> {
    let f = FactorsView::from(&ctx.client()?.corrections()?);
    out.emit(&f, || f.human())
}

/// Sets the active factors (the board validates them).
fn set(a: SetArgs, ctx: &mut Ctx, out: Output) -> Result<()> {
    let c = board_cmds::corrections_from_args(a.c_l, a.c_r, a.e_b, a.f_lat.as_deref(), a.f_lon)?;
    let client = ctx.client()?;
    client.set_corrections(c)?;
    let f = FactorsView::from(&client.corrections()?);
    out.emit(&f, || {
        format!(
            "set (not yet saved: `wheelcal factors save`): {}",
            f.human()
        )
    })
}

/// Persists the active factors.
fn save(ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    client.save_corrections()?;
    let f = FactorsView::from(&client.corrections()?);
    out.emit(&f, || format!("saved to flash: {}", f.human()))
}

/// Back to nominal geometry.
fn reset(ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    client.reset_corrections()?;
    let f = FactorsView::from(&client.corrections()?);
    out.emit(&f, || {
        "corrections reset to nominal (not yet saved: `wheelcal factors save`)\n".into()
    })
}

/// ROS 2 parameters from a result, the command line or the board.
fn export(a: ExportArgs, ctx: &mut Ctx, out: Output) -> Result<()> {
    let f = match (&a.from, a.c_l, a.c_r, a.e_b) {
        (Some(p), ..) => ros2::factors_from_json(p)?,
        (None, Some(c_l), Some(c_r), Some(e_b)) => ros2::DiffFactors { c_l, c_r, e_b },
        (None, None, None, None) => match ctx.client()?.corrections()? {
            calib_core::Corrections::DiffDrive { c_l, c_r, e_b } => {
                ros2::DiffFactors { c_l, c_r, e_b }
            }
            other => bail!(
                "the board's factors are not differential-drive factors: {}",
                board_cmds::factors_text(&other)
            ),
        },
        _ => bail!(
            "give --from RESULT.json, all of --c-l, --c-r, --e-b, or --port to read the board"
        ),
    };
    let yaml = ros2::diff_drive_yaml(&f, &a.controller)?;
    std::fs::write(&a.ros2, &yaml).with_context(|| format!("cannot write {}", a.ros2.display()))?;
    #[derive(serde::Serialize)]
    struct Exported<'a> {
        ros2_file: &'a std::path::Path,
        c_l: f64,
        c_r: f64,
        e_b: f64,
    }
    let e = Exported {
        ros2_file: &a.ros2,
        c_l: f.c_l,
        c_r: f.c_r,
        e_b: f.e_b,
    };
    out.emit(&e, || format!("wrote {}\n{yaml}", a.ros2.display()))
}
