//! `calibrate` on simulated recordings with known geometry: every robot in
//! robots/ that calibrate supports gets its geometry back within the fit's stated
//! uncertainty; one-direction squares report E_d / E_b not separable, both directions
//! separate them; recording artefacts (time offset, clock rate) are fitted as recording
//! parameters with no physics reported.

use calib_core::motion::{Direction, Program};
use calib_core::robot::Robot;
use calibrate::{
    calibrate, dead_reckoning_rmse, dead_reckoning_rmse_law, param_specs, robot_with, BoardFactors,
    CalOptions, Calibration, Factors, PlacedForLog, Series,
};
use formats::recording::Recording;
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

fn square(truth: &Robot, dir: Direction, seed: u64) -> sim::SimRecording {
    let motion = Motion::Program {
        program: Box::new(Program::umbmark_square(1.0, dir)),
        limits: Default::default(),
    };
    record(truth, &[], Surface::flat(), &motion, &cfg(seed)).unwrap()
}

fn random(truth: &Robot, seconds: f64, seed: u64) -> sim::SimRecording {
    let motion = Motion::Random(RandomMotion {
        duration_s: seconds,
        ..RandomMotion::default()
    });
    record(truth, &[], Surface::flat(), &motion, &cfg(seed)).unwrap()
}

/// Every fitted parameter within 4 stated sigmas (plus `floor` for what the simulator
/// does that a rigid kinematic model does not) of the truth.
fn assert_recovered(c: &Calibration, truth: &[f64], floor: f64) {
    for (p, t) in c.params.iter().zip(truth) {
        assert!(
            (p.value - t).abs() <= 4.0 * p.sigma + floor,
            "{}: fitted {} ± {}, true {}\n{c}",
            p.spec.name,
            p.value,
            p.sigma,
            t
        );
    }
}

#[test]
fn differential_robots_recovered_from_both_directions() {
    for name in ["mobolab", "robotest", "sweeper"] {
        let nominal = robot(name);
        let specs = param_specs(&nominal, false);
        let truth = [0.99, 1.006, 1.03]; // scale, ed, eb: inside the plausible ranges
        let actual = robot_with(&nominal, &specs, &truth);
        let recs: Vec<(String, Recording)> = [Direction::Cw, Direction::Ccw]
            .into_iter()
            .enumerate()
            .map(|(i, d)| (format!("{d:?}"), square(&actual, d, 3 + i as u64).recording))
            .collect();
        let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
        assert!(
            c.inseparable.pairs().is_empty(),
            "{name}: {:?}",
            c.inseparable.pairs()
        );
        assert!(c.implausible.is_empty(), "{name}: {:?}", c.implausible);
        assert_recovered(&c, &truth, 1e-3);
        assert!(
            c.joint_rmse_after_m < 0.5 * c.joint_rmse_before_m,
            "{name}\n{c}"
        );
    }
}

/// A parameter held at the robot file's value (`--hold`): a robot whose wheels are 1 %
/// small and whose separation is 3 % wide, both wheels alike (E_d = 1, as the robot file
/// says), two squares. Holding ed, the two others come back within 4 sigma and the 0.1 %
/// the simulator does beyond a rigid model, ed is not in the fit, the robot file's
/// wheels stay alike (c_L = c_R) and a note names what was held. Unknown names, all three
/// held, and an omni robot are refused naming the option.
#[test]
fn held_parameters_stay_at_the_robot_files_values() {
    let nominal = robot("mobolab");
    let specs = param_specs(&nominal, false);
    let actual = robot_with(&nominal, &specs, &[0.99, 1.0, 1.03]);
    let recs: Vec<(String, Recording)> = [Direction::Cw, Direction::Ccw]
        .into_iter()
        .enumerate()
        .map(|(i, d)| (format!("{d:?}"), square(&actual, d, 3 + i as u64).recording))
        .collect();
    let hold = |names: &[&str]| CalOptions {
        hold: names.iter().map(|n| n.to_string()).collect(),
        ..Default::default()
    };
    let c = calibrate(&nominal, &recs, None, &hold(&["ed"])).unwrap();
    println!("{c}");
    let names: Vec<&str> = c.params.iter().map(|p| p.spec.name.as_str()).collect();
    assert_eq!(names, ["scale", "eb"]);
    assert_recovered(&c, &[0.99, 1.03], 1e-3);
    match c.factors {
        Factors::Diff { c_l, c_r, .. } => assert!((c_l - c_r).abs() < 1e-12, "{c_l} {c_r}"),
        ref other => panic!("{other:?}"),
    }
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("--hold") && n.contains("ed")),
        "{:?}",
        c.notes
    );
    for bad in [&["wheel"][..], &["scale", "ed", "eb"][..]] {
        let e = calibrate(&nominal, &recs, None, &hold(bad)).unwrap_err();
        assert!(e.to_string().contains("--hold"), "{bad:?}: {e}");
    }
    let e = calibrate(&robot("omni4"), &recs, None, &hold(&["eb"])).unwrap_err();
    assert!(e.to_string().contains("--hold"), "{e}");
}

/// With the start pose fitted (`--free-start`), one square's start heading trades against
/// E_d and E_b: reported not separable. Dead-reckoned from the known start (the
/// default) the same square separates them: E_d bends the straight legs from the first
/// metre, E_b only turns at the corners; both come back within the fit's uncertainty.
#[test]
fn one_direction_reports_ed_eb_not_separable() {
    let nominal = robot("mobolab");
    let specs = param_specs(&nominal, false);
    let truth = [1.0, 1.006, 1.03];
    let actual = robot_with(&nominal, &specs, &truth);
    for d in [Direction::Cw, Direction::Ccw] {
        let recs = vec![("one".to_string(), square(&actual, d, 5).recording)];
        let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
        assert!(
            c.inseparable.pairs().is_empty(),
            "{d:?}: {:?}\n{c}",
            c.inseparable.pairs()
        );
        assert_recovered(&c, &truth, 1e-3);
        let free = CalOptions {
            free_start: true,
            ..CalOptions::default()
        };
        let c = calibrate(&nominal, &recs, None, &free).unwrap();
        assert!(
            c.inseparable
                .pairs()
                .iter()
                .any(|p| p[0] == "ed" && p[1] == "eb"),
            "{d:?}: {:?}\n{c}",
            c.inseparable.pairs()
        );
    }
}

/// Issue 52 item 9: what one turning direction cannot separate. A MoboLab with E_d 1.006
/// and E_b 1.03 on a floor tilted so that it drifts 1 mm/s downhill (1 rad from world x)
/// while it moves: one square each way, calibrated alone and together. Whatever follows
/// the turning direction goes into E_d and E_b when every recording turns one way; the
/// residuals cannot show it, so the calibration says so (`turning_one_way`, a note, and
/// the identifiability line) instead of calling every parameter separable. Written from
/// a first run of the simulator before the note existed: the clockwise square alone
/// fits E_d 1.0147 ± 0.0011 (7.6 sigma off the truth), the counter-clockwise one
/// 1.0053 ± 0.0032, both together 1.0042 ± 0.0010 (1.8 sigma). Asserted: the note on each
/// direction alone, naming it, and on neither both together nor a random drive (which
/// turns both ways); the clockwise E_d more than 3 sigma off, both together within 3.
#[test]
fn one_turning_direction_is_said_and_a_tilted_floor_shows_why() {
    let nominal = robot("mobolab");
    let specs = param_specs(&nominal, false);
    let truth = [1.0, 1.006, 1.03];
    let actual = robot_with(&nominal, &specs, &truth);
    let tilted = |d: Direction, seed: u64| {
        let motion = Motion::Program {
            program: Box::new(Program::umbmark_square(1.0, d)),
            limits: Default::default(),
        };
        let mut floor = Surface::flat();
        floor.tilt = Some(sim::Tilt {
            drift_m_s: 0.001,
            direction_rad: 1.0,
        });
        (
            format!("{d:?}"),
            record(&actual, &[], floor, &motion, &cfg(seed))
                .unwrap()
                .recording,
        )
    };
    let (cw, ccw) = (tilted(Direction::Cw, 5), tilted(Direction::Ccw, 6));
    let said = |c: &Calibration| c.notes.iter().any(|n| n.contains("turns one way"));
    let ed = |c: &Calibration| c.param("ed").map(|p| (p.value, p.sigma)).unwrap();
    for (rec, sense) in [(&cw, "clockwise"), (&ccw, "counter-clockwise")] {
        let c = calibrate(
            &nominal,
            std::slice::from_ref(rec),
            None,
            &CalOptions::default(),
        )
        .unwrap();
        println!("{c}");
        assert_eq!(c.turning_one_way, Some(sense), "{c}");
        assert!(said(&c), "{:?}", c.notes);
        assert!(
            !c.to_string().contains("every parameter is separable"),
            "{c}"
        );
        if sense == "clockwise" {
            let (v, s) = ed(&c);
            assert!((v - truth[1]).abs() > 3.0 * s, "E_d {v} ± {s}");
        }
    }
    let both = calibrate(&nominal, &[cw, ccw], None, &CalOptions::default()).unwrap();
    println!("{both}");
    assert_eq!(both.turning_one_way, None);
    assert!(!said(&both), "{:?}", both.notes);
    let (v, s) = ed(&both);
    assert!((v - truth[1]).abs() <= 3.0 * s, "E_d {v} ± {s}");
    let free = vec![("free".to_string(), random(&actual, 60.0, 9).recording)];
    let c = calibrate(&nominal, &free, None, &CalOptions::default()).unwrap();
    assert_eq!(c.turning_one_way, None, "{c}");
}

#[test]
fn omni_robots_recovered_from_free_motion() {
    for name in ["omni3", "omni4"] {
        let nominal = robot(name);
        let specs = param_specs(&nominal, false);
        let n = nominal.wheels.len();
        // radius scales, mounting angle offsets (rad), distance scales.
        let mut truth = vec![];
        truth.extend([1.01, 0.99, 1.0, 1.005][..n].iter());
        truth.extend([0.01, -0.015, 0.0, 0.005][..n].iter());
        truth.extend([1.02, 0.99, 1.0, 0.985][..n].iter());
        let actual = robot_with(&nominal, &specs, &truth);
        let recs = vec![("free".to_string(), random(&actual, 60.0, 9).recording)];
        // Dead-reckoned from the first pose (the default): within the stated uncertainty.
        let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
        println!("{c}");
        assert!(c.implausible.is_empty(), "{name}: {:?}\n{c}", c.implausible);
        assert_recovered(&c, &truth, 2e-3);
        // Aligned (start pose and clocks fitted): down to the motion-capture noise.
        let free = CalOptions {
            free_start: true,
            ..CalOptions::default()
        };
        let c = calibrate(&nominal, &recs, None, &free).unwrap();
        println!("{c}");
        assert!(c.implausible.is_empty(), "{name}: {:?}\n{c}", c.implausible);
        assert_recovered(&c, &truth, 2e-3);
        // Down to the simulated motion-capture noise (1 mm per axis).
        assert!(c.joint_rmse_after_m < 2e-3, "{name}\n{c}");
        if n == 3 {
            // Three wheels: the nine parameters map one to one onto the kinematics.
            for (p, t) in c.params.iter().zip(&truth) {
                assert!(
                    (p.value - t).abs() < 2e-3,
                    "{}: {} vs {t}",
                    p.spec.name,
                    p.value
                );
            }
        } else {
            // Four wheels: consistent encoders fix only 9 of the 12 numbers (any J' with
            // pinv(J') J = I fits); that must be said, not guessed.
            assert!(
                !c.unconstrained.is_empty() || !c.inseparable.pairs().is_empty(),
                "{c}"
            );
        }
    }
}

/// A 4-wheel mecanum robot (X rollers at 45 degrees, wheels at the corners of a
/// 0.2 m square, axles along y), the layout of most mecanum platforms.
fn mecanum() -> Robot {
    let mut t = String::from(
        "name = \"mecanum4\"\nkind = \"omni\"\n[drive]\ntype = \"dc\"\ngear_ratio = 1.0\nencoder_counts_per_rev = 1920\n",
    );
    // (name, alpha, beta, gamma): alpha + beta = 90 deg puts every wheel plane along x.
    for (n, a, g) in [
        ("fl", 45.0, -45.0),
        ("fr", -45.0, 45.0),
        ("rl", 135.0, 45.0),
        ("rr", -135.0, -45.0),
    ] {
        t.push_str(&format!(
            "[[wheels]]\nname = \"{n}\"\nradius_m = 0.03\nalpha_deg = {a}\nl_m = 0.14142135623730953\nbeta_deg = {}\ngamma_deg = {g}\n",
            90.0 - a
        ));
    }
    formats::robot_file::parse(&t, Path::new("mecanum4.toml")).unwrap()
}

/// Mecanum rollers 2 degrees steeper than nominal (and radii a little off): with the start
/// pose and clocks fitted (`--free-start`, one recording) the data ask for the roller
/// angle, the roller model is chosen over the 12 per-wheel numbers by the likelihood
/// ratio, and the angle comes back within its stated uncertainty. Dead-reckoned (the
/// default), one recording climbs the ladder by BIC instead: there the 12 per-wheel
/// numbers, which can express the same rollers, fit the simulator's contact details by a
/// chi-square 86 better, more than their 7 extra parameters cost (43 at 479 independent
/// residuals), and are kept; both models dead-reckon the run within 2 mm.
#[test]
fn mecanum_roller_angle_is_fitted_when_the_data_ask() {
    let nominal = mecanum();
    let specs = calibrate::roller_specs(&nominal, false);
    assert_eq!(specs.len(), 5, "four radii and one roller angle");
    let truth = [1.01, 0.99, 1.0, 1.005, 2f64.to_radians()];
    let ordered: Vec<f64> = specs
        .iter()
        .map(|s| match s.name.as_str() {
            "roller_angle_offset_rad" => truth[4],
            n => {
                truth[[
                    "radius_scale_fl",
                    "radius_scale_fr",
                    "radius_scale_rl",
                    "radius_scale_rr",
                ]
                .iter()
                .position(|w| *w == n)
                .unwrap()]
            }
        })
        .collect();
    let actual = robot_with(&nominal, &specs, &ordered);
    assert!((actual.wheels[0].gamma_rad.to_degrees() + 47.0).abs() < 1e-9);
    assert!((actual.wheels[1].gamma_rad.to_degrees() - 47.0).abs() < 1e-9);
    let recs = vec![("free".to_string(), random(&actual, 60.0, 9).recording)];
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert_kept(&c, "per-wheel radii, angles and distances");
    assert!(c.per_recording[0].dead_reckoning_after_m < 2e-3, "{c}");
    // The report's series follow the model kept: their RMS is the fit's.
    let series = calibrate::plots::calibration_series(&c, &nominal, &recs, None).unwrap();
    // Dead-reckoning objective: the series are dead-reckoned from the first pose.
    let (got, want) = (
        series[0].rms_fitted_m(),
        c.per_recording[0].dead_reckoning_after_m,
    );
    assert!((got - want).abs() <= 1e-9 * want, "{got} vs {want}");
    let free = CalOptions {
        free_start: true,
        ..CalOptions::default()
    };
    let c = calibrate(&nominal, &recs, None, &free).unwrap();
    println!("{c}");
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("the roller model is fitted")),
        "{c}"
    );
    assert!(c.implausible.is_empty(), "{:?}\n{c}", c.implausible);
    // 0.1 deg floor: what the simulator's contact model does that rigid kinematics does not.
    assert_recovered(&c, &ordered, 2e-3);
    let g = c
        .params
        .iter()
        .find(|p| p.spec.name == "roller_angle_offset_rad")
        .unwrap();
    assert!((g.value.to_degrees() - 2.0).abs() < 0.2, "{c}");
    // The fitted robot carries the roller angle: |gamma| 47 degrees on every wheel.
    for w in &c.geometry() {
        assert!(
            (w.gamma_deg.abs() - 47.0).abs() < 0.2,
            "{}: {}",
            w.name,
            w.gamma_deg
        );
    }
    assert!(c.joint_rmse_after_m < 2e-3, "{c}");
}

/// A mecanum robot's effective radius may be 15 % off the hub's (the real mecanum squares
/// want 1.12): with the start pose and clocks fitted (`--free-start`, one recording, as
/// noisy SLAM-like poses also get) the per-wheel and roller models have the ladder's
/// mecanum radius range too. Wheels 10 % large, one 60 s run: no radius is listed as
/// implausible, and each comes back within 4 sigma and the 0.2 % floor above.
#[test]
fn mecanum_free_start_takes_the_mecanum_radius_range() {
    let nominal = mecanum();
    let specs = param_specs(&nominal, false);
    let mut truth = vec![1.10; 4];
    truth.extend([0.0; 4]);
    truth.extend([1.0; 4]);
    let actual = robot_with(&nominal, &specs, &truth);
    let recs = vec![("free".to_string(), random(&actual, 60.0, 9).recording)];
    let free = CalOptions {
        free_start: true,
        ..CalOptions::default()
    };
    let c = calibrate(&nominal, &recs, None, &free).unwrap();
    println!("{c}");
    assert!(c.implausible.is_empty(), "{:?}\n{c}", c.implausible);
    let radii: Vec<_> = c
        .params
        .iter()
        .filter(|p| p.spec.name.starts_with("radius_scale_"))
        .collect();
    assert_eq!(radii.len(), 4, "{c}");
    for p in radii {
        assert!(
            (p.value - 1.10).abs() <= 4.0 * p.sigma + 2e-3,
            "{}\n{c}",
            p.spec.name
        );
        assert!(p.spec.plausible.1 >= 1.15 - 1e-12, "{:?}", p.spec.plausible);
    }
}

/// Mounting errors per wheel (no roller error) on the same mecanum robot: one roller angle
/// cannot explain them, so the full per-wheel model is kept and the note says why.
#[test]
fn mecanum_mounting_errors_keep_the_per_wheel_model() {
    let nominal = mecanum();
    let specs = param_specs(&nominal, false);
    let mut truth = vec![1.01, 0.99, 1.0, 1.005];
    truth.extend([0.02, -0.025, 0.0, 0.015]);
    truth.extend([1.03, 0.98, 1.0, 0.985]);
    let actual = robot_with(&nominal, &specs, &truth);
    let recs = vec![("free".to_string(), random(&actual, 60.0, 9).recording)];
    // Dead-reckoned, one recording: the ladder by BIC keeps the per-wheel model.
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert_kept(&c, "per-wheel radii, angles and distances");
    assert!(c.joint_rmse_after_m < 2e-3, "{c}");
    // Of the 12 numbers motion shows at most 9 (four wheels' speeds keep to one
    // constraint): the parameters the data alone leave free give their spread with the
    // priors the fit used, a wheel held to the wheels' mean within ALIKE_SCALE (1 %) or
    // ALIKE_ANGLE (1 degree) and the mean fixed far better by the data: at most twice
    // the alike sigma.
    let loose: Vec<_> = c
        .params
        .iter()
        .filter(|p| p.sigma_exceeds_range())
        .collect();
    assert!(!loose.is_empty(), "{c}");
    for p in loose {
        let alike = if p.spec.name.starts_with("alpha_offset") {
            calibrate::ALIKE_ANGLE
        } else {
            calibrate::ALIKE_SCALE
        };
        let s = p
            .sigma_with_priors
            .expect("a loose parameter's sigma with the priors");
        assert!(s > 0.0 && s <= 2.0 * alike, "{}: ± {s}\n{c}", p.spec.name);
    }
    // Start pose and clocks fitted: the roller test says why.
    let free = CalOptions {
        free_start: true,
        ..CalOptions::default()
    };
    let c = calibrate(&nominal, &recs, None, &free).unwrap();
    println!("{c}");
    assert!(
        c.params
            .iter()
            .all(|p| p.spec.name != "roller_angle_offset_rad"),
        "{c}"
    );
    assert!(
        c.notes
            .iter()
            .any(|n| n.starts_with("mecanum:") && n.contains("per-wheel angles")),
        "{c}"
    );
    assert!(c.joint_rmse_after_m < 2e-3, "{c}");
}

/// The same steeper rollers and wheels 2 % closer in, on wheels of unequal size (1.04,
/// 1.02, 1.03, 1.05): the longitudinal, lateral and turning scales with per-wheel radii.
/// The ladder keeps per-wheel radii, a common wheel distance and one roller angle, each
/// value within 4 sigma plus the simulator's floor (0.1 % and 0.1 degree). The control
/// with equal wheels is the test below (the three-parameter rung).
#[test]
fn mecanum_unequal_wheels_with_steeper_rollers_keep_radii_distance_and_roller() {
    let nominal = mecanum();
    let specs = param_specs(&nominal, false);
    let radii = [1.04, 1.02, 1.03, 1.05];
    let mut truth = radii.to_vec();
    truth.extend([0.0; 4]);
    truth.extend([0.98; 4]);
    let mut steeper = robot_with(&nominal, &specs, &truth);
    for w in steeper.wheels.iter_mut() {
        w.gamma_rad += w.gamma_rad.signum() * 2f64.to_radians();
    }
    let c = calibrate(
        &nominal,
        &free_runs(&steeper, 60),
        None,
        &CalOptions::default(),
    )
    .unwrap();
    println!("{c}");
    assert_kept(
        &c,
        "per-wheel radii, a common wheel distance and one roller angle",
    );
    assert!(c.implausible.is_empty(), "{:?}", c.implausible);
    let get = |name: &str| param(&c, name);
    for (i, want) in radii.iter().enumerate() {
        let p = get(&format!("radius_scale_{}", nominal.wheels[i].name));
        assert!(
            (p.value - want).abs() <= 4.0 * p.sigma + 1e-3,
            "{}\n{c}",
            p.spec.name
        );
    }
    let (l, g) = (get("l_scale"), get("roller_angle_offset_rad"));
    assert!((l.value - 0.98).abs() <= 4.0 * l.sigma + 1e-3, "{c}");
    assert!(
        (g.value - 2f64.to_radians()).abs() <= 4.0 * g.sigma + 0.1f64.to_radians(),
        "{c}"
    );
}

/// A mecanum robot whose rollers grip sideways otherwise than along (every roller 2
/// degrees steeper), on wheels 3 % large and 2 % closer in: in the body frame a
/// longitudinal, a lateral and a turning scale (the Jacobian's F_lon and F_lat). The
/// ladder keeps the three-parameter rung (scale, wheel distance and roller angle) over
/// per-wheel models, each value within 4 sigma plus the simulator's floor (0.1 % and
/// 0.1 degree, as above). The control, wheels only 3 % large, keeps the common scale.
#[test]
fn mecanum_lateral_and_longitudinal_scales_are_a_three_parameter_rung() {
    let nominal = mecanum();
    let runs = |truth: &Robot| free_runs(truth, 60);
    let specs = param_specs(&nominal, false);
    let mut truth = vec![1.03; 4];
    truth.extend([0.0; 4]);
    truth.extend([0.98; 4]);
    let mut steeper = robot_with(&nominal, &specs, &truth);
    for w in steeper.wheels.iter_mut() {
        w.gamma_rad += w.gamma_rad.signum() * 2f64.to_radians();
    }
    let c = calibrate(&nominal, &runs(&steeper), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert_kept(&c, "common scale, wheel distance and roller angle");
    assert!(c.implausible.is_empty(), "{:?}", c.implausible);
    let get = |name: &str| param(&c, name);
    let (s, l, g) = (get("scale"), get("l_scale"), get("roller_angle_offset_rad"));
    assert!((s.value - 1.03).abs() <= 4.0 * s.sigma + 1e-3, "{c}");
    assert!((l.value - 0.98).abs() <= 4.0 * l.sigma + 1e-3, "{c}");
    assert!(
        (g.value - 2f64.to_radians()).abs() <= 4.0 * g.sigma + 0.1f64.to_radians(),
        "{c}"
    );
    // Said as a roboticist would: sideways, a wheel turn carries the robot tan 45 / tan 47
    // = 93.3 % as far as along (the printed percentage within 0.3 of it: 0.1 degree).
    let (pct, note) = sideways_percent(&c);
    let want = 100.0 * 45f64.to_radians().tan() / 47f64.to_radians().tan();
    assert!((pct - want).abs() < 0.3, "{pct} against {want}: {note}");
    // The control: nothing but the wheels' size.
    let mut common = vec![1.03; 4];
    common.extend([0.0; 4]);
    common.extend([1.0; 4]);
    let plain = robot_with(&nominal, &specs, &common);
    let c = calibrate(&nominal, &runs(&plain), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert_kept(&c, "common scale");
}

/// Issue 56 §2's simulator test: a mecanum robot whose rollers grip sideways 4 % less
/// than along (every roller at 46.17 degrees for 45: tan 45 / tan 46.17 = 0.960) on wheels
/// 3 % large, driven as the real mecanum sessions are: squares forward, squares sideways
/// (the same square, translating along body y) and circles of 0.5 m, one each way
/// (six runs). Written before running it: the fit keeps a rung with the roller angle,
/// its sideways note says 96.0 % (within 0.3, the simulator's 0.1 degree floor), and the
/// fitted geometry (what `apply` now puts on the board) dead-reckons a held-out sideways
/// square within 5 mm while the factors alone (per-wheel sizes on the nominal robot) are
/// at least 3 times worse. The control, wheels 3 % large with nominal rollers on the same
/// runs, gets no sideways note (no direction term).
#[test]
fn mecanum_sideways_grip_is_recovered_from_squares_and_circles() {
    use calib_core::motion::Segment;
    use calibrate::{evaluate, Candidate};
    let nominal = mecanum();
    let specs = param_specs(&nominal, false);
    let mut common = vec![1.03; 4];
    common.extend([0.0; 4]);
    common.extend([1.0; 4]);
    let plain = robot_with(&nominal, &specs, &common);
    let gamma = (1.0f64 / 0.96).atan();
    let mut gripless = plain.clone();
    for w in gripless.wheels.iter_mut() {
        w.gamma_rad = w.gamma_rad.signum() * gamma;
    }
    let sideways_square = |d: Direction| {
        let turn = match d {
            Direction::Ccw => std::f64::consts::FRAC_PI_2,
            Direction::Cw => -std::f64::consts::FRAC_PI_2,
        };
        let mut segs = Vec::new();
        for _ in 0..4 {
            segs.push(Segment::Translate {
                dx_m: 0.0,
                dy_m: 1.0,
            });
            segs.push(Segment::Turn { angle_rad: turn });
        }
        Program::from_segments(&segs).unwrap()
    };
    let runs = |truth: &Robot| {
        let mut out = Vec::new();
        for (i, d) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
            for (kind, program) in [
                ("forward", Program::umbmark_square(1.0, d)),
                ("sideways", sideways_square(d)),
                ("circle", Program::circle(0.5, d, 1)),
            ] {
                let motion = Motion::Program {
                    program: Box::new(program),
                    limits: Default::default(),
                };
                let seed = 40 + 3 * i as u64 + out.len() as u64;
                let r = record(truth, &[], Surface::flat(), &motion, &cfg(seed)).unwrap();
                out.push((format!("{kind}-{d:?}"), r.recording));
            }
        }
        out
    };
    let c = calibrate(&nominal, &runs(&gripless), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(c.implausible.is_empty(), "{:?}", c.implausible);
    assert!(c.param("roller_angle_offset_rad").is_some(), "{c}");
    let (pct, note) = sideways_percent(&c);
    assert!((pct - 96.0).abs() < 0.3, "{pct}: {note}");
    // A held-out sideways square, on the board as apply puts it and by the factors alone.
    let motion = Motion::Program {
        program: Box::new(sideways_square(Direction::Ccw)),
        limits: Default::default(),
    };
    let held = record(&gripless, &[], Surface::flat(), &motion, &cfg(99)).unwrap();
    let Factors::Wheels {
        f_lat,
        f_lon,
        l_arc,
    } = &c.factors
    else {
        panic!("{c}")
    };
    let e = evaluate(
        &[
            Candidate::board(
                "fitted geometry",
                c.law_base_robot.clone(),
                calib_core::Corrections::omni([1.0; 4].into_iter().collect(), 1.0, *l_arc),
            ),
            Candidate::board(
                "factors alone",
                nominal.clone(),
                calib_core::Corrections::omni(f_lat.iter().copied().collect(), *f_lon, *l_arc),
            ),
        ],
        &[("held-out sideways square".into(), held.recording)],
    )
    .unwrap();
    let (geometry, factors) = (e.recordings[0].rmse_m[0], e.recordings[0].rmse_m[1]);
    println!(
        "held-out sideways square: fitted geometry {:.2} mm, factors alone {:.2} mm",
        geometry * 1e3,
        factors * 1e3
    );
    assert!(geometry < 5e-3, "{geometry}");
    assert!(geometry * 3.0 <= factors, "{geometry} against {factors}");
    let c = calibrate(&nominal, &runs(&plain), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(
        !c.notes.iter().any(|n| n.contains("sideways")),
        "{:?}",
        c.notes
    );
}

/// [Korayem et al.]'s wheeled-legged robot with its legs sweeping (the wheel contacts move along x
/// with them): wheel scale, left/right ratio and track recovered from a free run, the
/// kinematics following the recorded leg angles. (Four radii are not identifiable: the
/// encoders of consistent wheels on one side are averaged, so only scale and ed are.)
#[test]
fn wheeled_legged_recovered_with_moving_legs() {
    let nominal = robot("wlr");
    let specs = param_specs(&nominal, false);
    let names: Vec<&str> = specs.iter().map(|s| s.name.as_str()).collect();
    assert_eq!(names, ["scale", "ed", "eb"]);
    let truth = [0.99, 1.006, 1.03];
    let actual = robot_with(&nominal, &specs, &truth);
    let mut c = cfg(5);
    c.legs = sim::LegMotion::Random {
        min: 40f64.to_radians(),
        max: 140f64.to_radians(),
        period_s: 4.0,
    };
    let motion = Motion::Random(RandomMotion {
        duration_s: 60.0,
        ..RandomMotion::default()
    });
    let rec = record(&actual, &[], Surface::flat(), &motion, &c).unwrap();
    let recs = vec![("free".to_string(), rec.recording)];
    let cal = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{cal}");
    assert!(cal.implausible.is_empty(), "{:?}\n{cal}", cal.implausible);
    assert!(cal.inseparable.pairs().is_empty(), "{cal}");
    assert_recovered(&cal, &truth, 2e-3);
    // Down to the simulated motion-capture noise (1 mm per axis).
    assert!(cal.joint_rmse_after_m < 2e-3, "{cal}");
    // Without the leg columns the robot's wheels cannot be placed: a clear error.
    let mut bare = recs[0].1.clone();
    bare.leg_front = None;
    let e = calibrate(
        &nominal,
        &[("bare".into(), bare)],
        None,
        &CalOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("leg angle"), "{e}");
}

/// A recording of the nominal robot whose pose columns are replaced by the truth at
/// encoder time `(t - offset) / ratio`, as a late or fast motion-capture clock writes it.
fn with_clock(rec: &sim::SimRecording, offset_s: f64, ratio: f64) -> Recording {
    let mut r = rec.recording.clone();
    let t = &r.t;
    let at = |tau: f64| -> (f64, f64, f64) {
        let k = t.partition_point(|&v| v <= tau).clamp(1, t.len() - 1);
        let (a, b) = (&rec.truth[k - 1], &rec.truth[k]);
        let f = ((tau - t[k - 1]) / (t[k] - t[k - 1])).clamp(0.0, 1.0);
        (
            a.pose.x + (b.pose.x - a.pose.x) * f,
            a.pose.y + (b.pose.y - a.pose.y) * f,
            a.pose.theta + (b.pose.theta - a.pose.theta) * f,
        )
    };
    let t0 = t[0];
    let poses: Vec<Option<(f64, f64, f64)>> = (0..t.len())
        .map(|k| {
            r.x[k]
                .is_some()
                .then(|| at(t0 + (t[k] - t0 - offset_s) / ratio))
        })
        .collect();
    for (k, p) in poses.into_iter().enumerate() {
        if let Some((x, y, th)) = p {
            r.x[k] = Some(x);
            r.y[k] = Some(y);
            r.theta[k] = Some(th);
        }
    }
    r
}

#[test]
fn time_offset_and_clock_rate_are_recording_parameters() {
    let nominal = robot("mobolab");
    let sim = random(&nominal, 60.0, 21);
    for (offset, ratio) in [(0.1, 1.0), (0.0, 1.02), (-0.05, 0.99)] {
        let recs = vec![("clock".to_string(), with_clock(&sim, offset, ratio))];
        // Clocks are fitted only with --free-start (the dead-reckoning default takes the
        // clocks as recorded).
        let free = CalOptions {
            free_start: true,
            ..CalOptions::default()
        };
        let c = calibrate(&nominal, &recs, None, &free).unwrap();
        let nu = c.per_recording[0].nuisance;
        assert!(
            (nu.time_offset_s - offset).abs() < 0.01,
            "offset {offset}: {}\n{c}",
            nu.time_offset_s
        );
        assert!(
            (nu.clock_ratio - ratio).abs() < 1e-3,
            "ratio {ratio}: {}\n{c}",
            nu.clock_ratio
        );
        // No physics: the geometry stays nominal within its uncertainty.
        assert_recovered(&c, &[1.0, 1.0, 1.0], 1e-3);
        assert!(c.implausible.is_empty(), "{:?}", c.implausible);
    }
}

#[test]
fn no_ground_truth_is_refused_naming_the_recording() {
    let nominal = robot("mobolab");
    let mut rec = random(&nominal, 5.0, 2).recording;
    for k in 0..rec.len() {
        rec.x[k] = None;
        rec.y[k] = None;
        rec.theta[k] = None;
    }
    let e = calibrate(
        &nominal,
        &[("runs/no-mocap.csv".to_string(), rec)],
        None,
        &CalOptions::default(),
    )
    .unwrap_err();
    let text = e.to_string();
    assert!(text.starts_with("runs/no-mocap.csv:"), "{text}");
    assert!(text.contains("motion capture"), "{text}");
}

#[test]
fn another_robots_recording_is_refused_naming_the_file() {
    // A recording of the omni robot read against the differential robot: its wheel
    // columns do not exist, and the reader names the file.
    let omni = robot("omni3");
    let dir = std::env::temp_dir().join(format!("calib-bad-{}", std::process::id()));
    let sim = random(&omni, 3.0, 4);
    sim.write_dir(&dir).unwrap();
    let file = dir.join("recording.csv");
    let e = Recording::load(&file, &robot("mobolab")).unwrap_err();
    assert!(e.to_string().contains("recording.csv"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The mobolab robot with scale 0.99, E_d 1.006 and E_b 1.03 (the nominal robot, the
/// truth) driven around a clockwise and a counter-clockwise 1 m square (seeds 3 and 4),
/// named `Cw` and `Ccw`: the clean recordings the event tests spoil.
fn two_clean_squares() -> (Robot, [f64; 3], Vec<(String, Recording)>) {
    let nominal = robot("mobolab");
    let specs = param_specs(&nominal, false);
    let truth = [0.99, 1.006, 1.03];
    let actual = robot_with(&nominal, &specs, &truth);
    let clean = [Direction::Cw, Direction::Ccw]
        .into_iter()
        .enumerate()
        .map(|(i, d)| (format!("{d:?}"), square(&actual, d, 3 + i as u64).recording))
        .collect();
    (nominal, truth, clean)
}

/// Issue 21: an event must not bend the geometry. Every parameter of `c` (fitted with
/// `event` in the recordings) within one sigma of the clean fit `c0`; the shifts printed
/// in sigmas.
fn assert_within_clean_sigma(c: &Calibration, c0: &Calibration, event: &str) {
    for (p, p0) in c.params.iter().zip(&c0.params) {
        println!(
            "{}: {:.5} with {event}, {:.5} ± {:.5} clean: {:.2} sigma",
            p.spec.name,
            p.value,
            p0.value,
            p0.sigma,
            (p.value - p0.value).abs() / p0.sigma
        );
        assert!(
            (p.value - p0.value).abs() <= p0.sigma,
            "{}: {} with {event}, {} ± {} clean",
            p.spec.name,
            p.value,
            p0.value,
            p0.sigma
        );
    }
}

/// The recording with motion capture turned by `dth` (rad) about the pose at row `k`
/// from then on, ramped in over `ramp` rows: the robot turned where its encoders say it
/// did not (a wheel slipped), as run 02 of the real square 231220200029 starts.
fn with_slip(rec: &Recording, k: usize, ramp: usize, dth: f64) -> Recording {
    let mut r = rec.clone();
    let (x0, y0) = (rec.x[k].unwrap(), rec.y[k].unwrap());
    for i in k..r.len() {
        let a = dth * ((i - k) as f64 / ramp as f64).min(1.0);
        let (c, s) = (a.cos(), a.sin());
        if let (Some(x), Some(y), Some(th)) = (rec.x[i], rec.y[i], rec.theta[i]) {
            r.x[i] = Some(x0 + c * (x - x0) - s * (y - y0));
            r.y[i] = Some(y0 + s * (x - x0) + c * (y - y0));
            r.theta[i] = Some(th + a);
        }
    }
    r
}

/// Issue 21: a slip at a run's start (0.08 rad, as the real run 02) is reported with its
/// time and size, and does not move the geometry by more than its uncertainty (with the
/// slip left in, dead reckoning from the start would carry 0.08 rad to the end: the fit
/// would bend eb and ed to explain it).
#[test]
fn slip_at_start_is_reported_and_does_not_bend_the_geometry() {
    let (nominal, truth, clean) = two_clean_squares();
    let c0 = calibrate(&nominal, &clean, None, &CalOptions::default()).unwrap();
    assert!(c0.events.is_empty(), "{:?}", c0.events);
    let mut slipped = clean.clone();
    // 0.5 s into the run (50 Hz rows), over 0.2 s.
    slipped[0].1 = with_slip(&clean[0].1, 25, 10, 0.08);
    let c = calibrate(&nominal, &slipped, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let slips: Vec<_> = c.events.iter().filter(|e| e.kind == "slip").collect();
    assert_eq!(slips.len(), 1, "{:?}", c.events);
    let e = slips[0];
    assert_eq!(e.recording, "Cw");
    // Odometry minus motion capture: -0.08 rad, within the 10 % a 3 s window's noise
    // and geometry error leave; reported within its window of the slip's time.
    assert!((e.heading_rad + 0.08).abs() < 0.008, "{e:?}");
    // Reported where it happens: the span covers the 0.5-0.7 s ramp, and is kept under
    // 1 s (two 50 Hz samples of margin either side are 0.04 s; the detection window is
    // 3 s).
    println!("slip reported at {:.2} s for {:.2} s", e.t_s, e.duration_s);
    assert!(e.t_s <= 0.5 && e.t_s + e.duration_s >= 0.5 + 0.2, "{e:?}");
    assert!(e.duration_s < 1.0, "{e:?}");
    // Issue 21: at most one sigma (of the clean fit). Only the slip's span is kept out;
    // when the whole 3 s window was, scale moved 1.15 sigma (0.99009 with the slip,
    // 0.99037 ± 0.00025 clean, truth 0.99). And every parameter within 4 sigma of the
    // truth.
    assert_recovered(&c, &truth, 1e-3);
    assert_within_clean_sigma(&c, &c0, "the slip");
}

/// `rec` with motion capture `lead` rows ahead of the encoders through every turn
/// (rows whose heading changes faster than 0.5 rad/s, with `lead` rows of margin; a
/// square's legs turn under 0.3 rad/s): each such row shows the pose `lead` rows later,
/// so the lead is given back as the turn ends, as the real December spins show.
fn with_turn_lead(rec: &Recording, lead: usize) -> Recording {
    let mut r = rec.clone();
    let n = rec.len();
    let pose = |i: usize| Some((rec.x[i]?, rec.y[i]?, rec.theta[i]?));
    let turning: Vec<bool> = (0..n)
        .map(|i| {
            let j = (i + 1).min(n - 1);
            let i = j - 1;
            let dt = rec.t[j] - rec.t[i];
            match (pose(i), pose(j)) {
                (Some(a), Some(b)) => (b.2 - a.2).abs() / dt > 0.5,
                _ => false,
            }
        })
        .collect();
    for i in 0..n.saturating_sub(lead) {
        let near = (i.saturating_sub(lead)..(i + lead).min(n)).any(|k| turning[k]);
        if near && pose(i).is_some() && pose(i + lead).is_some() {
            r.x[i] = rec.x[i + lead];
            r.y[i] = rec.y[i + lead];
            r.theta[i] = rec.theta[i + lead];
        }
    }
    r
}

/// Issue 21: motion capture leading odometry by 0.1 s through every turn (the real
/// December spins) is reported as time leads, one per corner, and does not move the
/// geometry by more than its uncertainty of the clean fit: the lead is given back when
/// each turn ends, so only the few samples inside the turns see it (measured: scale 0.17,
/// ed 0.11, eb 0.50 sigma, eb narrower as a lead through the turns asks).
#[test]
fn a_clock_lead_through_turns_is_reported_and_does_not_bend_the_geometry() {
    let (nominal, truth, clean) = two_clean_squares();
    let c0 = calibrate(&nominal, &clean, None, &CalOptions::default()).unwrap();
    // 50 Hz rows: 5 rows are 0.1 s.
    let led: Vec<(String, Recording)> = clean
        .iter()
        .map(|(n, r)| (n.clone(), with_turn_lead(r, 5)))
        .collect();
    let c = calibrate(&nominal, &led, None, &CalOptions::default()).unwrap();
    println!("{c}");
    // One per corner, four corners a square; none taken for a slip (a slip would restart
    // dead reckoning and keep samples out). Each the heading a 0.1 s lead makes of the
    // turn rate: the squares' corners peak at about 1.0-1.2 rad/s, so 0.08-0.125 rad.
    let leads: Vec<_> = c.events.iter().filter(|e| e.kind == "time_lead").collect();
    let slips = c.events.iter().filter(|e| e.kind == "slip").count();
    println!("{} time leads, {slips} slips", leads.len());
    assert_eq!(leads.len(), 8, "{:?}", c.events);
    assert_eq!(slips, 0, "{:?}", c.events);
    for e in &leads {
        assert!((0.08..0.125).contains(&e.heading_rad.abs()), "{e:?}");
    }
    assert_recovered(&c, &truth, 1e-3);
    assert_within_clean_sigma(&c, &c0, "the lead");
}

/// Issue 23 §4: one motion-capture sample 2 m off and one encoder glitch of 1e12 counts
/// are found and reported (time, size), not fitted: the geometry stays within its
/// uncertainty of the clean fit.
#[test]
fn single_sample_glitches_are_reported_not_fitted() {
    let (nominal, _, clean) = two_clean_squares();
    let c0 = calibrate(&nominal, &clean, None, &CalOptions::default()).unwrap();
    let mut bad = clean.clone();
    let k = bad[1]
        .1
        .x
        .iter()
        .enumerate()
        .filter(|(_, v)| v.is_some())
        .nth(200)
        .unwrap()
        .0;
    bad[1].1.x[k] = bad[1].1.x[k].map(|v| v + 2.0);
    let enc = bad[0].1.wheels[0].enc.as_mut().unwrap();
    enc[300] = enc[300].map(|v| v + 1_000_000_000_000);
    let c = calibrate(&nominal, &bad, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let pose: Vec<_> = c
        .events
        .iter()
        .filter(|e| e.kind == "pose_glitch")
        .collect();
    let encs: Vec<_> = c
        .events
        .iter()
        .filter(|e| e.kind == "encoder_glitch")
        .collect();
    assert_eq!(pose.len(), 1, "{:?}", c.events);
    assert!((pose[0].position_m - 2.0).abs() < 0.01, "{:?}", pose[0]);
    assert_eq!(pose[0].recording, "Ccw");
    // The jump up and the jump back: two increments no motor makes.
    assert_eq!(encs.len(), 2, "{:?}", c.events);
    let row_t = bad[0].1.t[300] - bad[0].1.t[0];
    assert!(
        encs.iter().any(|e| (e.t_s - row_t).abs() < 1e-9),
        "{encs:?}"
    );
    assert_within_clean_sigma(&c, &c0, "the glitches");
}

/// Three 40 s runs of free motion of `truth`, seeds from `seed`.
fn free_runs(truth: &Robot, seed: u64) -> Vec<(String, Recording)> {
    (0..3)
        .map(|i| (format!("run{i}"), random(truth, 40.0, seed + i).recording))
        .collect()
}

/// The sideways note's percentage (how far a wheel turn carries the robot sideways
/// against along) and the note; a panic naming the notes when there is none.
fn sideways_percent(c: &Calibration) -> (f64, String) {
    let note = c
        .notes
        .iter()
        .find(|n| n.contains("sideways"))
        .unwrap_or_else(|| panic!("no sideways note: {:?}", c.notes));
    let pct: f64 = note
        .split(" % ")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no percentage in {note}"));
    (pct, note.clone())
}

/// The fitted parameter `name` of `c` (a panic naming it, with the report, when absent).
fn param<'a>(c: &'a Calibration, name: &str) -> &'a calibrate::FittedParam {
    c.params
        .iter()
        .find(|p| p.spec.name == name)
        .unwrap_or_else(|| panic!("no {name}\n{c}"))
}

/// Asserts that the model ladder kept the rung named `rung`.
fn assert_kept(c: &Calibration, rung: &str) {
    let kept = format!("kept: {rung},");
    assert!(c.notes.iter().any(|n| n.contains(&kept)), "{:?}", c.notes);
}

/// The model ladder on omni robots (three 40 s runs of free motion): a robot whose wheels
/// are all 3 % large keeps the one-parameter model, recovered within 4 sigma; a robot
/// with wheels of different sizes climbs to per-wheel radii, each recovered within 4
/// sigma. A model with more parameters is chosen only when it holds out.
#[test]
fn omni_ladder_keeps_the_simplest_model_that_holds_out() {
    let nominal = robot("omni3");
    let runs = |truth: &Robot| free_runs(truth, 30);
    let specs = param_specs(&nominal, false);
    // All three radii 3 % large, nothing else.
    let common = robot_with(
        &nominal,
        &specs,
        &[1.03, 1.03, 1.03, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
    );
    let c = calibrate(&nominal, &runs(&common), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert_kept(&c, "common scale");
    assert_eq!(c.params.len(), 1, "{c}");
    let p = &c.params[0];
    // Floor 0.1 %: what the simulator does that a rigid model does not (as above).
    assert!((p.value - 1.03).abs() <= 4.0 * p.sigma + 1e-3, "{c}");
    // Radii 2 % apart.
    let radii = [1.02, 0.99, 1.0];
    let uneven = robot_with(
        &nominal,
        &specs,
        &[radii[0], radii[1], radii[2], 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
    );
    let c = calibrate(&nominal, &runs(&uneven), None, &CalOptions::default()).unwrap();
    println!("{c}");
    // Per-wheel radii, not the wheels' centre nor per-wheel distances: no false centre.
    assert_kept(&c, "per-wheel radii and a common wheel distance");
    for (i, r) in radii.iter().enumerate() {
        let p = c
            .params
            .iter()
            .find(|p| p.spec.name == format!("radius_scale_{}", nominal.wheels[i].name))
            .unwrap_or_else(|| panic!("no radius for wheel {i}\n{c}"));
        assert!(
            (p.value - r).abs() <= 4.0 * p.sigma + 1e-3,
            "{}\n{c}",
            p.spec.name
        );
    }
}

/// `--hold` on an omni robot: the families of its ladder (radius, distance, angle, centre
/// on the omni3; roller instead of centre on a mecanum robot) are held at the robot
/// file's values. Three 40 s runs of free motion.
/// - Wheels 2 % apart in size on true distances, `--hold distance`: the ladder climbs
///   without the distance (per-wheel radii), each radius within 4 sigma and the
///   simulator's 0.1 % floor (as above), and the robot file's distances are the nominal
///   ones to the micrometre.
/// - Distances 3 % long on true wheels, `--hold radius`: only the distance is fitted,
///   within 4 sigma + 0.1 %, and the robot file's radii are nominal.
/// - One recording (the BIC ladder) holds the same.
/// - Refused, naming the option: a differential drive's names on an omni robot, a family
///   the robot's models do not have (centre on the mecanum robot), and every family held.
#[test]
fn omni_held_families_stay_at_the_robot_files_values() {
    let nominal = robot("omni3");
    let specs = param_specs(&nominal, false);
    let hold = |names: &[&str]| CalOptions {
        hold: names.iter().map(|n| n.to_string()).collect(),
        ..Default::default()
    };
    let held_note = |c: &Calibration, what: &str| {
        c.notes
            .iter()
            .any(|n| n.contains("--hold") && n.contains(what))
    };
    let radii = [1.02, 0.99, 1.0];
    let uneven = robot_with(
        &nominal,
        &specs,
        &[radii[0], radii[1], radii[2], 0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
    );
    let runs = free_runs(&uneven, 30);
    let c = calibrate(&nominal, &runs, None, &hold(&["distance"])).unwrap();
    println!("{c}");
    assert!(held_note(&c, "distance"), "{:?}", c.notes);
    assert!(
        c.params.iter().all(|p| !p.spec.name.starts_with("l_scale")),
        "{c}"
    );
    for (i, r) in radii.iter().enumerate() {
        let name = format!("radius_scale_{}", nominal.wheels[i].name);
        let p = c
            .params
            .iter()
            .find(|p| p.spec.name == name)
            .unwrap_or_else(|| panic!("no {name}\n{c}"));
        assert!((p.value - r).abs() <= 4.0 * p.sigma + 1e-3, "{name}\n{c}");
    }
    for (w, n) in c.fitted_robot.wheels.iter().zip(&nominal.wheels) {
        assert!((w.l_m - n.l_m).abs() < 1e-6, "{}: {} m", w.name, w.l_m);
    }
    // One recording: the BIC ladder holds it too.
    let one = calibrate(&nominal, &runs[..1], None, &hold(&["distance"])).unwrap();
    assert!(
        one.params
            .iter()
            .all(|p| !p.spec.name.starts_with("l_scale")),
        "{one}"
    );
    assert!(held_note(&one, "distance"), "{:?}", one.notes);

    let long = robot_with(
        &nominal,
        &specs,
        &[1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 1.03, 1.03, 1.03],
    );
    let c = calibrate(&nominal, &free_runs(&long, 30), None, &hold(&["radius"])).unwrap();
    println!("{c}");
    assert!(held_note(&c, "radius"), "{:?}", c.notes);
    let names: Vec<&str> = c.params.iter().map(|p| p.spec.name.as_str()).collect();
    assert_eq!(names, ["l_scale"], "{c}");
    let p = &c.params[0];
    assert!((p.value - 1.03).abs() <= 4.0 * p.sigma + 1e-3, "{c}");
    for (w, n) in c.fitted_robot.wheels.iter().zip(&nominal.wheels) {
        assert!(
            (w.radius_m - n.radius_m).abs() < 1e-9,
            "{}: {} m",
            w.name,
            w.radius_m
        );
    }

    for (robot, bad) in [
        (&nominal, &["eb"][..]),
        (&mecanum(), &["centre"][..]),
        (&nominal, &["radius", "distance", "angle", "centre"][..]),
    ] {
        let e = calibrate(robot, &runs, None, &hold(bad)).unwrap_err();
        assert!(
            e.to_string().contains("--hold"),
            "{} {bad:?}: {e}",
            robot.name
        );
    }
}

/// Three 40 s runs of free motion (seeds 50-52) of `nominal` with `effects` and the
/// simulator's wheels growing by `speed_scale` per m/s and its separation by `turn_scrub`
/// from a turn in place to an arc: what the laws' tests calibrate on.
fn law_runs(
    nominal: &Robot,
    effects: &[sim::Effect],
    speed_scale: f64,
    turn_scrub: f64,
) -> Vec<(String, Recording)> {
    law_runs_from(50, nominal, effects, speed_scale, turn_scrub)
}

/// [`law_runs`] with seeds `first`..`first + 2`.
fn law_runs_from(
    first: u64,
    nominal: &Robot,
    effects: &[sim::Effect],
    speed_scale: f64,
    turn_scrub: f64,
) -> Vec<(String, Recording)> {
    (0..3)
        .map(|i| {
            let mut c = cfg(first + i);
            c.sim.speed_scale = speed_scale;
            c.sim.turn_scrub = turn_scrub;
            let motion = Motion::Random(RandomMotion {
                duration_s: 40.0,
                ..RandomMotion::default()
            });
            let r = record(nominal, effects, Surface::flat(), &motion, &c).unwrap();
            (format!("run{i}"), r.recording)
        })
        .collect()
}

/// The uncertainty calibrate reports is the spread a user meets when the same robot is
/// calibrated again on other runs. Eight calibrations of the same simulated robot (E_b 4 %
/// wider on arcs than in a turn in place), each on three 40 s runs of free motion of its
/// own (seeds 50-52, 60-62, ..., 120-122): the standard deviation of their eight turn laws
/// and of their eight E_b, over the root mean square of the sigmas they report, is within
/// [0.5, 2] (a standard deviation of eight values is known to about 27 %, so this band is
/// about 2.5 of its sigmas wide; the fit's own sigmas, residual autocorrelation counted,
/// were 5 to 10 times too small here: the law's runs differ by 0.002, the fit said 0.0002).
/// The eight laws' mean is the simulator's 0.04 within three standard errors.
#[test]
fn reported_uncertainty_is_the_spread_between_calibrations() {
    let nominal = robot("mobolab");
    let fits: Vec<(f64, f64, f64, f64)> = (0..8)
        .map(|k| {
            let runs = law_runs_from(50 + 10 * k, &nominal, &[], 0.0, 0.04);
            let c = calibrate(&nominal, &runs, None, &CalOptions::default()).unwrap();
            let (law, eb) = (param(&c, "eb_arc"), param(&c, "eb"));
            (law.value, law.sigma, eb.value, eb.sigma)
        })
        .collect();
    println!("{fits:?}");
    let sd = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let rms = |v: &[f64]| (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt();
    let col = |f: fn(&(f64, f64, f64, f64)) -> f64| fits.iter().map(f).collect::<Vec<f64>>();
    let (laws, law_sigmas) = (col(|f| f.0), col(|f| f.1));
    let (ebs, eb_sigmas) = (col(|f| f.2), col(|f| f.3));
    for (what, values, sigmas) in [("law", &laws, &law_sigmas), ("eb", &ebs, &eb_sigmas)] {
        let ratio = sd(values) / rms(sigmas);
        println!(
            "{what}: spread {:.5}, reported {:.5}, ratio {ratio:.2}",
            sd(values),
            rms(sigmas)
        );
        assert!(
            (0.5..=2.0).contains(&ratio),
            "{what}: spread / reported sigma {ratio:.2}"
        );
    }
    let mean = laws.iter().sum::<f64>() / 8.0;
    assert!(
        (mean - 0.04).abs() <= 3.0 * sd(&laws) / 8f64.sqrt(),
        "{mean}"
    );
}

/// Separation that depends on the turn (wide tyres: `SimConfig::turn_scrub`, E_b 4 %
/// wider on a straight line than in a turn in place) on a differential drive, three
/// 40 s runs of free motion: the law is found (eb_arc 0.04 within 4 sigma and 0.01) and
/// kept because it holds out. The control, the same robot with a constant separation, gets
/// no law.
#[test]
fn turn_dependent_separation_is_found_and_not_invented() {
    let nominal = robot("mobolab");
    let runs = |scrub: f64| law_runs(&nominal, &[], 0.0, scrub);
    let c = calibrate(&nominal, &runs(0.04), None, &CalOptions::default()).unwrap();
    println!("{c}");
    let arc = c
        .params
        .iter()
        .find(|p| p.spec.name == "eb_arc")
        .unwrap_or_else(|| panic!("no law\n{c}"));
    assert!((arc.value - 0.04).abs() <= 4.0 * arc.sigma + 0.01, "{c}");
    // The JSON's law_tests: each law tested on its own against the same constant model,
    // the turn law kept (its value the fitted eb_arc / eb, held out better), the other
    // two not.
    let tests = |c: &Calibration| -> Vec<(String, bool, f64, f64, f64)> {
        c.law_tests
            .iter()
            .map(|t| {
                (
                    t.law.to_string(),
                    t.kept,
                    t.value,
                    t.heldout_m,
                    t.constant_heldout_m,
                )
            })
            .collect()
    };
    let t = tests(&c);
    println!("{t:?}");
    // The fourth: a pose lead tested on top of the turn law kept (none here: the poses
    // are on time), against the turn law alone.
    assert_eq!(
        t.iter().map(|t| (t.0.as_str(), t.1)).collect::<Vec<_>>(),
        [
            ("turn", true),
            ("speed", false),
            ("acceleration", false),
            ("pose lead", false)
        ]
    );
    assert!((t[0].2 - c.turn_law.arc_rel).abs() < 1e-12);
    assert!(t[0].3 <= 0.95 * t[0].4, "{t:?}");
    // What a board takes (`--write-board-robot`): the separation of a turn in place,
    // narrower than the robot file's (at the recordings' mean turn), and factors of one
    // with the law.
    let text = c.board_robot_toml();
    let board =
        formats::robot_file::parse(text.split_once('\n').unwrap().1, Path::new("b.toml")).unwrap();
    let l = |r: &Robot| r.wheels.iter().map(|w| w.l_m).collect::<Vec<_>>();
    assert_eq!(l(&board), l(&c.law_base_robot));
    assert!(l(&board)[0] < l(&c.fitted_robot)[0], "{board:?}");
    assert_eq!(
        c.board_robot_factors(),
        format!(
            "factors set --c-l 1.000000 --c-r 1.000000 --e-b 1.000000 --e-b-arc {:.6}",
            c.turn_law.arc_rel
        )
    );
    assert!(t[..3].iter().all(|x| x.4 == t[0].4), "{t:?}");
    assert_eq!(t[3].4, t[0].3, "{t:?}");
    let c = calibrate(&nominal, &runs(0.0), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(c.params.iter().all(|p| p.spec.name != "eb_arc"), "{c}");
    assert!(tests(&c).iter().all(|t| !t.1), "{:?}", tests(&c));
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("constant effective separation")),
        "{:?}",
        c.notes
    );
}

/// An omni robot whose wheels' effective distance from the centre grows 2 % from a turn
/// in place to an arc (`SimConfig::turn_scrub` on omni3: its turn divided by 1 + 0.02
/// (1 - rho^2), rho = |omega| L / |v|), three 40 s runs of free motion: the model ladder
/// keeps its rung and the turn law on top of it is found (l_arc 0.02 within 4 sigma and
/// 0.004: the simulator's turn ratio is its twist's, smoothed as the board smooths it,
/// calibration's the encoders' over 0.1 s either side) and kept because it holds out (at
/// most 95 % of the rung's held-out error). The control, the same robot whose distance
/// does not depend on the turn, gets no law.
#[test]
fn an_omni_robots_turn_dependent_wheel_distance_is_found_and_not_invented() {
    let nominal = robot("omni3");
    let runs = |scrub: f64| law_runs(&nominal, &[], 0.0, scrub);
    let c = calibrate(&nominal, &runs(0.02), None, &CalOptions::default()).unwrap();
    println!("{c}");
    let arc = param(&c, "l_arc");
    let t: Vec<_> = c
        .law_tests
        .iter()
        .filter(|t| t.parameter == "l_arc")
        .collect();
    assert_eq!(t.len(), 1, "{:?}", c.law_tests);
    println!("{:?}", t[0]);
    assert!(t[0].kept && t[0].heldout_m <= 0.95 * t[0].constant_heldout_m);
    assert!((t[0].value - c.turn_law.arc_rel).abs() < 1e-12);
    assert!(
        (c.turn_law.arc_rel - 0.02).abs() <= 4.0 * t[0].sigma + 0.004,
        "{c}"
    );
    assert!(arc.value.abs() >= 3.0 * arc.sigma, "{c}");
    // No false centre: the ladder, climbed again with the law, may keep the centre's
    // rung, but the simulated wheels sit about the body's origin (measured 0.3 mm).
    for p in c
        .params
        .iter()
        .filter(|p| p.spec.name.starts_with("centre_"))
    {
        assert!(p.value.abs() < 1e-3, "{c}");
    }
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("longer on arcs than in a turn in place")),
        "{:?}",
        c.notes
    );
    // What a board takes (`--write-board-robot`): the wheels' distance of a turn in place,
    // which its law widens, and factors of one with the law; the robot file's distance
    // sits at the recordings' mean turn, longer.
    let board_robot = |c: &Calibration| {
        let text = c.board_robot_toml();
        let body = text.split_once('\n').unwrap().1;
        formats::robot_file::parse(body, Path::new("board.toml")).unwrap()
    };
    // The same wheels to the bit but for the angles' trip through degrees (an ulp).
    let same = |a: &Robot, b: &Robot| {
        a.wheels.iter().zip(&b.wheels).all(|(a, b)| {
            (a.radius_m, a.l_m) == (b.radius_m, b.l_m)
                && (a.alpha_rad - b.alpha_rad).abs() < 1e-12
                && (a.beta_rad - b.beta_rad).abs() < 1e-12
        })
    };
    let b = board_robot(&c);
    assert!(same(&b, &c.law_base_robot), "{b:?}");
    assert!(b.wheels[0].l_m < c.fitted_robot.wheels[0].l_m, "{b:?}");
    assert_eq!(
        c.board_robot_factors(),
        format!(
            "factors set --f-lat 1,1,1 --f-lon 1 --l-arc {:.6}",
            c.turn_law.arc_rel
        )
    );
    let c = calibrate(&nominal, &runs(0.0), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(c.params.iter().all(|p| p.spec.name != "l_arc"), "{c}");
    assert_eq!(c.turn_law.arc_rel, 0.0);
    assert!(same(&board_robot(&c), &c.fitted_robot));
    assert_eq!(
        c.board_robot_factors(),
        "factors set --f-lat 1,1,1 --f-lon 1"
    );
    let t: Vec<_> = c
        .law_tests
        .iter()
        .filter(|t| t.parameter == "l_arc")
        .collect();
    assert!(t.len() == 1 && !t[0].kept, "{:?}", c.law_tests);
}

/// Wheels whose effective size depends on their speed (`SimConfig::speed_scale`: each
/// driven wheel rolls 10 % further per m/s of its rolling speed, so 3 % at the random
/// runs' 0.3 m/s) on a differential drive, three 40 s runs of free motion: the speed law
/// is found (speed_rel within 4 sigma and 0.01 per m/s of 0.1) and kept because it holds
/// out, and no turn law with it (one law at a time). The controls get no speed law: the
/// same robot with plain wheels, and the robot whose separation depends on the turn
/// (`turn_scrub` 4 %), which gets its turn law instead.
#[test]
fn speed_dependent_scale_is_found_and_not_invented() {
    let nominal = robot("mobolab");
    let runs = |speed: f64, scrub: f64| law_runs(&nominal, &[], speed, scrub);
    let named = |c: &Calibration, name: &str| c.params.iter().any(|p| p.spec.name == name);
    let c = calibrate(&nominal, &runs(0.1, 0.0), None, &CalOptions::default()).unwrap();
    println!("{c}");
    let law = c
        .params
        .iter()
        .find(|p| p.spec.name == "speed_rel")
        .unwrap_or_else(|| panic!("no speed law\n{c}"));
    assert!((law.value - 0.1).abs() <= 4.0 * law.sigma + 0.01, "{c}");
    // The robot file gets the wheel size at the runs' mean speed: grown by speed_rel
    // times a mean side speed between 0.03 m/s and the 0.5 m/s a side reaches (0.3 m/s
    // forward plus 1 rad/s times the 0.2 m half track; measured 0.223 m/s).
    let grown = c.fitted_robot.wheels[0].radius_m / c.law_base_robot.wheels[0].radius_m - 1.0;
    let mean_speed = grown / law.value;
    println!("robot file's wheel size grown by {grown:.5}: mean speed {mean_speed:.3} m/s");
    assert!((0.03..=0.5).contains(&mean_speed), "{mean_speed}");
    // The board takes the law itself, with c_L and c_R at standstill: the constant
    // factors over the board's are the robot file's growth (to rounding).
    let (c_l, b) = board_factors(&c);
    assert_eq!(b.laws.speed_rel, law.value);
    assert!((c_l / b.c_l - 1.0 - grown).abs() < 1e-12, "{c_l} {b:?}");
    assert!(!named(&c, "eb_arc"), "{c}");
    assert!(
        c.notes
            .iter()
            .any(|n| n.contains("speed law: the wheels' effective size depends on their speed")),
        "{:?}",
        c.notes
    );
    assert!(!named(&c, "accel_slip_s"), "{c}");
    // In words: at 0.5 m/s the simulated wheels roll 5 % further (within 0.5 %).
    let pct = number_after(&c, "at 0.5 m/s a wheel rolls ");
    assert!((pct - 5.0).abs() < 0.5, "{pct} %");
    let c = calibrate(&nominal, &runs(0.0, 0.0), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(
        !named(&c, "speed_rel") && !named(&c, "eb_arc") && !named(&c, "accel_slip_s"),
        "{c}"
    );
    assert!(
        matches!(c.factors, Factors::Diff { board: None, .. }),
        "{c}"
    );
    let c = calibrate(&nominal, &runs(0.0, 0.04), None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(
        !named(&c, "speed_rel") && named(&c, "eb_arc") && !named(&c, "accel_slip_s"),
        "{c}"
    );
}

/// Wheels that slip in proportion to their acceleration (`longitudinal_slip` by creep,
/// 0.05 s: each contact follows its wheel's speed 0.05 s late, so the ground lags the
/// wheels by 0.05 s times each change of speed) on a differential drive, three 40 s runs
/// of free motion: the acceleration law is found (accel_slip_s within 4 sigma and 0.01 s
/// of 0.05) and kept because it holds out, and neither other law with it. The controls
/// (plain wheels, wheels that grow with speed, a separation that depends on the turn) are
/// in `speed_dependent_scale_is_found_and_not_invented`.
#[test]
fn acceleration_slip_is_found_and_not_invented() {
    let nominal = robot("mobolab");
    let creep = sim::Effect::parse("longitudinal_slip=mechanism:creep,creep_s:0.05").unwrap();
    let recs = law_runs(&nominal, &[creep], 0.0, 0.0);
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let law = param(&c, "accel_slip_s");
    assert!((law.value - 0.05).abs() <= 4.0 * law.sigma + 0.01, "{c}");
    assert!(
        c.params
            .iter()
            .all(|p| p.spec.name != "eb_arc" && p.spec.name != "speed_rel"),
        "{c}"
    );
    // In words: cruising at 0.3 m/s, 0.05 s x 0.3 m/s = 15 mm behind (within the law's
    // own tolerance above, 0.01 s: 3 mm).
    let mm = number_after(&c, "cruising at 0.3 m/s the robot is ");
    assert!((mm - 15.0).abs() < 3.0, "{mm} mm");
    // The board takes the law and the same geometry as everyone else.
    let (c_l, b) = board_factors(&c);
    assert_eq!(b.laws.accel_slip_s, law.value);
    assert_eq!((b.laws.e_b_arc, b.laws.speed_rel), (0.0, 0.0));
    assert_eq!(c_l, b.c_l);
}

/// Poses that lead the encoders (a motion-capture stream stamped 40 ms early, as the
/// OptiOdom recordings' pose streams lead their odometry) on plain wheels, three 40 s runs
/// of free motion. A pose lead delta looks like an acceleration law of -delta (the ground
/// ahead of its wheels by delta times their speed), so the term is found (within 4 sigma
/// and 0.01 s of -0.04) and, holding out, kept for the fit. But no slip puts the ground
/// ahead of the wheels: the report names it a timestamp offset between the poses and the
/// encoders, and neither the board nor the robot file gets it (it is the logger's, not
/// the robot's). The geometry stays nominal within its uncertainty.
#[test]
fn poses_leading_the_encoders_are_named_a_timestamp_offset_and_kept_off_the_board() {
    let nominal = robot("mobolab");
    let recs: Vec<(String, Recording)> = (0..3)
        .map(|i| {
            let motion = Motion::Random(RandomMotion {
                duration_s: 40.0,
                ..RandomMotion::default()
            });
            let r = record(&nominal, &[], Surface::flat(), &motion, &cfg(50 + i)).unwrap();
            (format!("run{i}"), with_clock(&r, -0.04, 1.0))
        })
        .collect();
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let lead = param(&c, "accel_slip_s");
    assert!((lead.value + 0.04).abs() <= 4.0 * lead.sigma + 0.01, "{c}");
    let ms = number_after(&c, "the poses lead the wheels by ");
    assert!((ms - 40.0).abs() < 10.0, "{ms} ms");
    assert!(
        c.notes.iter().any(|n| n.contains("timestamp offset")),
        "{:?}",
        c.notes
    );
    match &c.factors {
        Factors::Diff { board, .. } => assert!(board.is_none(), "{board:?}"),
        f => panic!("{f:?}"),
    }
    for p in c.params.iter().filter(|p| p.spec.name != "accel_slip_s") {
        assert!(
            (p.value - p.spec.nominal).abs() <= 4.0 * p.sigma + 1e-3,
            "{}: {} ± {}\n{c}",
            p.spec.name,
            p.value,
            p.sigma
        );
    }
}

/// A pose lead is the logger's, not a rival of the robot's physics: a robot whose
/// separation widens 4 % on arcs (`turn_scrub`), recorded with poses stamped 40 ms early,
/// three 40 s runs of free motion. Tested alone against no law, the lead does not qualify
/// (the unmodelled turn law dominates: -40 ± 25 ms); the turn law does and is chosen, and
/// the lead, tested again on top of it, is kept: both fitted (the turn law within 4 sigma
/// and 0.01 of 0.04, the lead within 4 sigma and 0.01 s of 40 ms), the board gets the
/// turn law alone.
#[test]
fn a_pose_lead_is_fitted_beside_a_turn_law_not_instead_of_it() {
    let nominal = robot("mobolab");
    let recs = scrubbed_runs_leading(&nominal, 50, 0.04, 0.04);
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let (arc, lead) = (param(&c, "eb_arc"), param(&c, "accel_slip_s"));
    assert!((arc.value - 0.04).abs() <= 4.0 * arc.sigma + 0.01, "{c}");
    assert!((lead.value + 0.04).abs() <= 4.0 * lead.sigma + 0.01, "{c}");
    let kept: Vec<(&str, bool)> = c.law_tests.iter().map(|t| (t.law, t.kept)).collect();
    assert_eq!(
        kept,
        [
            ("turn", true),
            ("speed", false),
            ("acceleration", false),
            ("pose lead", true)
        ]
    );
    let (_, b) = board_factors(&c);
    assert!((b.laws.e_b_arc - c.turn_law.arc_rel).abs() < 1e-12, "{b:?}");
    assert_eq!((b.laws.speed_rel, b.laws.accel_slip_s), (0.0, 0.0), "{b:?}");
}

/// Three 40 s random runs (seeds `seed`..`seed + 2`) of a robot whose separation is
/// wider on arcs by `scrub` (the simulator's `turn_scrub`), their poses stamped `lead_s`
/// early.
fn scrubbed_runs_leading(
    nominal: &Robot,
    seed: u64,
    scrub: f64,
    lead_s: f64,
) -> Vec<(String, Recording)> {
    (0..3)
        .map(|i| {
            let mut c = cfg(seed + i);
            c.sim.turn_scrub = scrub;
            let motion = Motion::Random(RandomMotion {
                duration_s: 40.0,
                ..RandomMotion::default()
            });
            let r = record(nominal, &[], Surface::flat(), &motion, &c).unwrap();
            (format!("run{i}"), with_clock(&r, -lead_s, 1.0))
        })
        .collect()
}

/// The number that follows `words` in one of the calibration's notes.
fn number_after(c: &Calibration, words: &str) -> f64 {
    c.notes
        .iter()
        .find_map(|n| n.split(words).nth(1))
        .and_then(|t| t.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("no note says {words:?}: {:?}", c.notes))
}

/// A differential drive's constant c_L and the factors its board takes with the law.
fn board_factors(c: &Calibration) -> (f64, BoardFactors) {
    match &c.factors {
        Factors::Diff {
            c_l,
            board: Some(b),
            ..
        } => (*c_l, *b),
        other => panic!("no board law: {other:?}"),
    }
}

/// A known turn law (`--turn-law`): outside its plausible ±0.1, not finite, or given for
/// a skid-steer robot (whose law is fitted from its recordings), it is refused with a
/// message naming the option; within range on a differential drive, it is held and
/// reported.
#[test]
fn a_known_turn_law_is_checked_and_held() {
    let nominal = robot("mobolab");
    let rec = square(&nominal, Direction::Cw, 11);
    let recs = [("square".to_string(), rec.recording)];
    for bad in [0.3, -0.2, f64::NAN] {
        let opts = CalOptions {
            turn_law: Some(bad),
            ..Default::default()
        };
        let e = calibrate(&nominal, &recs, None, &opts).unwrap_err();
        assert!(e.to_string().contains("--turn-law"), "{bad}: {e}");
    }
    let skid = robot("rover4");
    let opts = CalOptions {
        turn_law: Some(0.005),
        ..Default::default()
    };
    let e = calibrate(&skid, &recs, None, &opts).unwrap_err();
    assert!(e.to_string().contains("--turn-law"), "{e}");
    let c = calibrate(&nominal, &recs, None, &opts).unwrap();
    assert_eq!(c.turn_law.arc_rel, 0.005);
    assert!(c.params.iter().all(|p| p.spec.name != "eb_arc"), "{c}");
}

/// An omni robot's known turn law held: omni3 whose wheels' distance grows 2 % on arcs
/// (`turn_scrub`), calibrated on two squares alone (they turn in place, so no law is
/// tested: the recordings turn on arcs for under 15 % of their turning) with
/// `--turn-law 0.02` given, then dead-reckoned on a held-out 40 s run of free motion. The
/// law is held (the factors' l_arc is exactly 0.02, no l_arc fitted) and the held-out
/// run with it is at most half the error of the same squares fitted without it (3.4
/// against 13.5 mm when written; the squares' one distance is a turn in place's, 2 %
/// short for the arcs).
#[test]
fn a_known_omni_turn_law_is_held_and_carries_to_arcs() {
    let nominal = robot("omni3");
    let scrub = |c: &mut RecordConfig| c.sim.turn_scrub = 0.02;
    let recs = two_squares(&nominal, scrub);
    let held = series(
        &nominal,
        [random_run(&nominal, RandomMotion::default(), 70, scrub)],
    );
    let with = |law: Option<f64>| {
        let opts = CalOptions {
            turn_law: law,
            ..Default::default()
        };
        calibrate(&nominal, &recs, None, &opts).unwrap()
    };
    let (c, c0) = (with(Some(0.02)), with(None));
    println!("{c}\n{c0}");
    assert_eq!(c.turn_law.arc_rel, 0.02);
    assert!(c.params.iter().all(|p| p.spec.name != "l_arc"), "{c}");
    assert!(
        matches!(c.factors, Factors::Wheels { l_arc, .. } if l_arc == 0.02),
        "{:?}",
        c.factors
    );
    assert!(c0.law_tests.iter().all(|t| !t.kept) && c0.turn_law.arc_rel == 0.0);
    let e = |c: &Calibration| {
        dead_reckoning_rmse_law(&c.law_base_robot, &c.turn_law, &held[0]).unwrap()
    };
    let (e, e0) = (e(&c), e(&c0));
    println!(
        "held-out free run: {:.1} mm with the law, {:.1} mm without",
        e * 1e3,
        e0 * 1e3
    );
    assert!(e <= 0.5 * e0, "{e} against {e0}");
}

/// Two squares (cw seed 11, ccw seed 12) of `nominal`, the simulator set by `tweak`.
fn two_squares(nominal: &Robot, tweak: impl Fn(&mut RecordConfig)) -> Vec<(String, Recording)> {
    [(Direction::Cw, 11), (Direction::Ccw, 12)]
        .into_iter()
        .map(|(dir, seed)| {
            let motion = Motion::Program {
                program: Box::new(Program::umbmark_square(1.0, dir)),
                limits: Default::default(),
            };
            let mut c = cfg(seed);
            tweak(&mut c);
            let r = record(nominal, &[], Surface::flat(), &motion, &c).unwrap();
            (format!("square{seed}"), r.recording)
        })
        .collect()
}

/// A random run of `nominal` within `motion`'s limits, the simulator tweaked by `tweak`.
fn random_run(
    nominal: &Robot,
    motion: RandomMotion,
    seed: u64,
    tweak: impl Fn(&mut RecordConfig),
) -> (String, Recording) {
    let mut c = cfg(seed);
    tweak(&mut c);
    let r = record(nominal, &[], Surface::flat(), &Motion::Random(motion), &c).unwrap();
    (format!("run{seed}"), r.recording)
}

/// A run as a log of driving: its poses blanked, only the encoders left.
fn without_poses(mut run: (String, Recording)) -> (String, Recording) {
    for v in [&mut run.1.x, &mut run.1.y, &mut run.1.theta] {
        v.iter_mut().for_each(|c| *c = None);
    }
    run
}

/// The runs as calibrate's series of `nominal`.
fn series(nominal: &Robot, runs: impl IntoIterator<Item = (String, Recording)>) -> Vec<Series> {
    runs.into_iter()
        .map(|(n, r)| Series::new(&n, nominal, &r).unwrap())
        .collect()
}

/// Mean dead-reckoned RMSE (m) of `robot` over `held`, from each run's first pose.
fn mean_dead_reckoning_rmse(robot: &Robot, held: &[Series]) -> f64 {
    held.iter()
        .map(|s| dead_reckoning_rmse(robot, s).unwrap())
        .sum::<f64>()
        / held.len() as f64
}

/// Where the robot file's one E_b sits on a known turn law (`--e-b-for`): two squares
/// (cw and ccw) of the simulator's 4 % turn-scrub robot, fitted with the law held at
/// 0.04. The board's factors are the same with or without `--e-b-for` (it applies the
/// law itself). By default the robot file's E_b is at the squares' mean turn, nearly all
/// in place (within a tenth of the law of the board's in-place E_b). Given a log of
/// driving on paths (four 40 s random runs whose yaw rate stays under 0.3 rad/s, their
/// poses blanked: only the encoders are read), it is the constant closest to the law on
/// that motion, between the in-place and arc values. Five other runs of the same kind of
/// driving, dead-reckoned with the robot file alone (as ROS 2 or another tool would), are
/// then on average at most half as far off as with the default, and nearer than with E_b
/// on arcs (measured 5.4, 17.2 and 12.4 mm). One run is not enough to learn from: the
/// constant closest on one run alone ranges from 3 % to 72 % of the law's widening over
/// five seeds, as a few sharp turns weigh most. Without a law the option changes nothing
/// and a note says so; on a robot with no turn law it is refused naming the option.
#[test]
fn a_known_turn_law_reaches_the_robot_file_for_the_motion_given() {
    let nominal = robot("mobolab");
    let squares = two_squares(&nominal, |c| c.sim.turn_scrub = 0.04);
    let on_paths = RandomMotion {
        duration_s: 40.0,
        omega_max_rad_s: 0.3,
        ..RandomMotion::default()
    };
    let paths = |seed: u64| random_run(&nominal, on_paths, seed, |c| c.sim.turn_scrub = 0.04);
    let log: Vec<(String, Recording)> = (61..65).map(|seed| without_poses(paths(seed))).collect();
    let fit = |turn_law: Option<f64>, e_b_for: &[(String, Recording)]| {
        let opts = CalOptions {
            turn_law,
            e_b_for: e_b_for.to_vec(),
            ..Default::default()
        };
        calibrate(&nominal, &squares, None, &opts).unwrap()
    };
    let e_b = |c: &Calibration| c.factors_e_b();
    let default = fit(Some(0.04), &[]);
    let for_paths = fit(Some(0.04), &log);
    let (_, board) = board_factors(&default);
    let (_, b) = board_factors(&for_paths);
    assert_eq!(
        (b.c_l, b.c_r, b.e_b, b.laws),
        (board.c_l, board.c_r, board.e_b, board.laws)
    );
    println!(
        "E_b: board {:.6}, default {:.6}, for paths {:.6}",
        board.e_b,
        e_b(&default),
        e_b(&for_paths)
    );
    assert!(e_b(&default) >= board.e_b, "{default}");
    assert!(
        e_b(&default) - board.e_b <= 0.1 * 0.04 * board.e_b,
        "{default}"
    );
    assert!(e_b(&for_paths) >= board.e_b, "{for_paths}");
    assert!(e_b(&for_paths) <= board.e_b * 1.04 + 1e-12, "{for_paths}");
    assert!(
        for_paths.notes.iter().any(|n| n.contains("--e-b-for")),
        "{:?}",
        for_paths.notes
    );
    assert!(
        for_paths.to_string().contains("for --e-b-for's driving"),
        "{for_paths}"
    );
    assert_eq!(
        (default.placed_for_log, for_paths.placed_for_log),
        (
            PlacedForLog::default(),
            PlacedForLog {
                e_b: true,
                wheel_size: false
            }
        )
    );
    assert!(
        default.to_string().contains("at the recordings' mean turn"),
        "{default}"
    );
    let held = series(&nominal, [60, 65, 66, 67, 68].map(paths));
    let err = |c: &Calibration| mean_dead_reckoning_rmse(&c.fitted_robot, &held);
    let mut on_arcs = default.clone();
    for w in on_arcs.fitted_robot.wheels.iter_mut() {
        w.l_m *= 1.04;
    }
    println!(
        "held out with the robot file: {:.1} mm for paths, {:.1} mm by default, {:.1} mm on arcs",
        err(&for_paths) * 1e3,
        err(&default) * 1e3,
        err(&on_arcs) * 1e3
    );
    assert!(err(&for_paths) < err(&on_arcs));
    assert!(err(&for_paths) <= 0.5 * err(&default));
    // No law: nothing to place, and the note says so.
    let plain = fit(None, &[]);
    let asked = fit(None, &log);
    assert_eq!(e_b(&plain), e_b(&asked));
    assert!(
        asked.notes.iter().any(|n| n.contains("--e-b-for")),
        "{:?}",
        asked.notes
    );
    let opts = CalOptions {
        e_b_for: log,
        ..Default::default()
    };
    let e = calibrate(&robot("omni4"), &squares, None, &opts).unwrap_err();
    assert!(e.to_string().contains("--e-b-for"), "{e}");
}

/// Where the robot file's one wheel size sits on a known speed law (`--e-b-for`, as for
/// the turn law above): two squares (cw and ccw) of the simulator's 0.1-per-m/s robot,
/// fitted with the law held at 0.1. The board's factors are the same with or without the
/// log (it applies the law itself, c_L and c_R at standstill). By default the robot
/// file's wheels are the law's at the squares' mean speed (near their 0.3 m/s cruise).
/// Given a log of slow driving (four 40 s random runs under 0.1 m/s, their poses
/// blanked), they are the law's at that driving's speed: between standstill and the
/// default, 0.1 x 0.01-0.1 m/s above standstill. Five other runs of the same driving,
/// dead-reckoned with the robot file alone, lose at most a quarter of what the default
/// loses against the law itself (as the board applies it): measured 2.55 mm for the slow
/// driving, 4.89 mm by default, 2.00 mm with the law (the simulator's slip and noise,
/// which no geometry removes). First written as "at most half the default's error", which
/// failed at 0.52 because of that floor.
#[test]
fn a_known_speed_law_reaches_the_robot_file_for_the_motion_given() {
    let nominal = robot("mobolab");
    let squares = two_squares(&nominal, |c| c.sim.speed_scale = 0.1);
    let gentle = RandomMotion {
        duration_s: 40.0,
        v_max_m_s: 0.1,
        omega_max_rad_s: 0.5,
        ..RandomMotion::default()
    };
    let slow = |seed: u64| random_run(&nominal, gentle, seed, |c| c.sim.speed_scale = 0.1);
    let log: Vec<(String, Recording)> = (71..75).map(|seed| without_poses(slow(seed))).collect();
    let fit = |e_b_for: &[(String, Recording)]| {
        let opts = CalOptions {
            speed_law: Some(0.1),
            e_b_for: e_b_for.to_vec(),
            ..Default::default()
        };
        calibrate(&nominal, &squares, None, &opts).unwrap()
    };
    let default = fit(&[]);
    let for_slow = fit(&log);
    let (_, board) = board_factors(&default);
    let (_, b) = board_factors(&for_slow);
    assert_eq!(
        (b.c_l, b.c_r, b.e_b, b.laws),
        (board.c_l, board.c_r, board.e_b, board.laws)
    );
    // The robot file's wheel size over the board's at standstill.
    let size = |c: &Calibration| {
        let (file, nom) = (&c.fitted_robot.wheels, &nominal.wheels);
        file.iter()
            .zip(nom)
            .map(|(f, n)| f.radius_m / n.radius_m)
            .sum::<f64>()
            / file.len() as f64
            / (0.5 * (board.c_l + board.c_r))
            - 1.0
    };
    println!(
        "robot file's wheels over standstill: default {:+.5}, for slow driving {:+.5}",
        size(&default),
        size(&for_slow)
    );
    assert!(size(&default) > 0.1 * 0.2, "{default}");
    assert!(
        (0.1 * 0.01..=0.1 * 0.1).contains(&size(&for_slow)),
        "{for_slow}"
    );
    assert!(
        for_slow
            .notes
            .iter()
            .any(|n| n.contains("--e-b-for") && n.contains("wheel size")),
        "{:?}",
        for_slow.notes
    );
    assert!(
        for_slow.to_string().contains("for --e-b-for's driving"),
        "{for_slow}"
    );
    assert_eq!(
        (default.placed_for_log, for_slow.placed_for_log),
        (
            PlacedForLog::default(),
            PlacedForLog {
                e_b: false,
                wheel_size: true
            }
        )
    );
    let held = series(&nominal, [70, 75, 76, 77, 78].map(slow));
    let err = |c: &Calibration| mean_dead_reckoning_rmse(&c.fitted_robot, &held);
    let with_law = held
        .iter()
        .map(|s| dead_reckoning_rmse_law(&default.law_base_robot, &default.turn_law, s).unwrap())
        .sum::<f64>()
        / held.len() as f64;
    println!(
        "held out with the robot file: {:.2} mm for slow driving, {:.2} mm by default; {:.2} mm with the law",
        err(&for_slow) * 1e3,
        err(&default) * 1e3,
        with_law * 1e3
    );
    assert!(err(&for_slow) - with_law <= 0.25 * (err(&default) - with_law));
}

/// A known speed law (`--speed-law`), the squares' counterpart of `--turn-law`: squares
/// run at one cruise speed, so their fit folds a speed law into the wheel size (the two
/// correlate at -0.995 on the real squares). Outside the board's ±0.2 per m/s, not finite,
/// or for a robot that is not a differential drive, it is refused naming the option.
/// Held at the simulator's 0.1 per m/s while two squares (cw and ccw) of the 0.1 robot
/// are fitted: the wheel size at standstill comes out at the truth, nominal (within 4
/// sigma and 0.1 %, what the simulator does that a rigid model does not), where without
/// the law it is the size at the squares' cruise speed (0.1 x a speed above 0.05 m/s
/// larger); a 40 s random run at other speeds, held out, is dead-reckoned at most half
/// as far off with the law as without it.
#[test]
fn a_known_speed_law_is_checked_and_held() {
    let nominal = robot("mobolab");
    let squares = two_squares(&nominal, |c| c.sim.speed_scale = 0.1);
    for bad in [0.3, -0.25, f64::NAN] {
        let opts = CalOptions {
            speed_law: Some(bad),
            ..Default::default()
        };
        let e = calibrate(&nominal, &squares, None, &opts).unwrap_err();
        assert!(e.to_string().contains("--speed-law"), "{bad}: {e}");
    }
    let opts = CalOptions {
        speed_law: Some(0.1),
        ..Default::default()
    };
    let e = calibrate(&robot("omni4"), &squares, None, &opts).unwrap_err();
    assert!(e.to_string().contains("--speed-law"), "{e}");
    let held = law_runs(&nominal, &[], 0.1, 0.0).swap_remove(0);
    let held = Some(&held);
    let without = calibrate(&nominal, &squares, held, &CalOptions::default()).unwrap();
    let with = calibrate(&nominal, &squares, held, &opts).unwrap();
    println!("{without}\n{with}");
    assert_eq!(with.turn_law.speed_rel, 0.1);
    assert!(
        with.params.iter().all(|p| p.spec.name != "speed_rel"),
        "{with}"
    );
    assert!(
        with.notes.iter().any(|n| n.contains("--speed-law")),
        "{:?}",
        with.notes
    );
    let scale = |c: &Calibration| {
        c.params
            .iter()
            .find(|p| p.spec.name == "scale")
            .unwrap()
            .clone()
    };
    let s = scale(&with);
    assert!((s.value - 1.0).abs() <= 4.0 * s.sigma + 1e-3, "{with}");
    assert!(scale(&without).value - 1.0 > 0.1 * 0.05, "{without}");
    // The board takes the law with c_L and c_R at standstill.
    let (_, b) = board_factors(&with);
    assert_eq!(b.laws.speed_rel, 0.1);
    let err = |c: &Calibration| c.heldout.as_ref().unwrap().rmse_after_m;
    println!(
        "held out: {:.1} mm without the law, {:.1} mm with it",
        err(&without) * 1e3,
        err(&with) * 1e3
    );
    assert!(err(&with) <= 0.5 * err(&without));
}

/// The wheels laid out about another point than the one motion capture tracks and the
/// odometry reports (a three-wheel omni robot whose wheels' centre is 25 mm forward and
/// 15 mm right of the body origin, rolling directions as nominal), three 40 s runs of free
/// motion: the ladder keeps the two-parameter centre model (per-wheel distances fit as
/// well with more parameters) and finds the centre within 4 sigma and 1 mm (what the
/// simulator does that a rigid model does not, as above), the radii at nominal.
#[test]
fn omni_wheels_centre_off_the_tracked_point_is_found() {
    let nominal = robot("omni3");
    let (dx, dy) = (0.025, -0.015);
    let mut truth = nominal.clone();
    for w in truth.wheels.iter_mut() {
        let (x, y) = (
            w.l_m * w.alpha_rad.cos() + dx,
            w.l_m * w.alpha_rad.sin() + dy,
        );
        let alpha = y.atan2(x);
        w.beta_rad += w.alpha_rad - alpha;
        w.alpha_rad = alpha;
        w.l_m = x.hypot(y);
    }
    let recs: Vec<(String, Recording)> = (0..3)
        .map(|i| (format!("run{i}"), random(&truth, 40.0, 30 + i).recording))
        .collect();
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    assert!(
        c.notes.iter().any(|n| n
            .contains("kept: per-wheel radii, a common wheel distance and the wheels' centre,")),
        "{:?}",
        c.notes
    );
    assert!(c.implausible.is_empty(), "{:?}", c.implausible);
    for p in &c.params {
        let t = match p.spec.name.as_str() {
            "centre_x_m" => dx,
            "centre_y_m" => dy,
            _ => 1.0,
        };
        assert!(
            (p.value - t).abs() <= 4.0 * p.sigma + 1e-3,
            "{}: {} ± {} against {t}\n{c}",
            p.spec.name,
            p.value,
            p.sigma
        );
    }
}

/// The reverse of the test above: a pose lead large enough to hide the robot's law. A
/// 2 % turn scrub with poses 100 ms early, three 40 s runs: tested alone, the turn law
/// is not significant (measured +0.019 ± 0.011, the lead unmodelled) and the lead is
/// chosen; tested again on top of the lead, the turn law is kept (+0.0193 ± 0.0003),
/// both land within 4 sigma and a quarter of their truth, and the board gets the turn
/// law alone.
#[test]
fn a_law_hidden_by_a_pose_lead_is_tested_on_top_of_it() {
    let nominal = robot("mobolab");
    let recs = scrubbed_runs_leading(&nominal, 70, 0.02, 0.10);
    let c = calibrate(&nominal, &recs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let (arc, lead) = (param(&c, "eb_arc"), param(&c, "accel_slip_s"));
    assert!(
        (c.turn_law.arc_rel - 0.02).abs() <= 4.0 * arc.sigma + 0.005,
        "{c}"
    );
    assert!((lead.value + 0.10).abs() <= 4.0 * lead.sigma + 0.025, "{c}");
    let tests: Vec<(&str, bool)> = c.law_tests.iter().map(|t| (t.law, t.kept)).collect();
    assert_eq!(
        tests,
        [
            ("turn", false),
            ("speed", false),
            ("acceleration", true),
            ("turn on the pose lead", true),
            ("speed on the pose lead", false),
        ],
        "{c}"
    );
    assert!(
        !c.law_tests[0].qualifies,
        "the turn law alone must not qualify: {c}"
    );
    // On top of the lead the turn law holds out better than the lead alone, and than the
    // speed law on the lead (which mimics part of a scrub on random motion: measured
    // 1.6 mm against 13.0 mm alone).
    let (turn, speed) = (&c.law_tests[3], &c.law_tests[4]);
    assert!(turn.constant_heldout_m == c.law_tests[2].heldout_m, "{c}");
    assert!(turn.heldout_m <= 0.95 * turn.constant_heldout_m, "{c}");
    assert!(turn.heldout_m < speed.heldout_m, "{c}");
    let (_, b) = board_factors(&c);
    assert!((b.laws.e_b_arc - c.turn_law.arc_rel).abs() < 1e-12, "{b:?}");
    assert_eq!((b.laws.speed_rel, b.laws.accel_slip_s), (0.0, 0.0), "{b:?}");
}

/// `n` random runs of `seconds` each of `nominal` named `mobolab-<kind>-<session>-run-NN`
/// (the real sessions' naming: session `<kind>-<session>`, kind of motion `<kind>`), 40 s each,
/// within `motion`'s limits (its duration replaced), the simulator tweaked by `tweak`;
/// seeds from `seed`.
fn named_runs(
    nominal: &Robot,
    (kind, session): (&str, &str),
    motion: RandomMotion,
    seed: u64,
    n: u64,
    effects: &[sim::Effect],
    tweak: impl Fn(&mut RecordConfig),
) -> Vec<(String, Recording)> {
    (0..n)
        .map(|i| {
            let mut c = cfg(seed + i);
            tweak(&mut c);
            let m = Motion::Random(RandomMotion {
                duration_s: 40.0,
                ..motion
            });
            let r = record(nominal, effects, Surface::flat(), &m, &c).unwrap();
            (
                format!("{}-{kind}-{session}-run-{:02}", nominal.name, i + 1),
                r.recording,
            )
        })
        .collect()
}

/// Slow free motion: 0.1 m/s and 0.5 rad/s at most (a side of mobolab, 0.2 m from the
/// centre, reaches 0.2 m/s).
fn slow() -> RandomMotion {
    RandomMotion {
        v_max_m_s: 0.1,
        omega_max_rad_s: 0.5,
        ..RandomMotion::default()
    }
}

/// Moderate free motion: 0.2 m/s and 0.5 rad/s at most (a side reaches 0.3 m/s).
fn moderate() -> RandomMotion {
    RandomMotion {
        v_max_m_s: 0.2,
        omega_max_rad_s: 0.5,
        ..RandomMotion::default()
    }
}

/// Moderate, gently curving driving: 0.25 m/s and 0.25 rad/s at most (a side reaches
/// 0.3 m/s).
fn moderate_cruise() -> RandomMotion {
    RandomMotion {
        v_max_m_s: 0.25,
        omega_max_rad_s: 0.25,
        ..RandomMotion::default()
    }
}

/// Fast free motion: 0.6 m/s and 1 rad/s at most (a side reaches 0.8 m/s).
fn fast() -> RandomMotion {
    RandomMotion {
        v_max_m_s: 0.6,
        omega_max_rad_s: 1.0,
        a_max_m_s2: 1.0,
        ..RandomMotion::default()
    }
}

/// A number of the calibration's JSON at `path` (keys), or None.
fn json_number(c: &Calibration, path: &[&str]) -> Option<f64> {
    let mut v = serde_json::to_value(c).unwrap();
    for k in path {
        v = v.get(*k)?.clone();
    }
    v.as_f64()
}

/// The speed law's test in the JSON's `law_tests`, as JSON.
fn speed_law_test(c: &Calibration) -> serde_json::Value {
    let v = serde_json::to_value(c).unwrap();
    v["law_tests"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["law"] == "speed")
        .unwrap_or_else(|| panic!("no speed law test\n{c}"))
        .clone()
}

/// Per held-out group of `by` (`by_session` or `by_kind`) of a law test: (group, the
/// constant geometry's held-out error, the law's), m.
fn held_out_groups(test: &serde_json::Value, by: &str) -> Vec<(String, f64, f64)> {
    test[by]
        .as_array()
        .unwrap_or_else(|| panic!("no {by} in {test}"))
        .iter()
        .map(|g| {
            (
                g["group"].as_str().unwrap().to_string(),
                g["constant_m"].as_f64().unwrap(),
                g["law_m"].as_f64().unwrap(),
            )
        })
        .collect()
}

/// A speed law fitted on slow runs only is applied within the speeds it was fitted on,
/// and held at its edge beyond them. The simulated wheels roll 1 + 0.1 |v| times their
/// size up to 0.3 m/s and no further beyond (`speed_scale_top_m_s`: a tyre whose
/// deformation saturates). Two sessions of moderate driving, each its own kind (free
/// motion, and gently curving cruising, both up to a side speed of 0.3 m/s), two 40 s
/// runs each, keep the law (0.1 within 4 sigma and 0.01: it holds out on each session
/// and kind) with a fitted range whose top is the fastest side speed the runs reached
/// (between 0.25 and 0.35 m/s). The board holding the calibration's factors and law
/// (calib-core's odometry, f64, 1 kHz) scales a side's travel at twice that top speed
/// exactly as at the top (within 1e-6), and within it by the law. On three fast runs
/// (sides up to 0.8 m/s) the board dead-reckons no worse than the same calibration's
/// constant geometry (the robot file) by more than the noise floor: the error the board
/// holding the truth itself (nominal wheels, 0.1 per m/s held at 0.3 m/s) leaves on the
/// same runs, what the encoders, the motion capture and the travel noise alone make.
#[test]
fn a_speed_law_fitted_on_slow_runs_is_held_at_its_edge_on_fast_runs() {
    use calib_core::correction::Corrections;
    use calib_core::diff_laws::DiffLawOdometry;
    use calib_core::kinematics::{Kinematics, Twist};
    let nominal = robot("mobolab");
    let tweak = |c: &mut RecordConfig| {
        c.sim.speed_scale = 0.1;
        c.sim.speed_scale_top_m_s = 0.3;
    };
    let mut runs = named_runs(&nominal, ("wander", "1"), moderate(), 300, 2, &[], tweak);
    runs.extend(named_runs(
        &nominal,
        ("cruise", "2"),
        moderate_cruise(),
        310,
        2,
        &[],
        tweak,
    ));
    let c = calibrate(&nominal, &runs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let law = c
        .params
        .iter()
        .find(|p| p.spec.name == "speed_rel")
        .unwrap_or_else(|| panic!("no speed law\n{c}"));
    assert!((law.value - 0.1).abs() <= 4.0 * law.sigma + 0.01, "{c}");
    let top = json_number(&c, &["turn_law", "range", "speed_max_m_s"])
        .unwrap_or_else(|| panic!("no fitted speed range in the JSON's turn_law\n{c}"));
    println!("speed law {:+.4} fitted up to {top:.3} m/s", law.value);
    assert!((0.25..=0.35).contains(&top), "{top}");
    let (_, b) = board_factors(&c);
    let corrections = b.corrections();
    // A steady straight run at side speed v: the board's travel over the kinematics'
    // once the smoothing has settled (3 s at 1 kHz: e^-30 of the start remains).
    let scale_at = |v: f64| {
        let kin = Kinematics::<f64>::new(&nominal, &corrections).unwrap();
        let mut odo = DiffLawOdometry::<f64>::new(&nominal, &corrections, 1e-3);
        let dphi = [v * 1e-3 / 0.05, v * 1e-3 / 0.05];
        let plain = kin.forward(&dphi);
        let mut out = Twist::new(0.0, 0.0, 0.0);
        for _ in 0..3000 {
            out = odo.apply(&dphi, |p| kin.forward(p));
        }
        out.vx / plain.vx
    };
    let (at_top, beyond) = (scale_at(top), scale_at(2.0 * top));
    println!("board's scale at {top:.3} m/s {at_top:.7}, at twice it {beyond:.7}");
    assert!((beyond - at_top).abs() < 1e-6, "{at_top} {beyond}");
    let within = scale_at(0.5 * top);
    assert!(
        ((within - 1.0) - 0.5 * (at_top - 1.0)).abs() < 1e-6,
        "{within} {at_top}"
    );
    // Fast runs: the board against the same calibration's constant geometry.
    let fast_runs = named_runs(&nominal, ("dash", "3"), fast(), 320, 3, &[], tweak);
    let held = series(&nominal, fast_runs);
    let truth: BoardFactors = serde_json::from_value(serde_json::json!({
        "c_l": 1.0, "c_r": 1.0, "e_b": 1.0,
        "e_b_arc": 0.0, "speed_rel": 0.1, "accel_slip_s": 0.0,
        "range": {"rho_min": 0.0, "rho_max": 1.0, "speed_max_m_s": 0.3}
    }))
    .unwrap();
    let board = |k: &Corrections| {
        held.iter()
            .map(|s| {
                calibrate::board_dead_reckoning_errors(&nominal, k, s)
                    .unwrap()
                    .0
            })
            .sum::<f64>()
            / held.len() as f64
    };
    let (e_board, e_truth) = (board(&corrections), board(&truth.corrections()));
    let e_constant = mean_dead_reckoning_rmse(&c.fitted_robot, &held);
    println!(
        "fast runs: board {:.1} mm, constant geometry {:.1} mm, the truth on the board {:.1} mm",
        e_board * 1e3,
        e_constant * 1e3,
        e_truth * 1e3
    );
    assert!(
        e_board <= e_constant + e_truth,
        "{e_board} {e_constant} {e_truth}"
    );
}

/// `n` squares of 1 m (cw and ccw in turn) of `nominal` at `v` m/s and `omega` rad/s,
/// named as [`named_runs`] names them, with `effects`; seeds from `seed`.
fn named_squares(
    nominal: &Robot,
    kind: &str,
    session: &str,
    (v, omega): (f64, f64),
    seed: u64,
    n: u64,
    effects: &[sim::Effect],
) -> Vec<(String, Recording)> {
    (0..n)
        .map(|i| {
            let dir = if i % 2 == 0 {
                Direction::Cw
            } else {
                Direction::Ccw
            };
            let motion = Motion::Program {
                program: Box::new(Program::umbmark_square(1.0, dir)),
                limits: calib_core::motion::ProfileLimits {
                    v_max: v,
                    omega_max: omega,
                    ..Default::default()
                },
            };
            let r = record(nominal, effects, Surface::flat(), &motion, &cfg(seed + i)).unwrap();
            (
                format!("{}-{kind}-{session}-run-{:02}", nominal.name, i + 1),
                r.recording,
            )
        })
        .collect()
}

/// A speed law that holds out over folds of recordings but not on every kind of motion
/// is refused. Two sessions of squares driven slowly (0.1 m/s, 0.5 rad/s) and two of
/// squares driven fast (0.4 m/s, 1 rad/s: kind `sprint`), two squares each; the wheels are
/// the same size at every speed, but the fast sessions were driven on wheels 1 % smaller
/// (worn tyres, another day). Over the pooled runs a speed law stands in for the
/// sessions' sizes, and folds of recordings (each with both kinds) cannot tell (today's
/// rule kept it: -0.076 per m/s, 10.0 against 14.6 mm over 5 folds). Held out by kind of
/// motion, the law fitted on the other kind's squares alone (one cruise speed and its
/// turns) barely differs from a constant size there: on at least one kind it does not
/// hold out (its error above [`calibrate::TURN_LAW_HOLDOUT_RATIO`] of the constant
/// geometry's, the rule a law's mean over folds must meet), so it is not kept (nothing
/// on the board, speed_rel 0), and the speed law's test gives the constant geometry's
/// and the law's held-out error per session (4) and per kind (2).
#[test]
fn a_speed_law_that_holds_on_one_kind_only_is_refused() {
    let nominal = robot("mobolab");
    let worn = [sim::Effect::WheelDiameterMismatch {
        ed: None,
        radius_scale: vec![("left".into(), 0.99), ("right".into(), 0.99)],
    }];
    let (slow, fast) = ((0.1, 0.5), (0.4, 1.0));
    let mut runs = named_squares(&nominal, "square", "1", slow, 400, 2, &[]);
    runs.extend(named_squares(&nominal, "square", "2", slow, 410, 2, &[]));
    runs.extend(named_squares(&nominal, "sprint", "3", fast, 420, 2, &worn));
    runs.extend(named_squares(&nominal, "sprint", "4", fast, 430, 2, &worn));
    let c = calibrate(&nominal, &runs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let t = speed_law_test(&c);
    println!("{t}");
    let kinds = held_out_groups(&t, "by_kind");
    let sessions = held_out_groups(&t, "by_session");
    assert_eq!(kinds.len(), 2, "{kinds:?}");
    assert_eq!(sessions.len(), 4, "{sessions:?}");
    let ratio = calibrate::TURN_LAW_HOLDOUT_RATIO;
    assert!(kinds.iter().any(|(_, k, l)| *l > ratio * k), "{kinds:?}");
    assert_eq!(t["kept"], false, "{t}");
    assert_eq!(c.turn_law.speed_rel, 0.0, "{c}");
    assert!(c.params.iter().all(|p| p.spec.name != "speed_rel"), "{c}");
}

/// A true speed law is kept: the same sessions and kinds of motion as above on one set of
/// wheels that roll 1 + 0.1 |v| times their size at every speed. The law fitted without
/// each session, and without each kind, wins on it (below the constant geometry's error;
/// the constant geometry fitted without
/// the fast runs sizes the wheels for slow ones, and the reverse); the law is kept,
/// 0.1 within 4 sigma and 0.01, and the board gets it with its range (the fastest side,
/// at least the 0.6 m/s the fast runs' straights reach).
#[test]
fn a_true_speed_law_wins_on_every_held_out_session_and_kind() {
    let nominal = robot("mobolab");
    let grow = |c: &mut RecordConfig| c.sim.speed_scale = 0.1;
    let mut runs = named_runs(&nominal, ("wander", "1"), slow(), 400, 2, &[], grow);
    runs.extend(named_runs(
        &nominal,
        ("wander", "2"),
        slow(),
        410,
        2,
        &[],
        grow,
    ));
    runs.extend(named_runs(
        &nominal,
        ("dash", "3"),
        fast(),
        420,
        2,
        &[],
        grow,
    ));
    runs.extend(named_runs(
        &nominal,
        ("dash", "4"),
        fast(),
        430,
        2,
        &[],
        grow,
    ));
    let c = calibrate(&nominal, &runs, None, &CalOptions::default()).unwrap();
    println!("{c}");
    let t = speed_law_test(&c);
    println!("{t}");
    let kinds = held_out_groups(&t, "by_kind");
    let sessions = held_out_groups(&t, "by_session");
    assert_eq!(kinds.len(), 2, "{kinds:?}");
    assert_eq!(sessions.len(), 4, "{sessions:?}");
    for (g, k, l) in kinds.iter().chain(&sessions) {
        assert!(l < k, "{g}: law {l} against constant {k}");
    }
    assert_eq!(t["kept"], true, "{t}");
    let law = c
        .params
        .iter()
        .find(|p| p.spec.name == "speed_rel")
        .unwrap_or_else(|| panic!("no speed law\n{c}"));
    assert!((law.value - 0.1).abs() <= 4.0 * law.sigma + 0.01, "{c}");
    let top = json_number(&c, &["factors", "board", "range", "speed_max_m_s"])
        .unwrap_or_else(|| panic!("no range on the board's factors\n{c}"));
    assert!(top >= 0.6, "{top}");
}
