//! The virtual board: the firmware's own application (`firmware-app`: control tick,
//! programs, trial log, safety, request handler, flash store) running against the
//! simulator instead of registers, served over a byte stream (a pseudo-terminal for
//! `wheelcal sim-board`, an in-memory pipe in tests).
//!
//! Time is simulated: the board ticks at 1 kHz of simulated time, paced against the wall
//! clock by `speed` (1 = real time). It also knows the truth: at the end of each trial it
//! records where the simulated robot really is relative to where it started, which
//! `--auto-measure` uses in place of a person with a tape measure.

use crate::flash::RamFlash;
use calib_core::encoder::CounterWidth;
use calib_core::odometry::Pose;
use calib_core::protocol::{BootReport, Mode, Params, Stored};
use calib_core::robot::{DriveType, Robot};
use calib_core::Corrections;
use firmware_app::{
    App, ByteStream, EncoderSource, PersistItem, Server, Store, WheelDriver, TICK_HZ,
};
use serde::{Deserialize, Serialize};
use sim::{SimRobot, WheelInput};
use std::time::{Duration, Instant};

/// Trial-log RAM of the virtual board: room for 100 000 records of a 4-wheel robot.
pub const LOG_BYTES: usize = 5 * 1024 * 1024;
/// Flash pages for the store.
const FLASH_PAGES: usize = 4;
const DT_US: u64 = 1_000_000 / TICK_HZ as u64;

/// The simulated hardware: the robot, and the inputs the application last set.
pub struct SimHardware {
    /// The simulated robot (true pose, encoders, physics).
    pub sim: SimRobot,
    inputs: Vec<WheelInput>,
    stepper: bool,
}

impl SimHardware {
    /// Hardware for `sim` with every motor off (zero duty, or zero steps for steppers).
    pub fn new(sim: SimRobot) -> Self {
        let n = sim.wheel_count();
        let stepper = sim.nominal().drive.kind == DriveType::Stepper;
        let off = if stepper {
            WheelInput::Steps(0)
        } else {
            WheelInput::Duty(0.0)
        };
        SimHardware {
            sim,
            inputs: vec![off; n],
            stepper,
        }
    }

    /// What the application last wrote to each motor (held until its next write).
    pub fn inputs(&self) -> &[WheelInput] {
        &self.inputs
    }

    /// One tick of the application against this hardware, then one tick of physics.
    fn tick(&mut self, app: &mut App<'_>, now_us: u64) {
        app.tick(
            now_us,
            &mut Encoders(&self.sim),
            &mut Motors {
                inputs: &mut self.inputs,
                stepper: self.stepper,
            },
        );
        // The inputs have the robot's wheel count, so stepping cannot fail.
        let _ = self.sim.step(DT_US as f64 * 1e-6, &self.inputs);
    }
}

/// The quadrature counters: the simulator's 16-bit encoder registers.
struct Encoders<'a>(&'a SimRobot);

impl EncoderSource for Encoders<'_> {
    fn width(&self) -> CounterWidth {
        CounterWidth::Bits16
    }
    fn raw(&mut self, wheel: usize) -> u32 {
        self.0.encoder_raw(wheel) as u32
    }
}

/// The motor outputs: H-bridge duty or step counts, held until the next tick.
struct Motors<'a> {
    inputs: &'a mut Vec<WheelInput>,
    stepper: bool,
}

impl WheelDriver for Motors<'_> {
    fn set_duty(&mut self, wheel: usize, duty: f32) {
        if let Some(i) = self.inputs.get_mut(wheel) {
            *i = WheelInput::Duty(duty as f64);
        }
    }
    fn set_steps(&mut self, wheel: usize, _steps_per_s: f32, steps: i32) {
        if let Some(i) = self.inputs.get_mut(wheel) {
            *i = WheelInput::Steps(steps);
        }
    }
    fn stop_all(&mut self) {
        let off = if self.stepper {
            WheelInput::Steps(0)
        } else {
            WheelInput::Duty(0.0)
        };
        self.inputs.iter_mut().for_each(|i| *i = off);
    }
    /// Motor off: the simulated wheel rolls with the ground.
    fn release(&mut self, wheel: usize) {
        if let Some(i) = self.inputs.get_mut(wheel) {
            *i = WheelInput::Free;
        }
    }
}

/// Where a trial really ended, relative to its start, against the board's odometry.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TrialTruth {
    /// The trial's id, as in the board's trial log.
    pub trial: u16,
    /// True end x in the start frame (along the start heading), m.
    pub true_x_m: f64,
    /// True end y in the start frame (left of the start heading), m.
    pub true_y_m: f64,
    /// True heading change, rad.
    pub true_theta_rad: f64,
    /// The board's odometry x at the end, same frame, m.
    pub odo_x_m: f64,
    /// The board's odometry y at the end, m.
    pub odo_y_m: f64,
    /// The board's odometry heading change, rad.
    pub odo_theta_rad: f64,
    /// x error, true minus odometry (docs/formats.md §3: measured minus odometry), m.
    pub x_err_m: f64,
    /// y error (true minus odometry), m.
    pub y_err_m: f64,
    /// Heading error (true minus odometry), rad.
    pub theta_err_rad: f64,
}

/// The board: application, server, store and simulated hardware.
pub struct VirtualBoard {
    /// The firmware application, as on the real board.
    pub app: App<'static>,
    server: Server,
    store: Store<RamFlash>,
    /// The simulated hardware the application drives.
    pub hw: SimHardware,
    now_us: u64,
    running_trial: Option<(u16, Pose<f64>)>,
    truths: Vec<TrialTruth>,
}

/// Something went wrong setting the board up.
#[derive(Debug)]
pub enum BoardError {
    /// The flash image file could not be read or made (the message names the file).
    FlashFile(String),
    /// The store on the flash could not be opened.
    Store(firmware_app::StoreError),
}

impl std::fmt::Display for BoardError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            BoardError::FlashFile(m) => f.write_str(m),
            BoardError::Store(e) => write!(f, "flash store: {e:?}"),
        }
    }
}
impl std::error::Error for BoardError {}

impl VirtualBoard {
    /// Boots a board for `robot` simulated by `sim`, with `flash` as its persistent store.
    /// A fresh flash boots with the robot file's geometry (as if it had been configured
    /// and saved once); stored values win over it, as on a real board.
    ///
    /// A flash image of the wrong size (`RamFlash::damaged`) is no flash of this board:
    /// what it holds is never loaded, even an item that reads whole, and boot reports it
    /// `corrupted` (nominal values in use).
    pub fn boot(robot: &Robot, sim: SimRobot, flash: RamFlash) -> Result<Self, BoardError> {
        let range = 0..flash.len() as u32;
        let wrong_size = flash.damaged().is_some();
        let mut store = Store::new(flash, range).map_err(BoardError::Store)?;
        let mut loaded = embassy_futures::block_on(store.load());
        if wrong_size {
            let not_loaded = |s: Stored| {
                if s == Stored::Loaded {
                    Stored::Invalid
                } else {
                    s
                }
            };
            loaded.boot = BootReport {
                params: not_loaded(loaded.boot.params),
                corrections: not_loaded(loaded.boot.corrections),
            };
            loaded.corrections = Corrections::None;
        }
        let mut params = loaded.params.clone();
        let mut boot = loaded.boot;
        if loaded.boot.params != Stored::Loaded {
            params = board_params(robot);
            boot = BootReport {
                params: loaded.boot.params,
                ..boot
            };
        }
        let corrections = loaded.corrections.clone();
        let app = new_app(params, corrections, boot);
        Ok(VirtualBoard {
            app,
            server: Server::new(),
            store,
            hw: SimHardware::new(sim),
            now_us: 0,
            running_trial: None,
            truths: Vec::new(),
        })
    }

    /// Simulated time, microseconds.
    pub fn now_us(&self) -> u64 {
        self.now_us
    }

    /// True when a motion program is under way (the pacing loop may run it flat out).
    pub fn busy(&self) -> bool {
        !matches!(self.app.status().mode, Mode::Idle)
    }

    /// Serves whatever the stream has, then runs one control tick.
    pub fn step<S: ByteStream>(&mut self, stream: &mut S) {
        self.serve_bytes(stream);
        if let Some(frame) = self.server.telemetry(&mut self.app) {
            stream.write(frame);
        }
        let before = self.app.status().trial;
        self.hw.tick(&mut self.app, self.now_us);
        self.now_us += DT_US;
        self.track_truth(before);
    }

    /// Answers the requests waiting in `stream` (saving to flash when asked).
    fn serve_bytes<S: ByteStream>(&mut self, stream: &mut S) {
        let store = &mut self.store;
        self.server
            .poll(&mut self.app, stream, self.now_us, |item: &PersistItem| {
                embassy_futures::block_on(store.save(item)).is_ok()
            });
    }

    fn track_truth(&mut self, before: Option<u16>) {
        let status = self.app.status();
        let idle = matches!(status.mode, Mode::Idle);
        match (self.running_trial, status.trial) {
            (None, Some(id)) if before != Some(id) || !idle => {
                // Odometry restarts at zero when a program starts: remember the true start.
                // Each trial draws its own floor noise: the idle board steps in real time,
                // and a coasting wheel's tail would otherwise move every later trial's
                // realisation by however long the host paused.
                self.hw.sim.reseed_travel_noise(u64::from(id));
                self.running_trial = Some((id, self.hw.sim.true_pose()));
            }
            (Some((id, start)), _) if idle => {
                let end = self.hw.sim.true_pose();
                let (s, c) = start.theta.sin_cos();
                let (dx, dy) = (end.x - start.x, end.y - start.y);
                let odo = self.app.pose();
                let t = TrialTruth {
                    trial: id,
                    true_x_m: c * dx + s * dy,
                    true_y_m: -s * dx + c * dy,
                    true_theta_rad: end.theta - start.theta,
                    odo_x_m: odo.x as f64,
                    odo_y_m: odo.y as f64,
                    odo_theta_rad: odo.theta as f64,
                    x_err_m: 0.0,
                    y_err_m: 0.0,
                    theta_err_rad: 0.0,
                };
                let t = TrialTruth {
                    x_err_m: t.true_x_m - t.odo_x_m,
                    y_err_m: t.true_y_m - t.odo_y_m,
                    theta_err_rad: t.true_theta_rad - t.odo_theta_rad,
                    ..t
                };
                self.truths.push(t);
                self.running_trial = None;
            }
            _ => {}
        }
    }

    /// Truth of the trials that ended so far.
    pub fn truths(&self) -> &[TrialTruth] {
        &self.truths
    }

    /// Serves `stream` until `stop` returns true, pacing simulated time at `speed` times
    /// real time (`f64::INFINITY`: as fast as possible while a program runs, real time
    /// while idle). `on_truth` is called for each trial that ends.
    pub fn serve<S: ByteStream>(
        &mut self,
        stream: &mut S,
        speed: f64,
        mut stop: impl FnMut() -> bool,
        mut on_truth: impl FnMut(&TrialTruth),
    ) {
        let start = Instant::now();
        let mut sim_us_at_start = self.now_us;
        let mut wall_ref = start;
        let mut reported = self.truths.len();
        let mut host_heard = Instant::now();
        while !stop() {
            let flat_out = speed.is_infinite() && self.busy();
            // Every byte from the host counts, busy or idle: a program started after a
            // quiet spell (the host thinking between runs) must not begin with its silence
            // already counted against the failsafe.
            let mut listening = Listening {
                inner: &mut *stream,
                heard: false,
            };
            if flat_out {
                for _ in 0..200 {
                    self.step(&mut listening);
                }
                if listening.heard {
                    host_heard = Instant::now();
                }
                // Flat out, simulated time runs far ahead of the host's clock: 0.5 s of
                // board time passes between two of its 50 ms status polls. The host-link
                // failsafe then judges the host's silence on the host's (wall) clock.
                if host_heard.elapsed() < HOST_ALIVE_WALL {
                    self.app.host_heard();
                }
                wall_ref = Instant::now();
                sim_us_at_start = self.now_us;
            } else {
                let pace = if speed.is_finite() { speed } else { 1.0 };
                let due_us =
                    sim_us_at_start + (wall_ref.elapsed().as_secs_f64() * pace * 1e6) as u64;
                let mut n = 0;
                while self.now_us < due_us && n < 5000 {
                    self.step(&mut listening);
                    n += 1;
                }
                if n == 0 {
                    // Still answer requests promptly while waiting for the next tick.
                    self.serve_bytes(&mut listening);
                    std::thread::sleep(Duration::from_micros(300));
                }
                if listening.heard {
                    host_heard = Instant::now();
                }
            }
            while reported < self.truths.len() {
                on_truth(&self.truths[reported]);
                reported += 1;
            }
        }
    }
}

/// While running flat out, a host heard within this much wall time is alive for the
/// host-link failsafe (the console polls every 50 ms while a program runs).
const HOST_ALIVE_WALL: Duration = Duration::from_millis(250);

/// A byte stream that notes whether anything arrived.
struct Listening<'a, S: ByteStream> {
    inner: &'a mut S,
    heard: bool,
}

impl<S: ByteStream> ByteStream for Listening<'_, S> {
    fn read(&mut self, buf: &mut [u8]) -> usize {
        let n = self.inner.read(buf);
        self.heard |= n > 0;
        n
    }
    fn write(&mut self, data: &[u8]) {
        self.inner.write(data)
    }
}

/// An application with its own trial-log RAM. The buffer is leaked on purpose: the
/// application borrows it for `'static` as the firmware borrows its static CCM array, and
/// a virtual board lives as long as its process (tests leak a few boards' worth).
fn new_app(params: Params, corrections: Corrections, boot: BootReport) -> App<'static> {
    let log: &'static mut [u8] = Box::leak(vec![0u8; LOG_BYTES].into_boxed_slice());
    App::new(params, corrections, boot, log, 0)
}

/// The board's parameters for a robot file: firmware defaults with this geometry.
pub fn board_params(robot: &Robot) -> Params {
    let mut p = firmware_app::defaults::params();
    p.robot = robot.clone();
    p
}

/// A RAM flash for a board (or mirrored to `file`).
pub fn board_flash(file: Option<std::path::PathBuf>) -> Result<RamFlash, String> {
    match file {
        Some(f) => RamFlash::with_file(FLASH_PAGES, f),
        None => Ok(RamFlash::new(FLASH_PAGES)),
    }
}

/// A virtual board serving an in-memory link on its own thread, with a client on the
/// other end: what the demo, the benches and the end-to-end tests run. Dropping it stops
/// the board.
pub struct InProcessBoard {
    /// The host's client on the link's host end.
    pub client: crate::client::Client<crate::link::MemoryEnd>,
    /// The truth of each trial as it ends.
    pub truths: std::sync::mpsc::Receiver<TrialTruth>,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl InProcessBoard {
    /// Boots a board for `robot` on `sim` (fresh flash) and connects a client through a
    /// link with the given faults per direction; not yet handshaken.
    pub fn start(
        robot: &Robot,
        sim: SimRobot,
        to_board: crate::link::Faults,
        to_host: crate::link::Faults,
        seed: u64,
    ) -> Result<Self, BoardError> {
        Self::start_paced(robot, sim, to_board, to_host, seed, f64::INFINITY)
    }

    /// As [`Self::start`], with simulated time paced at `speed` times real time (tests
    /// that must catch a program while it runs).
    pub fn start_paced(
        robot: &Robot,
        sim: SimRobot,
        to_board: crate::link::Faults,
        to_host: crate::link::Faults,
        seed: u64,
        speed: f64,
    ) -> Result<Self, BoardError> {
        use std::sync::atomic::Ordering;
        let flash = board_flash(None).map_err(BoardError::FlashFile)?;
        let mut board = VirtualBoard::boot(robot, sim, flash)?;
        let (host, mut end) = crate::link::memory_pair(to_board, to_host, seed);
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let (tx, truths) = std::sync::mpsc::channel();
        let s2 = stop.clone();
        let thread = std::thread::spawn(move || {
            board.serve(
                &mut end,
                speed,
                || s2.load(Ordering::Relaxed),
                |t| {
                    let _ = tx.send(*t);
                },
            )
        });
        Ok(InProcessBoard {
            client: crate::client::Client::new(host, "virtual board"),
            truths,
            stop,
            thread: Some(thread),
        })
    }
}

impl Drop for InProcessBoard {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}
