//! The independent generator: its own small physics, written apart from the
//! `sim` crate's effects and from diagnose's models, with mechanisms neither has. It
//! writes a formats.md recording as CSV text and reads it back with the project's parser,
//! so what diagnose sees is exactly what a user's file would give it.
//!
//! Physics, all in this file:
//! - commands: body twists (forward, sideways on omni, yaw) drawn as zero-mean random
//!   targets held 0.8-2.5 s, ramped with acceleration limits, so the robot reverses often
//!   and stays near the origin; wheel commands from the *nominal* geometry;
//! - actuator: a wheel follows its held command exactly, then the mechanisms act (speed
//!   droop, gear play per wheel); the encoder sits on the wheel shaft;
//! - ground: each wheel's contact travel (radius times wheel angle, with its own true
//!   radius, position and rolling direction), reduced by the floor (patch, cables); the
//!   body twist is the least-squares twist of the driven wheels' rolling constraints
//!   written as u . (v + w x p) (no Siegwart rows), with sideways motion of standard
//!   wheels from the tyre model only; traction limited by the normal load on the driven
//!   pair (leg posture); a caster that turns the body when the drive reverses;
//! - sensing: pose at 30 Hz with 1 mm / 2 mrad white noise, encoder counts floored.
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
use rigid::{contact, twist_from, WheelGeo};

/// A mechanism of this generator.
#[derive(Debug, Clone, PartialEq)]
pub enum Mech {
    /// Velocity loop against Coulomb friction: every command loses `droop` rad/s in its
    /// sign; below 2 droop the wheel turns at half the command (no dead zone).
    Droop(f64),
    /// Gear play per wheel (wheel rad, total), encoder on the wheel shaft.
    Play(Vec<f64>),
    /// True radius / nominal, per wheel.
    Radius(Vec<f64>),
    /// One wheel's polar angle (and with it its rolling direction) off by this, rad.
    MountAngle { wheel: usize, offset_rad: f64 },
    /// One wheel's distance from the centre scaled.
    MountDistance { wheel: usize, scale: f64 },
    /// A patch of floor (world x0..x1, y0..y1) where a wheel keeps `keep` of its travel.
    Patch {
        x0: f64,
        x1: f64,
        y0: f64,
        y1: f64,
        keep: f64,
    },
    /// Cables along world y every `spacing` m in x; each wheel's contact point crossing one
    /// loses `loss` m of rolling travel (spread over 5 mm of the crossing).
    Cables { spacing: f64, loss: f64 },
    /// Tyre relaxation: side velocity relaxes to -k v_x omega with time constant tau.
    LaggedSideSlip { k: f64, tau: f64 },
    /// The body's forward acceleration is bounded by mu g times the share of the weight on
    /// the driven (front) pair, which the leg posture sets.
    PostureTraction { mu: f64 },
    /// A trailing caster that swings round when the forward command reverses and turns the
    /// body by `kick_rad` (spread over 0.2 s) at each reversal.
    CasterKick { kick_rad: f64 },
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
    pub v_max: f64,
    pub w_max: f64,
    pub a_max: f64,
    pub mechs: Vec<Mech>,
    /// Leg angles (front, rear) from `start` to `end` linearly over the run (legged only).
    pub legs: ((f64, f64), (f64, f64)),
}

impl Gen {
    pub fn new(robot: Robot, seed: u64) -> Self {
        Gen {
            robot,
            seed,
            duration_s: 40.0,
            row_hz: 100.0,
            pose_hz: 30.0,
            pose_noise_m: 0.001,
            heading_noise_rad: 0.002,
            v_max: 0.3,
            w_max: 1.0,
            a_max: 0.6,
            mechs: Vec::new(),
            legs: (
                (std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
                (std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2),
            ),
        }
    }
}

/// Counts of what happened in a run (to check a case exercises its mechanism).
#[derive(Debug, Default, Clone)]
pub struct Stats {
    /// Seconds some wheel spent on the patch.
    pub patch_s: f64,
    /// Cable crossings, all wheels.
    pub crossings: usize,
    /// Reversals of the forward command.
    pub reversals: usize,
    /// Seconds the traction limit bound.
    pub slipping_s: f64,
}

fn geometry(robot: &Robot, legs: (f64, f64), truth: bool, mechs: &[Mech]) -> Vec<WheelGeo> {
    robot
        .wheels
        .iter()
        .enumerate()
        .map(|(i, w)| {
            let mut a = w.alpha_rad;
            let mut l = w.l_m;
            let mut r = w.radius_m;
            if truth {
                for m in mechs {
                    match m {
                        Mech::MountAngle { wheel, offset_rad } if *wheel == i => a += offset_rad,
                        Mech::MountDistance { wheel, scale } if *wheel == i => l *= scale,
                        Mech::Radius(s) => r *= s[i],
                        _ => {}
                    }
                }
            }
            let dir = a + w.beta_rad + w.gamma_rad;
            let mut p = (l * a.cos(), l * a.sin());
            if let Some(lg) = &robot.legs {
                let (xf, xr) = (
                    lg.body_length_m / 2.0 + lg.length_m * legs.0.cos(),
                    -lg.body_length_m / 2.0 + lg.length_m * legs.1.cos(),
                );
                p.0 = if p.0 > 0.0 { xf } else { xr };
            }
            WheelGeo {
                p,
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
    let omni = robot.kind == RobotKind::Omni;
    let driven: Vec<bool> = robot.wheels.iter().map(|w| w.driven).collect();
    let mut rng = ChaCha8Rng::seed_from_u64(g.seed);
    let noise_p = Normal::new(0.0, g.pose_noise_m).unwrap();
    let noise_h = Normal::new(0.0, g.heading_noise_rad).unwrap();
    let dt = 1e-3;
    let steps = (g.duration_s / dt).round() as usize;
    let row_every = (1.0 / (g.row_hz * dt)).round() as usize;
    let pose_period = 1.0 / g.pose_hz;
    let counts_per_rad = robot.drive.encoder_counts_per_rev / std::f64::consts::TAU;
    let find = |f: &dyn Fn(&Mech) -> bool| g.mechs.iter().find(|m| f(m)).cloned();

    // Commanded body twist: zero-mean random targets, acceleration-limited ramps.
    let mut target = (0.0, 0.0, 0.0);
    let mut hold = 0.0;
    let mut cmd_tw = (0.0f64, 0.0f64, 0.0f64);
    // State.
    let (mut x, mut y, mut th) = (0.0f64, 0.0f64, 0.0f64);
    let mut motor = vec![0.0f64; n]; // motor-side angle, wheel rad
    let mut wheel = vec![0.0f64; n]; // wheel angle (encoder)
    let mut vy_slip = 0.0f64;
    let mut vx_body = 0.0f64;
    let mut last_sign = 0.0f64;
    let mut kick_left = 0.0f64; // heading still to turn (rad)
    let mut stats = Stats::default();
    let mut next_pose = 0.0;
    let enc0: Vec<i64> = (0..n).map(|_| rng.random_range(-5000..5000)).collect();

    let mut csv = String::from("t");
    for w in &robot.wheels {
        write!(csv, ",cmd_{0},enc_{0}", w.name).unwrap();
    }
    csv.push_str(",x,y,theta");
    if robot.legs.is_some() {
        csv.push_str(",leg_front,leg_rear");
    }
    csv.push('\n');
    let mut cmd_w = vec![0.0f64; n];
    let mut cable_cell = vec![i64::MIN; n];

    for k in 0..=steps {
        let t = k as f64 * dt;
        let frac = t / g.duration_s;
        let legs = (
            g.legs.0 .0 + (g.legs.1 .0 - g.legs.0 .0) * frac,
            g.legs.0 .1 + (g.legs.1 .1 - g.legs.0 .1) * frac,
        );
        let nominal = geometry(robot, legs, false, &[]);
        let truth = geometry(robot, legs, true, &g.mechs);
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
                // Pull back towards the origin so the floor mechanisms are visited.
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
                cmd_w[i] = if driven[i] {
                    contact(&nominal[i], cmd_tw) / nominal[i].r
                } else {
                    0.0
                };
            }
            write!(csv, "{t:.4}").unwrap();
            for i in 0..n {
                let c = if driven[i] {
                    format!("{:.6}", cmd_w[i])
                } else {
                    String::new()
                };
                let e = enc0[i] + (wheel[i] * counts_per_rad).floor() as i64;
                write!(csv, ",{c},{e}").unwrap();
            }
            if t + 1e-9 >= next_pose {
                next_pose += pose_period;
                write!(
                    csv,
                    ",{:.6},{:.6},{:.6}",
                    x + noise_p.sample(&mut rng),
                    y + noise_p.sample(&mut rng),
                    th + noise_h.sample(&mut rng)
                )
                .unwrap();
            } else {
                csv.push_str(",,,");
            }
            if robot.legs.is_some() {
                write!(csv, ",{:.6},{:.6}", legs.0, legs.1).unwrap();
            }
            csv.push('\n');
        }
        if k == steps {
            break;
        }
        // Reversals of the forward command.
        if cmd_tw.0.abs() > 0.02 {
            let s = cmd_tw.0.signum();
            if last_sign != 0.0 && s != last_sign {
                stats.reversals += 1;
                if let Some(Mech::CasterKick { kick_rad }) =
                    find(&|m| matches!(m, Mech::CasterKick { .. }))
                {
                    kick_left += kick_rad;
                }
            }
            last_sign = s;
        }
        // Actuator: wheel rate from the held command, then the drive's play.
        let mut s_contact = vec![0.0f64; n];
        for i in 0..n {
            let mut rate = cmd_w[i];
            if let Some(Mech::Droop(d)) = find(&|m| matches!(m, Mech::Droop(_))) {
                rate = if rate.abs() > 2.0 * d {
                    rate - d * rate.signum()
                } else {
                    0.5 * rate
                };
            }
            motor[i] += rate * dt;
            let play = match find(&|m| matches!(m, Mech::Play(_))) {
                Some(Mech::Play(p)) => p[i],
                _ => 0.0,
            };
            let before = wheel[i];
            if driven[i] {
                let half = 0.5 * play;
                if motor[i] - wheel[i] > half {
                    wheel[i] = motor[i] - half;
                } else if wheel[i] - motor[i] > half {
                    wheel[i] = motor[i] + half;
                }
                s_contact[i] = (wheel[i] - before) / dt * truth[i].r;
            }
        }
        // Floor: patch and cables act on each wheel's contact travel.
        let (c, sn) = (th.cos(), th.sin());
        for i in 0..n {
            let (px, py) = truth[i].p;
            let wx = x + c * px - sn * py;
            let wy = y + sn * px + c * py;
            if let Some(Mech::Patch {
                x0,
                x1,
                y0,
                y1,
                keep,
            }) = find(&|m| matches!(m, Mech::Patch { .. }))
            {
                if (x0..=x1).contains(&wx) && (y0..=y1).contains(&wy) {
                    s_contact[i] *= keep;
                    stats.patch_s += dt;
                }
            }
            if let Some(Mech::Cables { spacing, loss }) =
                find(&|m| matches!(m, Mech::Cables { .. }))
            {
                let band = 0.005;
                let phase = wx.rem_euclid(spacing);
                if phase < band {
                    // Travel along world x the contact makes this step, from the wheel's
                    // rolling direction in the world.
                    let ux = truth[i].u.0 * c - truth[i].u.1 * sn;
                    let dxw = (s_contact[i] * ux * dt).abs();
                    let lost = (loss / band * dxw).min(s_contact[i].abs() * dt);
                    s_contact[i] -= lost / dt * s_contact[i].signum();
                }
                let cell = (wx / spacing).floor() as i64;
                if cell != cable_cell[i] {
                    if cable_cell[i] != i64::MIN {
                        stats.crossings += 1;
                    }
                    cable_cell[i] = cell;
                }
            }
        }
        // Body twist from the contacts.
        let mut tw = twist_from(&truth, &s_contact, &driven, omni);
        if let Some(Mech::PostureTraction { mu }) =
            find(&|m| matches!(m, Mech::PostureTraction { .. }))
        {
            let lg = robot.legs.as_ref().expect("legged robot");
            let (xf, xr) = (
                lg.body_length_m / 2.0 + lg.length_m * legs.0.cos(),
                -lg.body_length_m / 2.0 + lg.length_m * legs.1.cos(),
            );
            let share = (-xr / (xf - xr)).clamp(0.0, 1.0);
            let lim = mu * 9.81 * share * dt;
            let dv = tw.0 - vx_body;
            if dv.abs() > lim {
                stats.slipping_s += dt;
            }
            vx_body += dv.clamp(-lim, lim);
            tw.0 = vx_body;
        } else {
            vx_body = tw.0;
        }
        if let Some(Mech::LaggedSideSlip { k, tau }) =
            find(&|m| matches!(m, Mech::LaggedSideSlip { .. }))
        {
            let target = -k * tw.0 * tw.2;
            vy_slip += (target - vy_slip) * dt / tau;
            tw.1 += vy_slip;
        }
        if kick_left.abs() > 0.0 {
            let rate = 0.03f64.copysign(kick_left) / 0.2; // kick spread over 0.2 s per 0.03 rad
            let d = (rate * dt).clamp(-kick_left.abs(), kick_left.abs());
            tw.2 += d / dt;
            kick_left -= d;
            if kick_left.abs() < 1e-12 {
                kick_left = 0.0;
            }
        }
        // Free (undriven) wheels roll with the ground: their encoders see the body's motion.
        for i in 0..n {
            if !driven[i] {
                wheel[i] += contact(&truth[i], tw) / truth[i].r * dt;
            }
        }
        th += tw.2 * dt;
        let (c, sn) = (th.cos(), th.sin());
        x += (tw.0 * c - tw.1 * sn) * dt;
        y += (tw.0 * sn + tw.1 * c) * dt;
    }
    let rec = Recording::parse(&csv, Path::new("independent.csv"), robot)
        .expect("the generator writes formats.md recordings");
    (rec, stats)
}
