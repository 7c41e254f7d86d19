//! The guided calibration procedures (`umbmark run`, `omni run`): run each trial on the
//! board, get its measured end position (from a person, or from the virtual board's
//! truth), append it to the runs file at once, compute, upload and save the factors, run
//! the after trials, and report.
//!
//! Resuming: runs already in the runs file are not run again, so a person can stop (or
//! lose power) and start the same command later without losing what was measured.

use super::{omni, umbmark};
use crate::board;
use crate::client::Client;
use crate::virtual_board::TrialTruth;
use anyhow::{bail, Context, Result};
use calib_core::motion::{Direction, OmniPath};
use calib_core::odometry::Pose;
use calib_core::omni_circle_test::{self, MIN_RADIUS_BY_END_M};
use calib_core::protocol::{StopReason, DEFAULT_LINK_TIMEOUT_MS};
use calib_core::robot::{Robot, RobotKind};
use calib_core::Corrections;
use formats::runs_file::{Phase, RunRow, RunsFile, TestKind};
use serde::Serialize;
use std::io::{BufRead, Read, Write};
use std::path::{Path, PathBuf};
use std::time::Duration;

/// Which procedure to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// UMBmark squares on a differential drive ([Measuring errors]).
    Umbmark,
    /// Straight paths on an omnidirectional robot ([Redundant omni]).
    Omni,
}

/// Settings of a guided procedure (`umbmark run`, `omni run`).
#[derive(Debug, Clone)]
pub struct Options {
    /// Which procedure.
    pub kind: Kind,
    /// UMBmark: side of the square, m.
    pub side_m: f64,
    /// Omni: length of each straight path, m.
    pub length_m: f64,
    /// Runs per direction (UMBmark) or path (omni) before calibration.
    pub runs: usize,
    /// Runs per direction or path after calibration (usually `runs`).
    pub after_runs: usize,
    /// The runs file (formats.md §3) the measured end errors are appended to.
    pub runs_file: PathBuf,
    /// Read end errors from this virtual-board truth file instead of asking.
    pub auto_measure: Option<PathBuf>,
    /// Write the HTML report into this folder at the end.
    pub report: Option<PathBuf>,
    /// Also run the after trials once the factors are uploaded.
    pub after: bool,
    /// [Redundant omni]'s second pass: measure with the board's current factors in force and compose
    /// the secondary factors with them (the factors are remembered beside the runs file,
    /// so a resumed second pass composes with the same ones).
    pub second_pass: bool,
    /// Omni: idle wheels held or released on the paths; written beside the runs file so
    /// `omni compute` on it uses the same mode.
    pub idle_wheels: calib_core::protocol::IdleWheels,
    /// UMBmark: also drive circles of this radius (m) and laps each way, `runs` times,
    /// for the circle test's turn law ([`calib_core::circle_test`]).
    pub circles: Option<(f64, u8)>,
}

/// The radius of an omni robot's turns in place in the omni circle test: the board's
/// smallest circle, a turn in place as far as the turn law goes (rho = 1).
pub const TURN_IN_PLACE_RADIUS_M: f64 = 0.01;

/// Where a second pass remembers the factors it started from.
fn previous_file(runs_file: &Path) -> PathBuf {
    let mut s = runs_file.as_os_str().to_owned();
    s.push(".previous.json");
    PathBuf::from(s)
}

/// Where the omni circle test keeps the robot its runs were measured with.
fn measured_robot_file(runs_file: &Path) -> PathBuf {
    let mut s = runs_file.as_os_str().to_owned();
    s.push(".robot.toml");
    PathBuf::from(s)
}

/// The robot the runs of `runs_file` were measured with: the one kept beside it when the
/// runs file exists (a resumed procedure, the board perhaps holding the robot the
/// procedure gave it since), else the board's `board`, kept there now.
fn measured_robot(runs_file: &Path, board: Robot) -> Result<Robot> {
    let file = measured_robot_file(runs_file);
    if runs_file.exists() && file.exists() {
        let robot = formats::robot_file::load(&file)?;
        calibrate::same_wheels(&board, &robot).map_err(|e| {
            anyhow::anyhow!(
                "{}: {e}: the board is another robot than {} was measured on",
                file.display(),
                runs_file.display()
            )
        })?;
        return Ok(robot);
    }
    let text = format!(
        "# The robot {} was measured with (wheelcal omni run --circle-radius)\n{}",
        runs_file.display(),
        formats::robot_file::to_toml(&board)
    );
    formats::robot_file::write(&file, &text)
        .with_context(|| format!("cannot write {}", file.display()))?;
    Ok(board)
}

/// Where the measured end positions come from.
pub trait Measure {
    /// Tells the person what happens next (progress).
    fn say(&mut self, text: &str);
    /// Waits until the robot is placed at the start (nothing to wait for by default).
    fn ready(&mut self, _what: &str) -> Result<()> {
        Ok(())
    }
    /// The measured end error of `trial`, measured minus odometry, in the path frame (x
    /// along the first leg or the path, y to its left): `(x, y, theta)`. `odometry` is
    /// the board's end pose in that frame; `direction_rad` is the path's direction in the
    /// robot's start frame (0 for a UMBmark square, pi/2 for 4W-2). `heading`: the run
    /// needs its heading measured too (a turn in place: its end says nothing of its turn).
    fn end_error(
        &mut self,
        trial: u16,
        odometry: Pose<f32>,
        direction_rad: f64,
        what: &str,
        heading: bool,
    ) -> Result<(f64, f64, Option<f64>)>;
}

/// A person at a terminal with a tape measure.
pub struct Terminal;

fn read_line() -> Result<String> {
    let mut s = String::new();
    let n = std::io::stdin().lock().read_line(&mut s)?;
    if n == 0 {
        bail!("no more input (stdin closed): the runs measured so far are in the runs file; run the same command again to resume");
    }
    Ok(s)
}

impl Measure for Terminal {
    fn say(&mut self, text: &str) {
        eprintln!("{text}");
    }
    fn ready(&mut self, what: &str) -> Result<()> {
        loop {
            eprint!("{what}: place the robot on the start mark, heading along the first leg, and press Enter ");
            let _ = std::io::stderr().flush();
            match start_confirmation(&read_line()?) {
                Ok(()) => return Ok(()),
                Err(why) => eprintln!("  {why}"),
            }
        }
    }
    fn end_error(
        &mut self,
        _trial: u16,
        odo: Pose<f32>,
        _direction_rad: f64,
        what: &str,
        heading: bool,
    ) -> Result<(f64, f64, Option<f64>)> {
        let (x, y) = loop {
            eprint!(
                "{what}: measured end position x y in mm from the start mark (x along the first leg, y to its left; odometry says {:+.1} {:+.1}): ",
                odo.x * 1e3,
                odo.y * 1e3
            );
            let _ = std::io::stderr().flush();
            match parse_end_position(&read_line()?) {
                Ok((x_mm, y_mm)) => break (x_mm / 1e3 - odo.x as f64, y_mm / 1e3 - odo.y as f64),
                Err(why) => eprintln!("  {why}; type two numbers in millimetres, e.g. `12.5 -30`"),
            }
        };
        if !heading {
            return Ok((x, y, None));
        }
        loop {
            eprint!(
                "{what}: measured heading in degrees from the start heading (counter-clockwise positive, within +-180; odometry says {:+.2}): ",
                wrap_angle(f64::from(odo.theta)).to_degrees()
            );
            let _ = std::io::stderr().flush();
            match parse_heading_deg(&read_line()?) {
                Ok(deg) => return Ok((x, y, Some(heading_error(deg, odo.theta)))),
                Err(why) => eprintln!("  {why}; type one number in degrees, e.g. `-3.5`"),
            }
        }
    }
}

/// The answer to "press Enter to start": only an empty line or `y` starts the robot. A
/// measurement typed one prompt too early (`12.5 -30`) must not set it moving.
pub fn start_confirmation(line: &str) -> Result<(), String> {
    match line.trim() {
        "" | "y" | "Y" | "yes" => Ok(()),
        other => Err(format!(
            "`{other}` is not a go-ahead: the robot did not move. Press Enter alone (or type y) \
             when it is on the start mark; a measurement is asked for after the run"
        )),
    }
}

/// Largest end position a person can type (mm): 100 m, far beyond any test path.
const MAX_END_MM: f64 = 100_000.0;

/// A typed end position: exactly two numbers in millimetres, separated by spaces, a comma
/// or both; surrounding white space (the Enter key's newline) is ignored. Anything else is
/// refused with the reason, never guessed at.
pub fn parse_end_position(line: &str) -> std::result::Result<(f64, f64), String> {
    let tokens: Vec<&str> = line
        .trim()
        .split(|c: char| c == ',' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .collect();
    if tokens.len() != 2 {
        return Err(format!("got {} values, need exactly two", tokens.len()));
    }
    let mut v = [0.0; 2];
    for (slot, tok) in v.iter_mut().zip(&tokens) {
        *slot = tok
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("`{tok}` is not a number"))?;
        if slot.abs() > MAX_END_MM {
            return Err(format!("`{tok}` mm is more than 100 m from the start mark"));
        }
    }
    Ok((v[0], v[1]))
}

/// An angle within (-pi, pi].
fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w == -PI {
        PI
    } else {
        w
    }
}

/// A heading measured by hand (degrees from the start heading, within +-180) minus the
/// odometry's (radians, whole laps included), as a turn error within +-pi: a lap driven
/// counts as none, since a person sees only where the robot points.
pub fn heading_error(measured_deg: f64, odometry_rad: f32) -> f64 {
    wrap_angle(measured_deg.to_radians() - f64::from(odometry_rad))
}

/// A typed heading: one number of degrees within +-180; anything else is refused with
/// the reason.
pub fn parse_heading_deg(line: &str) -> std::result::Result<f64, String> {
    let t = line.trim();
    let v = t
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("`{t}` is not a number"))?;
    if v.abs() > 180.0 {
        return Err(format!("{v} degrees is beyond +-180"));
    }
    Ok(v)
}

/// A virtual board's truth (true end pose in the start frame, x along the start heading)
/// turned into the path frame, minus the reference end pose (same frame).
fn truth_error(
    t: &TrialTruth,
    direction_rad: f64,
    reference: Pose<f32>,
) -> (f64, f64, Option<f64>) {
    let (s, c) = direction_rad.sin_cos();
    let x = c * t.true_x_m + s * t.true_y_m;
    let y = -s * t.true_x_m + c * t.true_y_m;
    (
        x - reference.x as f64,
        y - reference.y as f64,
        Some(t.true_theta_rad - reference.theta as f64),
    )
}

/// The virtual board's truth, read from its truth file.
pub struct TruthFile {
    /// The truth file the virtual board appends to (`sim-board`'s `truth_file`).
    pub file: PathBuf,
    /// Do not print the procedure's messages to stderr.
    pub quiet: bool,
}

impl Measure for TruthFile {
    fn say(&mut self, text: &str) {
        if !self.quiet {
            eprintln!("{text}");
        }
    }
    fn end_error(
        &mut self,
        trial: u16,
        odo: Pose<f32>,
        direction_rad: f64,
        _what: &str,
        _heading: bool,
    ) -> Result<(f64, f64, Option<f64>)> {
        for _ in 0..100 {
            let truths = crate::sim_board::read_truths(&self.file)?;
            if let Some(t) = truths.iter().rev().find(|t| t.trial == trial) {
                return Ok(truth_error(t, direction_rad, odo));
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        bail!("--auto-measure: no truth for trial {trial} in {} (is the port a `wheelcal sim-board`?)", self.file.display())
    }
}

/// The truth handed over in-process (the demo).
pub struct TruthChannel<'a> {
    /// Receives each trial's truth from the virtual board.
    pub rx: &'a std::sync::mpsc::Receiver<TrialTruth>,
    /// Truths received so far, looked up by trial number.
    pub seen: Vec<TrialTruth>,
    /// Progress bar advanced once per measured trial, and showing the messages.
    pub progress: Option<indicatif::ProgressBar>,
}

impl Measure for TruthChannel<'_> {
    fn say(&mut self, text: &str) {
        if let Some(p) = &self.progress {
            p.set_message(text.to_string());
        }
    }
    fn end_error(
        &mut self,
        trial: u16,
        odo: Pose<f32>,
        direction_rad: f64,
        _what: &str,
        _heading: bool,
    ) -> Result<(f64, f64, Option<f64>)> {
        loop {
            if let Some(t) = self.seen.iter().find(|t| t.trial == trial) {
                if let Some(p) = &self.progress {
                    p.inc(1);
                }
                return Ok(truth_error(t, direction_rad, odo));
            }
            let t = self
                .rx
                .recv_timeout(Duration::from_secs(30))
                .context("the virtual board reported no truth for the trial")?;
            self.seen.push(t);
        }
    }
}

/// What the procedure found.
#[derive(Debug, Clone, Serialize)]
#[serde(untagged)]
pub enum ProcedureReport {
    /// A UMBmark result.
    Umbmark(Box<umbmark::UmbmarkReport>),
    /// An omni result.
    Omni(Box<omni::OmniReport>),
}

impl ProcedureReport {
    /// The human-readable summary printed without `--json`.
    pub fn human(&self) -> String {
        match self {
            ProcedureReport::Umbmark(r) => r.human(),
            ProcedureReport::Omni(r) => r.human(),
        }
    }
}

/// One trial to run.
#[derive(Debug, Clone, Copy)]
enum Trial {
    Square(Direction),
    /// An omni path, with its idle wheels held or released.
    Path(OmniPath, calib_core::protocol::IdleWheels),
    /// A circle of a radius (m) and laps, for the circle test.
    Circle(Direction, f64, u8),
}

impl Trial {
    fn path_name(self) -> &'static str {
        match self {
            Trial::Square(d) | Trial::Circle(d, ..) => d.as_str(),
            Trial::Path(p, _) => p.as_str(),
        }
    }

    /// What a person is told the run is: the direction of a square, "circle cw (0.5 m,
    /// 2 laps)", the name of an omni path.
    fn label(self) -> String {
        match self {
            Trial::Circle(d, r, laps) => format!("circle {} ({r} m, {laps} laps)", d.as_str()),
            t => t.path_name().to_string(),
        }
    }

    /// The runs file's test.
    fn test(self) -> TestKind {
        match self {
            Trial::Square(_) => TestKind::Umbmark,
            Trial::Path(..) => TestKind::Omni,
            Trial::Circle(..) => TestKind::Circle,
        }
    }

    /// The runs file's length column: the phase's `length` for squares and paths, the
    /// radius for a circle.
    fn length(self, length: f64) -> f64 {
        match self {
            Trial::Circle(_, radius_m, _) => radius_m,
            _ => length,
        }
    }

    /// Whether `r` is a run of this trial.
    fn counts(self, r: &RunRow) -> bool {
        r.test == self.test() && r.path == self.path_name()
    }
}

/// Runs the procedure on a board.
///
/// The phases: the trials the board's robot takes (`umbmark_trials`, `omni_trials`),
/// the runs file checked against them (`existing_runs`), on a second pass the factors it
/// starts from (`second_pass_factors`), the before runs still missing
/// (`Plan::run_before`), the factors computed (`umbmark_factors`, `omni_factors`) and put
/// on the board (`upload`), then the after runs and the report (`finish`).
pub fn run<L: Read + Write>(
    c: &mut Client<L>,
    opts: &Options,
    m: &mut dyn Measure,
) -> Result<ProcedureReport> {
    if opts.runs < 2 {
        bail!("--runs must be at least 2 (statistics need two runs per direction or path)");
    }
    let robot = c.params()?.robot;
    // The omni circle test gives the board a new robot: a resumed procedure computes from
    // the robot its runs were measured with, kept beside them.
    let robot = if opts.kind == Kind::Omni && opts.circles.is_some() {
        measured_robot(&opts.runs_file, robot)?
    } else {
        robot
    };
    let (test, trials, length) = match opts.kind {
        Kind::Umbmark => umbmark_trials(&robot, opts)?,
        Kind::Omni => omni_trials(&robot, opts)?,
    };
    if !(length.is_finite() && length > 0.0 && length <= 20.0) {
        bail!("the path length must be within (0, 20] m, got {length}");
    }
    let plan = Plan {
        opts,
        test,
        trials: &trials,
        length,
        existing: existing_runs(opts, test, length)?,
    };
    let have = |phase: Phase, t: Trial| plan.have(phase, t);
    // Before: nominal geometry, unless resuming a procedure whose factors are already
    // computed (then the before runs are complete and only the after runs remain).
    let before_done = trials.iter().all(|&t| have(Phase::Before, t) >= opts.runs);
    let previous = if opts.second_pass {
        Some(second_pass_factors(c, &opts.runs_file)?)
    } else {
        None
    };
    if !before_done {
        plan.run_before(c, m, previous.as_ref())?;
    }
    let runs = RunsFile::load(&opts.runs_file)?;
    let corrections = match opts.kind {
        Kind::Umbmark => umbmark_factors(&robot, &runs, m)?,
        Kind::Omni => match omni_factors(c, opts, m, &robot, &runs)? {
            Some(corrections) => corrections,
            // The omni circle test put its robot and factors on the board.
            None => return finish(c, opts, m, plan.measured(&robot, None), &have),
        },
    };
    upload(c, m, &robot, previous.as_ref(), corrections)?;
    finish(c, opts, m, plan.measured(&robot, previous.as_ref()), &have)
}

/// UMBmark's trials on the board's `robot` (a differential drive): a square each way,
/// and with `--circle-radius` a circle each way (in one pass only). Returns the runs
/// file's test, the trials and the square's side.
fn umbmark_trials(robot: &Robot, opts: &Options) -> Result<(TestKind, Vec<Trial>, f64)> {
    if robot.kind == RobotKind::SkidSteer {
        bail!("{SKID_UMBMARK}");
    }
    if robot.kind != RobotKind::DiffDrive {
        bail!(
            "the board's robot is {}: UMBmark is for differential drives (use `wheelcal omni run`)",
            robot.kind.as_str()
        );
    }
    let mut trials = vec![Trial::Square(Direction::Cw), Trial::Square(Direction::Ccw)];
    if let Some((radius_m, laps)) = opts.circles {
        if opts.second_pass {
            bail!("--circle-radius measures the turn law against the squares' factors in one pass: drop --second-pass (a second pass composes factors, not laws)");
        }
        trials.push(Trial::Circle(Direction::Cw, radius_m, laps));
        trials.push(Trial::Circle(Direction::Ccw, radius_m, laps));
    }
    Ok((TestKind::Umbmark, trials, opts.side_m))
}

/// The omni procedure's trials on the board's `robot` (an omni robot): both straight
/// paths with the idle-wheel mode (kept beside the runs file, and a resumed file's mode
/// required), and with `--circle-radius` turns in place and circles each way (in one
/// pass only, and circles wide enough to tell from the turns). Returns the runs file's
/// test, the trials and the path length.
fn omni_trials(robot: &Robot, opts: &Options) -> Result<(TestKind, Vec<Trial>, f64)> {
    if robot.kind != RobotKind::Omni {
        bail!("the board's robot is {}: the omni procedure is for omni robots (use `wheelcal umbmark run`)", robot.kind.as_str());
    }
    // Runs of one file share one idle-wheel mode; it is kept beside them so a
    // later `omni compute` on the file models the same.
    match omni::read_idle_sidecar(&opts.runs_file)? {
        Some(m) if m != opts.idle_wheels && opts.runs_file.exists() => bail!(
            "{} was measured with idle wheels {}; use --idle-wheels {} to resume it, or a new --runs-file",
            opts.runs_file.display(),
            m.as_str(),
            m.as_str()
        ),
        _ => omni::write_idle_sidecar(&opts.runs_file, opts.idle_wheels)?,
    }
    let mut trials = vec![
        Trial::Path(OmniPath::W1, opts.idle_wheels),
        Trial::Path(OmniPath::W2, opts.idle_wheels),
    ];
    if let Some((radius_m, laps)) = opts.circles {
        if opts.second_pass {
            bail!("--circle-radius measures the turn in place and the turn law against the straight paths' factors in one pass: drop --second-pass");
        }
        let l = robot.mean_wheel_distance_m();
        if omni_circle_test::share(radius_m, l) < 0.75 {
            bail!(
                "--circle-radius {radius_m} m: the omni circle test compares turns in place with circles at least twice the wheels' distance from the centre ({l:.3} m here): use --circle-radius {:.2} or more",
                2.0 * l
            );
        }
        for r in [TURN_IN_PLACE_RADIUS_M, radius_m] {
            trials.push(Trial::Circle(Direction::Cw, r, laps));
            trials.push(Trial::Circle(Direction::Ccw, r, laps));
        }
    }
    Ok((TestKind::Omni, trials, opts.length_m))
}

/// The runs file as it stands (empty when new), checked before anything moves: a file
/// that holds runs of another length, or circles of another radius, or has no laps
/// column for circles of several laps cannot take this procedure's runs.
fn existing_runs(opts: &Options, test: TestKind, length: f64) -> Result<RunsFile> {
    let existing = if opts.runs_file.exists() {
        RunsFile::load(&opts.runs_file)?
    } else {
        RunsFile::new(&opts.runs_file)
    };
    if existing
        .rows
        .iter()
        .any(|r| r.test == test && (r.length_m - length).abs() > 1e-9)
    {
        bail!(
            "{} already holds runs of another length; use a new --runs-file for {} m",
            opts.runs_file.display(),
            length
        );
    }
    if let Some((radius_m, laps)) = opts.circles {
        // Checked before anything moves: a circle driven but not recordable is lost.
        if laps != 1 && !RunsFile::takes_laps(&opts.runs_file) {
            bail!(
                "{} has no laps column for circles of {laps} laps: use a new --runs-file (or --circle-laps 1)",
                opts.runs_file.display()
            );
        }
        // An omni robot's turns in place are circles of their own radius.
        let other_radius = |r: f64| {
            (r - radius_m).abs() > 1e-9
                && !(opts.kind == Kind::Omni && (r - TURN_IN_PLACE_RADIUS_M).abs() <= 1e-9)
        };
        if let Some(r) = existing
            .rows
            .iter()
            .find(|r| r.test == TestKind::Circle && other_radius(r.length_m))
        {
            bail!(
                "{} already holds circles of radius {} m (line {}); use a new --runs-file for {} m",
                opts.runs_file.display(),
                r.length_m,
                r.line,
                radius_m
            );
        }
    }
    Ok(existing)
}

/// The factors a second pass measures with: those remembered beside the runs file (a
/// resumed second pass composes with the same ones), else the board's, remembered now.
fn second_pass_factors<L: Read + Write>(
    c: &mut Client<L>,
    runs_file: &Path,
) -> Result<Corrections> {
    let file = previous_file(runs_file);
    let read = crate::input::read_text(&file, crate::input::MAX_SIDECAR_BYTES, "factors record");
    let p: Corrections = match read {
        Ok(text) => serde_json::from_str(&text)
            .with_context(|| format!("{}: not a factors record", file.display()))?,
        Err(e) if !crate::input::is_not_found(&e) => return Err(e),
        Err(_) => {
            let p = c.corrections()?;
            std::fs::write(&file, serde_json::to_string(&p)?)
                .with_context(|| format!("cannot write {}", file.display()))?;
            p
        }
    };
    Ok(p)
}

/// What a procedure runs and what its runs file held when it started: the trials, the
/// path length and the rows already measured (a procedure resumes where it stopped).
struct Plan<'a> {
    opts: &'a Options,
    test: TestKind,
    trials: &'a [Trial],
    length: f64,
    existing: RunsFile,
}

impl Plan<'_> {
    /// Runs of `t` in `phase` the runs file held when the procedure started.
    fn have(&self, phase: Phase, t: Trial) -> usize {
        self.existing
            .rows
            .iter()
            .filter(|r| r.phase == phase && t.counts(r))
            .count()
    }

    /// The before runs still missing, with the factors a second pass measures with
    /// (`previous`) or none (nominal geometry).
    fn run_before<L: Read + Write>(
        &self,
        c: &mut Client<L>,
        m: &mut dyn Measure,
        previous: Option<&Corrections>,
    ) -> Result<()> {
        let opts = self.opts;
        if let Some(p) = previous {
            c.set_corrections(p.clone())?;
            m.say(&format!(
                "second pass: measuring with {}",
                board::FactorsView::from(p).human().trim()
            ));
        } else {
            c.reset_corrections()?;
        }
        m.say(&format!(
            "before calibration: {} runs per {}",
            opts.runs,
            if self.test == TestKind::Umbmark {
                "direction"
            } else {
                "path"
            }
        ));
        let plan = PhasePlan {
            runs: opts.runs,
            runs_file: &opts.runs_file,
            trials: self.trials,
            length: self.length,
            phase: Phase::Before,
        };
        run_phase(c, m, plan, &|t| self.have(Phase::Before, t))
    }

    /// What the runs were measured with, for [`finish`].
    fn measured<'b>(&'b self, robot: &'b Robot, previous: Option<&'b Corrections>) -> Measured<'b> {
        Measured {
            robot,
            trials: self.trials,
            length: self.length,
            previous,
        }
    }
}

/// UMBmark's factors from the runs measured: the circle test's turn law with them when
/// it kept one (the board's odometry applies it), else c_L, c_R and E_b.
fn umbmark_factors(robot: &Robot, runs: &RunsFile, m: &mut dyn Measure) -> Result<Corrections> {
    let r = umbmark::compute(robot, runs)?;
    if let Some(c) = &r.circles {
        m.say(&format!("circle test: {}", c.verdict));
    }
    Ok(match &r.factors {
        // The circle test kept a turn law: the board's odometry applies it.
        Some(f) => f.board.corrections(),
        None => Corrections::DiffDrive {
            c_l: r.c_l,
            c_r: r.c_r,
            e_b: r.eb,
        },
    })
}

/// The omni procedure's factors from the runs measured, or `None` when the omni circle
/// test gave the board a robot: the wheels' sizes and distances then go on the board as
/// its robot, with factors of one and the law, together or not at all, and are saved.
fn omni_factors<L: Read + Write>(
    c: &mut Client<L>,
    opts: &Options,
    m: &mut dyn Measure,
    robot: &Robot,
    runs: &RunsFile,
) -> Result<Option<Corrections>> {
    let r = omni::compute(robot, runs, opts.idle_wheels)?;
    let r = omni::with_circles(r, robot, runs, None)?;
    let Some(board_robot) = r.board_robot(robot)? else {
        return Ok(Some(r.corrections()?));
    };
    // The circle test: the wheels' sizes and distance go on the board as its
    // robot, with factors of one and the law, together or not at all.
    let circles = r.circles.as_ref().map(|c| c.verdict.clone());
    m.say(&format!(
        "omni circle test: {}",
        circles.unwrap_or_default()
    ));
    let n = board_robot.wheels.len();
    let target = board::Target {
        params: Some(board::with_robot(
            &c.params()?,
            board_robot,
            &measured_robot_file(&opts.runs_file),
        )?),
        corrections: r.corrections()?.laws_only(n),
    };
    board::apply_settings(c, &target)
        .context("the omni circle test's geometry and factors were not uploaded")?;
    c.save_params()?;
    c.save_corrections()?;
    m.say(&format!(
        "robot geometry and factors uploaded and saved: wheel distances x{:.5}, {}",
        r.circles.as_ref().map_or(1.0, |c| c.wheel_distance_scale),
        board::FactorsView::from(&target.corrections).human().trim()
    ));
    Ok(None)
}

/// Puts the computed factors on the board and saves them: on a second pass composed
/// with the factors measured with (`previous`), and validated first, so nothing is
/// uploaded from a computation the board would refuse.
fn upload<L: Read + Write>(
    c: &mut Client<L>,
    m: &mut dyn Measure,
    robot: &Robot,
    previous: Option<&Corrections>,
    corrections: Corrections,
) -> Result<()> {
    let corrections = match previous {
        Some(p) => p.compose(&corrections).with_context(|| {
            format!(
                "cannot compose the board's factors ({}) with ({}): they do not fit this procedure",
                crate::board::factors_text(p),
                crate::board::factors_text(&corrections)
            )
        })?,
        None => corrections,
    };
    // Validated here too: nothing is uploaded from a computation the board would refuse.
    corrections.validate(robot).map_err(|e| {
        anyhow::anyhow!("computed factors are not usable ({e}); nothing was uploaded")
    })?;
    c.set_corrections(corrections.clone())?;
    c.save_corrections()?;
    m.say(&format!(
        "factors uploaded and saved: {}",
        board::FactorsView::from(&corrections).human().trim()
    ));
    Ok(())
}

/// What a procedure measured with: the robot the board held, the trials, the path
/// length, and on a second pass the factors in force.
#[derive(Clone, Copy)]
struct Measured<'a> {
    robot: &'a Robot,
    trials: &'a [Trial],
    length: f64,
    previous: Option<&'a Corrections>,
}

/// The end of a procedure once the board holds its calibration: the after trials (when
/// asked), then the report of the whole runs file. `have(phase, trial)` counts the runs
/// the runs file held when the procedure started.
fn finish<L: Read + Write>(
    c: &mut Client<L>,
    opts: &Options,
    m: &mut dyn Measure,
    measured: Measured<'_>,
    have: &dyn Fn(Phase, Trial) -> usize,
) -> Result<ProcedureReport> {
    let Measured {
        robot,
        trials,
        length,
        previous,
    } = measured;
    if opts.after {
        let plan = PhasePlan {
            runs: opts.after_runs,
            runs_file: &opts.runs_file,
            trials,
            length,
            phase: Phase::After,
        };
        run_phase(c, m, plan, &|t| have(Phase::After, t))?;
    }
    let runs = RunsFile::load(&opts.runs_file)?;
    let rep = match opts.kind {
        Kind::Umbmark => {
            let r = umbmark::compute(robot, &runs)?;
            if let Some(dir) = &opts.report {
                crate::report::umbmark::write(&r, dir)?;
            }
            ProcedureReport::Umbmark(Box::new(r))
        }
        Kind::Omni => {
            let mut r = omni::compute(robot, &runs, opts.idle_wheels)?;
            let previous = previous.filter(|p| p.omni_factors().is_some());
            if let Some(p) = previous {
                r = omni::compose_with(r, p)?;
            }
            let r = omni::with_circles(r, robot, &runs, previous)?;
            if let Some(dir) = &opts.report {
                crate::report::omni::write(&r, dir)?;
            }
            ProcedureReport::Omni(Box::new(r))
        }
    };
    Ok(rep)
}

/// What one phase (before or after calibration) runs, in one value instead of a long
/// argument list to [`run_phase`].
#[derive(Debug, Clone, Copy)]
struct PhasePlan<'a> {
    /// Runs per direction (UMBmark) or per path (omni).
    runs: usize,
    /// Where each measured run is appended, so a stopped procedure resumes.
    runs_file: &'a Path,
    /// The squares or paths, in the order they run.
    trials: &'a [Trial],
    /// The square's side (UMBmark) or the path length (omni), metres (a circle's radius
    /// comes with its trial).
    length: f64,
    /// Before or after the factors were applied.
    phase: Phase,
}

/// Runs one phase: for each trial, the runs `have` says are still missing, each measured
/// by `m` and appended to the runs file.
fn run_phase<L: Read + Write>(
    c: &mut Client<L>,
    m: &mut dyn Measure,
    plan: PhasePlan<'_>,
    have: &dyn Fn(Trial) -> usize,
) -> Result<()> {
    let PhasePlan {
        runs,
        runs_file,
        trials,
        length,
        phase,
    } = plan;
    // A phase with circles gives a new runs file the `laps` column.
    let laps_column = trials.iter().any(|t| matches!(t, Trial::Circle(..)));
    for &t in trials {
        for k in have(t)..runs {
            let what = format!("{} {} run {}/{}", phase.as_str(), t.label(), k + 1, runs);
            let mut attempt = 0;
            let end = loop {
                m.ready(&what)?;
                m.say(&format!("{what}: running"));
                let limit = match t {
                    Trial::Square(d) => {
                        board::run_umbmark(c, d, length, 10, DEFAULT_LINK_TIMEOUT_MS)?
                    }
                    Trial::Path(p, idle) => {
                        board::run_omni(c, p, length, idle, 10, DEFAULT_LINK_TIMEOUT_MS)?
                    }
                    Trial::Circle(d, radius_m, laps) => {
                        board::run_circle(c, d, radius_m, laps, 10, DEFAULT_LINK_TIMEOUT_MS)?
                    }
                };
                let end = board::wait_program(c, limit + Duration::from_secs(60), |_| {})?;
                // Only a run that reached the path's end is a measurement: a cut one would
                // enter the statistics as a huge "error".
                match end.stop {
                    StopReason::ProgramDone => break end,
                    StopReason::LinkLost if attempt < LINK_LOST_RETRIES => {
                        attempt += 1;
                        m.say(&format!(
                            "{what}: cut short, this console was silent for over {DEFAULT_LINK_TIMEOUT_MS} ms (the board's link failsafe); not recorded: put the robot back at the start, it runs again"
                        ));
                    }
                    other => bail!(
                        "{what} ended before the path's end ({}): not recorded; the runs so far are kept, start the procedure again to resume",
                        stop_words(other)
                    ),
                }
            };
            let trial = c
                .trials()?
                .trials
                .last()
                .map(|t| t.id)
                .context("the board logged no trial")?;
            // The board's odometry in the path frame (x along the first leg or the path).
            let d = match t {
                Trial::Square(_) | Trial::Circle(..) => 0.0,
                Trial::Path(p, _) => {
                    let (ux, uy) = p.direction();
                    uy.atan2(ux)
                }
            };
            // UMBmark measures against the board's odometry (Borenstein). [Redundant omni]'s omni method
            // corrects the wheel commands and measures against the commanded end point:
            // on a redundant robot the odometry partly follows a deviation (the unused,
            // free-rolling wheels' encoders see it), which would hide half of it.
            let reference = match t {
                Trial::Square(_) | Trial::Circle(..) => {
                    let (sd, cd) = (d as f32).sin_cos();
                    let o = end.pose;
                    Pose::new(cd * o.x + sd * o.y, -sd * o.x + cd * o.y, o.theta)
                }
                Trial::Path(..) => Pose::new(length as f32, 0.0, 0.0),
            };
            let heading = matches!(t, Trial::Circle(_, r, _) if r < MIN_RADIUS_BY_END_M);
            let (x, y, th) = m.end_error(trial, reference, d, &what, heading)?;

            RunsFile::append_with(
                runs_file,
                &RunRow {
                    line: 0,
                    test: t.test(),
                    path: t.path_name().into(),
                    length_m: t.length(length),
                    x_err_m: x,
                    y_err_m: y,
                    theta_err_rad: th,
                    phase,
                    laps: match t {
                        Trial::Circle(_, _, laps) => laps,
                        _ => 1,
                    },
                },
                laps_column,
            )
            .with_context(|| format!("cannot append to {}", runs_file.display()))?;
        }
    }
    Ok(())
}

/// Why UMBmark refuses a skid-steer robot, and what to do instead.
pub const SKID_UMBMARK: &str = "the board's robot is skid_steer: UMBmark's closed form assumes errors of a few per cent, and a skid-steer robot's effective separation is 1.5-2 times its track (a 90-degree corner turns 45-60 degrees); record a few minutes of squares and arcs with poses and run `wheelcal calibrate`, then `wheelcal factors set` with its E_b";

/// Runs cut by the link failsafe that are run again before the procedure gives up.
const LINK_LOST_RETRIES: usize = 2;

/// Why a program stopped, in words.
pub(crate) fn stop_words(s: StopReason) -> &'static str {
    match s {
        StopReason::None => "not stopped",
        StopReason::Request => "stopped on request",
        StopReason::EStop => "emergency stop",
        StopReason::CommandTimeout => "command timeout",
        StopReason::Fault => "a fault; `wheelcal status` names it",
        StopReason::ProgramDone => "done",
        StopReason::LinkLost => "the link failsafe cut it: the console was silent too long",
    }
}

#[cfg(test)]
mod tests {
    use super::{heading_error, parse_end_position, parse_heading_deg};

    /// After a lap clockwise the odometry says -360.05 degrees; the robot, seen by a
    /// person, points 0.5 degrees left of its start: it turned 0.55 degrees less than the
    /// odometry says (+0.0096 rad, measured minus odometry). Whole laps do not count.
    #[test]
    fn a_heading_by_hand_is_measured_against_the_odometry_modulo_laps() {
        let odo = (-360.05f64).to_radians() as f32;
        let e = heading_error(0.5, odo);
        assert!((e - 0.55f64.to_radians()).abs() < 1e-6, "{e}");
        let e = heading_error(-179.0, (179.0f64 + 720.0).to_radians() as f32);
        assert!((e - 2f64.to_radians()).abs() < 1e-6, "{e}");
    }

    /// A typed heading: one number of degrees within +-180, with white space around it;
    /// anything else is refused with the reason.
    #[test]
    fn typed_headings() {
        assert_eq!(parse_heading_deg(" -3.5\n"), Ok(-3.5));
        assert_eq!(parse_heading_deg("180"), Ok(180.0));
        for (bad, says) in [
            ("", "not a number"),
            ("3 4", "not a number"),
            ("nan", "not a number"),
            ("181", "beyond +-180"),
            ("-200.5", "beyond +-180"),
            ("5deg", "not a number"),
        ] {
            let e = parse_heading_deg(bad).unwrap_err();
            assert!(e.contains(says), "{bad:?}: {e}");
        }
    }

    /// Issue 13.2: the prompt's own example was refused because of the newline, and
    /// `1 2 3` was taken as (1, 2).
    #[test]
    fn typed_end_positions() {
        assert_eq!(parse_end_position("12.5 -30\n"), Ok((12.5, -30.0)));
        assert_eq!(parse_end_position("  12.5,-30 \r\n"), Ok((12.5, -30.0)));
        assert_eq!(parse_end_position("12.5, -30"), Ok((12.5, -30.0)));
        assert_eq!(parse_end_position("-0.5\t4e1\n"), Ok((-0.5, 40.0)));
        for bad in [
            "1 2 3\n",
            "12.5\n",
            "\n",
            "12.5 abc\n",
            "nan 1",
            "1 inf",
            "1e6 0",
        ] {
            let e = parse_end_position(bad).unwrap_err();
            assert!(!e.is_empty(), "{bad:?}");
        }
        assert!(parse_end_position("1 2 3")
            .unwrap_err()
            .contains("3 values"));
        assert!(parse_end_position("12.5 abc")
            .unwrap_err()
            .contains("`abc`"));
    }
}
