//! `wheelcal demo`: the UMBmark procedure on a virtual board whose wheel-diameter ratio
//! and wheelbase error are drawn at random and hidden from the procedure; the truth is
//! only used at the end, to show how close the calibration came.

use crate::calibration::procedure::{self, Kind, Options, ProcedureReport, TruthChannel};
use crate::calibration::umbmark::UmbmarkReport;
use crate::link::Faults;
use crate::virtual_board::InProcessBoard;
use anyhow::{bail, Context, Result};
use calib_core::robot::RobotKind;
use formats::robot_file;
use rand::{Rng, SeedableRng};
use serde::Serialize;
use sim::{SimConfig, SimRobot, Surface};
use std::fmt::Write as _;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Floor roughness of the demo: random travel error of each wheel, metres per sqrt(metre).
pub const DEMO_ROUGHNESS: f64 = 3e-4;

const MOBOLAB: &str = include_str!("../../robots/mobolab.toml");

/// Result of `wheelcal demo`: the hidden errors, the estimates and E_max,sys before and after.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    /// Name of the demo robot.
    pub robot: String,
    /// Seed of the hidden errors and the simulation noise.
    pub seed: u64,
    /// Side of the UMBmark square, m.
    pub side_m: f64,
    /// Squares driven in each direction (CW and CCW), per phase.
    pub runs_per_direction: usize,
    /// The hidden wheel-diameter ratio E_d = D_R / D_L (the truth, revealed).
    pub true_ed: f64,
    /// The hidden wheelbase error E_b (true / nominal wheelbase).
    pub true_eb: f64,
    /// UMBmark's estimate of E_d.
    pub estimated_ed: f64,
    /// UMBmark's estimate of E_b.
    pub estimated_eb: f64,
    /// UMBmark's E_max,sys before correction, m.
    pub e_max_sys_before_m: f64,
    /// UMBmark's E_max,sys after correction, m.
    pub e_max_sys_after_m: f64,
    /// E_max,sys before divided by after (how many times smaller the error got).
    pub improvement: f64,
    /// With `--circle-radius`: the hidden tyre scrub (the turn law, e_b_arc).
    pub true_e_b_arc: Option<f64>,
    /// The circle test's estimate of it, and its sigma.
    pub estimated_e_b_arc: Option<(f64, f64)>,
    /// Wall-clock time the demo took, s.
    pub seconds: f64,
    /// The full UMBmark report of the demo's runs.
    pub umbmark: UmbmarkReport,
}

impl DemoReport {
    /// The human-readable summary printed without `--json`.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "wheelcal demo: UMBmark on a virtual {} (seed {}), {} x {} m squares each way, before and after", self.robot, self.seed, self.runs_per_direction, self.side_m);
        let _ = writeln!(
            s,
            "\n  {:<10} {:>16} {:>16} {:>12}",
            "robot", "E_max,sys before", "E_max,sys after", "improvement"
        );
        let _ = writeln!(
            s,
            "  {:<10} {:>13.2} mm {:>13.2} mm {:>11.1}x",
            self.robot,
            self.e_max_sys_before_m * 1e3,
            self.e_max_sys_after_m * 1e3,
            self.improvement
        );
        let _ = writeln!(
            s,
            "\n  hidden truth   E_d = {:.5}  E_b = {:.5}",
            self.true_ed, self.true_eb
        );
        let _ = writeln!(
            s,
            "  calibration    E_d = {:.5}  E_b = {:.5}  (exact-model fit)",
            self.estimated_ed, self.estimated_eb
        );
        let _ = writeln!(
            s,
            "  closed form    E_d = {:.5}  E_b = {:.5}",
            self.umbmark.closed_form.ed, self.umbmark.closed_form.eb
        );
        if let (Some(t), Some((k, sigma))) = (self.true_e_b_arc, self.estimated_e_b_arc) {
            let _ = writeln!(
                s,
                "  turn law       hidden e_b_arc = {t:.5}, circle test {k:.5} ± {sigma:.5}"
            );
        }
        let _ = writeln!(s, "\n  finished in {:.1} s", self.seconds);
        s
    }
}

/// Runs the demo. `robot_path` falls back to the built-in MoboLab when it does not exist
/// and is the default.
pub fn run(
    robot_path: &Path,
    seed: u64,
    runs: usize,
    side: f64,
    report: Option<&Path>,
    progress: bool,
    circles: Option<(f64, u8)>,
) -> Result<DemoReport> {
    let t0 = Instant::now();
    let robot = if robot_path.exists() {
        robot_file::load(robot_path)?
    } else if robot_path == Path::new("robots/mobolab.toml") {
        robot_file::parse(MOBOLAB, Path::new("robots/mobolab.toml (built in)"))?
    } else {
        bail!("no robot file {}", robot_path.display());
    };
    if robot.kind != RobotKind::DiffDrive {
        bail!(
            "the demo runs UMBmark: it needs a differential drive, {} is {}",
            robot.name,
            robot.kind.as_str()
        );
    }
    // Hidden errors of the size [Measuring errors] reports (E_max,sys of 30 to 100 mm on 4 m).
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let sign = |r: &mut rand_chacha::ChaCha8Rng| if r.random_bool(0.5) { 1.0 } else { -1.0 };
    let true_ed = 1.0 + sign(&mut rng) * rng.random_range(0.002..0.006);
    let true_eb = 1.0 + sign(&mut rng) * rng.random_range(0.01..0.03);
    let mut faults = sim::Faults::none(2);
    // E_d = D_R / D_L with the mean diameter kept.
    let (c_l, c_r) = calib_core::umbmark::wheel_factors(true_ed);
    faults.radius_scale = vec![c_l, c_r];
    faults.wheelbase_scale = true_eb;
    faults.travel_noise_m_per_sqrt_m = DEMO_ROUGHNESS;
    // With circles, tyres that scrub: 0.5-3 % wider on arcs (the OptiOdom robot's 0.5 %).
    let true_e_b_arc = circles.map(|_| rng.random_range(0.005..0.03));
    let run = VirtualRun {
        runs,
        length: side,
        report,
        after_runs: runs,
        progress,
        circles,
    };
    let cfg = SimConfig {
        seed,
        turn_scrub: true_e_b_arc.unwrap_or(0.0),
        ..SimConfig::default()
    };
    let sim = SimRobot::new(&robot, faults, Surface::flat(), cfg)?;
    let rep = match procedure_on_virtual_board(&robot, sim, Kind::Umbmark, run)? {
        ProcedureReport::Umbmark(rep) => *rep,
        ProcedureReport::Omni(_) => bail!("the procedure returned an omni result"),
    };
    let after = rep
        .e_max_sys_after_m
        .context("the after runs are missing")?;
    Ok(DemoReport {
        robot: robot.name.to_string(),
        seed,
        side_m: side,
        runs_per_direction: runs,
        true_ed,
        true_eb,
        estimated_ed: rep.ed,
        estimated_eb: rep.eb,
        e_max_sys_before_m: rep.e_max_sys_before_m,
        e_max_sys_after_m: after,
        improvement: rep.e_max_sys_before_m / after,
        true_e_b_arc,
        estimated_e_b_arc: rep.circles.as_ref().map(|c| (c.e_b_arc, c.e_b_arc_sigma)),
        seconds: t0.elapsed().as_secs_f64(),
        umbmark: rep,
    })
}

/// How a procedure runs on a virtual board: the settings [`umbmark_on_virtual_board`]
/// and [`procedure_on_virtual_board`] share, in one value instead of a long argument
/// list whose numbers are easy to swap.
#[derive(Debug, Clone, Copy)]
pub struct VirtualRun<'a> {
    /// Runs per direction (UMBmark) or per path (omni) before calibration.
    pub runs: usize,
    /// The square's side (UMBmark) or the path length (omni), metres.
    pub length: f64,
    /// Write the HTML report into this directory.
    pub report: Option<&'a Path>,
    /// Runs per direction or path after calibration (0: none).
    pub after_runs: usize,
    /// Show a progress bar on stderr.
    pub progress: bool,
    /// UMBmark: circles of this radius and laps beside the squares (the circle test).
    pub circles: Option<(f64, u8)>,
}

/// Runs the UMBmark procedure (auto-measured) on a virtual board simulating `robot` with
/// `faults` (noise seeded with `seed`), as `run` says.
pub fn umbmark_on_virtual_board(
    robot: &calib_core::Robot,
    faults: sim::Faults,
    seed: u64,
    run: VirtualRun<'_>,
) -> Result<UmbmarkReport> {
    let sim = SimRobot::new(
        robot,
        faults,
        Surface::flat(),
        SimConfig {
            seed,
            ..SimConfig::default()
        },
    )?;
    match procedure_on_virtual_board(robot, sim, Kind::Umbmark, run)? {
        ProcedureReport::Umbmark(rep) => Ok(*rep),
        ProcedureReport::Omni(_) => bail!("the procedure returned an omni result"),
    }
}

/// Runs a guided procedure, auto-measured, on a virtual board around `sim`, as `run`
/// says.
pub fn procedure_on_virtual_board(
    robot: &calib_core::Robot,
    sim: SimRobot,
    kind: Kind,
    run: VirtualRun<'_>,
) -> Result<ProcedureReport> {
    let VirtualRun {
        runs,
        length,
        report,
        after_runs,
        progress,
        circles,
    } = run;
    let seed = RUN_ID.fetch_add(1, Ordering::Relaxed);
    let mut board = InProcessBoard::start(robot, sim, Faults::none(), Faults::none(), seed)?;
    let dir =
        std::env::temp_dir().join(format!("wheelcal-procedure-{}-{seed}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let bar = progress.then(|| {
        let trials = if circles.is_some() { 4 } else { 2 };
        let b = indicatif::ProgressBar::new((trials * (runs + after_runs)) as u64);
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "{msg:40} [{bar:30}] {pos}/{len} runs {elapsed}",
            )
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
        );
        b
    });
    let mut measure = TruthChannel {
        rx: &board.truths,
        seen: Vec::new(),
        progress: bar.clone(),
    };
    let opts = Options {
        kind,
        side_m: length,
        length_m: length,
        runs,
        after_runs,
        runs_file: dir.join("runs.csv"),
        auto_measure: None,
        report: report.map(Path::to_path_buf),
        after: after_runs > 0,
        second_pass: false,
        idle_wheels: Default::default(),
        circles,
    };
    let client = &mut board.client;
    let result = client
        .hello()
        .map_err(anyhow::Error::from)
        .and_then(|_| procedure::run(client, &opts, &mut measure));
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let _ = std::fs::remove_dir_all(&dir);
    result
}

static RUN_ID: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
