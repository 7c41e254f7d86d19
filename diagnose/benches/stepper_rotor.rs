//! Bench binary: one replay of a stepper wheel with pull-out (`missed_steps`' default
//! mechanism, the rotor sub-stepped at 1 ms) over 1,000,000 rows at 7 ms, a command that
//! swings over the acceleration limit twice a second, so most rows are sub-stepped.
//! The pull-out fit made of these replays was the longest of round 0's fits on the
//! 3.6 M-row diagnose bench (8.9 s of its 10 s, BENCHMARKS.md). Prints the best of seven
//! runs.
//!
//!     cargo bench -p diagnose --features bench --bench stepper_rotor

use diagnose::actuator::{simulate_wheel, ActuatorParams};
use std::time::Instant;

fn main() {
    let n = 1_000_000;
    let t: Vec<f64> = (0..n).map(|k| k as f64 * 0.007).collect();
    let cmd: Vec<f64> = t
        .iter()
        .map(|s| 6.0 * (s * 0.5).sin() + 2.0 * (s * 3.0).sin().signum())
        .collect();
    // mobolab's steppers: 200 full steps per motor revolution through 4.875:1 gears, so
    // four full steps are 2 pi / 50 / 4.875 rad of wheel; the pull-out limit the 3.6 M-row
    // bench fits (18.84 rad/s²).
    let p = ActuatorParams {
        max_accel_rad_s2: Some(18.84),
        step_cycle_rad: Some(2.0 * std::f64::consts::PI / 50.0 / 4.875),
        ..Default::default()
    };
    let mut out = Vec::new();
    let mut best = f64::INFINITY;
    for _ in 0..7 {
        let t0 = Instant::now();
        simulate_wheel(&t, &cmd, &p, &mut out);
        best = best.min(t0.elapsed().as_secs_f64());
    }
    println!(
        "stepper rotor, {n} rows: best {:.1} ms (final angle {:.6} rad)",
        best * 1e3,
        out[n - 1]
    );
}
