//! The application state: the 1 kHz control tick and the request handler.
//!
//! One struct owns everything the tick and the handler share, so the glue only needs one
//! lock around it. The handler validates every request completely before changing
//! anything: a rejected request leaves the state as it was (a test compares the whole
//! state before and after).

use crate::log::TrialLog;
use crate::wheel::WheelState;
use crate::{defaults, EncoderSource, WheelDriver, FIRMWARE_VERSION};
use calib_core::diff_laws::DiffLawOdometry;
use calib_core::kinematics::Kinematics;
use calib_core::motion::{ProgramRunner, Setpoint};
use calib_core::odometry::{Odometry, Pose};
use calib_core::omni_laws::OmniLawOdometry;
use calib_core::protocol::{
    record_size, BootReport, ControlValue, CorrectionFault, Fault, IdleWheels, Info, LogChunk,
    Mode, Params, ParamsFault, ProgramError, ProgramSpec, Record, Rejection, Request, Response,
    Status, StopReason, TrialEnd, MAX_LOG_CHUNK, MIN_LINK_TIMEOUT_MS, PROTOCOL_VERSION,
    SCHEMA_FINGERPRINT,
};
use calib_core::robot::{DriveType, MAX_WHEELS};
use calib_core::{Corrections, Twist};
use heapless::String;

/// Control tick rate.
pub const TICK_HZ: u32 = 1000;
const DT: f32 = 1.0 / TICK_HZ as f32;

/// What the host asked to be written to flash.
#[derive(Debug, Clone, PartialEq)]
pub enum PersistItem {
    /// New active corrections, to be saved.
    Corrections(Corrections),
    /// New active parameters, to be saved.
    Params(Params),
}

/// The handler's verdict: answer now, or persist first and answer with
/// [`App::persisted`] once the (async) flash write is done.
#[derive(Debug)]
pub enum Handled<'a> {
    /// Send this answer now.
    Reply(Response<'a>),
    /// Write this to flash, then answer with [`App::persisted`].
    Persist(PersistItem),
}

/// Ticks per trajectory sample: the program's f64 profile (software floating point on the
/// Cortex-M4F, ~2700 instructions per evaluation) is sampled every 10 ms as the *average*
/// twist over those 10 ms, which the 1 kHz wheel loops then follow. Displacements stay
/// exact (each block commands exactly the profile's distance over it); only the speed
/// profile becomes a 100 Hz staircase, far faster than the robot's mechanics.
pub const TRAJECTORY_DIVIDER: u32 = 10;

/// A trajectory sample and the ticks it still applies to.
#[derive(Debug, Clone, Copy)]
struct Block {
    act: Act,
    ticks_left: u32,
}

/// What one wheel's motor gets this tick.
#[derive(Debug, Clone, Copy)]
enum Output {
    /// Drive off, free to turn (an idle omni wheel).
    Release,
    /// DC wheel: signed duty in [-1, 1], finite.
    Duty(f32),
    /// Stepper wheel: step rate (finite) and this tick's exact steps.
    Steps { rate_hz: f32, steps: i32 },
}

/// What the motion state asks of this tick.
#[derive(Debug, Clone, Copy)]
enum Act {
    Slew(Twist<f32>),
    Set(Twist<f32>),
    Wheel(usize, f32),
    Timeout,
    /// The host-link failsafe: no request within the program's link timeout.
    LinkLost,
    Done,
}

fn reply(r: Response<'_>) -> Result<Handled<'_>, Rejection> {
    Ok(Handled::Reply(r))
}

/// The plain acknowledgement.
fn ok() -> Result<Handled<'static>, Rejection> {
    reply(Response::Ok)
}

#[derive(Debug, Clone)]
enum Motion {
    Idle,
    /// Host-driven twist, stopped when `deadline_us` passes without a new command.
    Drive {
        target: Twist<f32>,
        deadline_us: u64,
    },
    /// The runner, its segment count, and the current trajectory block.
    Program(ProgramRunner, u8, Block),
}

/// Everything the board knows and does, minus the registers. The trial log lives in a
/// buffer the caller provides (`'a`).
pub struct App<'a> {
    /// The running omni program holds its idle wheels at zero speed (else: released).
    hold_idle: bool,
    params: Params,
    corrections: Corrections,
    boot: BootReport,
    kin: Kinematics<f32>,
    /// The corrections' laws of a differential drive (none: twists pass unchanged).
    laws: DiffLawOdometry<f32>,
    /// The corrections' turn law of an omni robot (none: twists pass unchanged).
    omni_laws: OmniLawOdometry<f32>,
    n: usize,
    dc: bool,
    /// None without encoders (open-loop steppers: odometry from the steps emitted).
    rad_per_count: Option<f32>,
    steps_per_rad: f32,
    wheels: [WheelState; MAX_WHEELS],
    odo: Odometry<f32>,
    motion: Motion,
    /// Body twist commanded this tick (slew-limited in drive and stop).
    twist: Twist<f32>,
    estop: bool,
    fault: Option<Fault>,
    stop: StopReason,
    log: TrialLog<'a>,
    decimation: u32,
    ticks: u64,
    trial_start_us: u64,
    boot_us: u64,
    now_us: u64,
    telemetry_us: u64,
    next_telemetry_us: u64,
    /// Result of the last Hello: false makes every other request a mismatch.
    peer_compatible: Option<bool>,
    bad_frames: u32,
    /// When the last valid request arrived (the host-link failsafe's clock).
    last_request_us: u64,
    /// The running program's host-link timeout (0: off).
    link_timeout_us: u64,
    /// Test builds: a NaN forced into one wheel's control path every tick.
    #[cfg(feature = "fault-injection")]
    injected_nan: Option<(usize, ControlValue)>,
}

fn kinematics(params: &Params, c: &Corrections) -> Option<Kinematics<f32>> {
    Kinematics::new(&params.robot, c).ok()
}

impl<'a> App<'a> {
    /// An application with validated `params` and `corrections` (as [`crate::Store::load`]
    /// returns them). Anything inconsistent falls back to the defaults, never panics.
    pub fn new(
        params: Params,
        corrections: Corrections,
        boot: BootReport,
        log_buf: &'a mut [u8],
        now_us: u64,
    ) -> Self {
        // Invalid parameters fall back to the defaults; corrections are kept only if they
        // fit the robot that results, else none.
        let params =
            if params.validate().is_ok() && kinematics(&params, &Corrections::None).is_some() {
                params
            } else {
                defaults::params()
            };
        let (corrections, kin) = match kinematics(&params, &corrections) {
            Some(k) if corrections.validate(&params.robot).is_ok() => (corrections, k),
            _ => {
                // Validated geometry always has nominal kinematics (Robot::new checks the
                // rank; the defaults are tested).
                let k = kinematics(&params, &Corrections::None).expect("validated geometry");
                (Corrections::None, k)
            }
        };
        let laws = DiffLawOdometry::new(&params.robot, &corrections, DT as f64);
        let omni_laws = OmniLawOdometry::new(&params.robot, &corrections, DT as f64);
        let mut app = App {
            wheels: core::array::from_fn(|_| WheelState::new(params.gains, 1.0)),
            params,
            corrections,
            boot,
            kin,
            laws,
            omni_laws,
            n: 0,
            dc: true,
            rad_per_count: None,
            steps_per_rad: 1.0,
            odo: Odometry::default(),
            motion: Motion::Idle,
            twist: Twist::zero(),
            estop: false,
            fault: None,
            stop: StopReason::None,
            hold_idle: false,
            log: TrialLog::new(log_buf),
            decimation: 10,
            ticks: 0,
            trial_start_us: 0,
            boot_us: now_us,
            now_us,
            telemetry_us: 0,
            next_telemetry_us: 0,
            peer_compatible: None,
            bad_frames: 0,
            last_request_us: now_us,
            link_timeout_us: 0,
            #[cfg(feature = "fault-injection")]
            injected_nan: None,
        };
        app.configure();
        app
    }

    /// The laws of the active corrections for the active robot (their smoothing restarts).
    fn configure_laws(&mut self) {
        self.laws = DiffLawOdometry::new(&self.params.robot, &self.corrections, DT as f64);
        self.omni_laws = OmniLawOdometry::new(&self.params.robot, &self.corrections, DT as f64);
    }

    /// Derives the per-wheel state from params (after boot or SetParams).
    fn configure(&mut self) {
        self.configure_laws();
        let p = &self.params;
        self.n = p.robot.wheel_count().min(MAX_WHEELS);
        self.dc = p.robot.drive.kind == DriveType::Dc;
        self.rad_per_count = p.robot.drive.rad_per_count().map(|r| r as f32);
        let spr = p.robot.drive.steps_per_wheel_rad();
        self.steps_per_rad = spr as f32;
        let gains = p.gains;
        // Keep the encoder extenders (they track the hardware); reset the rest.
        for w in self.wheels.iter_mut() {
            w.pi = calib_core::control::PiController::new(gains);
            w.steps = calib_core::stepper::StepAccumulator::new(spr);
            w.halt();
        }
    }

    /// The active parameters.
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The active corrections.
    pub fn corrections(&self) -> &Corrections {
        &self.corrections
    }

    /// The odometry pose (m, m, rad).
    pub fn pose(&self) -> Pose<f32> {
        self.odo.pose()
    }

    /// The trial log.
    pub fn log(&self) -> &TrialLog<'a> {
        &self.log
    }

    /// Commanded wheel rates (rad/s).
    pub fn wheel_cmds(&self) -> impl Iterator<Item = f32> + '_ {
        self.wheels[..self.n].iter().map(|w| w.cmd)
    }

    /// Test builds only (feature `fault-injection`): from the next tick on, forces a NaN
    /// into `wheel`'s control path at `value` (a command or measured rate, or both inputs
    /// of an output), as a bug upstream would; `None` stops it. Proves the boundary check.
    #[cfg(feature = "fault-injection")]
    pub fn inject_nan(&mut self, at: Option<(usize, ControlValue)>) {
        self.injected_nan = at;
    }

    /// The link layer heard the host now, by a clock of its own: for a board whose time
    /// runs faster than the host's (the virtual board flat out), where the host's silence
    /// must be judged on the host's clock. Real boards never need it: every valid request
    /// already counts.
    pub fn host_heard(&mut self) {
        self.last_request_us = self.now_us;
    }

    /// A damaged frame arrived (counted for the status).
    pub fn note_bad_frame(&mut self) {
        self.bad_frames = self.bad_frames.saturating_add(1);
    }

    fn moving(&self) -> bool {
        !matches!(self.motion, Motion::Idle)
            || self.twist != Twist::zero()
            || self.wheels[..self.n].iter().any(|w| w.cmd != 0.0)
    }

    fn uptime_ms(&self) -> u64 {
        self.now_us.saturating_sub(self.boot_us) / 1000
    }

    /// Cuts the motors: E-stop, fault, command timeout.
    fn cut(&mut self, reason: StopReason, end: TrialEnd) {
        self.motion = Motion::Idle;
        self.twist = Twist::zero();
        for w in self.wheels.iter_mut() {
            w.halt();
        }
        self.stop = reason;
        self.log.finish(end);
    }

    // -----------------------------------------------------------------------------------
    // Control tick
    // -----------------------------------------------------------------------------------

    /// One control period: read the encoders, update odometry, run the program or drive
    /// command, drive the wheels, log. Call at [`TICK_HZ`].
    pub fn tick(&mut self, now_us: u64, enc: &mut impl EncoderSource, drv: &mut impl WheelDriver) {
        self.tick_in_app(now_us, enc, drv);
    }

    /// [`App::tick`]'s body, not generic and never inlined, so that it is compiled here
    /// with this crate's optimisation (`s`) even when the firmware binary, where a generic
    /// tick would be instantiated, is built for size (`z`): the tick is the hot path.
    /// The board's counters and outputs are reached through a vtable (a few calls a tick).
    #[inline(never)]
    fn tick_in_app(&mut self, now_us: u64, enc: &mut dyn EncoderSource, drv: &mut dyn WheelDriver) {
        self.now_us = now_us;
        self.ticks = self.ticks.wrapping_add(1);
        let mut dphi = [0f32; MAX_WHEELS];
        self.read_encoders(enc, &mut dphi);
        let wheels = match self.setpoint(now_us) {
            Some(single) => self.drive_wheels(single, drv, &mut dphi),
            None => false,
        };
        if !wheels {
            drv.stop_all();
        }
        // Odometry with the corrected geometry (and its laws: a differential drive's or an
        // omni robot's, the other passing every twist unchanged).
        let (kin, laws) = (&self.kin, &mut self.laws);
        let d = self
            .omni_laws
            .apply(&dphi[..self.n], |p| laws.apply(p, |q| kin.forward(q)));
        self.odo.update(&d);
        self.log_tick(now_us);
    }

    /// Encoders: wrap extension, rates, the jump and stall monitor (a fault cuts the
    /// motion), and each wheel's rotation this tick into `dphi`.
    fn read_encoders(&mut self, enc: &mut dyn EncoderSource, dphi: &mut [f32; MAX_WHEELS]) {
        let width = enc.width();
        let mut fault = None;
        for (i, w) in self.wheels[..self.n].iter_mut().enumerate() {
            let delta = w.read(width, enc.raw(i));
            if let Some(rpc) = self.rad_per_count {
                w.update_rate(rpc, DT);
                // Deltas are at most half the counter range: i32 (cheaper than i64 -> f32).
                dphi[i] = delta as i32 as f32 * rpc;
                if fault.is_none() {
                    fault = w.monitor(i, delta, &self.params.safety);
                }
            }
        }
        if let Some(f) = fault {
            if self.fault.is_none() {
                self.fault = Some(f);
                self.cut(StopReason::Fault, TrialEnd::Fault);
            }
        }
    }

    /// The motion state's setpoint for this tick: the body twist is left in `self.twist`,
    /// and a single-wheel segment's wheel and rate are returned inside. `None`: the motors
    /// are to be cut (E-stop, fault, command timeout, lost host link).
    fn setpoint(&mut self, now_us: u64) -> Option<Option<(usize, f32)>> {
        if self.estop || self.fault.is_some() {
            self.twist = Twist::zero();
            return None;
        }
        let act = match &mut self.motion {
            Motion::Idle => Act::Slew(Twist::zero()),
            Motion::Drive {
                target,
                deadline_us,
            } => {
                if now_us >= *deadline_us {
                    Act::Timeout
                } else {
                    Act::Slew(*target)
                }
            }
            Motion::Program(..)
                if self.link_timeout_us > 0
                    && now_us.saturating_sub(self.last_request_us) > self.link_timeout_us =>
            {
                Act::LinkLost
            }
            Motion::Program(runner, _, block) => {
                if block.ticks_left == 0 {
                    let dt = TRAJECTORY_DIVIDER as f64 / TICK_HZ as f64;
                    block.act = match runner.setpoint(dt) {
                        Some(Setpoint::Body(t)) => {
                            Act::Set(Twist::new(t.vx as f32, t.vy as f32, t.omega as f32))
                        }
                        Some(Setpoint::Wheel { index, rate }) => {
                            Act::Wheel(index as usize, rate as f32)
                        }
                        None => Act::Done,
                    };
                    block.ticks_left = TRAJECTORY_DIVIDER;
                }
                block.ticks_left -= 1;
                block.act
            }
        };
        match act {
            Act::Slew(target) => self.twist = self.slew(self.twist, target),
            Act::Set(t) => self.twist = t,
            Act::Wheel(i, rate) => {
                self.twist = Twist::zero();
                return Some(Some((i, rate)));
            }
            Act::Timeout => {
                self.cut(StopReason::CommandTimeout, TrialEnd::CommandTimeout);
                return None;
            }
            Act::LinkLost => {
                self.cut(StopReason::LinkLost, TrialEnd::LinkLost);
                return None;
            }
            Act::Done => {
                self.motion = Motion::Idle;
                self.twist = Twist::zero();
                self.stop = StopReason::ProgramDone;
                self.log.finish(TrialEnd::Completed);
            }
        }
        Some(None)
    }

    /// Wheel commands and motor outputs: computed for every wheel first, checked, then
    /// written, so a non-finite value reaches no register (see [`Fault::NonFinite`]).
    /// Returns false when nothing was written and the motors are to be cut (a fault).
    /// Open-loop steppers' rotation this tick is the steps emitted, into `dphi`.
    fn drive_wheels(
        &mut self,
        single: Option<(usize, f32)>,
        drv: &mut dyn WheelDriver,
        dphi: &mut [f32; MAX_WHEELS],
    ) -> bool {
        let mut out = [Output::Release; MAX_WHEELS];
        if let Some(f) = self.wheel_outputs(single, &mut out) {
            if self.fault.is_none() {
                self.fault = Some(f);
            }
            self.cut(StopReason::Fault, TrialEnd::Fault);
            return false;
        }
        for (i, o) in out[..self.n].iter().enumerate() {
            match *o {
                Output::Release => drv.release(i),
                Output::Duty(d) => drv.set_duty(i, d),
                Output::Steps { rate_hz, steps } => {
                    drv.set_steps(i, rate_hz, steps);
                    if self.rad_per_count.is_none() {
                        dphi[i] = steps as f32 / self.steps_per_rad;
                    }
                }
            }
        }
        true
    }

    /// The trial log's record for this tick, at the trial's decimated rate.
    fn log_tick(&mut self, now_us: u64) {
        if self.log.recording().is_none() || !self.ticks.is_multiple_of(self.decimation as u64) {
            return;
        }
        let mut rec = Record {
            t_us: now_us.wrapping_sub(self.trial_start_us) as u32,
            pose: self.odo.pose(),
            ..Record::default()
        };
        for (i, w) in self.wheels[..self.n].iter().enumerate() {
            rec.counts[i] = (w.position() - w.origin) as i32;
            rec.cmd[i] = w.cmd;
        }
        self.log.log_record(&rec);
    }

    /// This tick's wheel commands and motor outputs, or the fault of the first output
    /// that is not a finite number (nothing is written then: every wheel stops).
    fn wheel_outputs(
        &mut self,
        single: Option<(usize, f32)>,
        out: &mut [Output; MAX_WHEELS],
    ) -> Option<Fault> {
        let n = self.n;
        let mut cmd = [0f32; MAX_WHEELS];
        match single {
            Some((i, rate)) if i < n => cmd[i] = rate,
            Some(_) => {}
            None => self.kin.inverse_into(&self.twist, &mut cmd[..n]),
        }
        let standing = self.twist == Twist::zero();
        // On an omni robot a wheel the motion does not use is switched off (released:
        // [Redundant omni] turns off the actuators of wheels 1 and 3 on 4W-2), unless the
        // running program asked for the idle wheels held at zero by their velocity loops
        // ([Redundant omni]'s 4W-1: "the other wheels have no angular velocity").
        let held = self.hold_idle && matches!(self.motion, Motion::Program(..));
        let omni = self.params.robot.kind == calib_core::robot::RobotKind::Omni && !held;
        for (i, w) in self.wheels[..n].iter_mut().enumerate() {
            w.cmd = cmd[i];
            #[cfg(feature = "fault-injection")]
            if let Some((wheel, value)) = self.injected_nan {
                if wheel == i {
                    match value {
                        ControlValue::Command => w.cmd = f32::NAN,
                        ControlValue::Rate => w.rate = f32::NAN,
                        // The outputs are the PI's and the step generator's; a NaN in
                        // either input reaches them.
                        ControlValue::Duty | ControlValue::StepRate => {
                            w.cmd = f32::NAN;
                            w.rate = f32::NAN;
                        }
                    }
                }
            }
            let nonfinite = |value| {
                Some(Fault::NonFinite {
                    wheel: i as u8,
                    value,
                })
            };
            if !w.cmd.is_finite() {
                return nonfinite(ControlValue::Command);
            }
            if self.dc && !w.rate.is_finite() {
                return nonfinite(ControlValue::Rate);
            }
            out[i] = if self.dc {
                // (below 1e-4 rad/s: the Jacobian's sin(180 deg) is 1e-16, not 0)
                if w.cmd.abs() < 1e-4 && omni && !standing {
                    w.pi.reset();
                    Output::Release
                } else if w.cmd == 0.0 && standing {
                    // Standing: no integrator creep, no hum.
                    w.pi.reset();
                    Output::Duty(0.0)
                } else {
                    let duty = w.pi.update(w.cmd, w.rate, DT);
                    if !duty.is_finite() {
                        return nonfinite(ControlValue::Duty);
                    }
                    // Finite, and within +-out_max <= 1 (the PI limits it; params are
                    // validated).
                    Output::Duty(duty)
                }
            } else {
                let rate_hz = w.steps.step_rate_hz(w.cmd);
                if !rate_hz.is_finite() {
                    return nonfinite(ControlValue::StepRate);
                }
                Output::Steps {
                    rate_hz,
                    steps: w.steps.advance(w.cmd, DT),
                }
            };
        }
        None
    }

    /// Moves `cur` towards `target` within the acceleration limits.
    fn slew(&self, cur: Twist<f32>, target: Twist<f32>) -> Twist<f32> {
        let l = &self.params.limits;
        let (a, al) = ((l.a_max as f32) * DT, (l.alpha_max as f32) * DT);
        // max/min, not clamp: clamp's panic path pulls core's float formatting (~15 KB).
        let step = |c: f32, t: f32, m: f32| c + (t - c).max(-m).min(m);
        Twist::new(
            step(cur.vx, target.vx, a),
            step(cur.vy, target.vy, a),
            step(cur.omega, target.omega, al),
        )
    }

    // -----------------------------------------------------------------------------------
    // Requests
    // -----------------------------------------------------------------------------------

    /// The live status (what GetStatus and telemetry report).
    pub fn status(&self) -> Status {
        Status {
            uptime_ms: self.uptime_ms(),
            mode: match &self.motion {
                Motion::Idle => Mode::Idle,
                Motion::Drive { .. } => Mode::Drive,
                Motion::Program(r, count, _) => Mode::Program {
                    segment: r.segment_index().min(255) as u8,
                    segments: *count,
                },
            },
            stop: self.stop,
            estop: self.estop,
            fault: self.fault,
            pose: self.odo.pose(),
            wheel_rates: self.wheels[..self.n].iter().map(|w| w.rate).collect(),
            wheel_cmds: self.wheels[..self.n].iter().map(|w| w.cmd).collect(),
            trial: self.log.recording(),
            log_free: self.log.free() as u32,
            dropped_records: self.log.dropped_total(),
            evicted_trials: self.log.evicted_total(),
            bad_frames: self.bad_frames,
        }
    }

    fn info(&self) -> Info {
        Info {
            firmware: firmware(),
            protocol_version: PROTOCOL_VERSION,
            schema: SCHEMA_FINGERPRINT,
            robot_kind: self.params.robot.kind,
            drive: self.params.robot.drive.kind,
            wheel_count: self.n as u8,
            uptime_ms: self.uptime_ms(),
            boot: self.boot,
            log_capacity: self.log.capacity() as u32,
            record_size: record_size(self.n) as u16,
        }
    }

    /// Refuses motion while E-stopped or faulted.
    fn motion_allowed(&self) -> Result<(), Rejection> {
        if self.estop {
            return Err(Rejection::EStopped);
        }
        if let Some(f) = self.fault {
            return Err(Rejection::Faulted(f));
        }
        Ok(())
    }

    /// Decides a request: validates completely, then acts, then answers.
    pub fn handle(&mut self, req: Request, now_us: u64) -> Handled<'_> {
        self.now_us = self.now_us.max(now_us);
        // Any valid request proves the host alive (the console polls while it waits).
        self.last_request_us = self.now_us;
        match self.handle_inner(req) {
            Ok(h) => h,
            Err(r) => Handled::Reply(Response::Rejected(r)),
        }
    }

    /// One request, dispatched to the phase that serves it: the handshake, stored values
    /// (corrections and parameters), motion, telemetry, the trial log.
    fn handle_inner(&mut self, req: Request) -> Result<Handled<'_>, Rejection> {
        if self.peer_compatible == Some(false) && !matches!(req, Request::Hello { .. }) {
            return Err(Rejection::ProtocolMismatch {
                board_version: PROTOCOL_VERSION,
                board_schema: SCHEMA_FINGERPRINT,
            });
        }
        match req {
            Request::Hello {
                protocol_version,
                schema,
            } => reply(self.hello(protocol_version, schema)),
            Request::GetInfo => reply(Response::Info(self.info())),
            Request::GetCorrections => reply(Response::Corrections(self.corrections.clone())),
            Request::SetCorrections(c) => self.set_corrections(c).and_then(|_| ok()),
            Request::SaveCorrections => {
                self.persist(PersistItem::Corrections(self.corrections.clone()))
            }
            Request::ResetCorrections => self.set_corrections(Corrections::None).and_then(|_| ok()),
            Request::GetParams => reply(Response::Params(self.params.clone())),
            Request::SetParams(p) => self.set_params(p).and_then(|_| ok()),
            Request::SaveParams => self.persist(PersistItem::Params(self.params.clone())),
            Request::ResetParams => self.set_params(defaults::params()).and_then(|_| ok()),
            Request::Drive { twist, timeout_ms } => {
                self.drive(twist, timeout_ms).and_then(|_| ok())
            }
            Request::RunProgram {
                program,
                log_rate_hz,
                link_timeout_ms,
            } => self
                .run_program(program, log_rate_hz, link_timeout_ms)
                .and_then(|_| ok()),
            Request::Stop => {
                self.stop_request();
                ok()
            }
            Request::EStop => {
                self.estop = true;
                self.cut(StopReason::EStop, TrialEnd::EStop);
                ok()
            }
            Request::ClearFault => {
                self.clear_fault();
                ok()
            }
            Request::GetStatus => reply(Response::Status(self.status())),
            Request::SetTelemetry { period_ms } => {
                self.set_telemetry(period_ms);
                ok()
            }
            Request::ListTrials => reply(Response::Trials(self.log.list())),
            Request::ReadLog {
                trial,
                offset,
                max_len,
            } => {
                let (data, total) =
                    self.log
                        .read(trial, offset, max_len.min(MAX_LOG_CHUNK as u16))?;
                reply(Response::LogChunk(LogChunk {
                    trial,
                    offset,
                    total,
                    data: calib_core::protocol::Bytes(data),
                }))
            }
            Request::ClearLogs => {
                if self.log.recording().is_some() {
                    return Err(Rejection::Busy);
                }
                self.log.clear();
                ok()
            }
        }
    }

    /// The handshake: the host's protocol version and schema decide whether any other
    /// request is served.
    fn hello(&mut self, protocol_version: u16, schema: u32) -> Response<'static> {
        let ok = protocol_version == PROTOCOL_VERSION && schema == SCHEMA_FINGERPRINT;
        self.peer_compatible = Some(ok);
        Response::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema: SCHEMA_FINGERPRINT,
            firmware: firmware(),
            compatible: ok,
        }
    }

    /// A save to flash, handed to the link layer: a flash erase stalls the CPU, so only
    /// with the motors stopped.
    fn persist(&self, item: PersistItem) -> Result<Handled<'static>, Rejection> {
        if self.moving() {
            return Err(Rejection::Busy);
        }
        Ok(Handled::Persist(item))
    }

    /// A twist command, held until `timeout_ms` (capped by the safety setting).
    fn drive(&mut self, twist: Twist<f32>, timeout_ms: u16) -> Result<(), Rejection> {
        self.motion_allowed()?;
        if matches!(self.motion, Motion::Program(..)) {
            return Err(Rejection::Busy);
        }
        let target = self.checked_twist(twist)?;
        let max = self.params.safety.command_timeout_ms;
        let t = if timeout_ms == 0 {
            max
        } else {
            timeout_ms.min(max)
        };
        self.motion = Motion::Drive {
            target,
            deadline_us: self.now_us + t as u64 * 1000,
        };
        Ok(())
    }

    /// A test path with its log rate and host-link failsafe.
    fn run_program(
        &mut self,
        program: ProgramSpec,
        log_rate_hz: u16,
        link_timeout_ms: u16,
    ) -> Result<(), Rejection> {
        if link_timeout_ms != 0 && link_timeout_ms < MIN_LINK_TIMEOUT_MS {
            return Err(Rejection::InvalidProgram(ProgramError::LinkTimeout {
                ms: link_timeout_ms,
            }));
        }
        self.start_program(program, log_rate_hz)?;
        self.link_timeout_us = link_timeout_ms as u64 * 1000;
        Ok(())
    }

    /// A controlled stop: the idle slew ramps the twist down at the limits.
    fn stop_request(&mut self) {
        if matches!(self.motion, Motion::Program(..)) {
            self.log.finish(TrialEnd::Stopped);
        }
        if !matches!(self.motion, Motion::Idle) {
            self.stop = StopReason::Request;
        }
        self.motion = Motion::Idle;
    }

    /// Unlatches an E-stop or fault; the wheels start from rest.
    fn clear_fault(&mut self) {
        self.estop = false;
        self.fault = None;
        for w in self.wheels.iter_mut() {
            w.halt();
        }
    }

    /// Status pushed every `period_ms` (0 off, at least 10 ms).
    fn set_telemetry(&mut self, period_ms: u16) {
        self.telemetry_us = if period_ms == 0 {
            0
        } else {
            period_ms.max(10) as u64 * 1000
        };
        self.next_telemetry_us = self.now_us;
    }

    fn checked_twist(&self, t: Twist<f32>) -> Result<Twist<f32>, Rejection> {
        let l = &self.params.limits;
        let ok = |v: f32, max: f64| v.is_finite() && (v.abs() as f64) <= max;
        if ok(t.vx, l.v_max) && ok(t.vy, l.v_max) && ok(t.omega, l.omega_max) {
            Ok(t)
        } else {
            Err(Rejection::InvalidProgram(ProgramError::Twist {
                twist: t,
                v_max: l.v_max,
                omega_max: l.omega_max,
            }))
        }
    }

    fn set_corrections(&mut self, c: Corrections) -> Result<(), Rejection> {
        if self.moving() {
            return Err(Rejection::Busy);
        }
        c.validate(&self.params.robot)
            .map_err(|e| Rejection::corrections(&e))?;
        let kin = kinematics(&self.params, &c)
            .ok_or(Rejection::InvalidCorrections(CorrectionFault::Singular))?;
        self.kin = kin;
        self.corrections = c;
        self.configure_laws();
        Ok(())
    }

    fn set_params(&mut self, p: Params) -> Result<(), Rejection> {
        if self.moving() {
            return Err(Rejection::Busy);
        }
        p.validate()
            .map_err(|e| Rejection::InvalidParams(ParamsFault::from(&e)))?;
        if let Err(e) = self.corrections.validate(&p.robot) {
            return Err(Rejection::InvalidParams(ParamsFault::CorrectionsDoNotFit(
                CorrectionFault::from(&e),
            )));
        }
        let kin = kinematics(&p, &self.corrections)
            .ok_or(Rejection::InvalidParams(ParamsFault::Singular))?;
        self.kin = kin;
        self.params = p;
        self.configure();
        Ok(())
    }

    fn start_program(&mut self, spec: ProgramSpec, log_rate_hz: u16) -> Result<(), Rejection> {
        self.motion_allowed()?;
        if self.moving() {
            return Err(Rejection::Busy);
        }
        spec.validate(
            self.n,
            self.params.robot.kind,
            self.params.safety.arena_m as f64,
        )
        .map_err(Rejection::InvalidProgram)?;
        let program = spec.program();
        self.hold_idle = matches!(
            spec,
            ProgramSpec::Omni {
                idle: IdleWheels::Held,
                ..
            }
        );
        // Odometry restarts at the origin: a trial's pose is relative to where it began.
        self.odo = Odometry::default();
        let count = program.segments.len() as u8;
        let block = Block {
            act: Act::Done,
            ticks_left: 0,
        };
        self.motion = Motion::Program(program.runner(self.params.limits), count, block);
        self.stop = StopReason::None;
        if log_rate_hz > 0 {
            self.decimation = (TICK_HZ / (log_rate_hz as u32).min(TICK_HZ)).max(1);
            self.trial_start_us = self.now_us;
            for w in self.wheels.iter_mut() {
                w.origin = w.position();
            }
            self.log.start(
                spec.kind(),
                self.uptime_ms(),
                (TICK_HZ / self.decimation) as u16,
                self.n as u8,
                record_size(self.n) as u16,
                &self.corrections,
            );
        }
        Ok(())
    }

    /// The answer to a [`Handled::Persist`] once the flash write finished.
    pub fn persisted(&mut self, ok: bool) -> Response<'static> {
        if ok {
            Response::Ok
        } else {
            Response::Rejected(Rejection::Storage)
        }
    }

    /// A telemetry status when one is due (call after each tick or byte batch).
    pub fn telemetry_due(&mut self) -> Option<Status> {
        if self.telemetry_us == 0 || self.now_us < self.next_telemetry_us {
            return None;
        }
        self.next_telemetry_us = self.now_us + self.telemetry_us;
        Some(self.status())
    }

    /// A digest of the state a request may change, for tests that check a rejected request
    /// changed nothing (the clock and the damaged-frame counter are left out).
    pub fn snapshot(&self) -> impl PartialEq + core::fmt::Debug {
        let status = Status {
            uptime_ms: 0,
            bad_frames: 0,
            ..self.status()
        };
        (
            self.params.clone(),
            self.corrections.clone(),
            status,
            self.log.list(),
            self.estop,
            self.peer_compatible,
            self.telemetry_us,
            format_motion(&self.motion),
        )
    }
}

fn format_motion(m: &Motion) -> (u8, Twist<f32>, u64, usize) {
    match m {
        Motion::Idle => (0, Twist::zero(), 0, 0),
        Motion::Drive {
            target,
            deadline_us,
        } => (1, *target, *deadline_us, 0),
        Motion::Program(r, _, _) => (2, Twist::zero(), 0, r.segment_index()),
    }
}

fn firmware() -> String<{ calib_core::protocol::FIRMWARE_LEN }> {
    let mut s = String::new();
    for c in FIRMWARE_VERSION.chars() {
        if s.push(c).is_err() {
            break;
        }
    }
    s
}
