//! What the console's process-level tests share: the `wheelcal` binary, the robot files,
//! scratch folders and a `wheelcal sim-board` process on a pseudo-terminal.
#![allow(dead_code)] // each test binary uses its own part

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// The `wheelcal` binary under test.
pub fn wheelcal() -> Command {
    Command::new(env!("CARGO_BIN_EXE_wheelcal"))
}

/// A robot file of `robots/`.
pub fn robot(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"))
}

/// The JSON a `wheelcal --json` run printed, after asserting it succeeded (its stderr
/// shown if not).
pub fn json_of(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// An empty scratch folder for one test.
pub fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wheelcal-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("temp dir");
    d
}

/// A `wheelcal sim-board` process; killed when dropped.
pub struct Board {
    /// The board process.
    pub child: Child,
    /// The link to its pseudo-terminal (`--port`).
    pub link: PathBuf,
}

impl Board {
    /// A board at full speed.
    pub fn start(robot_name: &str, dir: &Path) -> Board {
        Board::start_at(robot_name, dir, "max")
    }

    /// `speed` "1" runs the board in real time, as a robot on the floor: a drive's command
    /// refreshes and Ctrl-C land at the moments they would on a real robot.
    pub fn start_at(robot_name: &str, dir: &Path, speed: &str) -> Board {
        Board::start_with(robot_name, dir, speed, &[])
    }

    /// [`Board::start_at`] with more `sim-board` options (hidden effects, roughness).
    pub fn start_with(robot_name: &str, dir: &Path, speed: &str, extra: &[&str]) -> Board {
        Board::start_file(&robot(robot_name), dir, speed, extra)
    }

    /// [`Board::start_with`] of the robot file `robot_file`: the simulated robot is that
    /// file's, and so is the board's robot until `robot set` gives it another.
    pub fn start_file(robot_file: &Path, dir: &Path, speed: &str, extra: &[&str]) -> Board {
        let link = dir.join("board");
        let child = wheelcal()
            .args(["sim-board", "--speed", speed, "--robot"])
            .arg(robot_file)
            .args(extra)
            .arg("--link")
            .arg(&link)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("sim-board starts");
        let t0 = Instant::now();
        while !link.exists() {
            assert!(t0.elapsed() < Duration::from_secs(20), "no link after 20 s");
            std::thread::sleep(Duration::from_millis(20));
        }
        Board { child, link }
    }

    /// Runs `wheelcal --port LINK args...` with no standard input.
    pub fn run(&self, args: &[&str]) -> Output {
        wheelcal()
            .arg("--port")
            .arg(&self.link)
            .args(args)
            .stdin(Stdio::null())
            .output()
            .expect("wheelcal runs")
    }

    /// [`Board::run`] with stdout and stderr as text.
    pub fn run_text(&self, args: &[&str]) -> (Output, String, String) {
        let o = self.run(args);
        let out = String::from_utf8_lossy(&o.stdout).into_owned();
        let err = String::from_utf8_lossy(&o.stderr).into_owned();
        (o, out, err)
    }

    /// `wheelcal --json status`, parsed.
    pub fn status(&self) -> serde_json::Value {
        let o = self.run(&["--json", "status"]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        serde_json::from_slice(&o.stdout).expect("status JSON")
    }
}

impl Drop for Board {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Waits for `child` to end, failing the test with `what` after `limit`.
pub fn wait_exit(child: &mut Child, limit: Duration, what: &str) -> std::process::ExitStatus {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().expect("try_wait") {
            return s;
        }
        assert!(t0.elapsed() < limit, "{what}");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends `sig` (as `kill` spells it: `-STOP`, `-TERM`) to `child`.
pub fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(ok.success(), "kill {sig}");
}

/// The (x, y) of a `status --json` answer.
pub fn pose_of(status: &serde_json::Value) -> (f64, f64) {
    (
        status["pose"]["x"].as_f64().expect("pose.x"),
        status["pose"]["y"].as_f64().expect("pose.y"),
    )
}

/// A simulated 1 m UMBmark square of `truth` in direction `dir`, 50 rows a second.
pub fn sim_square(
    truth: &calib_core::robot::Robot,
    dir: calib_core::motion::Direction,
    seed: u64,
) -> formats::recording::Recording {
    let mut cfg = sim::RecordConfig {
        row_rate_hz: 50.0,
        ..sim::RecordConfig::default()
    };
    cfg.sim.seed = seed;
    let motion = sim::Motion::Program {
        program: Box::new(calib_core::motion::Program::umbmark_square(1.0, dir)),
        limits: Default::default(),
    };
    sim::record(truth, &[], sim::Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording
}

/// `wheelcal --json calibrate --no-cross-validation` of the mobolab robot on `args`
/// (`--recording ...`) with `extra` options, writing the robot file to `out`.
pub fn calibrate_mobolab(
    args: &[std::ffi::OsString],
    extra: &[&std::ffi::OsStr],
    out: &Path,
) -> Output {
    wheelcal()
        .args(["--json", "calibrate", "--no-cross-validation", "--robot"])
        .arg(robot("mobolab"))
        .args(args)
        .args(extra)
        .arg("--write-robot")
        .arg(out)
        .output()
        .unwrap()
}

/// Four 40 s random drives of `truth` (tyres scrubbing `scrub` on arcs), 50 rows a
/// second, seeds `seed`.., saved as `DIR/runN/recording.csv`; their folders.
pub fn random_runs(
    dir: &Path,
    truth: &calib_core::robot::Robot,
    scrub: f64,
    seed: u64,
) -> Vec<PathBuf> {
    (0..4)
        .map(|i| {
            let mut cfg = sim::RecordConfig {
                row_rate_hz: 50.0,
                ..sim::RecordConfig::default()
            };
            cfg.sim.seed = seed + i;
            cfg.sim.turn_scrub = scrub;
            let motion = sim::Motion::Random(sim::RandomMotion {
                duration_s: 40.0,
                ..sim::RandomMotion::default()
            });
            let r = sim::record(truth, &[], sim::Surface::flat(), &motion, &cfg).unwrap();
            let run = dir.join(format!("run{i}"));
            std::fs::create_dir_all(&run).unwrap();
            r.recording.save(&run.join("recording.csv")).unwrap();
            run
        })
        .collect()
}

/// The omni3 file and a simulated omni3 that differs from it as the `apply` and
/// `evaluate --board-robot` tests need: every wheel 3 % further from the centre, the
/// second mounted 1 degree off.
pub fn omni3_further_out_and_skewed() -> (PathBuf, calib_core::robot::Robot) {
    let nominal_file = robot("omni3");
    let mut truth = formats::robot_file::load(&nominal_file).unwrap();
    truth.wheels.iter_mut().for_each(|w| w.l_m *= 1.03);
    truth.wheels[1].alpha_rad += 1f64.to_radians();
    (nominal_file, truth)
}

/// `calibrate --json --write-board-robot` of `nominal_file` on three 40 s random drives of
/// `truth` with tyres scrubbing `scrub` (seeds `seed`..): its JSON, the JSON's file and
/// the board robot file.
pub fn calibrated(
    dir: &Path,
    nominal_file: &Path,
    truth: &calib_core::robot::Robot,
    scrub: f64,
    seed: u64,
) -> (serde_json::Value, PathBuf, PathBuf) {
    let runs = random_runs(dir, truth, scrub, seed);
    let (cal_json, board_file) = (dir.join("cal.json"), dir.join("board.toml"));
    let mut cal = wheelcal();
    cal.args(["--json", "calibrate", "--no-cross-validation", "--robot"])
        .arg(nominal_file);
    for r in &runs[..3] {
        cal.arg("--recording").arg(r);
    }
    let out = cal
        .arg("--write-board-robot")
        .arg(&board_file)
        .output()
        .unwrap();
    let c = json_of(&out);
    std::fs::write(&cal_json, &out.stdout).unwrap();
    (c, cal_json, board_file)
}

/// The processes with an open descriptor on `device` (read from /proc, independently of
/// the code under test).
pub fn fd_holders(device: &Path) -> Vec<u32> {
    let mut pids = Vec::new();
    for p in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = p.file_name().to_string_lossy().parse::<u32>() else {
            continue;
        };
        let Ok(fds) = std::fs::read_dir(p.path().join("fd")) else {
            continue;
        };
        if fds
            .flatten()
            .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|l| l == device))
        {
            pids.push(pid);
        }
    }
    pids
}

/// Waits until process `pid` holds the board's device (it has opened the port).
pub fn wait_until_held(link: &Path, pid: u32) {
    let device = std::fs::canonicalize(link).unwrap();
    let t0 = Instant::now();
    while !fd_holders(&device).contains(&pid) {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "process {pid} never opened {}",
            device.display()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
}
