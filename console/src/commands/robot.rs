//! `wheelcal robot get|set|save`: the robot geometry on the board. There is no `reset`:
//! the firmware's default parameters describe no particular robot, so a board reset to
//! them would no longer match its own motors and encoders; `set` the robot file instead.

use crate::args::RobotCmd;
use crate::board::{self, RobotView};
use crate::output::Output;
use crate::session::Ctx;
use anyhow::{anyhow, Context, Result};

/// Dispatches `robot` subcommands.
pub fn run(cmd: RobotCmd, ctx: &mut Ctx, out: Output) -> Result<()> {
    let client = ctx.client()?;
    let said = match cmd {
        RobotCmd::Get { out: file } => {
            let robot = client.params()?.robot;
            if let Some(f) = &file {
                formats::robot_file::write(f, &formats::robot_file::to_toml(&robot))
                    .with_context(|| format!("cannot write {}", f.display()))?;
            }
            file.map(|f| format!("written to {}", f.display()))
        }
        RobotCmd::Set { file } => {
            let robot = formats::robot_file::load(&file).map_err(|e| anyhow!("{e}"))?;
            let p = board::with_robot(&client.params()?, robot, &file)?;
            client.set_params(p)?;
            Some(format!(
                "set from {} (not yet saved: `wheelcal robot save`)",
                file.display()
            ))
        }
        RobotCmd::Save => {
            client.save_params()?;
            Some("saved to flash".into())
        }
    };
    let v = RobotView::from(&client.params()?.robot);
    out.emit(&v, || match &said {
        Some(s) => format!("{s}: {}", v.human()),
        None => v.human(),
    })
}
