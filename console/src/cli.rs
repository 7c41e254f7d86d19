//! Command-line interface of `wheelcal` (clap). Each subcommand is a few lines that call
//! the library modules, so the tests exercise the same code.

use crate::board_cmds::{self, FactorsView};
use crate::calibration::{omni, procedure, umbmark};
use crate::client::Client;
use crate::output::Output;
use crate::sim_board::{self, SimBoardOptions};
use crate::{demo, link, report, ros2};
use anyhow::{bail, Context, Result};
use calib_core::motion::{Direction, OmniPath};
use calib_core::Twist;
use clap::{Args, Parser, Subcommand, ValueEnum};
use formats::robot_file;
use formats::runs_file::RunsFile;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// wheelcal: calibrate wheeled robots' odometry, talk to wheelcal boards, diagnose
/// simulation against recordings.
#[derive(Debug, Parser)]
#[command(name = "wheelcal", version, about, long_about = None)]
pub struct Cli {
    /// Serial port of the board (or a virtual board's link, see `sim-board`).
    #[arg(long, global = true, env = "WHEELCAL_PORT")]
    pub port: Option<String>,
    /// Baud rate of the serial port.
    #[arg(long, global = true, default_value_t = 115_200)]
    pub baud: u32,
    /// One JSON object per result on stdout (human text otherwise).
    #[arg(long, global = true)]
    pub json: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Firmware, protocol and robot of the board.
    Info,
    /// Correction factors on the board, or exported to other tools.
    #[command(subcommand)]
    Factors(FactorsCmd),
    /// Drive at a body twist for a while, then stop.
    Drive(DriveArgs),
    /// Run one of the papers' test paths on the board.
    #[command(subcommand)]
    Run(RunCmd),
    /// The board's state; with --follow, a live telemetry stream.
    Status {
        #[arg(long)]
        follow: bool,
        /// Telemetry period with --follow.
        #[arg(long, default_value_t = 200)]
        period_ms: u16,
    },
    /// Trial logs on the board.
    #[command(subcommand)]
    Log(LogCmd),
    /// Controlled stop.
    Stop,
    /// Emergency stop: motors off now, latched until `clear-fault`.
    Estop,
    /// Clears a latched E-stop or fault.
    ClearFault,
    /// Interactive prompt with history and completion, for people at a bench.
    Console,
    /// UMBmark (Borenstein's bidirectional square) for differential drives.
    #[command(subcommand)]
    Umbmark(UmbmarkCmd),
    /// 001's F_lat / F_lon calibration for omni robots.
    #[command(subcommand)]
    Omni(OmniCmd),
    /// A virtual board (the firmware's application on the simulator) on a pseudo-terminal.
    SimBoard(SimBoardArgs),
    /// The whole UMBmark procedure on a virtual board with hidden errors, before and after.
    Demo(DemoArgs),
    /// Where a simulation and a recording part: locate, name the physics left out, fit it.
    Diagnose(DiagnoseArgs),
    /// The robot's geometry fitted to whole trajectories with motion-capture ground truth.
    Calibrate(crate::calibrate_cmd::CalibrateArgs),
    /// Simulator tools.
    #[command(subcommand)]
    Sim(SimCmd),
}

#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Robot description (formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Recording (formats.md §2): a CSV file or a run folder; repeatable, or a directory
    /// of run folders: several recordings are diagnosed jointly (shared geometry).
    #[arg(long, required = true)]
    pub recording: Vec<PathBuf>,
    /// Write an HTML report with plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the robot description with the fitted geometry applied.
    #[arg(long)]
    pub write_robot: Option<PathBuf>,
    /// Most effects to combine in one explanation.
    #[arg(long, default_value_t = 3)]
    pub max_effects: usize,
}

#[derive(Debug, Subcommand)]
pub enum SimCmd {
    /// Write a simulated recording with effects hidden in it (recording.csv, robot.toml,
    /// truth.csv, effects.txt).
    Record(SimRecordArgs),
}

#[derive(Debug, Args)]
pub struct SimRecordArgs {
    /// Robot description (formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// An effect to hide, `ID` or `ID=name:value,...` (catalogue ids of `diagnose`, or
    /// `tilted_floor`); repeatable.
    #[arg(long)]
    pub effect: Vec<String>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Length of the random trajectory, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub duration: f64,
    /// Drive a UMBmark square of this side (metres) instead of a random trajectory.
    #[arg(long)]
    pub umbmark_side: Option<f64>,
    /// Rows per second.
    #[arg(long, default_value_t = 200.0)]
    pub rate: f64,
    /// Camera pose noise, metres (standard deviation).
    #[arg(long)]
    pub vision_noise: Option<f64>,
}

#[derive(Debug, Subcommand)]
pub enum FactorsCmd {
    /// Show the active factors.
    Get,
    /// Set the active factors (validated by the board; not persisted until `save`).
    Set(SetArgs),
    /// Persist the active factors in the board's flash.
    Save,
    /// Back to nominal geometry (persist with `save`).
    Reset,
    /// Export factors, e.g. as ROS 2 diff_drive_controller parameters.
    Export(ExportArgs),
}

#[derive(Debug, Args)]
pub struct SetArgs {
    #[arg(long)]
    pub c_l: Option<f64>,
    #[arg(long)]
    pub c_r: Option<f64>,
    #[arg(long)]
    pub e_b: Option<f64>,
    /// Omni: one factor per wheel, comma-separated, in the robot file's order.
    #[arg(long, value_delimiter = ',')]
    pub f_lat: Option<Vec<f64>>,
    #[arg(long)]
    pub f_lon: Option<f64>,
}

#[derive(Debug, Args)]
pub struct ExportArgs {
    /// Write a ROS 2 parameter YAML file (left/right_wheel_radius_multiplier = c_L/c_R,
    /// wheel_separation_multiplier = E_b).
    #[arg(long)]
    pub ros2: PathBuf,
    /// Take the factors from a `--json` result (`umbmark compute --json > result.json`);
    /// without it and without --c-l/--c-r/--e-b, from the board (--port).
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

#[derive(Debug, Args)]
pub struct DriveArgs {
    /// Forward speed, m/s.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub vx: f32,
    /// Sideways speed (omni), m/s.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub vy: f32,
    /// Turn rate, rad/s (counter-clockwise positive).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub omega: f32,
    /// How long, seconds.
    #[arg(long, default_value_t = 1.0)]
    pub duration: f64,
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DirArg {
    Cw,
    Ccw,
}

impl From<DirArg> for Direction {
    fn from(d: DirArg) -> Self {
        match d {
            DirArg::Cw => Direction::Cw,
            DirArg::Ccw => Direction::Ccw,
        }
    }
}

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PathArg {
    #[value(name = "4W-1")]
    W1,
    #[value(name = "4W-2")]
    W2,
}

impl From<PathArg> for OmniPath {
    fn from(p: PathArg) -> Self {
        match p {
            PathArg::W1 => OmniPath::W1,
            PathArg::W2 => OmniPath::W2,
        }
    }
}

#[derive(Debug, Subcommand)]
pub enum RunCmd {
    /// A UMBmark square.
    Umbmark {
        #[arg(long, value_enum)]
        dir: DirArg,
        /// Side of the square, metres.
        #[arg(long, default_value_t = 4.0)]
        side: f64,
        /// Trial log rate, Hz (0 = no log).
        #[arg(long, default_value_t = 50)]
        log_rate: u16,
        /// Return at once instead of waiting for the end.
        #[arg(long)]
        no_wait: bool,
    },
    /// 001's straight omni path.
    Omni {
        #[arg(long, value_enum)]
        path: PathArg,
        /// Commanded length, metres.
        #[arg(long, default_value_t = 0.6)]
        length: f64,
        #[arg(long, default_value_t = 50)]
        log_rate: u16,
        #[arg(long)]
        no_wait: bool,
    },
}

#[derive(Debug, Subcommand)]
pub enum LogCmd {
    /// The trials on the board.
    List,
    /// Download a trial as a recording (formats.md §2, plus odo_ columns).
    Pull {
        #[arg(long)]
        trial: u16,
        #[arg(long)]
        out: PathBuf,
    },
    /// Delete all trials.
    Clear,
}

#[derive(Debug, Subcommand)]
pub enum UmbmarkCmd {
    /// Compute E_d, E_b, c_L, c_R from measured end errors (formats.md §3).
    Compute(ComputeArgs),
    /// The guided procedure on a board: n cw and n ccw squares, compute, upload, save,
    /// and the same again after.
    Run(ProcedureArgs),
}

#[derive(Debug, Subcommand)]
pub enum OmniCmd {
    /// Compute F_lat and F_lon from measured end errors of paths 4W-1 / 4W-2.
    Compute(ComputeArgs),
    /// The guided procedure on a board: n runs of 4W-1 and 4W-2, compute, upload, save,
    /// and the same again after.
    Run(ProcedureArgs),
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
    /// Omni second pass: the `--json` result of the first pass (its f_lat and f_lon were
    /// in force during these runs); the result is their composition (001).
    #[arg(long)]
    pub previous: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct ProcedureArgs {
    /// UMBmark: side of the square, metres.
    #[arg(long, default_value_t = 4.0)]
    pub side: f64,
    /// Omni: path length, metres.
    #[arg(long, default_value_t = 0.6)]
    pub length: f64,
    /// Runs per direction (UMBmark) or per path (omni).
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// Runs per direction or path after calibration (default: --runs).
    #[arg(long)]
    pub after_runs: Option<usize>,
    /// Measured runs are appended here as they are entered, so a stopped procedure
    /// resumes where it was.
    #[arg(long, default_value = "runs.csv")]
    pub runs_file: PathBuf,
    /// Take end errors from the virtual board's truth instead of asking.
    #[arg(long)]
    pub auto_measure: bool,
    /// The virtual board's truth file (default: PORT.truth.jsonl).
    #[arg(long)]
    pub truth: Option<PathBuf>,
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Skip the runs after calibration.
    #[arg(long)]
    pub no_after: bool,
    /// 001's second pass: measure with the board's current factors and compose the
    /// secondary factors with them (use a new --runs-file).
    #[arg(long)]
    pub second_pass: bool,
}

#[derive(Debug, Args)]
pub struct SimBoardArgs {
    /// Robot description (formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Create a symlink to the pseudo-terminal here (use it as --port).
    #[arg(long)]
    pub link: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds per second; `max` runs programs as fast as possible.
    #[arg(long, default_value = "1")]
    pub speed: String,
    /// A hidden fault, `ID=name:value,...` (e.g. `wheelbase_error=eb:1.03`); repeatable.
    #[arg(long)]
    pub effect: Vec<String>,
    /// Floor roughness: metres of travel noise per square-root metre.
    #[arg(long, default_value_t = 0.0)]
    pub roughness: f64,
    /// Keep the board's flash in this file (saved factors survive a restart).
    #[arg(long)]
    pub flash: Option<PathBuf>,
    /// Where to write the true end errors of trials (default: LINK.truth.jsonl).
    #[arg(long)]
    pub truth: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Robot description (default: robots/mobolab.toml).
    #[arg(long, default_value = "robots/mobolab.toml")]
    pub robot: PathBuf,
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Runs per direction.
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// Square side, metres.
    #[arg(long, default_value_t = 4.0)]
    pub side: f64,
    #[arg(long)]
    pub report: Option<PathBuf>,
}

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
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

type PortClient = Client<crate::stop::LockedPort>;

/// A lazily opened connection.
pub struct Ctx {
    pub port: Option<String>,
    pub baud: u32,
    pub client: Option<PortClient>,
    /// Relays E-stops from other terminals to the port while this process holds it.
    pub relay: Option<crate::stop::Relay>,
}

impl Ctx {
    fn client(&mut self) -> Result<&mut PortClient> {
        if self.client.is_none() {
            let port = self
                .port
                .clone()
                .context("this command talks to a board: give --port DEV (or set WHEELCAL_PORT)")?;
            let link = link::open_serial(&port, self.baud)?;
            let (link, relay) = crate::stop::hold(&port, link);
            let mut c = Client::new(link, &port);
            c.hello()?;
            self.client = Some(c);
            self.relay = relay;
        }
        Ok(self.client.as_mut().expect("just connected"))
    }
}

/// Runs a parsed command line.
pub fn run(cli: Cli, ctx: &mut Ctx) -> Result<()> {
    let out = Output::from_flag(cli.json);
    match cli.command {
        Command::Info => {
            let r = board_cmds::info(ctx.client()?)?;
            out.emit(&r, || r.human())
        }
        Command::Factors(FactorsCmd::Get) => {
            let f = FactorsView::from(&ctx.client()?.corrections()?);
            out.emit(&f, || f.human())
        }
        Command::Factors(FactorsCmd::Set(a)) => {
            let c = board_cmds::corrections_from_args(
                a.c_l,
                a.c_r,
                a.e_b,
                a.f_lat.as_deref(),
                a.f_lon,
            )?;
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
        Command::Factors(FactorsCmd::Save) => {
            let client = ctx.client()?;
            client.save_corrections()?;
            let f = FactorsView::from(&client.corrections()?);
            out.emit(&f, || format!("saved to flash: {}", f.human()))
        }
        Command::Factors(FactorsCmd::Reset) => {
            let client = ctx.client()?;
            client.reset_corrections()?;
            let f = FactorsView::from(&client.corrections()?);
            out.emit(&f, || {
                "corrections reset to nominal (not yet saved: `wheelcal factors save`)\n".into()
            })
        }
        Command::Factors(FactorsCmd::Export(a)) => {
            let f = match (&a.from, a.c_l, a.c_r, a.e_b) {
                (Some(p), ..) => ros2::factors_from_json(p)?,
                (None, Some(c_l), Some(c_r), Some(e_b)) => ros2::DiffFactors { c_l, c_r, e_b },
                (None, None, None, None) => match ctx.client()?.corrections()? {
                    calib_core::Corrections::DiffDrive { c_l, c_r, e_b } => ros2::DiffFactors { c_l, c_r, e_b },
                    other => bail!("the board's factors are not differential-drive factors: {other:?}"),
                },
                _ => bail!("give --from RESULT.json, all of --c-l, --c-r, --e-b, or --port to read the board"),
            };
            let yaml = ros2::diff_drive_yaml(&f, &a.controller)?;
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
        Command::Drive(a) => {
            if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 600.0) {
                bail!("--duration must be within (0, 600] seconds");
            }
            let client = ctx.client()?;
            board_cmds::drive_for(
                client,
                Twist::new(a.vx, a.vy, a.omega),
                Duration::from_secs_f64(a.duration),
            )?;
            let s = client.status()?;
            out.emit(&s, || format!("{}\n", board_cmds::status_line(&s)))
        }
        Command::Run(cmd) => {
            let client = ctx.client()?;
            let (no_wait, limit) = match cmd {
                RunCmd::Umbmark {
                    dir,
                    side,
                    log_rate,
                    no_wait,
                } => {
                    let limit = board_cmds::run_umbmark(client, dir.into(), side, log_rate)?;
                    (no_wait, limit)
                }
                RunCmd::Omni {
                    path,
                    length,
                    log_rate,
                    no_wait,
                } => {
                    let limit = board_cmds::run_omni(client, path.into(), length, log_rate)?;
                    (no_wait, limit)
                }
            };
            let s = if no_wait {
                client.status()?
            } else {
                let human = out == Output::Human;
                board_cmds::wait_program(client, limit, |s| {
                    if human {
                        eprint!("\r{}", board_cmds::status_line(s));
                    }
                })?
            };
            if out == Output::Human {
                eprintln!();
            }
            out.emit(&s, || format!("{}\n", board_cmds::status_line(&s)))
        }
        Command::Status { follow, period_ms } => {
            let client = ctx.client()?;
            if !follow {
                let s = client.status()?;
                return out.emit(&s, || format!("{}\n", board_cmds::status_line(&s)));
            }
            let _guard = crate::stop::Guard::new();
            client.set_telemetry(period_ms.max(20))?;
            while !crate::stop::requested() {
                if let Some(s) = client.next_telemetry(Duration::from_millis(500))? {
                    out.emit(&s, || format!("{}\n", board_cmds::status_line(&s)))?;
                }
            }
            client.set_telemetry(0)?;
            Ok(())
        }
        Command::Log(LogCmd::List) => {
            let t = board_cmds::trial_list(&ctx.client()?.trials()?);
            out.emit(&t, || t.human())
        }
        Command::Log(LogCmd::Pull { trial, out: file }) => {
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
            let r = board_cmds::pull_trial(client, trial, &file, |done, total| {
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
                    if r.dropped_records > 0 { format!("; WARNING: the board dropped {} records (log full): the trial is missing its end", r.dropped_records) } else { String::new() }
                )
            })
        }
        Command::Log(LogCmd::Clear) => {
            ctx.client()?.clear_logs()?;
            out.emit(&serde_json::json!({"cleared": true}), || {
                "trial logs cleared\n".into()
            })
        }
        Command::Stop => {
            ctx.client()?.stop()?;
            out.emit(&serde_json::json!({"stopped": true}), || "stopped\n".into())
        }
        Command::Estop => {
            // Another wheelcal may hold the port: it relays the E-stop at once.
            let relayed = match (&ctx.client, &ctx.port) {
                (None, Some(port)) => crate::stop::relay_estop(port)?,
                _ => None,
            };
            if relayed.is_none() {
                ctx.client()?.estop()?;
            }
            let ms = relayed.map(|t| t.as_secs_f64() * 1e3);
            out.emit(&serde_json::json!({"estop": true, "relayed_ms": ms}), || match ms {
                Some(ms) => format!("E-STOP sent through the wheelcal holding the port ({ms:.1} ms): motors off (clear with `wheelcal clear-fault`)\n"),
                None => "E-STOP latched: motors off (clear with `wheelcal clear-fault`)\n".into(),
            })
        }
        Command::ClearFault => {
            ctx.client()?.clear_fault()?;
            out.emit(&serde_json::json!({"cleared": true}), || {
                "fault and E-stop cleared\n".into()
            })
        }
        Command::Console => crate::repl::run(ctx, cli.json),
        Command::Umbmark(UmbmarkCmd::Compute(a)) => {
            let robot = robot_file::load(&a.robot)?;
            let runs = RunsFile::load(&a.runs)?;
            if a.previous.is_some() {
                bail!("--previous is for `omni compute`; a UMBmark second pass composes on the board (`umbmark run --second-pass`)");
            }
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
            let mut rep = omni::compute(&robot, &runs)?;
            if let Some(p) = &a.previous {
                rep = omni::compose_with(rep, &omni::factors_from_json(p)?)?;
            }
            if let Some(dir) = &a.report {
                let index = report::omni::write(&rep, dir)?;
                out.note(&format!("report: {}", index.display()));
            }
            out.emit(&rep, || rep.human())
        }
        Command::Umbmark(UmbmarkCmd::Run(a)) => {
            let port = ctx.port.clone().unwrap_or_default();
            let opts = procedure_options(&a, &port, procedure::Kind::Umbmark);
            let rep = procedure::run(ctx.client()?, &opts, measure_for(&opts).as_mut())?;
            out.emit(&rep, || rep.human())
        }
        Command::Omni(OmniCmd::Run(a)) => {
            let port = ctx.port.clone().unwrap_or_default();
            let opts = procedure_options(&a, &port, procedure::Kind::Omni);
            let rep = procedure::run(ctx.client()?, &opts, measure_for(&opts).as_mut())?;
            out.emit(&rep, || rep.human())
        }
        Command::SimBoard(a) => {
            let speed = match a.speed.as_str() {
                "max" | "inf" => f64::INFINITY,
                s => s
                    .parse::<f64>()
                    .ok()
                    .filter(|v| *v > 0.0 && v.is_finite())
                    .context("--speed takes a positive number or `max`")?,
            };
            let opts = SimBoardOptions {
                robot: a.robot,
                link: a.link,
                seed: a.seed,
                speed,
                effects: a.effect,
                roughness: a.roughness,
                flash: a.flash,
                truth: a.truth,
            };
            // Ctrl-C or SIGTERM ends the board cleanly (its link is removed).
            let _guard = crate::stop::Guard::new();
            let stop = Arc::new(AtomicBool::new(false));
            let s2 = stop.clone();
            std::thread::spawn(move || loop {
                if crate::stop::requested() {
                    s2.store(true, Ordering::Relaxed);
                    break;
                }
                std::thread::sleep(Duration::from_millis(20));
            });
            sim_board::run(&opts, stop, |ready| {
                let _ = out.emit(ready, || {
                    format!(
                        "virtual board ({}, seed {}) on {}{}\ntruth of each trial: {}\nCtrl-C to stop\n",
                        ready.robot,
                        ready.seed,
                        ready.pty,
                        ready.link.as_ref().map(|l| format!(" (link {l})")).unwrap_or_default(),
                        ready.truth_file
                    )
                });
                use std::io::Write;
                let _ = std::io::stdout().flush();
            })
        }
        Command::Calibrate(a) => crate::calibrate_cmd::run(&a, out),
        Command::Diagnose(a) => {
            let files = crate::calibrate_cmd::expand(&a.recording)?;
            if files.len() > 1 {
                return crate::calibrate_cmd::diagnose_many(&a, &files, out);
            }
            let recording = &files[0];
            let robot = robot_file::load(&a.robot)?;
            let rec = formats::recording::Recording::load(recording, &robot)?;
            for n in &rec.notes {
                out.note(&format!("{}: {n}", recording.display()));
            }
            let opts = diagnose::Options {
                max_effects: a.max_effects.clamp(1, 4),
            };
            let rep = diagnose::diagnose(&robot, &rec, &opts)
                .map_err(|e| anyhow::anyhow!("{}: {e}", recording.display()))?;
            if let Some(dir) = &a.report {
                if !report::font_available() {
                    bail!("plots need the DejaVu Sans font: apt-get install fonts-dejavu-core");
                }
                diagnose::plots::write_report_dir(&rep, dir)
                    .with_context(|| format!("cannot write the report into {}", dir.display()))?;
                out.note(&format!("report: {}", dir.join("index.html").display()));
                crate::mcap_out::write_report_paths(&rep, &dir.join("paths.mcap"))?;
            }
            if let Some(p) = &a.write_robot {
                diagnose::write_robot(&robot, &rep, p)
                    .with_context(|| format!("cannot write {}", p.display()))?;
                out.note(&format!("fitted robot: {}", p.display()));
            }
            out.emit(&rep, || rep.to_string())
        }
        Command::Sim(SimCmd::Record(a)) => {
            let robot = robot_file::load(&a.robot)?;
            let effects = a
                .effect
                .iter()
                .map(|e| {
                    sim::Effect::parse(e).map_err(|err| anyhow::anyhow!("--effect {e}: {err}"))
                })
                .collect::<Result<Vec<_>>>()?;
            if !(a.duration.is_finite() && a.duration > 0.0 && a.duration <= 7200.0) {
                bail!("--duration must be within (0, 7200] seconds");
            }
            let arena = calib_core::protocol::Safety::default().arena_m as f64;
            if let Some(side) = a.umbmark_side {
                if !(side.is_finite() && side > 0.0 && side <= arena) {
                    bail!("--umbmark-side must be within (0, {arena}] m, as on a board");
                }
            }
            let motion = match a.umbmark_side {
                Some(side) => sim::record::Motion::Program {
                    program: Box::new(calib_core::motion::Program::umbmark_square(
                        side,
                        Direction::Ccw,
                    )),
                    limits: Default::default(),
                },
                None => sim::record::Motion::Random(sim::record::RandomMotion {
                    duration_s: a.duration,
                    ..Default::default()
                }),
            };
            let mut cfg = sim::record::RecordConfig {
                row_rate_hz: a.rate,
                ..Default::default()
            };
            cfg.sim.seed = a.seed;
            if let Some(n) = a.vision_noise {
                cfg.sim.vision.sigma_xy_m = n;
            }
            let rec = sim::record::record(&robot, &effects, sim::Surface::flat(), &motion, &cfg)
                .map_err(|e| anyhow::anyhow!("{e}"))?;
            rec.write_dir(&a.out).map_err(|e| anyhow::anyhow!("{e}"))?;
            #[derive(serde::Serialize)]
            struct Written {
                out: String,
                rows: usize,
                effects: Vec<String>,
                seed: u64,
            }
            let w = Written {
                out: a.out.display().to_string(),
                rows: rec.recording.len(),
                effects: effects.iter().map(|e| e.to_string()).collect(),
                seed: a.seed,
            };
            out.emit(&w, || {
                format!(
                    "wrote {} rows to {} (effects: {})\n",
                    w.rows,
                    w.out,
                    if w.effects.is_empty() {
                        "none".into()
                    } else {
                        w.effects.join(" ")
                    }
                )
            })
        }
        Command::Demo(a) => {
            let rep = demo::run(
                &a.robot,
                a.seed,
                a.runs,
                a.side,
                a.report.as_deref(),
                out == Output::Human,
            )?;
            out.emit(&rep, || rep.human())
        }
    }
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

fn procedure_options(a: &ProcedureArgs, port: &str, kind: procedure::Kind) -> procedure::Options {
    procedure::Options {
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
    }
}
