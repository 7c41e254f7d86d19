//! Command-line interface of `wheelcal` (clap). Each subcommand is a few lines that call
//! the library modules, so the tests exercise the same code.

use crate::client::Client;
use crate::link;
use crate::output::Output;
use anyhow::{Context, Result};
use calib_core::motion::{Direction, OmniPath};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;
use std::process::ExitCode;

/// wheelcal: calibrate wheeled robots' odometry, talk to wheelcal boards, diagnose
/// simulation against recordings.
#[derive(Debug, Parser)]
#[command(name = "wheelcal", version, about, long_about = None)]
pub struct Cli {
    /// Serial port of the board (or a virtual board's link, see `sim-board`).
    #[arg(long, global = true, env = "WHEELCAL_PORT")]
    pub port: Option<String>,
    /// Baud rate of the serial port.
    #[arg(long, global = true, default_value_t = 115_200,
          value_parser = clap::value_parser!(u32).range(50..=12_000_000))]
    pub baud: u32,
    /// One JSON object per result on stdout (human text otherwise).
    #[arg(long, global = true)]
    pub json: bool,
    /// Write into folders wheelcal did not make and replace files of another kind (never
    /// the command's own inputs).
    #[arg(long, global = true)]
    pub force: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands of `wheelcal`.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Firmware, protocol and robot of the board.
    Info,
    /// Correction factors on the board, or exported to other tools.
    #[command(subcommand)]
    Factors(FactorsCmd),
    /// Drive at a body twist for a while, then stop.
    Drive(DriveArgs),
    /// Run a calibration test path (UMBmark square, omni straight path) on the board.
    #[command(subcommand)]
    Run(RunCmd),
    /// The board's state; with --follow, a live telemetry stream.
    Status {
        /// Keep printing telemetry until Ctrl-C.
        #[arg(long)]
        follow: bool,
        /// Telemetry period with --follow, milliseconds.
        #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u16).range(20..))]
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
    /// Omni calibration: F_lat / F_lon from the straight paths 4W-1 and 4W-2.
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
    /// Recordings from other tools' files (ROS 2 bags).
    #[command(subcommand)]
    Import(crate::commands::import::ImportCmd),
}

/// Arguments of `wheelcal diagnose`.
#[derive(Debug, Args)]
pub struct DiagnoseArgs {
    /// Robot description (docs/formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Recording (docs/formats.md §2): a CSV file, a run folder or a ROS 2 bag (with
    /// `--pose-topic`); repeatable, or a directory of run folders: several recordings are
    /// diagnosed jointly (shared geometry).
    #[arg(long, required = true)]
    pub recording: Vec<PathBuf>,
    /// Write an HTML report with plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Write the robot description with the fitted geometry applied.
    #[arg(long)]
    pub write_robot: Option<PathBuf>,
    /// Most effects to combine in one explanation (1 to 4).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub max_effects: u8,
    /// How to read recordings given as ROS 2 bags.
    #[command(flatten)]
    pub bag: crate::commands::import::BagFlags,
}

/// Subcommands of `wheelcal sim`.
#[derive(Debug, Subcommand)]
pub enum SimCmd {
    /// Write a simulated recording with effects hidden in it (recording.csv, robot.toml,
    /// truth.csv, effects.txt).
    Record(SimRecordArgs),
}

/// Arguments of `wheelcal sim record`.
#[derive(Debug, Args)]
pub struct SimRecordArgs {
    /// Robot description (docs/formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// An effect to hide, `ID` or `ID=name:value,...` (catalogue ids of `diagnose`, or
    /// `tilted_floor`); repeatable.
    #[arg(long)]
    pub effect: Vec<String>,
    /// Seed of the simulation's random noise and trajectory.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    /// Length of the random trajectory, seconds (at most 7200).
    #[arg(long, default_value_t = 60.0, value_parser = record_seconds)]
    pub duration: f64,
    /// Drive a UMBmark square of this side (metres, at most a board's default arena)
    /// instead of a random trajectory.
    #[arg(long, value_parser = arena_side)]
    pub umbmark_side: Option<f64>,
    /// Rows per second.
    #[arg(long, default_value_t = 200.0, value_parser = positive_f64)]
    pub rate: f64,
    /// Camera pose noise, metres (standard deviation).
    #[arg(long)]
    pub vision_noise: Option<f64>,
}

/// Subcommands of `wheelcal factors`.
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

/// Arguments of `wheelcal factors set`: only the factors given change, the others keep
/// the board's current values (nominal where it holds none).
#[derive(Debug, Args)]
pub struct SetArgs {
    /// Differential drive: left wheel radius multiplier c_L.
    #[arg(long)]
    pub c_l: Option<f64>,
    /// Differential drive: right wheel radius multiplier c_R.
    #[arg(long)]
    pub c_r: Option<f64>,
    /// Differential drive: wheelbase multiplier E_b.
    #[arg(long)]
    pub e_b: Option<f64>,
    /// Omni: one factor per wheel, comma-separated, in the robot file's order.
    #[arg(long, value_delimiter = ',', value_parser = trimmed_f64)]
    pub f_lat: Option<Vec<f64>>,
    /// Omni: common longitudinal factor F_lon.
    #[arg(long)]
    pub f_lon: Option<f64>,
}

/// Arguments of `wheelcal factors export`.
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
    /// Left wheel radius multiplier c_L (instead of the board's).
    #[arg(long)]
    pub c_l: Option<f64>,
    /// Right wheel radius multiplier c_R (instead of the board's).
    #[arg(long)]
    pub c_r: Option<f64>,
    /// Wheelbase multiplier E_b (instead of the board's).
    #[arg(long)]
    pub e_b: Option<f64>,
    /// Controller name at the top of the YAML.
    #[arg(long, default_value = "diff_drive_controller")]
    pub controller: String,
}

/// Arguments of `wheelcal drive`: a body twist and how long to hold it.
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
    /// How long, seconds (at most 600).
    #[arg(long, default_value_t = 1.0, value_parser = drive_seconds)]
    pub duration: f64,
}

/// Direction of a UMBmark square.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum DirArg {
    /// Clockwise.
    Cw,
    /// Counter-clockwise.
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

/// An omni test path.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PathArg {
    /// Straight along body x.
    #[value(name = "4W-1")]
    W1,
    /// Straight along body y.
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

/// Subcommands of `wheelcal run`.
#[derive(Debug, Subcommand)]
pub enum RunCmd {
    /// A UMBmark square.
    Umbmark {
        /// Direction of the square.
        #[arg(long, value_enum)]
        dir: DirArg,
        /// Side of the square, metres (at most the board's arena: checked with the board's
        /// own rule, `ProgramSpec::validate`, before anything is sent).
        #[arg(long, default_value_t = 4.0, allow_negative_numbers = true)]
        side: f64,
        /// Log rate and waiting.
        #[command(flatten)]
        run: ProgramRunArgs,
    },
    /// A straight omni test path (4W-1 along body x, 4W-2 along body y).
    Omni {
        /// Which straight path.
        #[arg(long, value_enum)]
        path: PathArg,
        /// Commanded length, metres (at most the board's arena: checked with the board's
        /// own rule before anything is sent).
        #[arg(long, default_value_t = 0.6, allow_negative_numbers = true)]
        length: f64,
        /// Log rate and waiting.
        #[command(flatten)]
        run: ProgramRunArgs,
        /// Idle-wheel mode.
        #[command(flatten)]
        idle: IdleArgs,
    },
}

/// What every `run` program shares.
#[derive(Debug, Clone, Copy, Args)]
pub struct ProgramRunArgs {
    /// Trial log rate, Hz (0 = no log).
    #[arg(long, default_value_t = 50, value_parser = clap::value_parser!(u16).range(0..=1000))]
    pub log_rate: u16,
    /// Return at once instead of waiting for the end (needs --no-link-failsafe: nobody
    /// would be left to keep the board's host-link failsafe alive).
    #[arg(long)]
    pub no_wait: bool,
    /// Host-link failsafe: the board stops the program when it hears nothing from this
    /// console for this long (a frozen or suspended console, a crashed host, a pulled
    /// cable), seconds.
    #[arg(long, default_value_t = 0.5, value_parser = link_timeout_s)]
    pub link_timeout: f64,
    /// Run without the host-link failsafe: the robot drives on if this computer stops
    /// talking to it.
    #[arg(long)]
    pub no_link_failsafe: bool,
}

impl ProgramRunArgs {
    /// The link timeout to send (ms, 0 = off), or why these options cannot go together.
    pub fn link_timeout_ms(&self) -> anyhow::Result<u16> {
        if self.no_link_failsafe {
            return Ok(0);
        }
        if self.no_wait {
            anyhow::bail!(
                "--no-wait leaves nobody to keep the board's host-link failsafe alive: the board \
                 would stop the robot {} s after this command returns. Add --no-link-failsafe \
                 to run without it (the robot then drives on whatever happens to this computer)",
                self.link_timeout
            );
        }
        Ok((self.link_timeout * 1000.0).round() as u16)
    }
}

/// Parses `--link-timeout` (seconds, within what the board accepts).
fn link_timeout_s(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of seconds"))?;
    let min = calib_core::protocol::MIN_LINK_TIMEOUT_MS as f64 / 1000.0;
    if !(min..=60.0).contains(&v) {
        return Err(format!(
            "{v} s is outside [{min}, 60] s (use --no-link-failsafe to turn it off)"
        ));
    }
    Ok(v)
}

/// Subcommands of `wheelcal log`.
#[derive(Debug, Subcommand)]
pub enum LogCmd {
    /// The trials on the board.
    List,
    /// Download a trial as a recording (docs/formats.md §2, plus odo_ columns).
    Pull {
        /// Trial number (see `log list`).
        #[arg(long)]
        trial: u16,
        /// Output recording file (CSV).
        #[arg(long)]
        out: PathBuf,
    },
    /// Delete all trials.
    Clear,
}

/// Subcommands of `wheelcal umbmark`.
#[derive(Debug, Subcommand)]
pub enum UmbmarkCmd {
    /// Compute E_d, E_b, c_L, c_R from measured end errors (docs/formats.md §3).
    Compute(ComputeArgs),
    /// The guided procedure on a board: n cw and n ccw squares, compute, upload, save,
    /// and the same again after.
    Run(ProcedureArgs),
}

/// Subcommands of `wheelcal omni`.
#[derive(Debug, Subcommand)]
pub enum OmniCmd {
    /// Compute F_lat and F_lon from measured end errors of paths 4W-1 / 4W-2.
    Compute(OmniComputeArgs),
    /// The guided procedure on a board: n runs of 4W-1 and 4W-2, compute, upload, save,
    /// and the same again after.
    Run(ProcedureArgs),
}

/// Arguments of `umbmark compute` (and the common part of `omni compute`).
#[derive(Debug, Args)]
pub struct ComputeArgs {
    /// Robot description (docs/formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Measured runs (docs/formats.md §3).
    #[arg(long)]
    pub runs: PathBuf,
    /// Write an HTML report with SVG and PNG plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Longest path (UMBmark side, omni straight path) a runs row may name, metres;
    /// longer rows are refused as implausible.
    #[arg(long, default_value_t = crate::calibration::plausible::DEFAULT_MAX_LENGTH_M)]
    pub max_length: f64,
}

/// `omni compute`: the common inputs, the first pass of a second pass, the idle wheels.
#[derive(Debug, Args)]
pub struct OmniComputeArgs {
    /// Robot, runs, report and length limit, as for `umbmark compute`.
    #[command(flatten)]
    pub common: ComputeArgs,
    /// Second pass: the `--json` result of the first pass (its f_lat and f_lon were in
    /// force during these runs); the result is their composition.
    #[arg(long)]
    pub previous: Option<PathBuf>,
    /// Idle-wheel mode.
    #[command(flatten)]
    pub idle: IdleArgs,
}

/// How the wheels an omni path does not drive behaved while the runs were measured.
#[derive(Debug, Args, Clone, Copy)]
pub struct IdleArgs {
    /// Idle wheels on omni paths: `released` (drive cut, free to turn) or `held` (velocity
    /// loop at zero). Default: what `omni run` wrote beside the runs, else the robot
    /// file's `[procedure] idle_wheels`, else released.
    #[arg(long, value_enum)]
    pub idle_wheels: Option<IdleArg>,
}

/// `--idle-wheels` values.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum IdleArg {
    /// Drive cut: free to turn.
    Released,
    /// Velocity loop at zero.
    Held,
}

impl From<IdleArg> for calib_core::protocol::IdleWheels {
    fn from(a: IdleArg) -> Self {
        match a {
            IdleArg::Released => Self::Released,
            IdleArg::Held => Self::Held,
        }
    }
}

/// Arguments of the guided procedures `umbmark run` and `omni run`.
#[derive(Debug, Args)]
pub struct ProcedureArgs {
    /// UMBmark: side of the square, metres (checked as by the board before each run).
    #[arg(long, default_value_t = 4.0)]
    pub side: f64,
    /// Omni: path length, metres (checked as by the board before each run).
    #[arg(long, default_value_t = 0.6)]
    pub length: f64,
    /// Runs per direction (UMBmark) or per path (omni).
    #[arg(long, default_value_t = 5, value_parser = run_count)]
    pub runs: usize,
    /// Runs per direction or path after calibration (default: --runs).
    #[arg(long, value_parser = run_count)]
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
    /// Write an HTML report with SVG and PNG plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Skip the runs after calibration.
    #[arg(long)]
    pub no_after: bool,
    /// Second pass: measure with the board's current factors and compose the
    /// secondary factors with them (use a new --runs-file).
    #[arg(long)]
    pub second_pass: bool,
    /// Omni: a robot file whose `[procedure] idle_wheels` says how idle wheels behave
    /// (`--idle-wheels` wins over it).
    #[arg(long)]
    pub robot: Option<PathBuf>,
    /// Idle-wheel mode.
    #[command(flatten)]
    pub idle: IdleArgs,
}

/// Arguments of `wheelcal sim-board`.
#[derive(Debug, Args)]
pub struct SimBoardArgs {
    /// Robot description (docs/formats.md §1).
    #[arg(long)]
    pub robot: PathBuf,
    /// Create a symlink to the pseudo-terminal here (use it as --port).
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Seed of the simulation's random noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds per second; `max` runs programs as fast as possible.
    #[arg(long, default_value = "1", value_parser = sim_speed)]
    pub speed: f64,
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

/// Arguments of `wheelcal demo`.
#[derive(Debug, Args)]
pub struct DemoArgs {
    /// Robot description (default: robots/mobolab.toml).
    #[arg(long, default_value = "robots/mobolab.toml")]
    pub robot: PathBuf,
    /// Seed of the hidden errors and the simulation noise.
    #[arg(long, default_value_t = 2026)]
    pub seed: u64,
    /// Runs per direction.
    #[arg(long, default_value_t = 5)]
    pub runs: usize,
    /// Square side, metres.
    #[arg(long, default_value_t = 4.0)]
    pub side: f64,
    /// Write an HTML report with SVG and PNG plots into this directory.
    #[arg(long)]
    pub report: Option<PathBuf>,
}

/// A finite number within `(0, max]`, for the value parsers below.
fn in_range(s: &str, max: f64, unit: &str) -> std::result::Result<f64, String> {
    let v = trimmed_f64(s)?;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        Err(format!("{v} is outside (0, {max}] {unit}"))
    }
}

fn positive_f64(s: &str) -> std::result::Result<f64, String> {
    let v = trimmed_f64(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a positive number"))
    }
}

fn drive_seconds(s: &str) -> std::result::Result<f64, String> {
    in_range(s, 600.0, "seconds")
}

fn record_seconds(s: &str) -> std::result::Result<f64, String> {
    in_range(s, 7200.0, "seconds")
}

/// A square side a board with the default arena would run.
fn arena_side(s: &str) -> std::result::Result<f64, String> {
    let arena = calib_core::protocol::Safety::default().arena_m as f64;
    in_range(s, arena, "m (a board's default arena)")
}

/// Runs per direction or path: a procedure needs at least one, and a person measures
/// each by hand.
fn run_count(s: &str) -> std::result::Result<usize, String> {
    match s.trim().parse::<usize>() {
        Ok(n) if (1..=100).contains(&n) => Ok(n),
        _ => Err(format!("'{}' is not a count within 1..=100", s.trim())),
    }
}

/// `max` (as fast as possible) or a positive number of simulated seconds per second.
fn sim_speed(s: &str) -> std::result::Result<f64, String> {
    match s.trim() {
        "max" | "inf" => Ok(f64::INFINITY),
        v => in_range(v, 1e6, "").map_err(|_| format!("'{v}': give a positive number or `max`")),
    }
}

/// A number with the spaces around it ignored, so `--f-lat '1, 1, 1, 1'` reads as a
/// person means it.
fn trimmed_f64(s: &str) -> std::result::Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|e| format!("'{}' is not a number ({e})", s.trim()))
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
            let e = name_the_port(e, &ctx);
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// An I/O failure on the open port (a broken pipe: the board or its cable went away)
/// names the port, so a person with several boards knows which one.
fn name_the_port(e: anyhow::Error, ctx: &Ctx) -> anyhow::Error {
    let (Some(_), Some(port)) = (&ctx.client, &ctx.port) else {
        return e;
    };
    let io = e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>().is_some()
            || c.downcast_ref::<crate::client::ClientError>()
                .is_some_and(|ce| matches!(ce, crate::client::ClientError::Io(_)))
    });
    if io && !format!("{e:#}").contains(port.as_str()) {
        e.context(format!("port {port}"))
    } else {
        e
    }
}

type PortClient = Client<crate::stop::LockedPort>;

/// A lazily opened connection.
pub struct Ctx {
    /// The serial port given with --port or WHEELCAL_PORT.
    pub port: Option<String>,
    /// Baud rate of the serial port.
    pub baud: u32,
    /// The open connection, once a command has needed one.
    pub client: Option<PortClient>,
    /// Relays E-stops from other terminals to the port while this process holds it.
    pub relay: Option<crate::stop::Relay>,
}

impl Ctx {
    pub(crate) fn client(&mut self) -> Result<&mut PortClient> {
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

/// Runs a parsed command line: dispatch only, each command is a module of
/// [`crate::commands`].
pub fn run(cli: Cli, ctx: &mut Ctx) -> Result<()> {
    use crate::commands::{board, diagnose, factors, log, omni, program, sim, umbmark};
    let out = Output::from_flag(cli.json);
    formats::safe_write::set_force(cli.force);
    match cli.command {
        Command::Info => board::info(ctx, out),
        Command::Factors(cmd) => factors::run(cmd, ctx, out),
        Command::Drive(a) => board::drive(a, ctx, out),
        Command::Run(cmd) => program::run(cmd, ctx, out),
        Command::Status { follow, period_ms } => board::status(follow, period_ms, ctx, out),
        Command::Log(cmd) => log::run(cmd, ctx, out),
        Command::Stop => board::stop(ctx, out),
        Command::Estop => board::estop(ctx, out),
        Command::ClearFault => board::clear_fault(ctx, out),
        Command::Console => crate::repl::run(ctx, cli.json),
        Command::Umbmark(cmd) => umbmark::run(cmd, ctx, out),
        Command::Omni(cmd) => omni::run(cmd, ctx, out),
        Command::SimBoard(a) => sim::sim_board(a, out),
        Command::Demo(a) => sim::demo(a, out),
        Command::Diagnose(a) => diagnose::run(a, out),
        Command::Calibrate(a) => crate::calibrate_cmd::run(&a, out),
        Command::Sim(cmd) => sim::run(cmd, out),
        Command::Import(cmd) => crate::commands::import::run(cmd, out),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory;

    /// clap's own consistency checks (conflicts, defaults, value parsers).
    #[test]
    fn cli_definition_is_consistent() {
        Cli::command().debug_assert();
    }

    /// Ranges are the parser's business: a bad value never reaches a command.
    #[test]
    fn out_of_range_values_are_refused_while_parsing() {
        let bad: [&[&str]; 9] = [
            &["wheelcal", "drive", "--duration", "0"],
            &["wheelcal", "drive", "--duration", "601"],
            &["wheelcal", "status", "--period-ms", "5"],
            &[
                "wheelcal", "sim", "record", "--robot", "r", "--out", "o", "--rate", "0",
            ],
            &[
                "wheelcal",
                "run",
                "umbmark",
                "--dir",
                "ccw",
                "--log-rate",
                "5000",
            ],
            &["wheelcal", "umbmark", "run", "--runs", "0"],
            &["wheelcal", "sim-board", "--robot", "r.toml", "--speed", "0"],
            &[
                "wheelcal",
                "sim",
                "record",
                "--robot",
                "r",
                "--out",
                "o",
                "--umbmark-side",
                "1e9",
            ],
            &[
                "wheelcal",
                "umbmark",
                "compute",
                "--robot",
                "r",
                "--runs",
                "x",
                "--previous",
                "p",
            ],
        ];
        for argv in bad {
            let e = Cli::try_parse_from(argv).expect_err(&argv.join(" "));
            assert_eq!(e.exit_code(), 2, "{}: {e}", argv.join(" "));
        }
        let ok = Cli::try_parse_from(["wheelcal", "sim-board", "--robot", "r", "--speed", "max"])
            .expect("max speed");
        match ok.command {
            Command::SimBoard(a) => assert_eq!(a.speed, f64::INFINITY),
            other => panic!("{other:?}"),
        }
    }

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
