//! Helpers for the closed-loop tests in `tests/`: calib-core's motion programs, step
//! generation and odometry driving the simulator the way the firmware will.

use calib_core::correction::Corrections;
use calib_core::encoder::{CounterExtender, CounterWidth};
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::motion::{ProfileLimits, Program};
use calib_core::odometry::{Odometry, Pose};
use calib_core::robot::{DriveType, Robot};
use calib_core::stepper::StepAccumulator;
use sim::{SimRobot, WheelInput};
use std::path::Path;

/// Loads `robots/<name>.toml` from the workspace.
pub fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    match formats::robot_file::load(&p) {
        Ok(r) => r,
        Err(e) => panic!("{e}"),
    }
}

/// `p` relative to `start`, in the frame of `start` rotated by `extra_rad` (x along the
/// first commanded direction).
pub fn in_frame(start: Pose<f64>, extra_rad: f64, p: (f64, f64)) -> (f64, f64) {
    let (s, c) = (start.theta + extra_rad).sin_cos();
    let (dx, dy) = (p.0 - start.x, p.1 - start.y);
    (c * dx + s * dy, -s * dx + c * dy)
}

/// The board's side of a run: commands from a program through the (corrected)
/// kinematics, steps from calib-core's step accumulator on stepper drives (ideal rates
/// otherwise), and odometry from the 16-bit encoder counters through the same kinematics.
pub struct Board {
    kin: Kinematics<f64>,
    steppers: Vec<StepAccumulator>,
    ext: Vec<CounterExtender>,
    rad_per_count: f64,
    /// Dead reckoning from the encoder counters through the same kinematics.
    pub odometry: Odometry<f64>,
    rates: Vec<f64>,
    inc: Vec<f64>,
    inputs: Vec<WheelInput>,
}

impl Board {
    /// A board for the simulator's nominal robot with `corr` applied to its kinematics,
    /// odometry starting at `start` and the counters at the simulator's current readings.
    pub fn new(sim: &SimRobot, corr: &Corrections, start: Pose<f64>) -> Self {
        let robot = sim.nominal();
        let n = robot.wheel_count();
        let kin = Kinematics::<f64>::new(robot, corr).expect("robot geometry is valid");
        let steppers = if robot.drive.kind == DriveType::Stepper {
            (0..n)
                .map(|_| StepAccumulator::new(robot.drive.steps_per_wheel_rad()))
                .collect()
        } else {
            Vec::new()
        };
        Board {
            kin,
            steppers,
            ext: (0..n)
                .map(|i| CounterExtender::new(CounterWidth::Bits16, sim.encoder_raw(i) as u32))
                .collect(),
            rad_per_count: std::f64::consts::TAU / robot.drive.encoder_counts_per_rev,
            odometry: Odometry::new(start),
            rates: vec![0.0; n],
            inc: vec![0.0; n],
            inputs: vec![WheelInput::Rate(0.0); n],
        }
    }

    /// One control tick: command `twist`, step the simulator, update odometry.
    pub fn tick(&mut self, sim: &mut SimRobot, twist: &Twist<f64>, dt: f64) {
        self.kin.inverse_into(twist, &mut self.rates);
        for (i, inp) in self.inputs.iter_mut().enumerate() {
            *inp = match self.steppers.get_mut(i) {
                Some(acc) => WheelInput::Steps(acc.advance(self.rates[i] as f32, dt as f32)),
                None => WheelInput::Rate(self.rates[i]),
            };
        }
        sim.step(dt, &self.inputs).expect("inputs match the robot");
        for (i, e) in self.ext.iter_mut().enumerate() {
            self.inc[i] = e.update(sim.encoder_raw(i) as u32) as f64 * self.rad_per_count;
        }
        self.odometry.update(&self.kin.forward(&self.inc));
    }

    /// Runs a whole program at 1 kHz.
    pub fn run(&mut self, sim: &mut SimRobot, program: &Program, limits: ProfileLimits) {
        let dt = 1e-3;
        let mut runner = program.runner(limits);
        while let Some(t) = runner.twist_at_tick(dt) {
            self.tick(sim, &t, dt);
        }
        // Let the last tick's motion settle (steppers finish their steps).
        for _ in 0..50 {
            self.tick(sim, &Twist::zero(), dt);
        }
    }
}
