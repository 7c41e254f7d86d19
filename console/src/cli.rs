//! Command-line interface of `wheelcal` (clap). Each subcommand is a few lines that call
//! the library modules, so the tests exercise the same code.

use crate::calibration::{omni, umbmark};
use crate::output::Output;
use crate::{report, ros2};
use anyhow::{Context, Result};
use calib_core::robot_file;
use calib_core::runs_file::RunsFile;
use clap::{Args, Parser, Subcommand};
use std::path::PathBuf;
use std::process::ExitCode;

/// wheelcal: calibrate wheeled robots' odometry, talk to wheelcal boards, diagnose
/// simulation against recordings.
#[derive(Debug, Parser)]
#[command(name = "wheelcal", version, about, long_about = None)]
pub struct Cli {
    /// One JSON object per result on stdout (human text otherwise).
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// UMBmark (Borenstein's bidirectional square) for differential drives.
    #[command(subcommand)]
    Umbmark(UmbmarkCmd),
    /// 001's F_lat / F_lon calibration for omni robots.
    #[command(subcommand)]
    Omni(OmniCmd),
    /// Correction factors: export to other tools.
    #[command(subcommand)]
    Factors(FactorsCmd),
}

#[derive(Debug, Subcommand)]
pub enum UmbmarkCmd {
    /// Compute E_d, E_b, c_L, c_R from measured end errors (formats.md §3).
    Compute(ComputeArgs),
}

#[derive(Debug, Subcommand)]
pub enum OmniCmd {
    /// Compute F_lat and F_lon from measured end errors of paths 4W-1 / 4W-2.
    Compute(ComputeArgs),
}

#[derive(Debug, Args)]
pub struct ComputeArgs {
    /// Robot description (formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Measured runs (formats.md §3).
    #[arg(long)]
    pub runs: PathBuf,
    /// Write an HTML report with SVG and PNG plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

#[derive(Debug, Subcommand)]
pub enum FactorsCmd {
    /// Export factors, e.g. as ROS 2 diff_drive_controller parameters.
    Export(ExportArgs),
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Write a ROS 2 parameter YAML file (left/right_wheel_radius_multiplier = c_L/c_R,
    /// wheel_separation_multiplier = E_b).
    #[arg(long)]
    pub ros2: PathBuf,
    /// Take the factors from a `--json` result (`umbmark compute --json > result.json`).
    #[arg(long, conflicts_with_all = ["c_l", "c_r", "e_b"])]
    pub from: Option<PathBuf>,
    #[arg(long)]
    pub c_l: Option<f64>,
    #[arg(long)]
    pub c_r: Option<f64>,
    #[arg(long)]
    pub e_b: Option<f64>,
    /// Controller name at the top of the YAML.
    #[arg(long, default_value = "diff_drive_controller")]
    pub controller: String,
}

/// Entry point of the binary: runs the command, prints errors to stderr.
pub fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli) -> Result<()> {
    let out = Output::from_flag(cli.json);
    match cli.command {
        Command::Umbmark(UmbmarkCmd::Compute(a)) => {
            let robot = robot_file::load(&a.robot)?;
            let runs = RunsFile::load(&a.runs)?;
            let rep = umbmark::compute(&robot, &runs)?;
            if let Some(dir) = &a.report {
                let index = report::umbmark::write(&rep, dir)?;
                out.note(&format!("report: {}", index.display()));
            }
            out.emit(&rep, || rep.human())
        }
        Command::Omni(OmniCmd::Compute(a)) => {
            let robot = robot_file::load(&a.robot)?;
            let runs = RunsFile::load(&a.runs)?;
            let rep = omni::compute(&robot, &runs)?;
            if let Some(dir) = &a.report {
                let index = report::omni::write(&rep, dir)?;
                out.note(&format!("report: {}", index.display()));
            }
            out.emit(&rep, || rep.human())
        }
        Command::Factors(FactorsCmd::Export(a)) => {
            let f = match (&a.from, a.c_l, a.c_r, a.e_b) {
                (Some(p), ..) => ros2::factors_from_json(p)?,
                (None, Some(c_l), Some(c_r), Some(e_b)) => ros2::DiffFactors { c_l, c_r, e_b },
                _ => anyhow::bail!("give --from RESULT.json or all of --c-l, --c-r, --e-b"),
            };
            let yaml = ros2::diff_drive_yaml(&f, &a.controller);
            std::fs::write(&a.ros2, &yaml)
                .with_context(|| format!("cannot write {}", a.ros2.display()))?;
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
    }
}
