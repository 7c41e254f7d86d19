//! Whole runs to recordings: robot + effects + motion + seed -> a docs/formats.md §2
//! [`Recording`] (what a real setup would have logged) with the ground truth kept
//! separately, and a directory writer that puts the robot TOML beside the CSV.
//!
//! Column conventions: `cmd_<wheel>` is the rate commanded for the control tick that
//! starts at `t` (driven wheels only; free wheels have a blank command); `enc_<wheel>` the
//! cumulative count at `t`; `x`, `y`, `theta` a vision sample taken at exactly `t`, on the
//! first row at or after each camera period, blank otherwise.

use crate::actuator::WheelInput;
use crate::effects::Effect;
use crate::error::check_range;
use crate::robot::{SimConfig, SimRobot};
use crate::surface::Surface;
use crate::SimError;
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::motion::{ProfileLimits, Program, Setpoint};
use calib_core::odometry::Pose;
use calib_core::robot::{Robot, RobotKind};
use formats::recording::{Recording, Row};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::Path;

/// A generated trajectory: piecewise targets approached within acceleration limits, with
/// straight runs, arcs, turns on the spot, reversals and pauses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomMotion {
    /// Length of the run (s).
    pub duration_s: f64,
    /// Largest forward speed (m/s).
    pub v_max_m_s: f64,
    /// Largest yaw rate (rad/s).
    pub omega_max_rad_s: f64,
    /// Largest linear acceleration (m/s^2).
    pub a_max_m_s2: f64,
    /// Largest angular acceleration (rad/s^2).
    pub alpha_max_rad_s2: f64,
    /// Shortest and longest time one target is held.
    pub segment_min_s: f64,
    /// Longest time one target is held (s).
    pub segment_max_s: f64,
}

impl Default for RandomMotion {
    fn default() -> Self {
        RandomMotion {
            duration_s: 60.0,
            v_max_m_s: 0.3,
            omega_max_rad_s: 1.0,
            a_max_m_s2: 0.5,
            alpha_max_rad_s2: 2.0,
            segment_min_s: 1.0,
            segment_max_s: 4.0,
        }
    }
}

/// What the robot is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub enum Motion {
    /// A calib-core motion program (UMBmark square, omni path, custom segments).
    Program {
        /// The program.
        program: Box<Program>,
        /// Speed and acceleration limits it runs with.
        limits: ProfileLimits,
    },
    /// A generated trajectory, seeded from the run's seed.
    Random(RandomMotion),
}

/// Leg angles over a run (wheeled-legged robots), rad.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LegMotion {
    /// Constant leg angles.
    Fixed {
        /// Front leg angle (rad).
        front: f64,
        /// Rear leg angle (rad).
        rear: f64,
    },
    /// Linear from `from` to `to` (front, rear) over `duration_s`, then held.
    Sweep {
        /// Start angles (front, rear), rad.
        from: (f64, f64),
        /// End angles (front, rear), rad.
        to: (f64, f64),
        /// Time of the sweep (s).
        duration_s: f64,
    },
    /// Smooth random sweeps within [min, max], a new target every `period_s`.
    Random {
        /// Smallest angle (rad).
        min: f64,
        /// Largest angle (rad).
        max: f64,
        /// Time between targets (s).
        period_s: f64,
    },
}

impl LegMotion {
    fn validate(&self) -> Result<(), SimError> {
        let all = match *self {
            LegMotion::Fixed { front, rear } => vec![front, rear],
            LegMotion::Sweep {
                from,
                to,
                duration_s,
            } => {
                check_range("legs.duration_s", duration_s, 1e-6, 1e9)?;
                vec![from.0, from.1, to.0, to.1]
            }
            LegMotion::Random { min, max, period_s } => {
                check_range("legs.period_s", period_s, 1e-3, 1e9)?;
                if min > max {
                    return Err(SimError::Config {
                        field: "legs.min",
                        message: format!("{min} is above legs.max {max}"),
                    });
                }
                vec![min, max]
            }
        };
        for a in all {
            check_range("legs angle (rad)", a, -10.0, 10.0)?;
        }
        Ok(())
    }
}

/// How the recorded commands reach the wheels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ActuatorMode {
    /// Commands are ideal wheel rates ([`WheelInput::Rate`]): the wheels do what is
    /// commanded except for the catalogue's actuator effects. A fault-free recording then
    /// has encoders that match the commands, which is what diagnose's nominal model
    /// assumes.
    #[default]
    Ideal,
    /// The board's real chain: stepper drives get step pulses from calib-core's step
    /// accumulator ([`WheelInput::Steps`]); DC drives are closed by calib-core's PI loop on
    /// the encoder counters ([`WheelInput::Duty`]), so the motor dynamics show.
    Physical,
}

/// Rates and the simulation settings of a recording.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordConfig {
    /// Sensors, start pose and surface of the run.
    pub sim: SimConfig,
    /// Control tick, s (1 kHz).
    pub dt_s: f64,
    /// Rows per second written (encoders and commands are sampled on every row).
    pub row_rate_hz: f64,
    /// Leg angles over the run (wheeled-legged robots).
    pub legs: LegMotion,
    /// How commands reach the wheels.
    pub actuator: ActuatorMode,
}

impl Default for RecordConfig {
    fn default() -> Self {
        RecordConfig {
            sim: SimConfig::default(),
            dt_s: 1e-3,
            row_rate_hz: 200.0,
            legs: LegMotion::Fixed {
                front: std::f64::consts::FRAC_PI_2,
                rear: std::f64::consts::FRAC_PI_2,
            },
            actuator: ActuatorMode::Ideal,
        }
    }
}

/// One row of the ground truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TruthRow {
    /// Time since start (s).
    pub t: f64,
    /// True pose in the world frame (m, m, rad).
    pub pose: Pose<f64>,
    /// Body twist over the tick before `t`, body frame.
    pub twist: Twist<f64>,
}

/// A simulated recording and what really happened.
#[derive(Debug, Clone, PartialEq)]
pub struct SimRecording {
    /// The nominal robot (what goes beside the CSV).
    pub robot: Robot,
    /// The effects simulated.
    pub effects: Vec<Effect>,
    /// Seed of the random generator (same seed, same recording).
    pub seed: u64,
    /// The recording as a robot would log it.
    pub recording: Recording,
    /// One per recording row.
    pub truth: Vec<TruthRow>,
}

/// Generates twist targets for [`RandomMotion`].
struct RandomTwist {
    m: RandomMotion,
    omni: bool,
    rng: ChaCha8Rng,
    target: Twist<f64>,
    now: Twist<f64>,
    until: f64,
}

impl RandomTwist {
    fn next_target(&mut self) -> Twist<f64> {
        let m = &self.m;
        let r = &mut self.rng;
        let v = m.v_max_m_s;
        let w = m.omega_max_rad_s;
        let mut sym = |a: f64| r.random_range(-a..=a);
        let kind = sym(1.0);
        let t = if kind < -0.8 {
            Twist::zero() // pause
        } else if kind < -0.5 {
            Twist::new(0.0, 0.0, sym(w)) // turn on the spot
        } else if kind < 0.0 {
            Twist::new(sym(v), if self.omni { sym(v) } else { 0.0 }, 0.0) // straight
        } else {
            Twist::new(sym(v), if self.omni { sym(v) * 0.5 } else { 0.0 }, sym(w))
            // arc
        };
        // Reversals: flip the longitudinal direction of the previous target half the time.
        if self.target.vx * t.vx > 0.0 && self.rng.random_bool(0.5) {
            return Twist::new(-t.vx, t.vy, t.omega);
        }
        t
    }

    fn twist(&mut self, t: f64, dt: f64) -> Twist<f64> {
        if t >= self.until {
            self.target = self.next_target();
            self.until = t + self
                .rng
                .random_range(self.m.segment_min_s..=self.m.segment_max_s);
        }
        let step = |now: f64, to: f64, a: f64| now + (to - now).clamp(-a * dt, a * dt);
        self.now = Twist::new(
            step(self.now.vx, self.target.vx, self.m.a_max_m_s2),
            step(self.now.vy, self.target.vy, self.m.a_max_m_s2),
            step(self.now.omega, self.target.omega, self.m.alpha_max_rad_s2),
        );
        self.now
    }
}

/// Leg angles at time t.
fn legs_at(
    l: &LegMotion,
    t: f64,
    state: &mut (f64, f64, f64, f64, f64),
    rng: &mut ChaCha8Rng,
) -> (f64, f64) {
    match *l {
        LegMotion::Fixed { front, rear } => (front, rear),
        LegMotion::Sweep {
            from,
            to,
            duration_s,
        } => {
            let s = (t / duration_s).clamp(0.0, 1.0);
            (from.0 + (to.0 - from.0) * s, from.1 + (to.1 - from.1) * s)
        }
        LegMotion::Random { min, max, period_s } => {
            // state: (from_f, from_r, to_f, to_r, t_start)
            if t >= state.4 + period_s || state.4 < 0.0 {
                let start = if state.4 < 0.0 {
                    (0.5 * (min + max), 0.5 * (min + max))
                } else {
                    (state.2, state.3)
                };
                *state = (
                    start.0,
                    start.1,
                    rng.random_range(min..=max),
                    rng.random_range(min..=max),
                    if state.4 < 0.0 {
                        0.0
                    } else {
                        state.4 + period_s
                    },
                );
            }
            // Smooth (cosine) blend between targets.
            let s = 0.5 - 0.5 * (std::f64::consts::PI * (t - state.4) / period_s).cos();
            (
                state.0 + (state.2 - state.0) * s,
                state.1 + (state.3 - state.1) * s,
            )
        }
    }
}

/// Runs `robot` with `effects` on `surface` through `motion` and records it.
pub fn record(
    robot: &Robot,
    effects: &[Effect],
    surface: Surface,
    motion: &Motion,
    cfg: &RecordConfig,
) -> Result<SimRecording, SimError> {
    check_range("dt_s", cfg.dt_s, 1e-6, 0.1)?;
    check_range("row_rate_hz", cfg.row_rate_hz, 1e-3, 1.0 / cfg.dt_s)?;
    cfg.legs.validate()?;
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.sim.seed ^ 0x005e_ed0f_7ec0_4d11);
    let mut leg_state = (0.0, 0.0, 0.0, 0.0, -1.0);
    let legs0 = legs_at(&cfg.legs, 0.0, &mut leg_state, &mut rng);
    let mut sim_cfg = cfg.sim.clone();
    sim_cfg.leg_front_rad = legs0.0;
    sim_cfg.leg_rear_rad = legs0.1;
    let mut sim = SimRobot::with_effects(robot, effects, surface, sim_cfg)?;
    let kin = Kinematics::<f64>::new(robot, &Corrections::None)
        .map_err(|_| SimError::SingularGeometry)?;
    let n = robot.wheel_count();
    let driven: Vec<bool> = robot.wheels.iter().map(|w| w.driven).collect();

    let (mut runner, duration) = match motion {
        Motion::Program { program, limits } => {
            (Some(program.runner(*limits)), program.duration(limits))
        }
        Motion::Random(m) => {
            check_range("random.duration_s", m.duration_s, 0.0, 1e6)?;
            for (f, v) in [
                ("random.v_max_m_s", m.v_max_m_s),
                ("random.omega_max_rad_s", m.omega_max_rad_s),
                ("random.a_max_m_s2", m.a_max_m_s2),
                ("random.alpha_max_rad_s2", m.alpha_max_rad_s2),
            ] {
                check_range(f, v, 1e-9, 1e3)?;
            }
            check_range("random.segment_min_s", m.segment_min_s, 1e-3, 1e6)?;
            check_range(
                "random.segment_max_s",
                m.segment_max_s,
                m.segment_min_s,
                1e6,
            )?;
            (None, m.duration_s)
        }
    };
    let mut random = match motion {
        Motion::Random(m) => Some(RandomTwist {
            m: *m,
            omni: robot.kind == RobotKind::Omni,
            rng: ChaCha8Rng::seed_from_u64(cfg.sim.seed ^ 0x7a11_ba11),
            target: Twist::zero(),
            now: Twist::zero(),
            until: 0.0,
        }),
        Motion::Program { .. } => None,
    };

    let dt = cfg.dt_s;
    let ticks_per_row = ((1.0 / cfg.row_rate_hz) / dt).round().max(1.0) as u64;
    let rest_ticks = ticks_per_row;
    let vision_period = 1.0 / cfg.sim.vision.rate_hz;
    let mut next_vision = 0.0;
    let mut rec = Recording::new(robot, true, robot.drive.encoder_counts_per_rev > 0.0);
    let mut truth = Vec::new();
    let mut cmd = vec![0.0; n];
    let mut enc = vec![0i64; n];
    let mut inputs = vec![WheelInput::Rate(0.0); n];
    let mut legs = legs0;
    let mut board = PhysicalBoard::new(&sim, robot, cfg.actuator);
    // After the motion, one row period of rest so the last row shows the robot stopped.
    let mut rest = 0;
    let mut row_countdown = 0;
    let mut k: u64 = 0;
    while rest <= rest_ticks {
        let t = k as f64 * dt;
        k += 1;
        // Command for the tick starting at t.
        let sp = match (&mut runner, &mut random) {
            (Some(r), _) => r.setpoint(dt),
            (None, Some(g)) if t < duration => Some(Setpoint::Body(g.twist(t, dt))),
            _ => None,
        };
        match sp {
            Some(Setpoint::Body(tw)) => kin.inverse_into(&tw, &mut cmd),
            Some(Setpoint::Wheel { index, rate }) => {
                cmd.iter_mut().for_each(|c| *c = 0.0);
                if let Some(c) = cmd.get_mut(index as usize) {
                    *c = rate;
                }
            }
            None => {
                cmd.iter_mut().for_each(|c| *c = 0.0);
                rest += 1;
            }
        }
        for i in 0..n {
            if !driven[i] {
                cmd[i] = 0.0;
            }
        }
        let row_due = row_countdown == 0;
        row_countdown = if row_due {
            ticks_per_row - 1
        } else {
            row_countdown - 1
        };
        if row_due {
            for (i, e) in enc.iter_mut().enumerate() {
                *e = sim.encoder_count(i);
            }
            let truth_pose = sim.true_pose();
            let pose = if t >= next_vision - 1e-9 {
                next_vision += vision_period;
                let m = cfg.sim.vision.measure(&truth_pose, &mut rng);
                Some((m.x, m.y, m.theta))
            } else {
                None
            };
            rec.push_row(Row {
                t,
                cmd: Some(&cmd),
                enc: Some(&enc),
                pose,
                legs: Some(legs),
            });
            truth.push(TruthRow {
                t,
                pose: truth_pose,
                twist: sim.true_twist(),
            });
        }
        legs = legs_at(&cfg.legs, t + dt, &mut leg_state, &mut rng);
        board.inputs(&sim, &cmd, dt, &mut inputs);
        sim.step(dt, &inputs)?;
        sim.set_legs(legs.0, legs.1)?;
    }
    // Free wheels are not commanded: blank their command column.
    for (w, d) in rec.wheels.iter_mut().zip(&driven) {
        if !d {
            w.cmd = None;
        }
    }
    Ok(SimRecording {
        robot: robot.clone(),
        effects: effects.to_vec(),
        seed: cfg.sim.seed,
        recording: rec,
        truth,
    })
}

/// The board side of [`ActuatorMode::Physical`].
struct PhysicalBoard {
    mode: ActuatorMode,
    steppers: Vec<calib_core::stepper::StepAccumulator>,
    pi: Vec<calib_core::control::PiController>,
    ext: Vec<calib_core::encoder::CounterExtender>,
    speed: Vec<f64>,
    rad_per_count: f64,
}

impl PhysicalBoard {
    fn new(sim: &SimRobot, robot: &Robot, mode: ActuatorMode) -> Self {
        use calib_core::encoder::{CounterExtender, CounterWidth};
        let n = robot.wheel_count();
        let stepper = robot.drive.kind == calib_core::robot::DriveType::Stepper;
        PhysicalBoard {
            mode,
            steppers: if stepper {
                (0..n)
                    .map(|_| {
                        calib_core::stepper::StepAccumulator::new(robot.drive.steps_per_wheel_rad())
                    })
                    .collect()
            } else {
                Vec::new()
            },
            pi: vec![calib_core::control::PiController::new(sim.pi_gains()); n],
            ext: (0..n)
                .map(|i| CounterExtender::new(CounterWidth::Bits16, sim.encoder_raw(i) as u32))
                .collect(),
            speed: vec![0.0; n],
            rad_per_count: robot.drive.rad_per_count().unwrap_or(0.0),
        }
    }

    fn inputs(&mut self, sim: &SimRobot, cmd: &[f64], dt: f64, out: &mut [WheelInput]) {
        for (i, o) in out.iter_mut().enumerate() {
            *o = match (self.mode, self.steppers.get_mut(i)) {
                (ActuatorMode::Ideal, _) => WheelInput::Rate(cmd[i]),
                (ActuatorMode::Physical, Some(acc)) => {
                    WheelInput::Steps(acc.advance(cmd[i] as f32, dt as f32))
                }
                (ActuatorMode::Physical, None) => {
                    // Encoder speed at 1 kHz is coarse (one count per tick is several
                    // rad/s): the loop sees a 10 ms low-pass of it, as firmware would.
                    let d = self.ext[i].update(sim.encoder_raw(i) as u32) as f64;
                    self.speed[i] += 0.1 * (d * self.rad_per_count / dt - self.speed[i]);
                    let duty = self.pi[i].update(cmd[i] as f32, self.speed[i] as f32, dt as f32);
                    WheelInput::Duty(duty as f64)
                }
            };
        }
    }
}

impl SimRecording {
    /// Writes `recording.csv`, `robot.toml` (the nominal robot), `truth.csv` (t, x, y,
    /// theta, vx, vy, omega) and `effects.txt` (one `--effect` string per line, then the
    /// seed) into `dir`, creating it.
    pub fn write_dir(&self, dir: &Path) -> Result<(), SimError> {
        let io = |path: &Path| {
            let path = path.to_path_buf();
            move |error| SimError::Io { path, error }
        };
        // Only into a new folder or one wheelcal made: never over a real run's files.
        formats::safe_write::claim_dir(dir).map_err(io(dir))?;
        let p = dir.join("recording.csv");
        let mut csv = Vec::new();
        self.recording.write_csv(&mut csv).map_err(io(&p))?;
        formats::safe_write::replace_file(&p, &csv).map_err(io(&p))?;
        let p = dir.join("robot.toml");
        formats::safe_write::replace_file(&p, formats::robot_file::to_toml(&self.robot).as_bytes())
            .map_err(io(&p))?;
        let p = dir.join("truth.csv");
        let mut s = String::from("t,x,y,theta,vx,vy,omega\n");
        for r in &self.truth {
            s.push_str(&format!(
                "{},{},{},{},{},{},{}\n",
                r.t, r.pose.x, r.pose.y, r.pose.theta, r.twist.vx, r.twist.vy, r.twist.omega
            ));
        }
        formats::safe_write::replace_file(&p, s.as_bytes()).map_err(io(&p))?;
        let p = dir.join("effects.txt");
        let mut s: String = self.effects.iter().map(|e| format!("{e}\n")).collect();
        s.push_str(&format!("# seed {}\n", self.seed));
        formats::safe_write::replace_file(&p, s.as_bytes()).map_err(io(&p))?;
        Ok(())
    }
}
