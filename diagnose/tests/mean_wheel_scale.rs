//! A mean wheel scale (both tyres 1 % small) is named by diagnose's catalogue (moved
//! here from calibrate's simulator tests when calibrate became its own crate).

use calib_core::robot::Robot;
use sim::{record, Motion, RandomMotion, RecordConfig, Surface};
use std::path::Path;

fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

fn cfg(seed: u64) -> RecordConfig {
    let mut c = RecordConfig {
        row_rate_hz: 50.0,
        ..RecordConfig::default()
    };
    c.sim.seed = seed;
    c
}

#[test]
fn diagnose_names_a_mean_wheel_scale() {
    // Both tyres 1 % smaller than nominal: no ed (the ratio is 1), no eb; the catalogue's
    // wheel_scale expresses it.
    let nominal = robot("mobolab");
    let effect = sim::Effect::parse(
        "wheel_diameter_mismatch=radius_scale_left:0.99,radius_scale_right:0.99",
    )
    .unwrap();
    let motion = Motion::Random(RandomMotion {
        duration_s: 60.0,
        ..RandomMotion::default()
    });
    let rec = record(&nominal, &[effect], Surface::flat(), &motion, &cfg(17))
        .unwrap()
        .recording;
    let rep = diagnose::diagnose(&nominal, &rec, &diagnose::Options::default()).unwrap();
    println!("{rep}");
    assert_eq!(rep.verdict, "wheel_scale", "{rep}");
    let scale = rep.findings[0].parameters["scale"];
    // A tenth of the hidden 1 %.
    assert!((scale - 0.99).abs() < 1e-3, "{scale}");
    assert!(rep.implausible.is_empty());
}
