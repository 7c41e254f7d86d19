//! How `calibrate`'s laws fare held out by session and by kind of motion on the real
//! robots (`shared/real/sessions/`), laws on and off (issue 56 §1):
//! - each robot's runs all together (differential: 164, omni3: 67, mecanum: 68): the law
//!   tests' held-out errors per session and per kind left out (`law_tests`' `by_session`
//!   and `by_kind`: the constant model and the law fitted without it), mean, median and
//!   worst, and what was kept;
//! - the differential robot with each kind of motion, and each month, kept apart: the
//!   board (its factors and laws) against the same calibration's constant geometry (the
//!   robot file) on the runs kept apart.
//!
//!     cargo run --release -p calibrate --example laws_by_session_and_kind [-- --sessions DIR]

#[path = "../tests/support/proxy.rs"]
mod proxy;

fn main() {
    let dir = proxy::sessions_dir_from_args();
    let fail = |e: String| -> ! {
        eprintln!("{e}");
        std::process::exit(1)
    };
    println!("| robot | runs | law | decided | held out by | groups | constant: mean / median / worst (mm) | law: mean / median / worst (mm) | law holds out on | kept |");
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for robot in ["diff", "omni3", "omni4"] {
        let (nominal, recs) = proxy::robot_runs(&dir, robot, |_| true).unwrap_or_else(|e| fail(e));
        let t0 = std::time::Instant::now();
        let c = calibrate::calibrate(&nominal, &recs, None, &calibrate::CalOptions::default())
            .unwrap_or_else(|e| fail(e.to_string()));
        eprintln!(
            "{robot}: {} runs calibrated in {:.2} s",
            recs.len(),
            t0.elapsed().as_secs_f64()
        );
        for t in &c.law_tests {
            for (by, groups) in [("session", &t.by_session), ("kind", &t.by_kind)] {
                let mm = |v: Vec<f64>| {
                    let (a, b, w) = proxy::mean_median_worst(&v);
                    format!("{:.1} / {:.1} / {:.1}", a * 1e3, b * 1e3, w * 1e3)
                };
                let won = groups
                    .iter()
                    .filter(|g| g.law_m <= calibrate::TURN_LAW_HOLDOUT_RATIO * g.constant_m)
                    .count();
                println!(
                    "| {robot} | {} | {} {:+.4} | {} | {by} | {} | {} | {} | {won} of {} | {} |",
                    recs.len(),
                    t.law,
                    t.value,
                    t.decided,
                    groups.len(),
                    mm(groups.iter().map(|g| g.constant_m).collect()),
                    mm(groups.iter().map(|g| g.law_m).collect()),
                    groups.len(),
                    t.kept
                );
            }
            if robot == "diff" {
                for g in &t.by_kind {
                    eprintln!(
                        "  {} law, {} kept apart: {:.1} mm constant, {:.1} mm law",
                        t.law,
                        g.group,
                        g.constant_m * 1e3,
                        g.law_m * 1e3
                    );
                }
            }
        }
    }
    // The bench: calibrate as the command line runs it (cross-validation by run), on
    // every run of the differential robot, three times.
    let (nominal, recs) = proxy::robot_runs(&dir, "diff", |_| true).unwrap_or_else(|e| fail(e));
    let opts = calibrate::CalOptions {
        leave_one_out: true,
        ..Default::default()
    };
    let mut times = Vec::new();
    for _ in 0..3 {
        let t0 = std::time::Instant::now();
        calibrate::calibrate(&nominal, &recs, None, &opts).unwrap_or_else(|e| fail(e.to_string()));
        times.push(t0.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    eprintln!(
        "bench: calibrate with cross-validation by run on {} runs: {:.2} s median ({:.2}-{:.2})",
        recs.len(),
        times[1],
        times[0],
        times[2]
    );
    println!("\n| trained on | runs | kept apart | runs | law kept | board (mm) | constant geometry (mm) | board / constant | calibrate (s) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for (k, _) in proxy::kept_apart_sets(&dir).unwrap_or_else(|e| fail(e)) {
        let law = k
            .law
            .as_ref()
            .map_or("none".to_string(), |(n, v)| format!("{n} {v:+.4}"));
        println!(
            "| {} | {} | {} | {} | {law} | {:.2} | {:.2} | {:.3} | {:.2} |",
            k.training,
            k.train_runs,
            k.tested,
            k.test_runs,
            k.board_m * 1e3,
            k.constant_m * 1e3,
            k.ratio(),
            k.seconds
        );
    }
}
