//! Bench binary: `diagnose` on many real recordings at once (issue 52: 48 recordings
//! took 112 s and 3.7 GB when the shared geometry was an aligned fit of all of them; goal
//! under 30 s and 500 MB). The first N differential-drive runs of the OptiOdom sessions
//! in name order (default 48), diagnosed jointly once; prints the wall time. Peak memory
//! from the shell:
//!
//!     WHEELCAL_SESSIONS=../shared/real/sessions /usr/bin/time -f "%e s %M KB" \
//!         cargo bench -p diagnose --features bench --bench joint_many -- 48

use formats::recording::Recording;
use std::time::Instant;

fn main() {
    let dir = match testdata::sessions_dir_if_set() {
        Ok(d) => d,
        Err(why) => {
            eprintln!("joint_many: {why}");
            std::process::exit(2);
        }
    };
    let n: usize = std::env::args()
        .skip(1)
        .find_map(|a| a.parse().ok())
        .unwrap_or(48);
    let mut runs: Vec<String> = std::fs::read_dir(&dir)
        .expect("the sessions folder")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|f| f.starts_with("diff-"))
        .collect();
    runs.sort();
    runs.truncate(n);
    let robot = formats::robot_file::load(&dir.join(&runs[0]).join("robot.toml")).unwrap();
    let recs: Vec<(String, Recording)> = runs
        .iter()
        .map(|r| {
            let rec = Recording::load(&dir.join(r).join("recording.csv"), &robot).unwrap();
            (r.clone(), rec)
        })
        .collect();
    let rows: usize = recs.iter().map(|(_, r)| r.len()).sum();
    let t0 = Instant::now();
    let r = diagnose::multi::diagnose_many(&robot, &recs, &diagnose::Options::default())
        .expect("diagnosable");
    println!(
        "{} recordings, {rows} rows: {:.2} s (goal < 30 s), joint aligned RMSE {:.2} -> {:.2} mm",
        recs.len(),
        t0.elapsed().as_secs_f64(),
        r.joint_rmse_nominal_m * 1e3,
        r.joint_rmse_shared_geometry_m * 1e3
    );
}
