//! Issue 21's held-out proxy on `shared/real/sessions/` (see `diagnose::calibrate::proxy`):
//! the geometry `calibrate` fits on a square session, dead-reckoned from the first row on
//! the circles and Ivanjko paths of the nearest day, against the OptiOdom authors'
//! parameters from the same session. Goal: no session above the authors
//! (ratio <= 1.0), geometric mean of the ratios <= 0.94. Skipped when the data are absent.
//! Baseline (start pose and clocks fitted per recording, as first built): geometric mean
//! 1.112, worst 1.259. With the dead-reckoning objective and events kept out: 1.004, worst
//! 1.079 (the ignored whole-proxy test fails: the goal is not met).

use diagnose::calibrate::{calibrate, proxy, CalOptions};
use std::path::PathBuf;

fn dir() -> Option<PathBuf> {
    let d = proxy::sessions_dir(&PathBuf::from(env!("CARGO_MANIFEST_DIR")));
    if d.is_none() {
        eprintln!("skipping: shared/real/sessions is absent");
    }
    d
}

fn train(
    robot: &calib_core::robot::Robot,
    recs: &[(String, formats::recording::Recording)],
) -> Result<calib_core::robot::Robot, String> {
    calibrate(robot, recs, None, &CalOptions::default())
        .map(|c| c.fitted_robot)
        .map_err(|e| e.to_string())
}

/// Fast subset: one two-run December session (the worst-transferring kind at baseline:
/// 1.22; 1.18 on this subset) against 12 of its 46 test runs. Must not lose to the
/// authors.
#[test]
fn one_december_session_transfers_no_worse_than_optiodom() {
    let Some(d) = dir() else { return };
    let r = proxy::run_diff(&d, Some(&["231220200045"]), Some(12), &train).unwrap();
    print!("{}", proxy::table(&r));
    assert_eq!(r.len(), 1);
    assert_eq!(r[0].tests.len(), 12);
    assert!(r[0].ratio() <= 1.0, "ratio {:.3}", r[0].ratio());
}

/// Every square session against every paired test run (about 4 s in release).
#[test]
#[ignore = "the whole proxy: run with --release -- --ignored"]
fn every_square_session_beats_optiodom() {
    let Some(d) = dir() else { return };
    let r = proxy::run_diff(&d, None, None, &train).unwrap();
    print!("{}", proxy::table(&r));
    assert_eq!(r.len(), 8);
    for s in &r {
        assert!(s.ratio() <= 1.0, "{}: ratio {:.3}", s.session, s.ratio());
    }
    let g = proxy::geometric_mean_ratio(&r);
    assert!(g <= 0.94, "geometric mean {g:.3}");
}
