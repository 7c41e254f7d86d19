//! A small kinematic generator of recordings with known effects, written independently of
//! the diagnose models (its own integration at 1 kHz substeps, its own actuator and ground
//! physics), so tests compare two implementations of the same physics.
#![allow(dead_code)]

use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::{Robot, RobotKind};
use formats::recording::{Recording, Row};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

/// An effect as the generator applies it.
#[derive(Debug, Clone, PartialEq)]
pub enum Truth {
    /// D_right / D_left with the mean kept (diff drive).
    Ed(f64),
    /// Per-wheel radius multipliers.
    RadiusScales(Vec<f64>),
    Eb(f64),
    Mu(f64),
    SideSlip(f64),
    Bumps {
        spacing: f64,
        loss: f64,
    },
    Backlash(f64),
    MissedSteps(f64),
    Lag(f64),
    Deadband(f64),
    /// Out of catalogue: a tilted floor, the body drifts downhill (world +y) at this
    /// speed (m/s) while the wheels turn.
    Tilt(f64),
}

#[derive(Debug, Clone)]
pub struct Config {
    pub robot: Robot,
    pub seed: u64,
    pub duration_s: f64,
    /// Rows per second (encoders, commands).
    pub rate_hz: f64,
    pub pose_rate_hz: f64,
    pub pose_noise_m: f64,
    pub heading_noise_rad: f64,
    pub truths: Vec<Truth>,
    pub with_cmd: bool,
    pub with_enc: bool,
    /// Peak accelerations of the commanded profile (m/s^2).
    pub accel: f64,
    pub speed: f64,
}

impl Config {
    pub fn new(robot: Robot, seed: u64) -> Self {
        Config {
            robot,
            seed,
            duration_s: 40.0,
            rate_hz: 50.0,
            pose_rate_hz: 25.0,
            pose_noise_m: 0.002,
            heading_noise_rad: 0.004,
            truths: Vec::new(),
            with_cmd: true,
            with_enc: true,
            accel: 0.6,
            speed: 0.3,
        }
    }
}

/// Commanded body twist profile: random segments, ramped with acceleration limits.
fn profile(cfg: &Config, rng: &mut ChaCha8Rng, dt: f64) -> Vec<Twist<f64>> {
    let n = (cfg.duration_s / dt).ceil() as usize + 1;
    let omni = cfg.robot.kind == RobotKind::Omni;
    let legged = cfg.robot.kind == RobotKind::WheeledLegged;
    let mut out = Vec::with_capacity(n);
    let mut cur = Twist::new(0.0, 0.0, 0.0);
    let mut target = cur;
    let mut seg_end = 0.0;
    let (v, a) = (cfg.speed, cfg.accel);
    let alpha = a * 4.0;
    let mut t = 0.0;
    for _ in 0..n {
        if t >= seg_end {
            seg_end = t + rng.random_range(1.0..3.0);
            let kind = rng.random_range(0..6);
            let sgn = if rng.random_bool(0.25) { -1.0 } else { 1.0 };
            target = match kind {
                0 => Twist::new(sgn * v, 0.0, 0.0),
                1 => Twist::new(v * 0.7, 0.0, rng.random_range(-1.2..1.2)),
                2 if !legged => Twist::new(0.0, 0.0, if rng.random_bool(0.5) { 1.5 } else { -1.5 }),
                3 => Twist::new(0.0, 0.0, 0.0),
                _ => Twist::new(
                    sgn * v * rng.random_range(0.5..1.0),
                    0.0,
                    rng.random_range(-0.6..0.6),
                ),
            };
            if omni {
                target.vy = rng.random_range(-v..v);
            }
            if legged {
                target.omega *= 0.3;
            }
        }
        if t > cfg.duration_s - 1.5 {
            target = Twist::new(0.0, 0.0, 0.0);
        }
        let step = |c: f64, g: f64, lim: f64| c + (g - c).clamp(-lim * dt, lim * dt);
        cur = Twist::new(
            step(cur.vx, target.vx, a),
            step(cur.vy, target.vy, a),
            step(cur.omega, target.omega, alpha),
        );
        out.push(cur);
        t += dt;
    }
    out
}

/// The generated recording and the true path at the pose rows.
pub struct Generated {
    pub recording: Recording,
    pub truth_xy: Vec<(f64, f64)>,
}

pub fn generate(cfg: &Config) -> Generated {
    let mut rng = ChaCha8Rng::seed_from_u64(cfg.seed);
    let robot = &cfg.robot;
    let nw = robot.wheels.len();
    let sub = 1e-3; // physics step
    let per_row = (1.0 / cfg.rate_hz / sub).round() as usize;
    let prof = profile(cfg, &mut rng, sub);
    let nominal = Kinematics::<f64>::new(robot, &Corrections::None).unwrap();
    // True geometry.
    let mut true_robot = robot.clone();
    for tr in &cfg.truths {
        match tr {
            Truth::Ed(ed) => {
                for w in true_robot.wheels.iter_mut() {
                    w.radius_m *= calib_core::umbmark::wheel_factor(w, *ed);
                }
            }
            Truth::RadiusScales(s) => {
                for (w, s) in true_robot.wheels.iter_mut().zip(s) {
                    w.radius_m *= s;
                }
            }
            Truth::Eb(eb) => {
                for w in true_robot.wheels.iter_mut() {
                    w.l_m *= eb;
                }
            }
            _ => {}
        }
    }
    let truth = Kinematics::<f64>::new(&true_robot, &Corrections::None).unwrap();
    let get = |f: fn(&Truth) -> Option<f64>| cfg.truths.iter().find_map(f);
    let deadband = get(|t| {
        if let Truth::Deadband(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let lag = get(|t| {
        if let Truth::Lag(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let max_acc = get(|t| {
        if let Truth::MissedSteps(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let backlash = get(|t| {
        if let Truth::Backlash(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let mu = get(|t| if let Truth::Mu(v) = t { Some(*v) } else { None });
    let side = get(|t| {
        if let Truth::SideSlip(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let tilt = get(|t| {
        if let Truth::Tilt(v) = t {
            Some(*v)
        } else {
            None
        }
    });
    let bumps = cfg.truths.iter().find_map(|t| {
        if let Truth::Bumps { spacing, loss } = t {
            Some((*spacing, *loss))
        } else {
            None
        }
    });
    let share = robot.wheels.iter().filter(|w| w.driven).count() as f64 / nw as f64;
    let rad_per_count = robot.drive.rad_per_count().unwrap_or(1e-3);
    let enc_offset: Vec<i64> = (0..nw).map(|_| rng.random_range(-5000..5000)).collect();
    let pose_noise = Normal::new(0.0, cfg.pose_noise_m).unwrap();
    let head_noise = Normal::new(0.0, cfg.heading_noise_rad).unwrap();

    let mut rec = Recording::new(robot, cfg.with_cmd, cfg.with_enc);
    let mut rate = vec![0.0; nw]; // wheel rate after lag / step loss
    let mut motor = vec![0.0; nw];
    let mut wheel = vec![0.0; nw];
    let (mut x, mut y, mut th) = (
        rng.random_range(-0.5..0.5),
        rng.random_range(-0.5..0.5),
        rng.random_range(-3.0..3.0f64),
    );
    let mut owed = vec![0.0f64; nw];
    let mut contact: Option<Vec<f64>> = None;
    let radii: Vec<f64> = true_robot.wheels.iter().map(|w| w.radius_m).collect();
    let pos: Vec<(f64, f64)> = true_robot.wheels.iter().map(|w| w.position()).collect();
    let dirs: Vec<(f64, f64)> = true_robot
        .wheels
        .iter()
        .map(|w| {
            let r = w.rolling_row();
            (r[0], r[1])
        })
        .collect();
    let mut next_pose = 0.0;
    let mut truth_xy = Vec::new();
    let mut held_cmd = vec![0.0; nw];
    let mut last_cmd = vec![0.0; nw];
    for (i, tw) in prof.iter().enumerate() {
        let tnow = i as f64 * sub;
        if i % per_row == 0 {
            // A row: the controller samples its command and the encoders.
            held_cmd = nominal.inverse(tw).to_vec();
            let enc: Vec<i64> = wheel
                .iter()
                .zip(&enc_offset)
                .map(|(a, o)| (a / rad_per_count).floor() as i64 + o)
                .collect();
            let pose = if tnow + 1e-9 >= next_pose {
                next_pose += 1.0 / cfg.pose_rate_hz;
                truth_xy.push((x, y));
                Some((
                    x + pose_noise.sample(&mut rng),
                    y + pose_noise.sample(&mut rng),
                    th + head_noise.sample(&mut rng),
                ))
            } else {
                None
            };
            rec.push_row(Row {
                t: tnow,
                cmd: Some(&held_cmd),
                enc: Some(&enc),
                pose,
                legs: None,
            });
        }
        // Actuators (Euler at 1 kHz).
        let mut wheel_inc = vec![0.0; nw];
        for j in 0..nw {
            let mut c = held_cmd[j];
            if deadband.is_some_and(|d| c.abs() < d) {
                c = 0.0;
            }
            let mut r = match lag {
                Some(tau) => rate[j] + (c - rate[j]) * sub / tau,
                None => c,
            };
            if let Some(a) = max_acc {
                // Pull-out: the rotor cannot follow faster changes; steps are lost.
                r = rate[j] + (r - rate[j]).clamp(-a * sub, a * sub);
            }
            let inc = r * sub;
            rate[j] = r;
            motor[j] += inc;
            let before = wheel[j];
            match backlash {
                Some(b) => {
                    if motor[j] - wheel[j] > b / 2.0 {
                        wheel[j] = motor[j] - b / 2.0;
                    } else if wheel[j] - motor[j] > b / 2.0 {
                        wheel[j] = motor[j] + b / 2.0;
                    }
                }
                None => wheel[j] = motor[j],
            }
            wheel_inc[j] = wheel[j] - before;
        }
        let _ = &mut last_cmd;
        // Ground: per-wheel contact travel (cables take their toll, traction bounds the
        // contact acceleration), least-squares body twist, side slip, tilt drift.
        let mut disp: Vec<f64> = (0..nw).map(|j| radii[j] * wheel_inc[j]).collect();
        for j in 0..nw {
            if owed[j] > 0.0 && disp[j] != 0.0 {
                let take = owed[j].min(disp[j].abs());
                disp[j] -= take.copysign(disp[j]);
                owed[j] -= take;
            }
        }
        if let Some(mu) = mu {
            let a = mu * 9.80665 * share;
            let c = contact.get_or_insert_with(|| disp.iter().map(|d| d / sub).collect());
            for j in 0..nw {
                let want = disp[j] / sub;
                c[j] += (want - c[j]).clamp(-a * sub, a * sub);
                disp[j] = c[j] * sub;
            }
        }
        let ang: Vec<f64> = (0..nw).map(|j| disp[j] / radii[j]).collect();
        let mut d = truth.forward(&ang);
        if let Some(k) = side {
            d.vy -= k * (d.vx / sub) * (d.omega / sub) * sub;
        }
        let moving = wheel_inc.iter().any(|v| *v != 0.0);
        let before = (x, y, th);
        // Exact arc in the world frame.
        let (s, c) = th.sin_cos();
        let (dx, dy) = if d.omega.abs() > 1e-12 {
            let r1 = d.omega.sin() / d.omega;
            let r2 = (1.0 - d.omega.cos()) / d.omega;
            (r1 * d.vx - r2 * d.vy, r2 * d.vx + r1 * d.vy)
        } else {
            (d.vx, d.vy)
        };
        x += c * dx - s * dy;
        y += s * dx + c * dy;
        th += d.omega;
        if let (Some(v), true) = (tilt, moving) {
            y += v * sub;
        }
        if let Some((spacing, loss)) = bumps {
            for j in 0..nw {
                let (bx, by) = pos[j];
                let wx0 = before.0 + before.2.cos() * bx - before.2.sin() * by;
                let wx1 = x + th.cos() * bx - th.sin() * by;
                let k = ((wx1 / spacing).floor() - (wx0 / spacing).floor()).abs();
                if k > 0.0 {
                    let along = (th.cos() * dirs[j].0 - th.sin() * dirs[j].1).abs();
                    owed[j] += k * loss * along;
                }
            }
        }
    }
    let _ = rng.random::<u8>();
    Generated {
        recording: rec,
        truth_xy,
    }
}
