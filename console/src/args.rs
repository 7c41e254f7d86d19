//! The command line of `wheelcal` as clap types: what each command accepts, with the
//! value parsers that keep bad values from reaching a command. Only data and parsing
//! live here, so every command module can take its arguments from this module without
//! depending on the dispatcher (`cli`).

use anyhow::{bail, Result};
use calib_core::motion::{Direction, OmniPath};
use clap::{Args, Parser, Subcommand, ValueEnum};
use std::path::PathBuf;

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
    /// The robot geometry on the board (wheel radii, positions, angles).
    #[command(subcommand)]
    Robot(RobotCmd),
    /// Put a calibration on the board in one step: its geometry (with --board-robot) and
    /// its factors and laws, set together or not at all, then read back.
    Apply(ApplyArgs),
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
        /// With --follow, also serve the telemetry live to Foxglove (its WebSocket
        /// protocol, ROS 2 messages; docs/formats.md "MCAP channels") on ADDR: HOST:PORT,
        /// an IP or a port; without ADDR on 127.0.0.1:8765 (port 0: a free one). The
        /// address is printed on stderr. Needs a wheelcal built with the cargo feature
        /// `foxglove` (`cargo build --release -p wheelcal --features foxglove`).
        #[arg(long, value_name = "ADDR", requires = "follow", num_args = 0..=1,
              default_missing_value = crate::foxglove_live::DEFAULT_ADDR)]
        foxglove: Option<String>,
    },
    /// Trial logs on the board: it keeps the last 8 trials (a ninth program evicts the
    /// oldest; `log list` counts the evicted), so pull each one you need.
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
    Calibrate(CalibrateArgs),
    /// How well robot files dead-reckon recordings they were not fitted to: the judge of a
    /// calibration, against others.
    Evaluate(EvaluateArgs),
    /// Simulator tools.
    #[command(subcommand)]
    Sim(SimCmd),
    /// Recordings from other tools' files (ROS 2 bags).
    #[command(subcommand)]
    Import(ImportCmd),
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
    /// Write the measured, nominal and fitted paths as TUM trajectories (measured.txt,
    /// nominal.txt, fitted.txt) into this folder, for evo (docs/formats.md "TUM files").
    #[arg(long, value_name = "DIR")]
    pub tum: Option<PathBuf>,
    /// Most effects to combine in one explanation (1 to 4).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u8).range(1..=4))]
    pub max_effects: u8,
    /// Merge faster rows to about this many per second while reading (commands averaged,
    /// counts and poses kept as sampled; docs/formats.md §2, "Fast recordings"); 0 keeps
    /// every row.
    #[arg(long, default_value_t = formats::decimate::DEFAULT_MAX_ROW_RATE_HZ, value_parser = max_rate)]
    pub max_rate: f64,
    /// How to read recordings given as ROS 2 bags.
    #[command(flatten)]
    pub bag: BagFlags,
}

/// `--max-rate`: a finite rate, 0 or more.
fn max_rate(s: &str) -> Result<f64, String> {
    let v: f64 = s
        .parse()
        .map_err(|_| format!("'{s}' is not a number of rows per second"))?;
    if !v.is_finite() || v < 0.0 {
        return Err(format!("{s}: give 0 (every row) or a positive rate"));
    }
    Ok(v)
}

impl DiagnoseArgs {
    /// The row rate to merge to, if any.
    pub fn max_row_rate_hz(&self) -> Option<f64> {
        (self.max_rate > 0.0).then_some(self.max_rate)
    }
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
    /// Drive one counter-clockwise circle of this radius (metres, its diameter at most a
    /// board's default arena) instead: the arcs `calibrate` needs to test a turn law.
    #[arg(long, value_parser = arena_radius, conflicts_with = "umbmark_side")]
    pub circle_radius: Option<f64>,
    /// Rows per second.
    #[arg(long, default_value_t = 200.0, value_parser = positive_f64)]
    pub rate: f64,
    /// Camera pose noise, metres (standard deviation), within [0, 1].
    #[arg(long, value_parser = vision_noise_m)]
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

/// Subcommands of `wheelcal robot`.
#[derive(Debug, Subcommand)]
pub enum RobotCmd {
    /// Show the board's robot geometry.
    Get {
        /// Also write it as a robot file (docs/formats.md §1).
        #[arg(long, value_name = "FILE.toml")]
        out: Option<PathBuf>,
    },
    /// Give the board the geometry of a robot file (the same kind and wheels, in the same
    /// order: e.g. `calibrate --write-board-robot`'s); validated by the board, idle only,
    /// not persisted until `save`. Its gains, limits and safety settings are kept.
    Set {
        /// The robot file.
        #[arg(value_name = "FILE.toml")]
        file: PathBuf,
    },
    /// Persist the board's parameters (its robot among them) in flash.
    Save,
}

/// Arguments of `wheelcal apply`.
#[derive(Debug, Args)]
pub struct ApplyArgs {
    /// The calibration: `calibrate --json`'s output (or a `--report` folder), or
    /// `umbmark compute`'s or `omni compute`'s `--json` result.
    #[arg(value_name = "CALIBRATION.json")]
    pub calibration: PathBuf,
    /// The geometry the board is to hold with the calibration's laws (`calibrate
    /// --write-board-robot`'s robot file); its factors are then ones and the laws.
    /// Without it the board keeps its robot and gets the calibration's factors, unless
    /// the calibration fitted geometry no factor carries (an omni robot's wheel
    /// distances, angles, centre or roller angle): then the board takes the
    /// calibration's own fitted geometry (its JSON's `board_geometry`) the same way.
    #[arg(long, value_name = "FILE.toml", conflicts_with = "factors_only")]
    pub board_robot: Option<PathBuf>,
    /// Set the calibration's factors only and keep the board's geometry, even when they
    /// leave fitted parameters out (listed): for a board whose geometry was measured
    /// some other way.
    #[arg(long)]
    pub factors_only: bool,
    /// Persist what was set in flash (the parameters, when a geometry was set, and the
    /// factors).
    #[arg(long)]
    pub save: bool,
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
    /// Differential drive: wheelbase multiplier E_b (in a turn in place, with a turn law).
    #[arg(long)]
    pub e_b: Option<f64>,
    /// Differential drive: the turn law, how much wider the effective separation is on
    /// arcs than in a turn in place (`calibrate`'s eb_arc / eb; 0.005 is 0.5 %; 0 removes
    /// it). The board's odometry applies it; wheel commands use E_b.
    #[arg(long, value_name = "EB_ARC", allow_negative_numbers = true)]
    pub e_b_arc: Option<f64>,
    /// Differential drive: the speed law, how much larger the wheels roll per m/s of
    /// their side's speed (`calibrate`'s speed_rel; 0.01 is 1 % per m/s; 0 removes it;
    /// c_L and c_R are then the sizes at standstill). The board's odometry applies it.
    #[arg(long, value_name = "PER_M_S", allow_negative_numbers = true)]
    pub speed_rel: Option<f64>,
    /// Differential drive: the acceleration law, the ground's lag behind each side's speed
    /// in seconds (`calibrate`'s accel_slip_s; 0 removes it). The board's odometry takes
    /// this lag times each side's change of speed off its travel.
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub accel_slip_s: Option<f64>,
    /// Differential drive: the motion the laws were fitted on (`calibrate`'s
    /// `factors.board.range`), comma-separated: the smallest and largest turn ratio
    /// (0 straight, 1 a turn in place) and the fastest side speed (m/s). Beyond it the
    /// board's odometry holds each law at its value at the edge.
    #[arg(long, value_name = "RHO_MIN,RHO_MAX,SPEED_MAX", value_delimiter = ',', value_parser = trimmed_f64)]
    pub law_range: Option<Vec<f64>>,
    /// Omni: one factor per wheel, comma-separated, in the robot file's order.
    #[arg(long, value_delimiter = ',', value_parser = trimmed_f64)]
    pub f_lat: Option<Vec<f64>>,
    /// Omni: common longitudinal factor F_lon.
    #[arg(long)]
    pub f_lon: Option<f64>,
    /// Omni: the turn law, how much longer the wheels' effective distance from the centre
    /// is on arcs than in a turn in place (0.019 is 1.9 %; 0 removes it). The board's
    /// odometry applies it; wheel commands use F_lat and F_lon.
    #[arg(long, value_name = "L_ARC", allow_negative_numbers = true)]
    pub l_arc: Option<f64>,
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
    /// A circle driven forward: the arcs a calibration needs to see how the robot turns on
    /// arcs, beside the squares' turns in place (`calibrate` tests a turn-radius law only
    /// when the recordings turn on arcs).
    Circle {
        /// Direction of the circle.
        #[arg(long, value_enum)]
        dir: DirArg,
        /// Radius, metres (its diameter at most the board's arena: checked with the
        /// board's own rule before anything is sent). Record several radii to see a law.
        #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
        radius: f64,
        /// Times round (1 to 10).
        #[arg(long, default_value_t = 1)]
        laps: u8,
        /// Log rate and waiting.
        #[command(flatten)]
        run: ProgramRunArgs,
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
            "{} s is outside [{min}, 60] s (use --no-link-failsafe to turn it off)",
            s.trim()
        ));
    }
    Ok(v)
}

/// Subcommands of `wheelcal log`.
#[derive(Debug, Subcommand)]
pub enum LogCmd {
    /// The trials on the board: at most the last 8 trials (older ones were evicted to
    /// make room, and are counted).
    List,
    /// Download a trial as a recording: a CSV file (docs/formats.md §2, plus odo_
    /// columns) or, for a name ending in .mcap, an MCAP file.
    Pull {
        /// Trial number (see `log list`).
        #[arg(long)]
        trial: u16,
        /// Output file: a recording CSV (name ending in .csv) or MCAP (.mcap: ROS 2
        /// messages, docs/formats.md "MCAP channels").
        #[arg(long)]
        out: PathBuf,
        /// Also write the board's odometry as a TUM trajectory (odometry.txt) into this
        /// folder, for evo and other trajectory tools (docs/formats.md "TUM files").
        #[arg(long, value_name = "DIR")]
        tum: Option<PathBuf>,
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
    /// With circle rows (the omni circle test): write the geometry a board takes with
    /// factors of one and the turn law (the factors' wheel sizes, the circles' wheel
    /// distances), for `wheelcal apply RESULT.json --board-robot FILE`.
    #[arg(long, value_name = "FILE.toml")]
    pub write_board_robot: Option<PathBuf>,
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
    /// UMBmark: also drive circles of this radius (metres) each way, --runs times, and
    /// compute the turn law from their ends (the circle test): what squares, which turn
    /// only in place, cannot show. At least twice half the wheelbase. Omni: also turn in
    /// place (1 cm circles, their heading measured) and drive circles of this radius, at
    /// least twice the wheels' distance from the centre, each way, --runs times (the omni
    /// circle test): the wheels' distance and the turn law, which straight paths cannot
    /// show, go on the board as its robot with factors of one and the law.
    #[arg(long)]
    pub circle_radius: Option<f64>,
    /// Laps of each circle (1 to 10): more laps, a larger end error to measure.
    #[arg(long, default_value_t = 2)]
    pub circle_laps: u8,
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
    /// Tyre scrub: a differential drive's effective wheelbase (an omni robot's wheel
    /// distance from the centre) this much longer on arcs than in a turn in place, e.g.
    /// 0.04 (within +-0.5); what `umbmark run --circle-radius` and `calibrate` on squares
    /// and circles measure.
    #[arg(long, default_value_t = 0.0)]
    pub turn_scrub: f64,
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
    /// Also hide a tyre scrub (0.5-3 %) and run the circle test with circles of this
    /// radius (metres) beside the squares.
    #[arg(long)]
    pub circle_radius: Option<f64>,
    /// Laps of each circle (1 to 10).
    #[arg(long, default_value_t = 2)]
    pub circle_laps: u8,
}

/// A finite number within `(0, max]`, for the value parsers below.
fn in_range(s: &str, max: f64, unit: &str) -> std::result::Result<f64, String> {
    let v = trimmed_f64(s)?;
    if v.is_finite() && v > 0.0 && v <= max {
        Ok(v)
    } else {
        // The user's own text: a value such as 1e300 would print as 301 digits.
        Err(format!("'{}' is outside (0, {max}] {unit}", s.trim()))
    }
}

fn positive_f64(s: &str) -> std::result::Result<f64, String> {
    let v = trimmed_f64(s)?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("'{}' is not a positive number", s.trim()))
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

/// A circle's radius: positive, its diameter within a board's default arena.
fn arena_radius(s: &str) -> std::result::Result<f64, String> {
    let arena = calib_core::protocol::Safety::default().arena_m as f64;
    in_range(s, arena / 2.0, "m (half a board's default arena)")
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
/// A camera's pose noise (m, standard deviation): from none to 1 m, already far more
/// than any pose source a calibration can use (motion capture is ~1 mm, a camera on
/// markers ~1 cm) and a few times a test path's size, beyond which the simulated
/// recording is noise alone.
fn vision_noise_m(s: &str) -> std::result::Result<f64, String> {
    let v = trimmed_f64(s)?;
    if v.is_finite() && (0.0..=1.0).contains(&v) {
        Ok(v)
    } else {
        Err(format!(
            "'{}' is outside [0, 1] m (a camera's pose noise, standard deviation)",
            s.trim()
        ))
    }
}

/// A number for a message: plain when short, in exponent form when it would need many
/// digits (1e300 would print as 301).
fn shown(v: f64) -> String {
    if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

fn trimmed_f64(s: &str) -> std::result::Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .map_err(|e| format!("'{}' is not a number ({e})", s.trim()))
}

/// Arguments of `wheelcal calibrate`.
#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Robot description (docs/formats.md §1): the nominal geometry.
    #[arg(long)]
    pub robot: PathBuf,
    /// Recording with motion-capture poses (docs/formats.md §2): a CSV file, a run folder
    /// holding recording.csv, a directory of run folders, or a ROS 2 bag (with
    /// `--pose-topic`); repeatable.
    #[arg(long, required = true)]
    pub recording: Vec<PathBuf>,
    /// A recording kept out of the fit: its dead-reckoning RMSE before and after.
    #[arg(long)]
    pub holdout: Option<PathBuf>,
    /// Write the robot description with all fitted geometry.
    #[arg(long)]
    pub write_robot: Option<PathBuf>,
    /// Write the geometry a board takes with its laws (`wheelcal robot set`): every fitted
    /// dimension, with a kept turn law's separation or wheel distance of a turn in place
    /// and a speed law's wheel size at standstill (the board's laws widen and grow them).
    /// Without a law it is `--write-robot`'s. The board's factors are then ones and the
    /// laws only (the note gives the `factors set` line).
    #[arg(long, value_name = "FILE.toml")]
    pub write_board_robot: Option<PathBuf>,
    /// Write calibration.json, summary.txt, robot.toml (and ros2.yaml), per-recording
    /// path and error plots, a correlation plot, index.html and paths.mcap into this folder.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Skip leave-one-out cross-validation.
    #[arg(long)]
    pub no_cross_validation: bool,
    /// Also fit where motion capture tracks on the body (omni robots; an error on a
    /// differential drive).
    #[arg(long)]
    pub marker_offset: bool,
    /// Fit each recording's start pose, time offset and clock ratio (for recordings whose
    /// frame is not the robot's start frame). Default: dead-reckon each recording from its
    /// first measured pose, compared every 5 cm of travel.
    #[arg(long)]
    pub free_start: bool,
    /// Huber's loss (scale: 1.345 robust sigmas of the squared-loss residuals) instead of
    /// least squares.
    #[arg(long)]
    pub robust: bool,
    /// Cross-validation: hold out each `run`, `session` (run folders
    /// `<robot>-<path>-<session>-run-NN`) or `path-kind` (square, circular...) in turn
    /// (default: run, unless --no-cross-validation).
    #[arg(long, value_parser = ["run", "session", "path-kind"])]
    pub cv: Option<String>,
    /// Lever arm (m) at which heading errors count in the dead-reckoning objective
    /// (default 0.1; longer levers transferred better on the differential robot's real
    /// runs and worse on the omni robots', see docs/calibrate.md).
    #[arg(long)]
    pub heading_lever: Option<f64>,
    /// A known turn law, held fixed while the geometry is fitted: how much wider a
    /// differential drive's effective separation (an omni robot's wheel distance from the
    /// centre, l_arc) is on arcs than in a turn in place (eb_arc / eb; 0.005 is 0.5 %).
    /// Take it from an earlier calibrate on runs with arcs (circles, free driving): the
    /// JSON's `turn_law.arc_rel`. Squares turn in place and cannot find it themselves.
    #[arg(long, value_name = "EB_ARC", allow_negative_numbers = true)]
    pub turn_law: Option<f64>,
    /// A differential drive's known speed law, held fixed while the geometry is fitted:
    /// how much further a wheel rolls per m/s of its speed (speed_rel; 0.02 is 1 % at
    /// 0.5 m/s). Take it from an earlier calibrate on runs at several speeds: the JSON's
    /// `turn_law.speed_rel`, or its `law_tests`. Squares run at one cruise speed and
    /// cannot tell it from the wheel size.
    #[arg(long, value_name = "SPEED_REL", allow_negative_numbers = true)]
    pub speed_law: Option<f64>,
    /// Hold the turn and speed laws an earlier calibration kept, as --turn-law and
    /// --speed-law hold them: its JSON (the `--json` output), or a --report folder (its
    /// calibration.json). Calibrate once on runs with arcs or at several speeds, then on
    /// squares with this. A law the earlier calibration did not keep is tested as usual.
    #[arg(long, value_name = "CALIBRATION", conflicts_with_all = ["turn_law", "speed_law"])]
    pub laws_from: Option<PathBuf>,
    /// A log of the driving the robot file and ros2.yaml are for (as --recording: a file,
    /// a run folder, a directory of them or a bag; repeatable; only the encoders are
    /// read). With a turn law, which neither can apply, their one E_b is then the constant
    /// whose dead reckoning of this driving stays closest to the law's (by default: at the
    /// recordings' mean turn); with a speed law, their one wheel size likewise (by
    /// default: at the recordings' mean speed). The board applies the laws either way.
    #[arg(long, value_name = "RECORDING")]
    pub e_b_for: Vec<PathBuf>,
    /// Hold parameters at the robot file's values instead of fitting them (repeatable).
    /// A differential drive or skid-steer robot: `scale` (both wheels' size), `ed` (their
    /// ratio), `eb` (the separation). An omni robot, a family of its model ladder:
    /// `radius` (wheel sizes), `distance` (wheels' distances from the centre), `angle`
    /// (mounting angles), `roller` (a mecanum robot's roller angle), `centre` (the wheels'
    /// centre). For a dimension measured some other way, or to compare a smaller model on
    /// held-out runs.
    #[arg(long, value_name = "PARAM", value_parser = [
        "scale", "ed", "eb", "radius", "distance", "angle", "roller", "centre",
    ])]
    pub hold: Vec<String>,
    /// How to read recordings given as ROS 2 bags.
    #[command(flatten)]
    pub bag: BagFlags,
}

/// Arguments of `wheelcal evaluate`.
#[derive(Debug, Args)]
pub struct EvaluateArgs {
    /// The robot file judged (docs/formats.md §1): for example one `calibrate
    /// --write-robot` wrote. With `--board`, the board's robot, the one the calibration
    /// was fitted from (its factors correct it); it is then listed after the boards.
    #[arg(long)]
    pub robot: PathBuf,
    /// A calibration (calibrate's `--json` output or a `--report` folder) judged as a
    /// board applies its factors to `--robot`: every law it kept included, through the
    /// firmware's own odometry, not the one constant E_b its robot file carries. Listed
    /// first, so it is the one judged; repeatable.
    #[arg(long, value_name = "CALIBRATION")]
    pub board: Vec<PathBuf>,
    /// With `--board`: the robot geometry the board holds (`wheelcal robot set`, e.g.
    /// `calibrate --write-board-robot`'s), so each calibration is judged as that board
    /// applies it: this geometry with factors of one and the calibration's laws (the same
    /// wheels as `--robot`, by name and order).
    #[arg(long, value_name = "FILE.toml", requires = "board")]
    pub board_robot: Option<PathBuf>,
    /// A robot file to compare it with: the nominal, an earlier calibration, another
    /// tool's parameters (the same wheels, by name and order); repeatable.
    #[arg(long, value_name = "ROBOT")]
    pub against: Vec<PathBuf>,
    /// Recording with motion-capture poses in the robot's start frame (docs/formats.md
    /// §2), best one the robot file was not fitted to: a CSV file, a run folder holding
    /// recording.csv, a directory of run folders, or a ROS 2 bag (with `--pose-topic`);
    /// repeatable.
    #[arg(long, required = true)]
    pub recording: Vec<PathBuf>,
    /// Write each recording's measured poses and each robot file's dead reckoning of it
    /// as TUM trajectories into this folder, for evo (docs/formats.md "TUM files").
    #[arg(long, value_name = "DIR")]
    pub tum: Option<PathBuf>,
    /// How to read recordings given as ROS 2 bags.
    #[command(flatten)]
    pub bag: BagFlags,
}

/// Subcommands of `wheelcal import`.
#[derive(Debug, Subcommand)]
pub enum ImportCmd {
    /// A ROS 2 bag (rosbag2 folder or .mcap file, CDR messages) to a recording folder
    /// (recording.csv and a copy of the robot file).
    Ros2(Ros2Args),
}

/// Arguments of `wheelcal import ros2`.
#[derive(Debug, Args)]
pub struct Ros2Args {
    /// The bag: a rosbag2 folder (metadata.yaml beside .mcap files) or one .mcap file.
    pub bag: PathBuf,
    /// Robot description (formats.md §1); its encoder_counts_per_rev turns joint radians
    /// into counts.
    #[arg(long)]
    pub robot: PathBuf,
    /// Where to write recording.csv and robot.toml (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing recording.csv / robot.toml in --out.
    #[arg(long)]
    pub force: bool,
    /// The bag's reading options.
    #[command(flatten)]
    pub bag_flags: BagFlags,
}

/// How to read a bag: shared by every command that takes one.
#[derive(Debug, Args, Clone)]
pub struct BagFlags {
    /// WHEEL=JOINT: the JointState joint of a robot-file wheel (repeatable); a wheel not
    /// named reads `<wheel>_wheel_joint`.
    #[arg(long = "joint", value_name = "WHEEL=JOINT")]
    pub joints: Vec<String>,
    /// The sensor_msgs/msg/JointState topic.
    #[arg(long, default_value = "/joint_states")]
    pub joint_topic: String,
    /// The pose topic: geometry_msgs/msg/PoseStamped, PoseWithCovarianceStamped,
    /// nav_msgs/msg/Odometry or tf2_msgs/msg/TFMessage (/tf); required to read a bag.
    #[arg(long)]
    pub pose_topic: Option<String>,
    /// The fixed frame of the poses (map, world); required with tf.
    #[arg(long)]
    pub pose_frame: Option<String>,
    /// The robot's body frame (base_link); required with tf.
    #[arg(long)]
    pub base_frame: Option<String>,
    /// The static tf topic.
    #[arg(long, default_value = "/tf_static")]
    pub tf_static_topic: String,
    /// geometry_msgs/msg/Twist or TwistStamped commands (default: /cmd_vel when present).
    #[arg(long)]
    pub cmd_topic: Option<String>,
    /// Seconds after which the last command counts as a stop (diff_drive_controller's
    /// cmd_vel_timeout).
    #[arg(long, default_value_t = 0.5)]
    pub cmd_timeout: f64,
    /// Stamp messages with the recorder's receive time instead of their header stamps.
    #[arg(long)]
    pub use_receive_time: bool,
    /// Do not interpolate between pose samples further apart than this, seconds.
    #[arg(long, default_value_t = 0.5)]
    pub max_pose_gap: f64,
    /// Import what precedes a damaged chunk instead of failing.
    #[arg(long)]
    pub keep_partial: bool,
}

impl BagFlags {
    /// The importer's options.
    pub fn options(&self) -> Result<ros2bag::ImportOptions> {
        let mut joints = Vec::new();
        for j in &self.joints {
            let Some((w, n)) = j.split_once('=') else {
                bail!("--joint {j}: expected WHEEL=JOINT, e.g. --joint left=left_wheel_joint");
            };
            joints.push((w.trim().to_string(), n.trim().to_string()));
        }
        for (v, f) in [
            (self.cmd_timeout, "--cmd-timeout"),
            (self.max_pose_gap, "--max-pose-gap"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                bail!("{f} {}: must be a positive number of seconds", shown(v));
            }
        }
        let Some(pose_topic) = self.pose_topic.clone() else {
            bail!("reading a ROS 2 bag needs --pose-topic (e.g. /mocap/pose, /odom or /tf)");
        };
        Ok(ros2bag::ImportOptions {
            joints,
            joint_topic: self.joint_topic.clone(),
            pose_topic,
            pose_frame: self.pose_frame.clone(),
            base_frame: self.base_frame.clone(),
            tf_static_topic: self.tf_static_topic.clone(),
            cmd_topic: self.cmd_topic.clone(),
            cmd_timeout_s: self.cmd_timeout,
            use_receive_time: self.use_receive_time,
            max_pose_gap_s: self.max_pose_gap,
            keep_partial: self.keep_partial,
        })
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
}
