//! Per-wheel forms of the actuator mechanisms (issue 55 §1), on the habits generator with
//! seeds and robots its suite does not use. Tolerances from the physics: a time constant or
//! delay to 15 % of itself (the commands' row interval is 10 ms, a quarter of the shortest
//! constant), an acceleration limit to 10 %; a wheel without the effect is not reported
//! at its range's bound (said as no effect). And the control: equal wheels keep one value.

mod habits;

use calib_core::robot::presets;
use diagnose::{diagnose, Options, Report};
use habits::{generate, Act, Gen, Style, Wheel};

fn run(g: &Gen) -> Report {
    let rec = generate(g).0.expect("a clean clock");
    let r = diagnose(&g.robot, &rec, &Options::default()).unwrap();
    println!("{r}");
    r
}

fn chain(acts: Vec<Act>) -> Wheel {
    Wheel {
        chain: acts,
        ..Wheel::default()
    }
}

fn param(r: &Report, effect: &str, name: &str) -> f64 {
    let f = r
        .findings
        .iter()
        .find(|f| f.effect == effect)
        .unwrap_or_else(|| panic!("no {effect} in {:?}", r.findings));
    f.parameters
        .get(name)
        .copied()
        .unwrap_or_else(|| panic!("no {name} in {:?}", f.parameters))
}

/// Three omni wheels, the second lagging twice as long: `first_order_per_wheel`.
#[test]
fn a_lag_that_differs_per_wheel_is_fitted_per_wheel() {
    let mut g = Gen::new(presets::omni3(0.035, 0.15), 8801, Style::Legs);
    g.wheels = vec![
        chain(vec![Act::Lag(0.03)]),
        chain(vec![Act::Lag(0.07)]),
        chain(vec![Act::Lag(0.03)]),
    ];
    let r = run(&g);
    assert_eq!(r.verdict.as_str(), "motor_lag");
    let f = r.findings.iter().find(|f| f.effect == "motor_lag").unwrap();
    assert_eq!(f.mechanism, "first_order_per_wheel");
    for (w, truth) in [("w1", 0.03), ("w2", 0.07), ("w3", 0.03)] {
        let v = param(&r, "motor_lag", &format!("tau_s_{w}"));
        assert!((v / truth - 1.0).abs() < 0.15, "{w}: {v} for {truth}");
    }
}

/// A DC diff drive whose left motor cannot accelerate faster than 9 rad/s^2.
#[test]
fn one_weak_motor_is_its_own_acceleration_limit() {
    let mut g = Gen::new(
        presets::diff_drive("weak", 0.045, 0.36, Default::default()),
        8802,
        Style::Joystick,
    );
    g.a_max = 1.0;
    g.wheels[0] = chain(vec![Act::Slew(9.0)]);
    let r = run(&g);
    assert_eq!(r.verdict.as_str(), "motor_lag");
    let left = param(&r, "motor_lag", "slew_rad_s2_left");
    assert!((left / 9.0 - 1.0).abs() < 0.10, "left {left}");
    // The right motor has no limit: either fitted well above the left's, or at its
    // range's bound, and then not reported but said.
    let f = r.findings.iter().find(|f| f.effect == "motor_lag").unwrap();
    match f.parameters.get("slew_rad_s2_right") {
        Some(&right) => assert!(right > 2.0 * left, "right {right} against left {left}"),
        None => assert!(
            r.notes
                .iter()
                .any(|n| n.contains("no effect fitted for slew_rad_s2_right")),
            "{:?}",
            r.notes
        ),
    }
}

/// The control: both wheels lag alike (0.05 s): one `tau_s`, no per-wheel form.
#[test]
fn equal_lags_keep_one_value() {
    let mut g = Gen::new(
        presets::diff_drive("equal", 0.045, 0.36, Default::default()),
        8803,
        Style::Joystick,
    );
    g.wheels = vec![chain(vec![Act::Lag(0.05)]), chain(vec![Act::Lag(0.05)])];
    let r = run(&g);
    assert_eq!(r.verdict.as_str(), "motor_lag");
    let f = r.findings.iter().find(|f| f.effect == "motor_lag").unwrap();
    assert_eq!(f.mechanism, "first_order", "{:?}", f.parameters);
    let tau = param(&r, "motor_lag", "tau_s");
    assert!((tau / 0.05 - 1.0).abs() < 0.15, "tau {tau}");
}

/// Play earns its place at reversals (issue 55 §3): a dead band that differs by direction
/// (0.9 rad/s forward, 0.3 backward, a DC diff drive driven leg by leg with stops, seed and
/// robot of no suite) loses
/// travel at every start from rest, so backlash, however well it fits, is listed as
/// standing for something else (its restarts' loss at least half its reversals'), and is
/// not the verdict.
#[test]
fn a_dead_band_by_direction_is_not_named_play() {
    let mut g = Gen::new(
        presets::diff_drive("band", 0.04, 0.3, Default::default()),
        8804,
        Style::Legs,
    );
    let band = chain(vec![Act::DeadBand {
        fwd: 0.9,
        back: 0.3,
    }]);
    g.wheels = vec![band.clone(), band];
    let r = run(&g);
    assert_ne!(r.verdict.as_str(), "backlash");
    if r.findings.iter().any(|f| f.effect == "backlash") {
        let i = r
            .implausible
            .iter()
            .find(|i| i.effect == "backlash")
            .expect("backlash listed as implausible");
        assert!(i.value >= 0.5, "{i:?}");
    }
}

/// A delay on one wheel only (0.06 s on the left of a DC diff drive): the left's delay is
/// measured (15 %), and the right's, which the fit pushes to the bound of its range
/// (1e-4 s), is said as no effect, not reported as a delay of 1e-4 s (issue 55: no
/// parameter on its prior's edge).
#[test]
fn a_wheel_without_the_effect_is_not_reported_at_the_bound() {
    let mut g = Gen::new(
        presets::diff_drive("late", 0.045, 0.36, Default::default()),
        8805,
        Style::Joystick,
    );
    g.wheels[0] = chain(vec![Act::Delay(0.06)]);
    let r = run(&g);
    assert_eq!(r.verdict.as_str(), "motor_lag");
    let f = r.findings.iter().find(|f| f.effect == "motor_lag").unwrap();
    assert_eq!(f.mechanism, "delay_per_wheel", "{:?}", f.parameters);
    let left = param(&r, "motor_lag", "delay_s_left");
    assert!((left / 0.06 - 1.0).abs() < 0.15, "left {left}");
    for (name, v) in &f.parameters {
        let spec_floor = 1e-4;
        assert!(*v > 1.05 * spec_floor, "{name} = {v} at the range's bound");
    }
    assert!(
        !f.parameters.contains_key("delay_s_right")
            && r.notes
                .iter()
                .any(|n| n.contains("no effect fitted for delay_s_right")),
        "{:?} {:?}",
        f.parameters,
        r.notes
    );
}
