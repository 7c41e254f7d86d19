//! Bench binary (not criterion: one run takes seconds): diagnoses a 10-minute, 200 Hz
//! recording of [Redundant omni]'s 4-wheel omni robot (120,000 rows, 30 Hz vision) simulated by the
//! `sim` crate with two wheel radius errors and motor lag hidden in it, and prints the
//! wall time of each run.
//!
//!     cargo bench -p diagnose --features bench

use calib_core::robot::presets;
use sim::{record, Effect, Motion, RandomMotion, RecordConfig, Surface};
use std::time::Instant;

fn main() {
    let robot = presets::omni4();
    let effects = [
        Effect::parse("wheel_diameter_mismatch=radius_scale_w1:1.01,radius_scale_w4:0.995")
            .expect("effect"),
        Effect::parse("motor_lag=tau_s:0.05").expect("effect"),
    ];
    let mut cfg = RecordConfig::default();
    cfg.sim.seed = 42;
    cfg.row_rate_hz = 200.0;
    let motion = Motion::Random(RandomMotion {
        duration_s: 600.0,
        v_max_m_s: 0.15,
        ..RandomMotion::default()
    });
    let rec = record(&robot, &effects, Surface::flat(), &motion, &cfg)
        .expect("simulated")
        .recording;
    assert!(rec.len() >= 120_000, "{} rows", rec.len());
    let mut times = Vec::new();
    for run in 0..3 {
        let t0 = Instant::now();
        let r =
            diagnose::diagnose(&robot, &rec, &diagnose::Options::default()).expect("diagnosable");
        let dt = t0.elapsed().as_secs_f64();
        times.push(dt);
        println!(
            "run {run}: {dt:.2} s, verdict {}, findings {:?}, ground RMSE {:.2} -> {:.2} mm, model runs {} ground + {} actuator",
            r.verdict,
            r.findings.iter().map(|f| f.effect.as_str()).collect::<Vec<_>>(),
            r.rmse.ground.before_m * 1e3,
            r.rmse.ground.after_m * 1e3,
            r.model_runs_ground,
            r.model_runs_actuator
        );
    }
    times.sort_by(|a, b| a.total_cmp(b));
    println!(
        "diagnose {} rows x 4 wheels: min {:.2} s, median {:.2} s (goal < 10 s)",
        rec.len(),
        times[0],
        times[1]
    );
}
