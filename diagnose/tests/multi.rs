//! `diagnose` on several recordings (issue 52 item 5): the shared geometry is the one
//! `calibrate` gives by default for the same recordings (so the two commands agree), and
//! each recording's row says what its own aligned fit and the shared geometry leave.

mod common;

use calibrate::{calibrate, CalOptions};
use common::{generate, Config, Truth};
use diagnose::Options;

/// Three 40 s drives of one diff drive whose separation is 3 % wider than its file
/// (the generator's own physics, seeds no other test uses). The shared geometry equals
/// calibrate's default fit of the same three recordings parameter by parameter (to
/// 1e-12: the same fit), finds the wider separation (eb within 0.5 % of 1.03), and the
/// shared geometry leaves each recording closer to its poses than the nominal one.
#[test]
fn the_shared_geometry_is_calibrates() {
    let robot = calib_core::robot::presets::diff_drive("wide", 0.04, 0.3, Default::default());
    let recs: Vec<(String, formats::recording::Recording)> = (0..3)
        .map(|i| {
            let mut c = Config::new(robot.clone(), 9101 + i);
            c.truths = vec![Truth::Eb(1.03)];
            (format!("run{i}"), generate(&c).recording)
        })
        .collect();
    let multi = diagnose::multi::diagnose_many(&robot, &recs, &Options::default()).unwrap();
    println!("{multi}");
    let cal = calibrate(
        &robot,
        &recs,
        None,
        &CalOptions {
            leave_one_out: true,
            ..CalOptions::default()
        },
    )
    .unwrap();
    assert_eq!(multi.geometry.params.len(), cal.params.len());
    for (a, b) in multi.geometry.params.iter().zip(&cal.params) {
        assert_eq!(a.spec.name, b.spec.name);
        assert!(
            (a.value - b.value).abs() <= 1e-12,
            "{}: {} vs {}",
            a.spec.name,
            a.value,
            b.value
        );
    }
    let eb = multi
        .geometry
        .params
        .iter()
        .find(|p| p.spec.name == "eb")
        .unwrap()
        .value;
    assert!((eb / 1.03 - 1.0).abs() < 0.005, "eb {eb}");
    assert_eq!(multi.recordings.len(), 3);
    for r in &multi.recordings {
        assert!(
            r.rmse_shared_geometry_m < 0.5 * r.rmse_nominal_m,
            "{}: {} -> {}",
            r.name,
            r.rmse_nominal_m,
            r.rmse_shared_geometry_m
        );
    }
    assert!(multi.joint_rmse_shared_geometry_m < 0.5 * multi.joint_rmse_nominal_m);
}
