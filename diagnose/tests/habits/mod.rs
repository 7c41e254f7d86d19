//! The habits generator (issue 55's own judge): recordings as other people make them,
//! with other robots, rates, noise, driving habits and loggers, and physics none of the
//! other generators has. Its own code: not the `sim` crate, not diagnose's models, not the
//! blind or independent generators (it shares only the rigid-body arithmetic of
//! `rigid/mod.rs`). 1 kHz Euler integration; a formats.md CSV written and read back with
//! the project's parser, so diagnose sees exactly what a user's file would give it.
//!
//! - **Driving habits.** `Joystick`: forward (and on omni robots sideways) speed and yaw
//!   rate as sums of two slow sines with random periods and phases, through zero so the
//!   robot reverses, stopped for a second every 8-14 s, steered home when over 0.8 m out.
//!   `Legs`: straight legs of 0.3-1.0 m (forward or backward, on omni robots in any
//!   direction), trapezoidal speed, a stop, a turn in place of 60-180 degrees either way.
//! - **Actuators, per wheel**, a chain between the held command and the motor shaft:
//!   transport delay, a dead band that may differ by direction (the motor stays still until
//!   the command leaves it, then follows it), a second-order response (natural frequency,
//!   damping), a first-order lag, an acceleration limit (a weak motor); then gear play
//!   between the motor (whose shaft carries the encoder) and the wheel.
//! - **Geometry**: each wheel's rolling radius and distance from the centre scaled.
//! - **Sensing**: poses at their own rate with white noise, AR(1) noise, a random-walk
//!   drift of the motion-capture frame (position and heading), quantisation, a latency.
//! - **Logger faults**: an encoder scale on one wheel, a sign-flipped encoder, swapped
//!   encoder columns, stale rows (the encoders or the pose repeat the previous row's
//!   values), dropped rows, jittered timestamps and timestamps that go back, a permanent
//!   jump of the pose frame (a relocalisation).
#![allow(dead_code, clippy::needless_range_loop)]

use calib_core::robot::{Robot, RobotKind};
use formats::recording::Recording;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::collections::VecDeque;
use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;
use std::path::Path;

#[path = "../rigid/mod.rs"]
mod rigid;
use rigid::{contact, twist_from, wrap, WheelGeo};

/// How the person drives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Style {
    Joystick,
    Legs,
}

/// One stage of a wheel's actuator chain (applied in the order listed in the module doc).
#[derive(Debug, Clone, PartialEq)]
pub enum Act {
    /// The motor sees the command this many seconds late.
    Delay(f64),
    /// The motor stays still while the command is inside (-back, fwd) rad/s.
    DeadBand { fwd: f64, back: f64 },
    /// Second-order response: natural frequency (rad/s) and damping ratio.
    SecondOrder { wn: f64, zeta: f64 },
    /// First-order lag with this time constant (s).
    Lag(f64),
    /// The motor's angular acceleration is at most this (rad/s^2).
    Slew(f64),
}

/// A wheel's physics.
#[derive(Debug, Clone, PartialEq)]
pub struct Wheel {
    pub chain: Vec<Act>,
    /// Total gear play between the motor and the wheel (rad).
    pub play_rad: f64,
    /// True rolling radius over nominal.
    pub radius_scale: f64,
    /// True distance from the centre over nominal.
    pub l_scale: f64,
}

impl Default for Wheel {
    fn default() -> Self {
        Wheel {
            chain: vec![],
            play_rad: 0.0,
            radius_scale: 1.0,
            l_scale: 1.0,
        }
    }
}

/// A logger fault.
#[derive(Debug, Clone, PartialEq)]
pub enum Fault {
    /// One wheel's logged counts are this times the true counts.
    EncoderScale { wheel: usize, k: f64 },
    /// One wheel's logged counts have the wrong sign.
    SignFlip { wheel: usize },
    /// Two wheels' encoder columns are swapped.
    Swap { a: usize, b: usize },
    /// This share of rows repeat the previous row's encoder values.
    StaleEncoders { p: f64 },
    /// This share of pose samples repeat the previous pose sample.
    StalePoses { p: f64 },
    /// This share of rows are not written.
    DroppedRows { p: f64 },
    /// Written times jitter by this standard deviation (s), and `back` times the written
    /// time goes back by `back_s` against the previous row.
    Clock {
        jitter_s: f64,
        back: usize,
        back_s: f64,
    },
    /// From this fraction of the run on, the pose frame is displaced (x, y, theta).
    PoseJump { at: f64, dx: f64, dy: f64, dth: f64 },
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct Gen {
    pub robot: Robot,
    pub seed: u64,
    pub style: Style,
    pub duration_s: f64,
    pub row_hz: f64,
    pub pose_hz: f64,
    pub sigma_m: f64,
    pub sigma_rad: f64,
    /// AR(1) coefficient per pose sample.
    pub rho: f64,
    /// Random-walk drift of the motion-capture frame, per square root of a second.
    pub drift_m: f64,
    pub drift_rad: f64,
    /// Pose quantisation steps (0: none).
    pub quant_m: f64,
    pub quant_rad: f64,
    /// Poses are the truth this many seconds earlier (a latency).
    pub latency_s: f64,
    pub v_max: f64,
    pub w_max: f64,
    pub a_max: f64,
    pub wheels: Vec<Wheel>,
    pub faults: Vec<Fault>,
}

impl Gen {
    pub fn new(robot: Robot, seed: u64, style: Style) -> Self {
        let n = robot.wheels.len();
        Gen {
            robot,
            seed,
            style,
            duration_s: 60.0,
            row_hz: 100.0,
            pose_hz: 50.0,
            sigma_m: 0.001,
            sigma_rad: 0.002,
            rho: 0.0,
            drift_m: 0.0,
            drift_rad: 0.0,
            quant_m: 0.0,
            quant_rad: 0.0,
            latency_s: 0.0,
            v_max: 0.3,
            w_max: 1.2,
            a_max: 0.8,
            wheels: vec![Wheel::default(); n],
            faults: vec![],
        }
    }
}

/// What happened (to check each case does what it says, and how large its signal is).
#[derive(Debug, Default, Clone)]
pub struct Stats {
    pub rows: usize,
    pub pose_samples: usize,
    pub reversals: usize,
    pub distance_m: f64,
    pub turn_rad: f64,
    /// Per wheel: RMS of the motor rate's gap to the command (rad/s).
    pub motor_gap_rms: Vec<f64>,
    /// Per wheel: travel the play took (rad of motor turning that did not turn the wheel).
    pub play_taken_rad: Vec<f64>,
    /// Dead reckoning from the true motor angles with the nominal geometry against the
    /// true pose: RMS position (m) and heading (rad).
    pub dr_rms_m: f64,
    pub dr_rms_rad: f64,
    /// Rows whose encoders or pose were stale, rows dropped, times that went back.
    pub stale_rows: usize,
    pub dropped_rows: usize,
    pub times_back: usize,
}

fn geometry(robot: &Robot, wheels: &[Wheel], truth: bool) -> Vec<WheelGeo> {
    robot
        .wheels
        .iter()
        .zip(wheels)
        .map(|(w, p)| {
            let (rs, ls) = if truth {
                (p.radius_scale, p.l_scale)
            } else {
                (1.0, 1.0)
            };
            let a = w.alpha_rad;
            let l = w.l_m * ls;
            let dir = a + w.beta_rad + w.gamma_rad;
            WheelGeo {
                p: (l * a.cos(), l * a.sin()),
                u: (dir.sin(), -dir.cos()),
                r: w.radius_m * rs * w.gamma_rad.cos(),
            }
        })
        .collect()
}

/// The body twist the person asks for at time t.
struct Driver {
    style: Style,
    omni: bool,
    v_max: f64,
    w_max: f64,
    a_max: f64,
    // Joystick: periods and phases of two sines per axis; next stop.
    per: [[f64; 4]; 3],
    next_stop: f64,
    stop_until: f64,
    // Legs: the current manoeuvre and its progress.
    leg: Option<(f64, f64, f64, f64)>, // (vx dir, vy dir, yaw dir, remaining distance or angle)
    pause: f64,
    cmd: (f64, f64, f64),
}

impl Driver {
    fn new(g: &Gen, omni: bool, rng: &mut ChaCha8Rng) -> Self {
        let mut per = [[0.0; 4]; 3];
        for axis in per.iter_mut() {
            *axis = [
                rng.random_range(3.0..7.0),
                rng.random_range(0.0..TAU),
                rng.random_range(9.0..17.0),
                rng.random_range(0.0..TAU),
            ];
        }
        Driver {
            style: g.style,
            omni,
            v_max: g.v_max,
            w_max: g.w_max,
            a_max: g.a_max,
            per,
            next_stop: rng.random_range(8.0..14.0),
            stop_until: 0.0,
            leg: None,
            pause: 0.5,
            cmd: (0.0, 0.0, 0.0),
        }
    }

    /// The next held command (dt = the row interval), given the true pose.
    fn step(&mut self, t: f64, dt: f64, pose: (f64, f64, f64), rng: &mut ChaCha8Rng) {
        let (x, y, th) = pose;
        let d = (x * x + y * y).sqrt();
        // Home direction in the body frame.
        let (hx, hy) = (-x * th.cos() - y * th.sin(), x * th.sin() - y * th.cos());
        let target = match self.style {
            Style::Joystick => {
                if t >= self.next_stop {
                    self.stop_until = t + 1.0;
                    self.next_stop = t + rng.random_range(8.0..14.0);
                }
                if t < self.stop_until {
                    (0.0, 0.0, 0.0)
                } else {
                    let s = |a: &[f64; 4]| {
                        0.6 * (TAU * t / a[0] + a[1]).sin() + 0.4 * (TAU * t / a[2] + a[3]).sin()
                    };
                    let mut v = self.v_max * s(&self.per[0]);
                    let mut vy = if self.omni {
                        self.v_max * s(&self.per[1])
                    } else {
                        0.0
                    };
                    let mut w = self.w_max * s(&self.per[2]);
                    if d > 0.8 {
                        // Steer home: drive along the home direction (either way on a
                        // diff drive) and turn towards it.
                        v = 0.7 * self.v_max * hx / d;
                        if self.omni {
                            vy = 0.7 * self.v_max * hy / d;
                        } else {
                            let ang = if hx >= 0.0 {
                                hy.atan2(hx)
                            } else {
                                (-hy).atan2(-hx)
                            };
                            w = (2.0 * ang).clamp(-self.w_max, self.w_max);
                        }
                    }
                    (v, vy, w)
                }
            }
            Style::Legs => {
                if self.pause > 0.0 {
                    self.pause -= dt;
                    (0.0, 0.0, 0.0)
                } else {
                    if self.leg.is_none() {
                        // Alternate: a turn in place, then a leg.
                        let turn = rng.random_bool(0.4);
                        self.leg = Some(if turn {
                            let a = rng.random_range(PI / 3.0..PI);
                            (0.0, 0.0, if rng.random_bool(0.5) { 1.0 } else { -1.0 }, a)
                        } else {
                            let len = rng.random_range(0.3..1.0);
                            let (mut ux, mut uy) = if self.omni {
                                let a = rng.random_range(0.0..TAU);
                                (a.cos(), a.sin())
                            } else {
                                (if rng.random_bool(0.5) { 1.0 } else { -1.0 }, 0.0)
                            };
                            if d > 0.6 {
                                // Head home.
                                if self.omni {
                                    (ux, uy) = (hx / d, hy / d);
                                } else {
                                    ux = hx.signum();
                                }
                            }
                            (ux, uy, 0.0, len)
                        });
                    }
                    let (ux, uy, uw, left) = self.leg.unwrap();
                    // Trapezoid: the speed the remaining distance allows.
                    let (top, acc) = if uw != 0.0 {
                        (self.w_max, 3.0 * self.a_max)
                    } else {
                        (self.v_max, self.a_max)
                    };
                    let cur = if uw != 0.0 {
                        self.cmd.2.abs()
                    } else {
                        (self.cmd.0.powi(2) + self.cmd.1.powi(2)).sqrt()
                    };
                    let s = top.min((2.0 * acc * left.max(0.0)).sqrt());
                    let left = left - cur * dt;
                    if left <= 0.0 || (s < 1e-3 && cur < 1e-3) {
                        self.leg = None;
                        self.pause = rng.random_range(0.3..1.0);
                        (0.0, 0.0, 0.0)
                    } else {
                        self.leg = Some((ux, uy, uw, left));
                        (ux * s, uy * s, uw * s)
                    }
                }
            }
        };
        let step = |c: f64, tg: f64, lim: f64| c + (tg - c).clamp(-lim, lim);
        self.cmd = (
            step(self.cmd.0, target.0, self.a_max * dt),
            step(self.cmd.1, target.1, self.a_max * dt),
            step(self.cmd.2, target.2, 3.0 * self.a_max * dt),
        );
    }
}

/// A wheel's actuator state.
#[derive(Default, Clone)]
struct Motor {
    delayed: VecDeque<f64>,
    rate2: f64,
    acc2: f64,
    lagged: Option<f64>,
    rate: f64,
    angle: f64,
    wheel_angle: f64,
}

impl Motor {
    /// Advances by dt under held command `cmd` (rad/s); returns the motor rate.
    fn step(&mut self, chain: &[Act], cmd: f64, dt: f64) -> f64 {
        let mut u = cmd;
        for a in chain {
            u = match *a {
                Act::Delay(s) => {
                    let n = (s / dt).round() as usize;
                    self.delayed.push_back(u);
                    if self.delayed.len() > n {
                        self.delayed.pop_front().unwrap()
                    } else {
                        0.0
                    }
                }
                Act::DeadBand { fwd, back } => {
                    if u > -back && u < fwd {
                        0.0
                    } else {
                        u
                    }
                }
                Act::SecondOrder { wn, zeta } => {
                    self.acc2 += (wn * wn * (u - self.rate2) - 2.0 * zeta * wn * self.acc2) * dt;
                    self.rate2 += self.acc2 * dt;
                    self.rate2
                }
                Act::Lag(tau) => {
                    let l = self.lagged.unwrap_or(0.0);
                    let l = l + (u - l) * (dt / tau).min(1.0);
                    self.lagged = Some(l);
                    l
                }
                Act::Slew(amax) => self.rate + (u - self.rate).clamp(-amax * dt, amax * dt),
            };
        }
        self.rate = u;
        self.angle += u * dt;
        u
    }

    /// The wheel follows the motor through `play` of gear play; returns the wheel's
    /// angle increment.
    fn wheel(&mut self, play: f64) -> f64 {
        let before = self.wheel_angle;
        let gap = self.angle - self.wheel_angle;
        if gap > play / 2.0 {
            self.wheel_angle = self.angle - play / 2.0;
        } else if gap < -play / 2.0 {
            self.wheel_angle = self.angle + play / 2.0;
        }
        self.wheel_angle - before
    }
}

/// Generates the recording (formats.md CSV, parsed back) and what happened; the parser's
/// refusal is returned as the error text.
pub fn generate(g: &Gen) -> (Result<Recording, String>, Stats) {
    let robot = &g.robot;
    let n = robot.wheels.len();
    assert!(robot.wheels.iter().all(|w| w.driven) && robot.legs.is_none());
    assert!(matches!(robot.kind, RobotKind::Omni | RobotKind::DiffDrive));
    assert_eq!(g.wheels.len(), n);
    let omni = robot.kind == RobotKind::Omni;
    let all = vec![true; n];
    let mut rng = ChaCha8Rng::seed_from_u64(g.seed);
    let dt = 1e-3;
    let steps = (g.duration_s / dt).round() as usize;
    let row_every = (1.0 / (g.row_hz * dt)).round() as usize;
    let pose_period = 1.0 / g.pose_hz;
    let counts_per_rad = robot.drive.encoder_counts_per_rev / TAU;
    let nominal = geometry(robot, &g.wheels, false);
    let truth = geometry(robot, &g.wheels, true);
    let mut driver = Driver::new(g, omni, &mut rng);

    let innov = (1.0 - g.rho * g.rho).sqrt();
    let np = Normal::new(0.0, g.sigma_m * innov).unwrap();
    let nh = Normal::new(0.0, g.sigma_rad * innov).unwrap();
    let unit = Normal::new(0.0, 1.0).unwrap();
    let mut e = (
        g.sigma_m * unit.sample(&mut rng),
        g.sigma_m * unit.sample(&mut rng),
        g.sigma_rad * unit.sample(&mut rng),
    );
    let mut drift = (0.0f64, 0.0f64, 0.0f64);
    // Indices of the rows whose time goes back.
    let n_rows = steps / row_every + 1;
    let mut back_rows: Vec<usize> = Vec::new();
    let mut jitter_s = 0.0;
    let mut back_s = 0.0;
    for f in &g.faults {
        if let Fault::Clock {
            jitter_s: j,
            back,
            back_s: b,
        } = f
        {
            jitter_s = *j;
            back_s = *b;
            for k in 0..*back {
                let span = n_rows / (back + 1);
                back_rows.push(span * (k + 1) + rng.random_range(0..span / 4));
            }
        }
    }
    let fault = |f: &dyn Fn(&Fault) -> bool| g.faults.iter().find(|x| f(x)).cloned();
    let stale_enc = match fault(&|f| matches!(f, Fault::StaleEncoders { .. })) {
        Some(Fault::StaleEncoders { p }) => p,
        _ => 0.0,
    };
    let stale_pose = match fault(&|f| matches!(f, Fault::StalePoses { .. })) {
        Some(Fault::StalePoses { p }) => p,
        _ => 0.0,
    };
    let dropped = match fault(&|f| matches!(f, Fault::DroppedRows { .. })) {
        Some(Fault::DroppedRows { p }) => p,
        _ => 0.0,
    };
    let jump = fault(&|f| matches!(f, Fault::PoseJump { .. }));

    let mut motors = vec![Motor::default(); n];
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    let (mut dx, mut dy, mut dth) = (0.0f64, 0.0f64, 0.0f64);
    // The true pose history for the latency (one per step).
    let lag_steps = (g.latency_s / dt).round() as usize;
    let mut history: VecDeque<(f64, f64, f64)> = VecDeque::new();
    let enc0: Vec<i64> = (0..n).map(|_| rng.random_range(-8000..8000)).collect();
    let mut stats = Stats {
        motor_gap_rms: vec![0.0; n],
        play_taken_rad: vec![0.0; n],
        ..Stats::default()
    };
    let mut gap_n = 0usize;
    let (mut dr_sq, mut dr_h, mut dr_n) = (0.0, 0.0, 0usize);
    let mut last_sign = 0.0f64;
    let mut cmd_w = vec![0.0f64; n];
    let mut next_pose = 0.0;
    let mut last_enc_written: Option<Vec<i64>> = None;
    let mut last_pose_written: Option<(f64, f64, f64)> = None;
    let mut last_t_written = f64::NEG_INFINITY;
    let mut row_index = 0usize;

    let mut csv = String::from("t");
    for w in &robot.wheels {
        write!(csv, ",cmd_{0},enc_{0}", w.name).unwrap();
    }
    csv.push_str(",x,y,theta\n");

    for k in 0..=steps {
        let t = k as f64 * dt;
        history.push_back((x, y, th));
        if history.len() > lag_steps + 1 {
            history.pop_front();
        }
        if k % row_every == 0 {
            driver.step(t, 1.0 / g.row_hz, (x, y, th), &mut rng);
            for i in 0..n {
                cmd_w[i] = contact(&nominal[i], driver.cmd) / nominal[i].r;
            }
            // The row, as the logger writes it.
            let this_row = row_index;
            row_index += 1;
            let mut enc: Vec<i64> = (0..n)
                .map(|i| (motors[i].angle * counts_per_rad).floor() as i64)
                .collect();
            for f in &g.faults {
                match *f {
                    Fault::EncoderScale { wheel, k } => {
                        enc[wheel] = (motors[wheel].angle * counts_per_rad * k).floor() as i64
                    }
                    Fault::SignFlip { wheel } => enc[wheel] = -enc[wheel],
                    _ => {}
                }
            }
            for f in &g.faults {
                if let Fault::Swap { a, b } = *f {
                    enc.swap(a, b);
                }
            }
            let mut enc: Vec<i64> = enc.iter().zip(&enc0).map(|(e, o)| e + o).collect();
            if let Some(last) = &last_enc_written {
                if stale_enc > 0.0 && rng.random_bool(stale_enc) {
                    enc = last.clone();
                    stats.stale_rows += 1;
                }
            }
            let write_row = !(dropped > 0.0 && k > 0 && k < steps && rng.random_bool(dropped));
            let mut tw = t + if jitter_s > 0.0 {
                jitter_s * unit.sample(&mut rng)
            } else {
                0.0
            };
            if back_rows.contains(&this_row) {
                tw = last_t_written - back_s;
                stats.times_back += 1;
            } else if tw <= last_t_written {
                tw = last_t_written + 1e-4;
            }
            let pose_due = t + 1e-9 >= next_pose;
            if pose_due {
                next_pose += pose_period;
            }
            if write_row {
                last_t_written = tw;
                stats.rows += 1;
                write!(csv, "{tw:.4}").unwrap();
                for i in 0..n {
                    write!(csv, ",{:.6},{}", cmd_w[i], enc[i]).unwrap();
                }
                last_enc_written = Some(enc);
            } else {
                stats.dropped_rows += 1;
            }
            if pose_due && write_row {
                let step_s = pose_period.sqrt();
                drift.0 += g.drift_m * step_s * unit.sample(&mut rng);
                drift.1 += g.drift_m * step_s * unit.sample(&mut rng);
                drift.2 += g.drift_rad * step_s * unit.sample(&mut rng);
                e = (
                    g.rho * e.0 + np.sample(&mut rng),
                    g.rho * e.1 + np.sample(&mut rng),
                    g.rho * e.2 + nh.sample(&mut rng),
                );
                let (tx, ty, tth) = *history.front().unwrap();
                let mut p = (tx + e.0 + drift.0, ty + e.1 + drift.1, tth + e.2 + drift.2);
                if let Some(Fault::PoseJump { at, dx, dy, dth }) = &jump {
                    if t >= at * g.duration_s {
                        p = (p.0 + dx, p.1 + dy, p.2 + dth);
                    }
                }
                if g.quant_m > 0.0 {
                    p.0 = (p.0 / g.quant_m).round() * g.quant_m;
                    p.1 = (p.1 / g.quant_m).round() * g.quant_m;
                }
                if g.quant_rad > 0.0 {
                    p.2 = (p.2 / g.quant_rad).round() * g.quant_rad;
                }
                if let Some(last) = last_pose_written {
                    if stale_pose > 0.0 && rng.random_bool(stale_pose) {
                        p = last;
                        stats.stale_rows += 1;
                    }
                }
                last_pose_written = Some(p);
                write!(csv, ",{:.6},{:.6},{:.6}", p.0, p.1, wrap(p.2)).unwrap();
                stats.pose_samples += 1;
                let gap = ((dx - x).powi(2) + (dy - y).powi(2)).sqrt();
                dr_sq += gap * gap;
                dr_h += wrap(dth - th).powi(2);
                dr_n += 1;
            } else if write_row {
                csv.push_str(",,,");
            }
            if write_row {
                csv.push('\n');
            }
        }
        if k == steps {
            break;
        }
        if driver.cmd.0.abs() > 0.02 {
            let s = driver.cmd.0.signum();
            if last_sign != 0.0 && s != last_sign {
                stats.reversals += 1;
            }
            last_sign = s;
        }
        // Actuators, gear play, wheels rolling, body twist.
        let mut s_true = vec![0.0f64; n];
        let mut s_nom = vec![0.0f64; n];
        for i in 0..n {
            let before = motors[i].angle;
            let rate = motors[i].step(&g.wheels[i].chain, cmd_w[i], dt);
            stats.motor_gap_rms[i] += (rate - cmd_w[i]).powi(2);
            let dw = motors[i].wheel(g.wheels[i].play_rad);
            stats.play_taken_rad[i] += ((motors[i].angle - before) - dw).abs();
            s_true[i] = dw / dt * truth[i].r;
            s_nom[i] = (motors[i].angle - before) / dt * nominal[i].r;
        }
        gap_n += 1;
        let tw = twist_from(&truth, &s_true, &all, omni);
        stats.distance_m += (tw.0 * tw.0 + tw.1 * tw.1).sqrt() * dt;
        stats.turn_rad += tw.2.abs() * dt;
        th += tw.2 * dt;
        x += (tw.0 * th.cos() - tw.1 * th.sin()) * dt;
        y += (tw.0 * th.sin() + tw.1 * th.cos()) * dt;
        let nt = twist_from(&nominal, &s_nom, &all, omni);
        dth += nt.2 * dt;
        dx += (nt.0 * dth.cos() - nt.1 * dth.sin()) * dt;
        dy += (nt.0 * dth.sin() + nt.1 * dth.cos()) * dt;
    }
    stats.motor_gap_rms = stats
        .motor_gap_rms
        .iter()
        .map(|s| (s / gap_n.max(1) as f64).sqrt())
        .collect();
    stats.dr_rms_m = (dr_sq / dr_n.max(1) as f64).sqrt();
    stats.dr_rms_rad = (dr_h / dr_n.max(1) as f64).sqrt();
    let rec = Recording::parse(&csv, Path::new("habits.csv"), robot).map_err(|e| e.to_string());
    (rec, stats)
}
