//! The blind generator: its own small physics, written apart from the `sim` crate's
//! effects, from diagnose's models and from the independent generator's mechanisms (its
//! structure follows `independent/mod.rs`: held commands, 1 kHz Euler integration, a
//! formats.md recording written as CSV and read back with the project's parser, so what
//! diagnose sees is exactly what a user's file would give it).
//!
//! Physics, all in this file:
//! - commands: body twists (forward, sideways on omni, yaw) drawn as zero-mean random
//!   targets held 0.8-2.5 s, ramped with acceleration limits (yaw: three times the linear
//!   limit), pulled back towards the origin when the robot is over 0.6 m away; wheel
//!   commands from the *nominal* geometry, held from one row to the next;
//! - actuator: the motor follows its held command exactly; the encoder sits on the motor
//!   shaft (the counts are per wheel revolution) and may drop counts above a count rate;
//!   the wheel turns with the motor unless its hub slips on the shaft;
//! - ground: each wheel's contact travel is its rolling radius (which may vary with the
//!   wheel's angle or drift in time) times its angle increment, then the floor acts
//!   (carpet grain keeps less travel in one world direction), then traction (each wheel's
//!   contact speed changes at most as fast as its own normal load allows); the body twist
//!   is the least-squares twist of the driven wheels' rolling constraints u . (v + w x p)
//!   (no sideways motion of standard wheels except from the slope's tyre drift);
//! - sensing: pose at 30 Hz with white or AR(1)-coloured noise, optional motion-capture
//!   marker swaps (one pose sample displaced), encoder counts floored.
//!
//! `Stats` reports, from the generator's own bookkeeping, what each mechanism did (time
//! spent slipping, counts dropped, the eccentric wheel's mean rolling radius...) and how
//! far the true motion leaves dead reckoning from the encoders with the nominal geometry
//! (the size of the signal, to compare with the pose noise).
#![allow(dead_code, clippy::needless_range_loop)]

use calib_core::robot::{Robot, RobotKind};
use formats::recording::Recording;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::fmt::Write as _;
use std::path::Path;

#[path = "../rigid/mod.rs"]
mod rigid;
use rigid::{contact, twist_from, wrap, WheelGeo};

const G: f64 = 9.81;

/// A mechanism of this generator.
#[derive(Debug, Clone, PartialEq)]
pub enum Mech {
    /// An eccentric (out-of-round) wheel: its rolling radius is
    /// r0 (1 + amp cos(phi + phase)) at wheel angle phi (the axle sits `amp` r0 off the
    /// rim's centre), so its mean over a revolution is the nominal r0.
    Eccentric { wheel: usize, amp: f64, phase: f64 },
    /// Tyre wear or warm-up: one wheel's radius goes linearly in time from nominal (t = 0)
    /// to `end_scale` times nominal (end of the run).
    RadiusDrift { wheel: usize, end_scale: f64 },
    /// Traction per wheel: wheel i's contact speed changes at most mu g load[i] per
    /// second, load[i] its normal load over the mean driven wheel's (a payload off-centre
    /// loads one side more).
    Traction { mu: f64, load: Vec<f64> },
    /// A hub slipping on the motor shaft (a loose set screw): the wheel's angular
    /// acceleration is bounded by `alpha_max` (rad/s^2) while the motor, and its encoder,
    /// follow the command.
    HubSlip { wheel: usize, alpha_max: f64 },
    /// Carpet grain: a wheel whose contact moves in world direction psi keeps
    /// 1 - loss (1 + cos(psi - dir_rad)) / 2 of its travel (all of it against the grain,
    /// 1 - loss along it).
    CarpetGrain { dir_rad: f64, loss: f64 },
    /// An encoder counter that cannot count faster than this (counts per second): counts
    /// beyond it are dropped (each wheel).
    CountRateLimit { counts_per_s: f64 },
    /// Every wheel's distance from the centre times this (a diff drive's wheelbase).
    Wheelbase(f64),
    /// A floor slope: the tyres' side force against gravity makes them drift sideways at a
    /// slip angle; the body's sideways velocity is k |v_x| (y_body . downhill), downhill the
    /// world direction `down_rad`. Only while the robot moves, in proportion to its speed.
    Slope { down_rad: f64, k: f64 },
}

/// What to generate.
#[derive(Debug, Clone)]
pub struct Gen {
    pub robot: Robot,
    pub seed: u64,
    pub duration_s: f64,
    pub row_hz: f64,
    pub pose_hz: f64,
    pub pose_noise_m: f64,
    pub heading_noise_rad: f64,
    /// AR(1) coefficient of the pose noise per pose sample (0 = white).
    pub noise_rho: f64,
    /// Motion-capture marker swaps: this many single pose samples displaced by 3-5 cm
    /// (random direction) and 0.03-0.1 rad (random sign).
    pub marker_swaps: usize,
    pub v_max: f64,
    pub w_max: f64,
    pub a_max: f64,
    pub mechs: Vec<Mech>,
}

impl Gen {
    pub fn new(robot: Robot, seed: u64) -> Self {
        Gen {
            robot,
            seed,
            duration_s: 60.0,
            row_hz: 100.0,
            pose_hz: 30.0,
            pose_noise_m: 0.001,
            heading_noise_rad: 0.002,
            noise_rho: 0.0,
            marker_swaps: 0,
            v_max: 0.3,
            w_max: 1.0,
            a_max: 0.6,
            mechs: Vec::new(),
        }
    }
}

/// What happened in a run (to check a case exercises its mechanism, and how large the
/// signal is).
#[derive(Debug, Default, Clone)]
pub struct Stats {
    /// Rows written.
    pub rows: usize,
    /// Reversals of the forward command.
    pub reversals: usize,
    /// Distance the body's centre travelled (unsigned), m.
    pub distance_m: f64,
    /// Total turn (unsigned), rad.
    pub turn_rad: f64,
    /// Per wheel: contact travel / (angle turned x nominal radius), the mean rolling
    /// radius over nominal (before floor and traction).
    pub mean_radius_ratio: Vec<f64>,
    /// Diff drive: the travel-weighted mean of r_right / r_left (= D_R / D_L).
    pub mean_ed: f64,
    /// Per wheel: seconds its traction or hub limit bound.
    pub slipping_s: Vec<f64>,
    /// Per wheel: travel the traction or hub limit took (|wheel surface - contact|
    /// integrated, m; for the hub, at the nominal radius against the motor).
    pub slip_m: Vec<f64>,
    /// Per wheel: share of the motor's turning the encoder did not count.
    pub counts_dropped: Vec<f64>,
    /// Share of the contact travel the carpet took.
    pub carpet_loss: f64,
    /// Sideways drift from the slope, m (integrated |v_y|).
    pub slope_drift_m: f64,
    /// Marker swaps written.
    pub swaps: usize,
    /// Dead reckoning from the encoders with the nominal geometry against the true pose
    /// (both from the same start), RMS over the pose samples: position (m) and heading
    /// (rad); and the largest position gap.
    pub dr_rms_m: f64,
    pub dr_rms_heading_rad: f64,
    pub dr_max_m: f64,
}

/// The wheels' geometry at time fraction `frac` of the run (nominal if not `truth`).
fn geometry(robot: &Robot, truth: bool, mechs: &[Mech], frac: f64) -> Vec<WheelGeo> {
    robot
        .wheels
        .iter()
        .enumerate()
        .map(|(i, w)| {
            let a = w.alpha_rad;
            let mut l = w.l_m;
            let mut r = w.radius_m;
            if truth {
                for m in mechs {
                    match m {
                        Mech::RadiusDrift { wheel, end_scale } if *wheel == i => {
                            r *= 1.0 + (end_scale - 1.0) * frac
                        }
                        Mech::Wheelbase(s) => l *= s,
                        _ => {}
                    }
                }
            }
            let dir = a + w.beta_rad + w.gamma_rad;
            WheelGeo {
                p: (l * a.cos(), l * a.sin()),
                u: (dir.sin(), -dir.cos()),
                r: r * w.gamma_rad.cos(),
            }
        })
        .collect()
}

/// Generates the recording (as formats.md CSV, parsed back) and what happened.
pub fn generate(g: &Gen) -> (Recording, Stats) {
    let robot = &g.robot;
    let n = robot.wheels.len();
    assert!(
        robot.wheels.iter().all(|w| w.driven) && robot.legs.is_none(),
        "the blind generator drives every wheel of a legless robot"
    );
    assert!(
        matches!(robot.kind, RobotKind::Omni | RobotKind::DiffDrive),
        "diff drive or omni"
    );
    let omni = robot.kind == RobotKind::Omni;
    // Every wheel is driven (asserted above): all of them give the body twist.
    let all = vec![true; n];
    let mut rng = ChaCha8Rng::seed_from_u64(g.seed);
    let dt = 1e-3;
    let steps = (g.duration_s / dt).round() as usize;
    let row_every = (1.0 / (g.row_hz * dt)).round() as usize;
    let pose_period = 1.0 / g.pose_hz;
    let counts_per_rad = robot.drive.encoder_counts_per_rev / std::f64::consts::TAU;
    let find = |f: &dyn Fn(&Mech) -> bool| g.mechs.iter().find(|m| f(m)).cloned();
    let eccentric = find(&|m| matches!(m, Mech::Eccentric { .. }));
    let traction = find(&|m| matches!(m, Mech::Traction { .. }));
    let hub = find(&|m| matches!(m, Mech::HubSlip { .. }));
    let carpet = find(&|m| matches!(m, Mech::CarpetGrain { .. }));
    let count_limit = find(&|m| matches!(m, Mech::CountRateLimit { .. }));
    let slope = find(&|m| matches!(m, Mech::Slope { .. }));
    let nominal = geometry(robot, false, &[], 0.0);

    // Pose noise: AR(1) with the stated marginal standard deviations.
    let innov = (1.0 - g.noise_rho * g.noise_rho).sqrt();
    let noise_p = Normal::new(0.0, g.pose_noise_m * innov).unwrap();
    let noise_h = Normal::new(0.0, g.heading_noise_rad * innov).unwrap();
    let (mut ex, mut ey, mut eth) = (
        Normal::new(0.0, g.pose_noise_m).unwrap().sample(&mut rng),
        Normal::new(0.0, g.pose_noise_m).unwrap().sample(&mut rng),
        Normal::new(0.0, g.heading_noise_rad)
            .unwrap()
            .sample(&mut rng),
    );
    // Marker swaps: pose sample indices, spread over the run away from its ends.
    let n_pose = (g.duration_s * g.pose_hz).floor() as usize;
    let mut swap_at: Vec<usize> = Vec::new();
    for s in 0..g.marker_swaps {
        let span = (n_pose - (4.0 * g.pose_hz) as usize) / g.marker_swaps.max(1);
        let lo = (2.0 * g.pose_hz) as usize + s * span;
        swap_at.push(rng.random_range(lo..lo + span));
    }

    let mut target = (0.0, 0.0, 0.0);
    let mut hold = 0.0;
    let mut cmd_tw = (0.0f64, 0.0f64, 0.0f64);
    // State: true pose, dead reckoning, per-wheel motor, wheel and encoder angles.
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    let (mut dx, mut dy, mut dth) = (0.0f64, 0.0f64, 0.0f64);
    let mut wheel = vec![0.0f64; n];
    let mut wheel_rate = vec![0.0f64; n];
    let mut enc = vec![0.0f64; n];
    let mut contact_v: Vec<Option<f64>> = vec![None; n];
    let mut last_sign = 0.0f64;
    let mut stats = Stats {
        slipping_s: vec![0.0; n],
        slip_m: vec![0.0; n],
        counts_dropped: vec![0.0; n],
        ..Stats::default()
    };
    let mut turned = vec![0.0f64; n];
    let mut motor_turned = vec![0.0f64; n];
    let mut travel_geo = vec![0.0f64; n];
    let mut dropped = vec![0.0f64; n];
    let (mut ed_num, mut ed_den) = (0.0f64, 0.0f64);
    let (mut carpet_lost, mut carpet_total) = (0.0f64, 0.0f64);
    let (mut dr_sq, mut dr_h_sq, mut dr_n) = (0.0f64, 0.0f64, 0usize);
    let mut next_pose = 0.0;
    let mut pose_index = 0usize;
    let enc0: Vec<i64> = (0..n).map(|_| rng.random_range(-5000..5000)).collect();

    let mut csv = String::from("t");
    for w in &robot.wheels {
        write!(csv, ",cmd_{0},enc_{0}", w.name).unwrap();
    }
    csv.push_str(",x,y,theta\n");
    let mut cmd_w = vec![0.0f64; n];

    for k in 0..=steps {
        let t = k as f64 * dt;
        let frac = t / g.duration_s;
        let truth = geometry(robot, true, &g.mechs, frac);
        // Row: log, then update the held commands (a command holds until the next row).
        if k % row_every == 0 {
            if hold <= 0.0 {
                hold = rng.random_range(0.8..2.5);
                target = (
                    rng.random_range(-g.v_max..g.v_max),
                    if omni {
                        rng.random_range(-g.v_max..g.v_max)
                    } else {
                        0.0
                    },
                    rng.random_range(-g.w_max..g.w_max),
                );
                // Pull back towards the origin.
                let d = (x * x + y * y).sqrt();
                if d > 0.6 {
                    let (bx, by) = (-x * th.cos() - y * th.sin(), x * th.sin() - y * th.cos());
                    target.0 = g.v_max * 0.8 * bx.signum();
                    if omni {
                        target.1 = g.v_max * 0.8 * by / d;
                    }
                }
            }
            let step = |c: f64, tg: f64, lim: f64| c + (tg - c).clamp(-lim, lim);
            let rdt = 1.0 / g.row_hz;
            cmd_tw = (
                step(cmd_tw.0, target.0, g.a_max * rdt),
                step(cmd_tw.1, target.1, g.a_max * rdt),
                step(cmd_tw.2, target.2, 3.0 * g.a_max * rdt),
            );
            hold -= rdt;
            for i in 0..n {
                cmd_w[i] = contact(&nominal[i], cmd_tw) / nominal[i].r;
            }
            stats.rows += 1;
            write!(csv, "{t:.4}").unwrap();
            for i in 0..n {
                let e = enc0[i] + (enc[i] * counts_per_rad).floor() as i64;
                write!(csv, ",{:.6},{e}", cmd_w[i]).unwrap();
            }
            if t + 1e-9 >= next_pose {
                next_pose += pose_period;
                ex = g.noise_rho * ex + noise_p.sample(&mut rng);
                ey = g.noise_rho * ey + noise_p.sample(&mut rng);
                eth = g.noise_rho * eth + noise_h.sample(&mut rng);
                let (mut px, mut py, mut pth) = (x + ex, y + ey, th + eth);
                if swap_at.contains(&pose_index) {
                    let d = rng.random_range(0.03..0.05);
                    let a = rng.random_range(0.0..std::f64::consts::TAU);
                    px += d * a.cos();
                    py += d * a.sin();
                    pth +=
                        rng.random_range(0.03..0.1) * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                    stats.swaps += 1;
                }
                pose_index += 1;
                write!(csv, ",{px:.6},{py:.6},{pth:.6}").unwrap();
                let (ddx, ddy) = (dx - x, dy - y);
                let gap = (ddx * ddx + ddy * ddy).sqrt();
                dr_sq += gap * gap;
                dr_h_sq += wrap(dth - th).powi(2);
                dr_n += 1;
                stats.dr_max_m = stats.dr_max_m.max(gap);
            } else {
                csv.push_str(",,,");
            }
            csv.push('\n');
        }
        if k == steps {
            break;
        }
        if cmd_tw.0.abs() > 0.02 {
            let s = cmd_tw.0.signum();
            if last_sign != 0.0 && s != last_sign {
                stats.reversals += 1;
            }
            last_sign = s;
        }
        // Actuator: the motor follows the held command; the encoder on its shaft counts
        // what its counter can; the wheel turns with the motor unless its hub slips.
        let mut s_contact = vec![0.0f64; n];
        let mut enc_inc = vec![0.0f64; n];
        for i in 0..n {
            let motor_inc = cmd_w[i] * dt;
            let mut e_inc = motor_inc;
            if let Some(Mech::CountRateLimit { counts_per_s }) = &count_limit {
                let lim = counts_per_s / counts_per_rad * dt;
                e_inc = motor_inc.clamp(-lim, lim);
                dropped[i] += (motor_inc - e_inc).abs();
            }
            enc[i] += e_inc;
            motor_turned[i] += motor_inc.abs();
            enc_inc[i] = e_inc;
            let rate = match &hub {
                Some(Mech::HubSlip {
                    wheel: hw,
                    alpha_max,
                }) if *hw == i => {
                    let d = cmd_w[i] - wheel_rate[i];
                    if d.abs() > alpha_max * dt {
                        stats.slipping_s[i] += dt;
                    }
                    let w = wheel_rate[i] + d.clamp(-alpha_max * dt, alpha_max * dt);
                    stats.slip_m[i] += (cmd_w[i] - w).abs() * nominal[i].r * dt;
                    w
                }
                _ => cmd_w[i],
            };
            wheel_rate[i] = rate;
            let before = wheel[i];
            wheel[i] += rate * dt;
            let mut r = truth[i].r;
            if let Some(Mech::Eccentric {
                wheel: ew,
                amp,
                phase,
            }) = &eccentric
            {
                if *ew == i {
                    // Exact integral of r0 (1 + amp cos(phi + phase)) over the step.
                    let dphi = wheel[i] - before;
                    r = if dphi.abs() > 1e-15 {
                        truth[i].r
                            * (1.0
                                + amp * ((wheel[i] + phase).sin() - (before + phase).sin()) / dphi)
                    } else {
                        truth[i].r * (1.0 + amp * (before + phase).cos())
                    };
                }
            }
            s_contact[i] = (wheel[i] - before) / dt * r;
            turned[i] += (wheel[i] - before).abs();
            travel_geo[i] += (s_contact[i] * dt).abs();
        }
        if !omni && n == 2 {
            let w = (wheel_rate[0] * dt).abs();
            ed_num += w * truth[1].r / truth[0].r;
            ed_den += w;
        }
        // Floor: carpet grain, by the world direction each contact moves in.
        if let Some(Mech::CarpetGrain { dir_rad, loss }) = &carpet {
            let (c, sn) = (th.cos(), th.sin());
            for i in 0..n {
                let (ux, uy) = (
                    truth[i].u.0 * c - truth[i].u.1 * sn,
                    truth[i].u.0 * sn + truth[i].u.1 * c,
                );
                let sgn = s_contact[i].signum();
                let psi = (uy * sgn).atan2(ux * sgn);
                let keep = 1.0 - loss * (1.0 + (psi - dir_rad).cos()) / 2.0;
                carpet_total += (s_contact[i] * dt).abs();
                carpet_lost += (s_contact[i] * (1.0 - keep) * dt).abs();
                s_contact[i] *= keep;
            }
        }
        // Traction per wheel: the contact speed follows at most mu g load.
        if let Some(Mech::Traction { mu, load }) = &traction {
            for i in 0..n {
                let lim = mu * G * load[i] * dt;
                let c = contact_v[i].unwrap_or(s_contact[i]);
                let d = s_contact[i] - c;
                if d.abs() > lim {
                    stats.slipping_s[i] += dt;
                }
                let c = c + d.clamp(-lim, lim);
                stats.slip_m[i] += (s_contact[i] - c).abs() * dt;
                contact_v[i] = Some(c);
                s_contact[i] = c;
            }
        }
        // Body twist from the contacts; the slope's sideways tyre drift.
        let mut tw = twist_from(&truth, &s_contact, &all, omni);
        if let Some(Mech::Slope { down_rad, k }) = &slope {
            // Body y in the world is (-sin th, cos th).
            let across = -th.sin() * down_rad.cos() + th.cos() * down_rad.sin();
            let vy = k * tw.0.abs() * across;
            tw.1 += vy;
            stats.slope_drift_m += vy.abs() * dt;
        }
        stats.distance_m += (tw.0 * tw.0 + tw.1 * tw.1).sqrt() * dt;
        stats.turn_rad += tw.2.abs() * dt;
        th += tw.2 * dt;
        let (c, sn) = (th.cos(), th.sin());
        x += (tw.0 * c - tw.1 * sn) * dt;
        y += (tw.0 * sn + tw.1 * c) * dt;
        // Dead reckoning from the encoders with the nominal geometry.
        let s_nom: Vec<f64> = (0..n).map(|i| enc_inc[i] / dt * nominal[i].r).collect();
        let nt = twist_from(&nominal, &s_nom, &all, omni);
        dth += nt.2 * dt;
        let (c, sn) = (dth.cos(), dth.sin());
        dx += (nt.0 * c - nt.1 * sn) * dt;
        dy += (nt.0 * sn + nt.1 * c) * dt;
    }
    stats.mean_radius_ratio = (0..n)
        .map(|i| travel_geo[i] / (turned[i] * nominal[i].r))
        .collect();
    stats.mean_ed = if ed_den > 0.0 { ed_num / ed_den } else { 1.0 };
    stats.counts_dropped = (0..n).map(|i| dropped[i] / motor_turned[i]).collect();
    stats.carpet_loss = if carpet_total > 0.0 {
        carpet_lost / carpet_total
    } else {
        0.0
    };
    stats.dr_rms_m = (dr_sq / dr_n.max(1) as f64).sqrt();
    stats.dr_rms_heading_rad = (dr_h_sq / dr_n.max(1) as f64).sqrt();
    let rec = Recording::parse(&csv, Path::new("blind.csv"), robot)
        .expect("the generator writes formats.md recordings");
    (rec, stats)
}
