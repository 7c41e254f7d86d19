//! Bench binary (not criterion: one run takes seconds): diagnoses a 10-minute, 200 Hz
//! recording of the 4-wheel omni robot (120,000 rows, 30 Hz vision) with a wheel radius
//! error and motor lag hidden in it, and prints the wall time of each run.
//!
//!     cargo bench -p diagnose

#[path = "../tests/common/mod.rs"]
mod common;

use calib_core::robot::presets;
use common::{generate, Config, Truth};
use std::time::Instant;

fn main() {
    let mut cfg = Config::new(presets::omni4(), 42);
    cfg.duration_s = 599.999; // 600 s at 200 Hz: rows 0 .. 119,999
    cfg.rate_hz = 200.0;
    cfg.pose_rate_hz = 30.0;
    cfg.speed = 0.15;
    cfg.truths = vec![
        Truth::RadiusScales(vec![1.01, 0.99, 1.0, 1.005]),
        Truth::Lag(0.05),
    ];
    let g = generate(&cfg);
    let rec = g.recording;
    assert_eq!(rec.len(), 120_000, "rows");
    let mut times = Vec::new();
    for run in 0..3 {
        let t0 = Instant::now();
        let r = diagnose::diagnose(&cfg.robot, &rec, &diagnose::Options::default())
            .expect("diagnosable");
        let dt = t0.elapsed().as_secs_f64();
        times.push(dt);
        println!(
            "run {run}: {dt:.2} s, verdict {}, findings {:?}, rmse {:.2} -> {:.2} mm, model runs {} ground + {} actuator",
            r.verdict,
            r.findings
                .iter()
                .map(|f| f.effect.as_str())
                .collect::<Vec<_>>(),
            r.rmse_nominal_m * 1e3,
            r.rmse_final_m * 1e3,
            r.model_runs_ground,
            r.model_runs_actuator
        );
    }
    times.sort_by(|a, b| a.total_cmp(b));
    println!(
        "diagnose 120000 rows x 4 wheels: min {:.2} s, median {:.2} s (goal < 10 s)",
        times[0], times[1]
    );
}
