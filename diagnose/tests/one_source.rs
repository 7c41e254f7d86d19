//! One definition of Borenstein's E_d split: the simulator's faults for an `ed` effect,
//! diagnose's geometry for the same effect and calibrate's geometry for an `ed`
//! parameter all give calib-core's `umbmark::wheel_factors`, to the last bit.

use calib_core::robot::presets;
use calib_core::umbmark::wheel_factors;
use calibrate::{param_specs, robot_with};

#[test]
fn sim_diagnose_and_calibrate_split_e_d_alike() {
    let robot = presets::mobolab();
    for ed in [0.985, 1.0, 1.006, 1.02] {
        let (l, r) = wheel_factors(ed);
        let effect = sim::Effect::parse(&format!("wheel_diameter_mismatch=ed:{ed}")).unwrap();
        let (faults, _) =
            sim::Faults::from_effects(&robot, &[effect], sim::Surface::flat()).unwrap();
        assert_eq!(faults.radius_scale, vec![l, r], "sim, ed {ed}");
        let specs = param_specs(&robot, false);
        let fitted = robot_with(&robot, &specs, &[1.0, ed, 1.0]);
        let got: Vec<f64> = fitted
            .wheels
            .iter()
            .zip(&robot.wheels)
            .map(|(a, b)| a.radius_m / b.radius_m)
            .collect();
        for (g, w) in got.iter().zip([l, r]) {
            assert!((g - w).abs() < 1e-15, "calibrate, ed {ed}: {got:?}");
        }
        let model = diagnose::effects::Model::default()
            .with(diagnose::effects::Effect::WheelDiameterMismatch, vec![ed]);
        assert_eq!(model.geometry(&robot).0, vec![l, r], "diagnose, ed {ed}");
    }
}

/// Effect ids and mechanism names come from `formats::catalogue` alone: every pair the
/// simulator makes and every pair diagnose names is in the one table, and every entry
/// of the table is made or named by one of them.
#[test]
fn sim_and_diagnose_name_effects_from_the_one_catalogue() {
    use formats::catalogue::{EFFECT_IDS, GEOMETRY, MECHANISMS, WHEEL_SCALE};
    let sim_pairs: Vec<(&str, &str)> = sim::effects::Mechanism::ALL
        .iter()
        .map(|(_, name, id)| (*name, *id))
        .collect();
    for p in &sim_pairs {
        assert!(
            MECHANISMS.contains(p),
            "sim makes {p:?}, not in the catalogue"
        );
    }
    let mut diag_pairs = vec![];
    for e in diagnose::effects::Effect::ALL {
        let (id, m) = (e.id(), e.mechanism());
        assert!(
            EFFECT_IDS.contains(&id) || id == WHEEL_SCALE,
            "diagnose names effect {id}"
        );
        if m != GEOMETRY {
            assert!(MECHANISMS.contains(&(m, id)), "diagnose names {m} of {id}");
            diag_pairs.push((m, id));
        }
    }
    for p in MECHANISMS {
        assert!(
            sim_pairs.contains(&p) || diag_pairs.contains(&p),
            "catalogue entry {p:?} is used by neither"
        );
    }
    // The simulator's effect ids are the catalogue's.
    assert_eq!(sim::effects::EFFECT_IDS, EFFECT_IDS);
}
