//! Real recordings of ../shared/real (OptiOdom: a differential-drive UMBmark square and a
//! three-wheel omni square, encoders and motion capture). Skipped when the folder is
//! absent. The fit must improve the ground RMSE substantially: the README says these
//! robots have real systematic errors (25 mm end error, 3.6 % over-rotation).

use diagnose::{diagnose, Options};
use formats::recording::Recording;
use std::path::PathBuf;

fn run(folder: &str) -> Option<diagnose::Report> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../shared/real")
        .join(folder);
    if !dir.exists() {
        eprintln!("skipping: {} is absent", dir.display());
        return None;
    }
    let robot = formats::robot_file::load(&dir.join("robot.toml")).expect("robot file");
    let rec = Recording::load(&dir.join("recording.csv"), &robot).expect("recording");
    let r = diagnose(&robot, &rec, &Options::default()).expect("diagnosable");
    println!("{r}");
    if let Ok(out) = std::env::var("DIAG_REPORT_DIR") {
        diagnose::plots::write_report_dir(&r, &PathBuf::from(out).join(folder)).unwrap();
    }
    Some(r)
}

#[test]
fn diff_square_fit_improves() {
    let Some(r) = run("diff-square-run-01") else {
        return;
    };
    assert!(!r.findings.is_empty(), "a systematic error is found");
    // Motion capture is sub-millimetre, so what is left after the fit is unmodelled
    // motion; the geometric fit must still remove at least half of the RMSE.
    assert!(
        r.rmse_final_m < 0.5 * r.rmse_nominal_m,
        "{} -> {}",
        r.rmse_nominal_m,
        r.rmse_final_m
    );
}

#[test]
fn omni3_square_fit_improves() {
    let Some(r) = run("omni3-square-run-01") else {
        return;
    };
    assert!(!r.findings.is_empty(), "a systematic error is found");
    assert!(
        r.rmse_final_m < 0.5 * r.rmse_nominal_m,
        "{} -> {}",
        r.rmse_nominal_m,
        r.rmse_final_m
    );
}
