//! `calibrate` with SLAM-like poses: centimetre noise, and a loop-closure jump.
//!
//! A SLAM trajectory is noisier than motion capture and jumps when it closes a loop. The
//! simulator's camera is set to 1 cm and 0.01 rad per sample at 10 Hz; one recording gets
//! a jump of (6 cm, -4 cm, 3 deg) at t = 30 s, applied to every pose after it, as a map
//! correction moves the whole rest of the trajectory.
//!
//! - Poses this noisy make calibrate fit each recording's start pose (dead reckoning from
//!   one pose sample of 1 cm and 0.01 rad tilts a whole recording: measured here, scale,
//!   E_d and E_b came out 8-11 sigma off the truth that way). It says so, and the geometry
//!   is the truth within 3 stated sigmas.
//! - The jump is reported as a `pose_jump` event at its time (within one pose sample,
//!   0.1 s), and the recording is split there, each part with its own start. The geometry
//!   fitted with the jump is then within 2 stated sigmas of the one fitted without it:
//!   the jump costs a sample, not an offset on the half of the recording after it.
//! - The notes state the pose noise the uncertainties assume: from the steps of the poses
//!   against the wheels' steps, within 20 % of the simulated 10 mm.
//! - A motion-capture recording (1 mm) reports no jump and keeps the dead-reckoning
//!   objective.

use calib_core::robot::Robot;
use calibrate::{calibrate, CalOptions, Calibration};
use formats::recording::Recording;
use sim::{record, Motion, RandomMotion, RecordConfig, Surface, VisionConfig};
use std::path::Path;

fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

const SLAM_SIGMA_M: f64 = 0.01;

fn run(truth: &Robot, seed: u64, vision: VisionConfig) -> Recording {
    let mut cfg = RecordConfig {
        row_rate_hz: 50.0,
        ..RecordConfig::default()
    };
    cfg.sim.seed = seed;
    cfg.sim.vision = vision;
    let motion = Motion::Random(RandomMotion {
        duration_s: 60.0,
        ..RandomMotion::default()
    });
    record(truth, &[], Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording
}

fn slam() -> VisionConfig {
    VisionConfig {
        rate_hz: 10.0,
        sigma_xy_m: SLAM_SIGMA_M,
        sigma_theta_rad: 0.01,
    }
}

/// Every pose from `t_s` on moved by (dx, dy) and turned by dth about the origin.
fn jump(rec: &mut Recording, t_s: f64, (dx, dy, dth): (f64, f64, f64)) {
    let (s, c) = dth.sin_cos();
    for i in 0..rec.t.len() {
        if rec.t[i] - rec.t[0] < t_s {
            continue;
        }
        if let (Some(x), Some(y), Some(th)) = (rec.x[i], rec.y[i], rec.theta[i]) {
            rec.x[i] = Some(c * x - s * y + dx);
            rec.y[i] = Some(s * x + c * y + dy);
            rec.theta[i] = Some(th + dth);
        }
    }
}

fn fit(recs: Vec<(String, Recording)>) -> Calibration {
    calibrate(&robot("mobolab"), &recs, None, &CalOptions::default()).unwrap()
}

#[test]
fn a_slam_jump_is_reported_and_costs_one_sample() {
    // The true robot: wheels 0.6 % apart in diameter, wheelbase 3 % wide.
    let nominal = robot("mobolab");
    let specs = calibrate::param_specs(&nominal, false);
    let truth = calibrate::robot_with(&nominal, &specs, &[1.0, 1.006, 1.03]);
    let a = run(&truth, 61, slam());
    let b = run(&truth, 62, slam());
    let clean = fit(vec![("a".into(), a.clone()), ("b".into(), b.clone())]);
    let mut b_jump = b.clone();
    jump(&mut b_jump, 30.0, (0.06, -0.04, 3f64.to_radians()));
    let jumped = fit(vec![("a".into(), a), ("b".into(), b_jump)]);
    eprintln!("without the jump:\n{clean}\nwith it:\n{jumped}");

    let jumps: Vec<_> = jumped
        .events
        .iter()
        .filter(|e| e.kind == "pose_jump")
        .collect();
    assert_eq!(jumps.len(), 1, "{:#?}", jumped.events);
    let j = jumps[0];
    assert_eq!(j.recording, "b");
    assert!((j.t_s - 30.0).abs() <= 0.1 + 1e-9, "jump at {} s", j.t_s);
    assert!(
        (j.position_m - 0.072).abs() < 0.05,
        "size {} m",
        j.position_m
    );
    assert!(
        clean.events.iter().all(|e| e.kind != "pose_jump"),
        "{:#?}",
        clean.events
    );
    assert!(
        jumped.per_recording.iter().any(|r| r.name == "b#2"),
        "{jumped}"
    );
    assert!(clean.free_start && jumped.free_start);
    assert!(
        clean.notes.iter().any(|n| n.contains("SLAM-like")),
        "{:?}",
        clean.notes
    );
    for (p, t) in clean.params.iter().zip([1.0, 1.006, 1.03]) {
        assert!(
            (p.value - t).abs() <= 3.0 * p.sigma,
            "{}: {} ± {}, true {t}\n{clean}",
            p.spec.name,
            p.value,
            p.sigma
        );
    }
    for (p, q) in jumped.params.iter().zip(&clean.params) {
        assert!(
            (p.value - q.value).abs() <= 2.0 * q.sigma.max(p.sigma),
            "{}: {} with the jump, {} ± {} without\n{jumped}",
            p.spec.name,
            p.value,
            q.value,
            q.sigma
        );
    }
    // The stated pose noise: the simulated 10 mm within 20 %.
    let note = jumped
        .notes
        .iter()
        .find(|n| n.contains("poses scatter"))
        .expect("a pose-noise note");
    let mm: f64 = note
        .split("poses scatter ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .expect("a number");
    assert!((mm - 10.0).abs() < 2.0, "{note}");
}

#[test]
fn motion_capture_reports_no_jump() {
    let r = robot("mobolab");
    let recs = vec![
        ("a".into(), run(&r, 63, VisionConfig::default())),
        ("b".into(), run(&r, 64, VisionConfig::default())),
    ];
    let c = fit(recs);
    assert!(
        c.events.iter().all(|e| e.kind != "pose_jump"),
        "{:#?}",
        c.events
    );
    assert!(!c.free_start, "{:?}", c.notes);
}
