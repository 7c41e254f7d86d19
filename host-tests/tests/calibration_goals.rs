//! Issue 6's goals, measured on virtual boards (firmware application + simulator):
//! UMBmark on [Measuring errors]'s three robots improves E_max,sys at least 10x and ends within 1.5x of
//! the non-systematic floor; the procedure resumes without losing runs; a failed
//! computation uploads nothing.

use formats::robot_file;
use formats::runs_file::{Phase, RunsFile};
use std::path::{Path, PathBuf};
use wheelcal::demo::{umbmark_on_virtual_board, VirtualRun, DEMO_ROUGHNESS};

fn robot(name: &str) -> calib_core::Robot {
    robot_file::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(name),
    )
    .unwrap()
}

fn faults(ed: f64, eb: f64) -> sim::Faults {
    let mut f = sim::Faults::none(2);
    let (l, r) = calib_core::umbmark::wheel_factors(ed);
    f.radius_scale = vec![l, r];
    f.wheelbase_scale = eb;
    f.travel_noise_m_per_sqrt_m = DEMO_ROUGHNESS;
    f
}

/// E_max,sys of consecutive groups of 5 runs per direction, averaged: one 5-run
/// E_max,sys varies by tens of percent from noise alone, so the floor and the result
/// are both compared as means over three groups.
fn mean_e_max_sys(cw: &[wheelcal::output::PointM], ccw: &[wheelcal::output::PointM]) -> f64 {
    let centroid = |p: &[wheelcal::output::PointM]| {
        let n = p.len() as f64;
        (
            p.iter().map(|q| q.x_m).sum::<f64>() / n,
            p.iter().map(|q| q.y_m).sum::<f64>() / n,
        )
    };
    let groups: Vec<f64> = cw
        .chunks(5)
        .zip(ccw.chunks(5))
        .map(|(a, b)| calib_core::umbmark::e_max_sys(centroid(a), centroid(b)))
        .collect();
    groups.iter().sum::<f64>() / groups.len() as f64
}

#[test]
fn umbmark_reaches_ten_x_and_the_noise_floor_on_000s_robots() {
    // Errors of the size [Measuring errors] measured and larger; calibration from 5 runs per direction as
    // in the paper; after it, 15 runs per direction. The floor: the same robot with
    // perfect geometry under the same floor roughness, 15 runs per direction.
    let mut table = String::from(
        "robot      E_d      E_b      before mm  after mm  floor mm  improvement  after/floor\n",
    );
    for (i, (name, ed, eb)) in [
        ("robotest.toml", 1.004, 1.012),
        ("mobolab.toml", 0.996, 1.02),
        ("sweeper.toml", 1.003, 0.985),
    ]
    .into_iter()
    .enumerate()
    {
        let r = robot(name);
        let seed = 100 + i as u64;
        let run = |runs, after_runs| VirtualRun {
            runs,
            length: 4.0,
            report: None,
            after_runs,
            progress: false,
            circles: None,
        };
        let rep = umbmark_on_virtual_board(&r, faults(ed, eb), seed, run(5, 15)).unwrap();
        let perfect =
            umbmark_on_virtual_board(&r, faults(1.0, 1.0), seed + 50, run(15, 0)).unwrap();
        let a = rep.after.as_ref().unwrap();
        let after = mean_e_max_sys(&a.cw.points, &a.ccw.points);
        let floor = mean_e_max_sys(&perfect.before.cw.points, &perfect.before.ccw.points);
        let imp = rep.e_max_sys_before_m / after;
        table.push_str(&format!(
            "{:<10} {ed:.4}  {eb:.4}  {:>9.1}  {:>8.2}  {:>8.2}  {:>10.1}x  {:>10.2}\n",
            r.name,
            rep.e_max_sys_before_m * 1e3,
            after * 1e3,
            floor * 1e3,
            imp,
            after / floor
        ));
        assert!(imp >= 10.0, "{}: improvement {imp:.1}x\n{table}", r.name);
        assert!(
            after <= 1.5 * floor,
            "{}: after {:.2} mm vs floor {:.2} mm\n{table}",
            r.name,
            after * 1e3,
            floor * 1e3
        );
        // The exact fit finds the hidden geometry to the noise's resolution.
        assert!(
            (rep.ed - ed).abs() < 5e-4 && (rep.eb - eb).abs() < 2e-3,
            "{}: E_d {} E_b {}",
            r.name,
            rep.ed,
            rep.eb
        );
    }
    eprintln!("{table}");
}

fn temp_runs(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wheelcal-goals-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d.join("runs.csv")
}

#[test]
fn a_failed_computation_uploads_nothing() {
    use wheelcal::calibration::procedure::{self, Kind, Options, TruthFile};
    use wheelcal::link::Faults;
    use wheelcal::virtual_board::InProcessBoard;

    let r = robot("mobolab.toml");
    let sim = sim::SimRobot::new(
        &r,
        sim::Faults::none(2),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&r, sim, Faults::none(), Faults::none(), 1).unwrap();
    let c = &mut board.client;
    c.hello().unwrap();
    let before = calib_core::Corrections::DiffDrive {
        c_l: 1.001,
        c_r: 0.999,
        e_b: 1.01,
    };
    c.set_corrections(before.clone()).unwrap();
    // Complete 'before' runs whose errors (3 m on a 4 m square) no real geometry gives.
    let runs = temp_runs("fail");
    let mut text = String::from("test,path,length_m,x_err_m,y_err_m\n");
    for _ in 0..3 {
        text.push_str("umbmark,cw,4,-30.0,-30.0\numbmark,ccw,4,-30.0,30.0\n");
    }
    std::fs::write(&runs, text).unwrap();
    let opts = Options {
        kind: Kind::Umbmark,
        side_m: 4.0,
        length_m: 4.0,
        runs: 3,
        after_runs: 3,
        runs_file: runs.clone(),
        auto_measure: None,
        report: None,
        after: true,
        second_pass: false,
        idle_wheels: Default::default(),
        circles: None,
    };
    let mut m = TruthFile {
        file: runs.with_extension("truth"),
        quiet: true,
    };
    let err = procedure::run(c, &opts, &mut m).unwrap_err().to_string();
    assert!(
        err.contains("runs.csv") || err.contains("not usable"),
        "{err}"
    );
    assert_eq!(
        c.corrections().unwrap(),
        before,
        "nothing may be uploaded after a failed computation"
    );
    // The runs file is untouched: still the 6 rows written above.
    assert_eq!(RunsFile::load(&runs).unwrap().rows.len(), 6);
}

/// The person at the robot in the procedures below: ready at once, keeps what the
/// procedure says, measures with the simulator's truth `left` times, then walks away
/// (stdin closed).
struct Person<'a, 'b> {
    truth: &'a mut wheelcal::calibration::procedure::TruthChannel<'b>,
    said: Vec<String>,
    left: usize,
}

impl wheelcal::calibration::procedure::Measure for Person<'_, '_> {
    fn say(&mut self, text: &str) {
        self.said.push(text.to_string());
    }
    fn ready(&mut self, _: &str) -> anyhow::Result<()> {
        Ok(())
    }
    fn end_error(
        &mut self,
        trial: u16,
        odo: calib_core::odometry::Pose<f32>,
        direction_rad: f64,
        what: &str,
        heading: bool,
    ) -> anyhow::Result<(f64, f64, Option<f64>)> {
        if self.left == 0 {
            anyhow::bail!("no more input");
        }
        self.left -= 1;
        self.truth
            .end_error(trial, odo, direction_rad, what, heading)
    }
}

#[test]
fn a_stopped_procedure_resumes_without_losing_runs() {
    use wheelcal::calibration::procedure::{self, Kind, Options, TruthChannel};
    use wheelcal::link::Faults;
    use wheelcal::virtual_board::InProcessBoard;

    let r = robot("mobolab.toml");
    let sim = sim::SimRobot::new(
        &r,
        faults(1.003, 1.01),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&r, sim, Faults::none(), Faults::none(), 2).unwrap();
    let c = &mut board.client;
    c.hello().unwrap();
    let runs = temp_runs("resume");
    let _ = std::fs::remove_file(&runs);
    let opts = Options {
        kind: Kind::Umbmark,
        side_m: 1.0,
        length_m: 1.0,
        runs: 3,
        after_runs: 3,
        runs_file: runs.clone(),
        auto_measure: None,
        report: None,
        after: true,
        second_pass: false,
        idle_wheels: Default::default(),
        circles: None,
    };
    let mut truth = TruthChannel {
        rx: &board.truths,
        seen: Vec::new(),
        progress: None,
    };
    // Stop after 4 measured runs: 3 cw and 1 ccw are kept.
    // Measures 4 runs, then the person walks away (stdin closed).
    let mut quits = Person {
        truth: &mut truth,
        said: vec![],
        left: 4,
    };
    assert!(procedure::run(c, &opts, &mut quits).is_err());
    let kept = RunsFile::load(&runs).unwrap();
    assert_eq!(kept.rows.len(), 4);
    // Resume: only the missing 2 ccw before-runs and the 6 after-runs are run.
    let rep = procedure::run(c, &opts, &mut truth).unwrap();
    let all = RunsFile::load(&runs).unwrap();
    assert_eq!(all.rows.len(), 12);
    assert_eq!(
        all.rows.iter().filter(|r| r.phase == Phase::Before).count(),
        6
    );
    assert_eq!(&all.rows[..4], &kept.rows[..4]);
    assert!(matches!(rep, procedure::ProcedureReport::Umbmark(ref u) if u.after.is_some()));
}

#[test]
fn omni_procedure_over_cables_improves_at_least_80_percent() {
    // The guided omni procedure end to end (board, protocol, truth, compute, upload,
    // after runs) on [Redundant omni]'s robot with wheels 1 % to 3 % off their nominal radius, over
    // cables every 30 mm costing 0.8 mm of travel per crossing (world-fixed, across x:
    // 4W-1 crosses them). Ten runs per path before and after, as in [Redundant omni] (Table II: 80 %).
    // Measured: 42.3 mm -> 5.8 mm, 86 % (the same on every run since each trial draws its
    // own floor noise; before, 80-87 % by how long the host paused between runs).
    use wheelcal::calibration::procedure::{Kind, ProcedureReport};
    let r = robot("omni4.toml");
    let effects = [
        sim::Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0008").unwrap(),
        sim::Effect::parse("wheel_diameter_mismatch=radius_scale_w1:1.03,radius_scale_w2:0.99,radius_scale_w3:1.01,radius_scale_w4:0.98").unwrap(),
    ];
    let (mut faults, surface) =
        sim::Faults::from_effects(&r, &effects, sim::Surface::flat()).unwrap();
    faults.travel_noise_m_per_sqrt_m = DEMO_ROUGHNESS;
    let s = sim::SimRobot::new(
        &r,
        faults,
        surface,
        sim::SimConfig {
            seed: 7,
            ..Default::default()
        },
    )
    .unwrap();
    let run = wheelcal::demo::VirtualRun {
        runs: 10,
        length: 0.6,
        report: None,
        after_runs: 10,
        progress: false,
        circles: None,
    };
    let rep = wheelcal::demo::procedure_on_virtual_board(&r, s, Kind::Omni, run).unwrap();
    let ProcedureReport::Omni(o) = rep else {
        panic!("omni expected")
    };
    let imp = o.improvement_index_percent.unwrap();
    eprintln!(
        "omni4 over cables on a virtual board: mean radial error {:.2} mm -> {:.2} mm, improvement {imp:.1} %, F_lat {:?}, F_lon {:.4}",
        o.mean_radial_error_m * 1e3,
        o.mean_radial_error_after_m.unwrap() * 1e3,
        o.f_lat,
        o.f_lon
    );
    assert!(imp >= 80.0, "improvement {imp:.1} %");
}

#[test]
fn omni_second_pass_composes_with_the_first_factors() {
    // The board already runs with a first pass that corrected about half of each wheel's
    // error; the second pass measures with it in force and composes. The final multiplier
    // of every wheel must be 1 / radius_scale (what makes it deliver its nominal travel).
    use calib_core::Corrections;
    use wheelcal::calibration::procedure::{self, Kind, Options, TruthChannel};
    use wheelcal::link::Faults;
    use wheelcal::virtual_board::InProcessBoard;

    let scales = [1.03, 0.99, 1.01, 0.98];
    let r = robot("omni4.toml");
    let effect = format!(
        "wheel_diameter_mismatch=radius_scale_w1:{},radius_scale_w2:{},radius_scale_w3:{},radius_scale_w4:{}",
        scales[0], scales[1], scales[2], scales[3]
    );
    let (faults, surface) = sim::Faults::from_effects(
        &r,
        &[sim::Effect::parse(&effect).unwrap()],
        sim::Surface::flat(),
    )
    .unwrap();
    let s = sim::SimRobot::new(
        &r,
        faults,
        surface,
        sim::SimConfig {
            seed: 5,
            ..Default::default()
        },
    )
    .unwrap();
    let mut board = InProcessBoard::start(&r, s, Faults::none(), Faults::none(), 5).unwrap();
    let c = &mut board.client;
    c.hello().unwrap();
    let first: Vec<f64> = scales.iter().map(|k: &f64| 1.0 / k.sqrt()).collect();
    c.set_corrections(Corrections::Omni {
        f_lat: heapless::Vec::from_slice(&first).unwrap(),
        f_lon: 1.0,
    })
    .unwrap();
    let runs = temp_runs("second-pass");
    let _ = std::fs::remove_file(&runs);
    let _ = std::fs::remove_file(runs.with_extension("csv.previous.json"));
    let opts = Options {
        kind: Kind::Omni,
        side_m: 0.6,
        length_m: 0.6,
        runs: 4,
        after_runs: 0,
        runs_file: runs,
        auto_measure: None,
        report: None,
        after: false,
        second_pass: true,
        idle_wheels: Default::default(),
        circles: None,
    };
    let mut truth = TruthChannel {
        rx: &board.truths,
        seen: Vec::new(),
        progress: None,
    };
    procedure::run(c, &opts, &mut truth).unwrap();
    let Corrections::Omni { f_lat, f_lon } = c.corrections().unwrap() else {
        panic!("omni factors expected")
    };
    for (i, k) in scales.iter().enumerate() {
        let m = f_lon * f_lat[i];
        // 0.2 %: what 4 noise-free runs per path leave (encoder and step quantisation).
        assert!(
            (m * k - 1.0).abs() < 2e-3,
            "wheel {}: multiplier {m:.5}, want {:.5}",
            i + 1,
            1.0 / k
        );
    }
}

#[test]
fn a_run_cut_by_the_link_failsafe_is_run_again_not_recorded() {
    // The console stalls for 1.5 s (suspended, or starved of CPU) while the first square
    // runs: the board's link failsafe (0.5 s) cuts the program. The cut run must not enter
    // the runs file as a measurement (its "end error" is wherever the robot stopped); the
    // procedure says so and runs it again, and ends with exactly the runs asked for, every
    // one a closed 0.5 m square (end error under 10 cm on this robot, against ~0.5 m for
    // a square cut a quarter of the way round).
    use std::time::Duration;
    use wheelcal::calibration::procedure::{self, Kind, Options, TruthChannel};
    use wheelcal::link::Faults;
    use wheelcal::virtual_board::InProcessBoard;

    let r = robot("mobolab.toml");
    let sim = sim::SimRobot::new(
        &r,
        faults(1.003, 1.01),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    // Paced at 4x real time, a 0.5 m square takes ~2.5 s of wall time and the console
    // polls every 50 ms (0.2 s of board time, inside the 0.5 s failsafe): the host's write
    // 30 falls inside the first run, and its 1.5 s stall is 6 s of board time.
    let stall = Faults::stall(30, Duration::from_millis(1500));
    let mut board = InProcessBoard::start_paced(&r, sim, stall, Faults::none(), 3, 4.0).unwrap();
    let c = &mut board.client;
    c.hello().unwrap();
    let runs = temp_runs("link-lost");
    let _ = std::fs::remove_file(&runs);
    let opts = Options {
        kind: Kind::Umbmark,
        side_m: 0.5,
        length_m: 0.5,
        runs: 2,
        after_runs: 0,
        runs_file: runs.clone(),
        auto_measure: None,
        report: None,
        after: false,
        second_pass: false,
        idle_wheels: Default::default(),
        circles: None,
    };
    let mut m = Person {
        truth: &mut TruthChannel {
            rx: &board.truths,
            seen: Vec::new(),
            progress: None,
        },
        said: vec![],
        left: usize::MAX,
    };
    procedure::run(c, &opts, &mut m).unwrap();
    let cut = m.said.iter().filter(|s| s.contains("cut short")).count();
    assert_eq!(cut, 1, "{:#?}", m.said);
    let all = RunsFile::load(&runs).unwrap();
    assert_eq!(all.rows.len(), 4);
    for row in &all.rows {
        let e = row.x_err_m.hypot(row.y_err_m);
        assert!(e < 0.1, "a recorded run ended {e} m off: {row:?}");
    }
}

#[test]
fn a_program_started_after_a_quiet_spell_is_not_cut() {
    // The virtual board flat out judges the host's silence on the wall clock. It used to
    // count only what arrived while a program ran, so a program started after the host
    // had been quiet for over 250 ms (thinking between two runs) began with its silence
    // already spent: unless the first status poll came within ~2 ms (0.5 s of board time
    // flat out), the failsafe cut it. Under load (a loaded 2-core CI machine) that made
    // the guided procedures record cut runs as measurements.
    use std::time::Duration;
    use wheelcal::board;
    use wheelcal::link::Faults;
    use wheelcal::virtual_board::InProcessBoard;
    let r = robot("mobolab.toml");
    let sim = sim::SimRobot::new(
        &r,
        faults(1.0, 1.0),
        sim::Surface::flat(),
        Default::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&r, sim, Faults::none(), Faults::none(), 4).unwrap();
    let c = &mut board.client;
    c.hello().unwrap();
    for _ in 0..2 {
        let limit = board::run_umbmark(
            c,
            calib_core::motion::Direction::Cw,
            1.0,
            10,
            calib_core::protocol::DEFAULT_LINK_TIMEOUT_MS,
        )
        .unwrap();
        // The first poll 100 ms after the start: inside the 250 ms the board counts a
        // host it just heard as alive, but 0.5 s of board time has long passed flat out.
        std::thread::sleep(Duration::from_millis(100));
        let end = board::wait_program(c, limit + Duration::from_secs(60), |_| {}).unwrap();
        assert_eq!(end.stop, calib_core::protocol::StopReason::ProgramDone);
        std::thread::sleep(Duration::from_millis(1000));
    }
}
