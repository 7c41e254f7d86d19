//! Simulated seconds per wall-clock second: omni4 ([Redundant omni]) at 1 kHz control with
//! DC motor dynamics, calib-core's PI velocity loop closing each wheel on its encoder, and
//! the [Redundant omni] cable strip (5 mm cables every 30 mm) under the wheels.
//!
//! One iteration simulates 10 s (10 000 ticks) of [Redundant omni]'s 4W-1 path back and forth;
//! criterion reports the time per iteration, so real-time factor = 10 s / that time.

use calib_core::control::PiController;
use calib_core::correction::Corrections;
use calib_core::encoder::{CounterExtender, CounterWidth};
use calib_core::kinematics::{Kinematics, Twist};
use criterion::{criterion_group, criterion_main, Criterion};
use sim::{Effect, SimConfig, SimRobot, Surface, WheelInput};
use std::hint::black_box;
use std::path::Path;

const TICKS: usize = 10_000;

fn run_10s(robot: &calib_core::Robot, effects: &[Effect]) -> f64 {
    let mut sim = SimRobot::with_effects(robot, effects, Surface::flat(), SimConfig::default())
        .expect("valid setup");
    let k = Kinematics::<f64>::new(robot, &Corrections::None).expect("valid robot");
    let gains = sim.pi_gains();
    let mut pi = [PiController::new(gains); 4];
    let mut ext: [CounterExtender; 4] = core::array::from_fn(|i| {
        CounterExtender::new(CounterWidth::Bits16, sim.encoder_raw(i) as u32)
    });
    let rad_per_count = std::f64::consts::TAU / robot.drive.encoder_counts_per_rev;
    let mut speed = [0.0f64; 4];
    let mut set = [0.0f64; 4];
    let mut inputs = [WheelInput::Duty(0.0); 4];
    let dt = 1e-3;
    for tick in 0..TICKS {
        // 0.15 m/s along +x for 5 s, then back.
        let v = if tick < TICKS / 2 { 0.15 } else { -0.15 };
        k.inverse_into(&Twist::new(v, 0.0, 0.0), &mut set);
        for i in 0..4 {
            let d = ext[i].update(sim.encoder_raw(i) as u32) as f64 * rad_per_count / dt;
            // Encoder speed at 1 kHz is coarse (3.3 rad/s per count): low-pass 10 ms.
            speed[i] += 0.1 * (d - speed[i]);
            inputs[i] =
                WheelInput::Duty(pi[i].update(set[i] as f32, speed[i] as f32, dt as f32) as f64);
        }
        sim.step(dt, &inputs).expect("valid inputs");
    }
    sim.true_pose().x
}

fn bench(c: &mut Criterion) {
    let robot = formats::robot_file::load(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/omni4.toml"),
    )
    .expect("robots/omni4.toml");
    let effects =
        [Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0018").expect("valid effect")];
    let mut g = c.benchmark_group("sim");
    g.sample_size(20);
    g.bench_function("omni4_dc_pi_cables_10s_at_1kHz", |b| {
        b.iter(|| black_box(run_10s(black_box(&robot), &effects)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
