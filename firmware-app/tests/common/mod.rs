//! A simple wheel plant for the application's host tests: first-order DC motors or ideal
//! steppers, quadrature counters read through 16-bit timers, and the true body motion
//! integrated from the true wheel rotation through the *true* geometry (which may differ
//! from what the firmware believes).
#![allow(dead_code)]

use calib_core::encoder::CounterWidth;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{integrate_arc, Pose};
use calib_core::protocol::{BootReport, Params, Stored};
use calib_core::robot::{DriveType, Robot, MAX_WHEELS};
use calib_core::{Corrections, Twist};
use firmware_app::{App, EncoderSource, WheelDriver};

pub const LOG: usize = 16 * 1024;
pub const DT: f64 = 1e-3;

/// Motor: tau dw/dt = K u - w - load sign(w), K = 20 rad/s at full duty, tau = 50 ms.
pub const K: f64 = 20.0;
pub const TAU: f64 = 0.05;

pub struct Encoders {
    pub angle: [f64; MAX_WHEELS],
    pub rad_per_count: f64,
    /// A stuck encoder keeps returning this raw value.
    pub frozen: [Option<u32>; MAX_WHEELS],
    /// Counts added to the reading (a glitch).
    pub glitch: [i64; MAX_WHEELS],
}

impl Encoders {
    pub fn counts(&self, i: usize) -> i64 {
        (self.angle[i] / self.rad_per_count).floor() as i64 + self.glitch[i]
    }
}

impl EncoderSource for Encoders {
    fn width(&self) -> CounterWidth {
        CounterWidth::Bits16
    }
    fn raw(&mut self, i: usize) -> u32 {
        if let Some(r) = self.frozen[i] {
            return r;
        }
        // A 16-bit timer starting at 30000 so the test crosses wraps.
        (self.counts(i) + 30_000).rem_euclid(65_536) as u32
    }
}

#[derive(Default)]
pub struct Motors {
    pub duty: [f32; MAX_WHEELS],
    pub steps: [i32; MAX_WHEELS],
    pub stop_all_calls: u32,
}

impl WheelDriver for Motors {
    fn set_duty(&mut self, wheel: usize, duty: f32) {
        self.duty[wheel] = duty;
    }
    fn set_steps(&mut self, wheel: usize, _steps_per_s: f32, steps: i32) {
        self.steps[wheel] = steps;
    }
    fn stop_all(&mut self) {
        self.duty = [0.0; MAX_WHEELS];
        self.steps = [0; MAX_WHEELS];
        self.stop_all_calls += 1;
    }
}

pub struct Bench {
    pub app: App<'static>,
    pub enc: Encoders,
    pub mot: Motors,
    pub omega: [f64; MAX_WHEELS],
    pub t_us: u64,
    pub pose: Pose<f64>,
    pub load: f64,
    true_kin: Kinematics<f64>,
    n: usize,
    dc: bool,
    steps_per_rad: f64,
}

pub fn boot() -> BootReport {
    BootReport {
        corrections: Stored::Loaded,
        params: Stored::Loaded,
    }
}

impl Bench {
    /// The firmware believes `params` and `corrections`; the robot really is
    /// `true_robot`.
    pub fn new(params: Params, corrections: Corrections, true_robot: &Robot) -> Self {
        let n = params.robot.wheel_count();
        let rpc = params.robot.drive.rad_per_count().unwrap_or(1e-3);
        Bench {
            dc: params.robot.drive.kind == DriveType::Dc,
            steps_per_rad: params.robot.drive.steps_per_wheel_rad(),
            app: App::new(params, corrections, boot(), vec![0u8; LOG].leak(), 0),
            enc: Encoders {
                angle: [0.0; MAX_WHEELS],
                rad_per_count: rpc,
                frozen: [None; MAX_WHEELS],
                glitch: [0; MAX_WHEELS],
            },
            mot: Motors::default(),
            omega: [0.0; MAX_WHEELS],
            t_us: 0,
            pose: Pose::default(),
            load: 0.0,
            true_kin: Kinematics::new(true_robot, &Corrections::None).unwrap(),
            n,
        }
    }

    /// One control tick, then the plant moves for one period under its outputs.
    pub fn tick(&mut self) {
        self.app.tick(self.t_us, &mut self.enc, &mut self.mot);
        let mut dphi = [0.0; MAX_WHEELS];
        for (i, d) in dphi.iter_mut().enumerate().take(self.n) {
            if self.dc {
                // 10 Euler substeps: the motor's 50 ms constant is resolved finely.
                let h = DT / 10.0;
                for _ in 0..10 {
                    let w = self.omega[i];
                    let fric = if w.abs() > 1e-9 {
                        self.load * w.signum()
                    } else {
                        0.0
                    };
                    self.omega[i] += h / TAU * (K * self.mot.duty[i] as f64 - w - fric);
                    *d += self.omega[i] * h;
                }
            } else {
                *d = self.mot.steps[i] as f64 / self.steps_per_rad;
                self.omega[i] = *d / DT;
            }
            self.enc.angle[i] += *d;
        }
        let disp = self.true_kin.forward(&dphi[..self.n]);
        self.pose = integrate_arc(self.pose, &disp);
        self.t_us += 1000;
    }

    pub fn run_ms(&mut self, ms: u64) {
        for _ in 0..ms {
            self.tick();
        }
    }

    pub fn now(&self) -> u64 {
        self.t_us
    }
}

/// Where calib-core says the robot ends: the program's per-tick twists turned into wheel
/// commands by the firmware's (corrected) kinematics, executed exactly by the true robot.
pub fn predicted_end(
    program: &calib_core::motion::Program,
    params: &Params,
    corrections: &Corrections,
    true_robot: &Robot,
) -> Pose<f64> {
    let cmd = Kinematics::<f64>::new(&params.robot, corrections).unwrap();
    let truth = Kinematics::<f64>::new(true_robot, &Corrections::None).unwrap();
    let mut r = program.runner(params.limits);
    let mut pose = Pose::default();
    let mut w = [0.0; MAX_WHEELS];
    let n = params.robot.wheel_count();
    while let Some(t) = r.twist_at_tick(DT) {
        cmd.inverse_into(&Twist::new(t.vx * DT, t.vy * DT, t.omega * DT), &mut w[..n]);
        pose = integrate_arc(pose, &truth.forward(&w[..n]));
    }
    pose
}
