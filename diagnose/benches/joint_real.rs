//! Bench binary: joint diagnosis of the six real UMBmark squares of data/real
//! (OptiOdom differential robot, about 8,300 rows): shared geometry with leave-one-out,
//! each square's own fit for the evidence table, and each square diagnosed against the
//! shared geometry. Prints the wall time of each run; the goal is under 5 s.
//!
//!     cargo bench -p diagnose --features bench --bench joint_real

use formats::recording::Recording;
use std::time::Instant;

fn main() {
    let base = testdata::real_dir();
    let robot = formats::robot_file::load(&base.join("diff-square-run-01/robot.toml")).unwrap();
    let recs: Vec<(String, Recording)> = (1..=6)
        .map(|i| {
            let name = format!("diff-square-run-0{i}");
            let rec = Recording::load(&base.join(&name).join("recording.csv"), &robot).unwrap();
            (name, rec)
        })
        .collect();
    let rows: usize = recs.iter().map(|(_, r)| r.len()).sum();
    let mut times = Vec::new();
    for run in 0..3 {
        let t0 = Instant::now();
        let r = diagnose::multi::diagnose_many(&robot, &recs, &diagnose::Options::default())
            .expect("diagnosable");
        let dt = t0.elapsed().as_secs_f64();
        times.push(dt);
        println!(
            "run {run}: {dt:.2} s for {rows} rows, joint RMSE {:.2} -> {:.2} mm",
            r.joint_rmse_nominal_m * 1e3,
            r.joint_rmse_shared_geometry_m * 1e3
        );
    }
    times.sort_by(|a, b| a.total_cmp(b));
    println!("median {:.2} s (goal < 5 s)", times[1]);
}
