//! The independent suite: recordings from a generator with its own physics
//! (`independent/mod.rs`: not the `sim` crate's effects, not diagnose's models) and with
//! mechanisms neither crate has: speed droop friction, gear play that differs per wheel
//! with a small diameter mismatch, one omni wheel mounted at another angle, one omni wheel
//! further out, a slippery patch, cables crossed wheel by wheel, side slip that lags the
//! turn (tyre relaxation), traction set by the leg posture, and a caster that turns the
//! body at each reversal (outside the catalogue: it must be described by what the residual
//! depends on, under a `depends_on` list in the JSON report, not named as catalogue
//! physics).
//!
//! Seeds, cases and tolerances were fixed in the commit that added this file, before any
//! diagnose change. Each case states the expected verdict, the mechanism where
//! it matters and its parameters with tolerances from the physics (a wheel mounting angle
//! to 0.5 degrees, a distance to 1.5 %, a diameter ratio to 0.15 %, a slip or friction
//! coefficient to 20-30 %, floor bounds to 10 cm). The first and current scores are in the
//! docs/diagnose.md and here.
//!
//! Hard assertions: the noise-only controls give `none`. The wheeled-legged posture slip
//! (found two rounds ago, `unexplained` for two rounds, found again) has its own check,
//! `posture_slip_regression`. The other cases are scored.
//!
//! First run (commit 'independent suite...', diagnose of main 5f02c13): see docs/diagnose.md.
//! `DIAG_CASE=name` runs only the cases whose name contains it.

mod check;
mod independent;

use calib_core::robot::{presets, Drive, Robot};
use diagnose::{diagnose, Options};
use independent::{generate, Gen, Mech};

fn dc_diff() -> Robot {
    presets::diff_drive("dc_diff", 0.05, 0.40, Drive::default())
}

struct Case {
    name: &'static str,
    gen: Gen,
    /// Expected verdict; "any" = one of `also`.
    verdict: &'static str,
    also: Vec<&'static str>,
    /// Accepted mechanisms for (effect).
    mechanisms: Vec<(&'static str, Vec<&'static str>)>,
    params: Vec<check::ParamCheck>,
    /// A word the report's `depends_on` descriptions must contain (outside the catalogue).
    depends_on: Option<&'static str>,
}

fn case(name: &'static str, robot: Robot, seed: u64, mechs: Vec<Mech>) -> Case {
    let mut gen = Gen::new(robot, seed);
    gen.mechs = mechs;
    Case {
        name,
        gen,
        verdict: "none",
        also: vec![],
        mechanisms: vec![],
        params: vec![],
        depends_on: None,
    }
}

fn cases() -> Vec<Case> {
    let deg = std::f64::consts::PI / 180.0;
    let mut out = Vec::new();

    // Controls: white pose noise only, on each robot kind.
    out.push(case("control_diff", dc_diff(), 1901, vec![]));
    out.push(case("control_omni4", presets::omni4(), 1902, vec![]));
    let mut c = case("control_wlr", check::robot_file("wlr"), 1903, vec![]);
    c.gen.legs = ((90.0 * deg, 90.0 * deg), (60.0 * deg, 120.0 * deg));
    out.push(c);

    // Speed droop: a velocity loop of finite gain against Coulomb friction loses a constant
    // rate at every command (friction, no dead zone).
    let mut c = case("droop_friction", dc_diff(), 1911, vec![Mech::Droop(0.8)]);
    c.verdict = "coulomb_friction";
    c.mechanisms = vec![("coulomb_friction", vec!["droop"])];
    c.params = vec![("coulomb_friction", "droop_rad_s", 0.8, 0.2, true)];
    out.push(c);

    // Gear play per wheel (5 deg left, 1.5 deg right) and a 0.5 % diameter mismatch.
    let mut c = case(
        "play_per_wheel_and_ed",
        dc_diff(),
        1912,
        vec![
            Mech::Play(vec![5.0 * deg, 1.5 * deg]),
            Mech::Radius(vec![1.0 - 0.0025, 1.0 + 0.0025]),
        ],
    );
    c.verdict = "any";
    c.also = vec!["backlash", "wheel_diameter_mismatch"];
    c.params = vec![
        (
            "wheel_diameter_mismatch",
            "ed",
            1.0025 / 0.9975,
            0.0015,
            false,
        ),
        ("backlash", "backlash_rad_left", 5.0 * deg, 0.25, true),
        (
            "backlash",
            "backlash_rad_right",
            1.5 * deg,
            1.0 * deg,
            false,
        ),
    ];
    out.push(c);

    // One omni wheel mounted 2.5 degrees off: one parameter, not four radii.
    let mut c = case(
        "omni_one_wheel_angle",
        presets::omni4(),
        1913,
        vec![Mech::MountAngle {
            wheel: 1,
            offset_rad: 2.5 * deg,
        }],
    );
    c.verdict = "wheel_angle_error";
    c.params = vec![(
        "wheel_angle_error",
        "alpha_offset_rad_w2",
        2.5 * deg,
        0.5 * deg,
        false,
    )];
    out.push(c);

    // One omni wheel 6 % further out.
    let mut c = case(
        "omni_one_wheel_distance",
        presets::omni4(),
        1914,
        vec![Mech::MountDistance {
            wheel: 2,
            scale: 1.06,
        }],
    );
    c.verdict = "wheel_position_error";
    c.params = vec![("wheel_position_error", "l_scale_w3", 1.06, 0.015, false)];
    out.push(c);

    // A slippery patch: local loss, not periodic.
    let mut c = case(
        "slippery_patch",
        dc_diff(),
        1915,
        vec![Mech::Patch {
            x0: 0.1,
            x1: 0.5,
            y0: -0.3,
            y1: 0.3,
            keep: 0.85,
        }],
    );
    c.verdict = "floor_bumps";
    c.mechanisms = vec![("floor_bumps", vec!["region"])];
    c.params = vec![
        ("floor_bumps", "loss_per_spacing", 0.15, 0.05, false),
        ("floor_bumps", "start_m", 0.1, 0.1, false),
        ("floor_bumps", "end_m", 0.5, 0.1, false),
    ];
    out.push(c);

    // Cables every 5 cm, each wheel losing 1 mm as it crosses one on its own.
    let mut c = case(
        "cables_wheel_by_wheel",
        dc_diff(),
        1916,
        vec![Mech::Cables {
            spacing: 0.05,
            loss: 0.001,
        }],
    );
    c.verdict = "floor_bumps";
    c.params = vec![
        ("floor_bumps", "spacing_m", 0.05, 0.005, false),
        ("floor_bumps", "loss_per_spacing", 0.02, 0.25, true),
    ];
    out.push(c);

    // Side slip that lags the turn (tyre relaxation length): still lateral slip.
    let mut c = case(
        "tyre_relaxation",
        dc_diff(),
        1917,
        vec![Mech::LaggedSideSlip { k: 0.06, tau: 0.3 }],
    );
    c.verdict = "lateral_slip";
    c.params = vec![("lateral_slip", "side_slip_s", 0.06, 0.3, true)];
    out.push(c);

    // Traction from the leg posture (regression: found two rounds ago).
    let mut c = case(
        "posture_slip_wlr",
        check::robot_file("wlr"),
        1918,
        vec![Mech::PostureTraction { mu: 0.1 }],
    );
    c.gen.legs = ((90.0 * deg, 90.0 * deg), (60.0 * deg, 120.0 * deg));
    c.gen.a_max = 1.5;
    c.verdict = "longitudinal_slip";
    c.params = vec![("longitudinal_slip", "mu", 0.1, 0.3, true)];
    out.push(c);

    // A caster kicking the heading at each reversal: outside the catalogue.
    let mut c = case(
        "caster_kick",
        dc_diff(),
        1919,
        vec![Mech::CasterKick { kick_rad: 0.03 }],
    );
    c.verdict = "unexplained";
    c.depends_on = Some("reversal");
    out.push(c);
    out
}

struct Outcome {
    name: String,
    control: bool,
    verdict_ok: bool,
    full_ok: bool,
    detail: String,
}

fn depends_on_texts(v: &serde_json::Value, out: &mut Vec<String>) {
    match v {
        serde_json::Value::Object(m) => {
            for (k, x) in m {
                if k == "depends_on" {
                    out.push(x.to_string());
                }
                depends_on_texts(x, out);
            }
        }
        serde_json::Value::Array(a) => a.iter().for_each(|x| depends_on_texts(x, out)),
        _ => {}
    }
}

fn run(case: &Case) -> Outcome {
    let (rec, stats) = generate(&case.gen);
    let r = diagnose(&case.gen.robot, &rec, &Options::default()).expect("diagnosable");
    let (verdict_ok, mut problems) =
        check::verdict_and_params(&r, case.verdict, &case.also, &case.params);
    for (e, ok) in &case.mechanisms {
        if let Some(f) = r.findings.iter().find(|f| f.effect == *e) {
            if !ok.contains(&f.mechanism.as_str()) {
                problems.push(format!("{e} mechanism {} (expected {ok:?})", f.mechanism));
            }
        }
    }
    if let Some(word) = case.depends_on {
        let mut texts = Vec::new();
        depends_on_texts(&serde_json::to_value(&r).unwrap(), &mut texts);
        if !texts.iter().any(|t| t.contains(word)) {
            problems.push(format!("no depends_on naming '{word}' ({texts:?})"));
        }
    }
    let detail = format!(
        "{:?} {:?} ground {:.2}->{:.2} mm, actuator {:.3}->{:.3} mm; {stats:?}",
        r.findings
            .iter()
            .map(|f| format!("{}/{}({})", f.effect, f.mechanism, f.fit))
            .collect::<Vec<_>>(),
        r.findings.iter().map(|f| &f.parameters).collect::<Vec<_>>(),
        r.rmse.ground.before_m * 1e3,
        r.rmse.ground.after_m * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.before_m) * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.after_m) * 1e3,
    );
    Outcome {
        name: case.name.to_string(),
        control: case.verdict == "none",
        verdict_ok,
        full_ok: problems.is_empty(),
        detail: format!("verdict {}; {}; {detail}", r.verdict, problems.join("; ")),
    }
}

#[test]
fn independent_mechanisms() {
    let all = cases();
    let outcomes: Vec<Outcome> = check::run_selected(&all, |c| c.name, run);
    for o in &outcomes {
        let tag = match (o.full_ok, o.verdict_ok) {
            (true, _) => "ok  ",
            (false, true) => "part",
            _ => "FAIL",
        };
        println!("{tag} {:26} {}", o.name, o.detail);
    }
    let n = outcomes.len();
    let full = outcomes.iter().filter(|o| o.full_ok).count();
    let verdicts = outcomes.iter().filter(|o| o.verdict_ok).count();
    println!("SCORE: {full}/{n} fully right, {verdicts}/{n} right verdicts");
    let bad: Vec<&str> = outcomes
        .iter()
        .filter(|o| o.control && !o.verdict_ok)
        .map(|o| o.name.as_str())
        .collect();
    assert!(bad.is_empty(), "controls not none: {bad:?}");
}

/// The wheeled-legged posture slip, found two rounds ago and `unexplained` since: the
/// regression check. Identification names it (along-track error that follows
/// acceleration). The body-bound mechanism read what the drive asks from the driven
/// front pair alone, whose kinematics put the body's sideways velocity at the front axle
/// (vy = -omega x_front): every turn then spent grip the robot does not spend, so mu came
/// out 0.1165 for 0.1 and the ground RMSE stayed at 19.6 mm (noise 1.2 mm), `unexplained`.
/// With every wheel's sliding constraint in that reading (`DriveAsks`): mu 0.0981, ground
/// RMSE 70.0 -> 1.67 mm, verdict `longitudinal_slip`.
#[test]
fn posture_slip_regression() {
    let all: Vec<Case> = cases()
        .into_iter()
        .filter(|c| c.name == "posture_slip_wlr")
        .collect();
    let o = run(&all[0]);
    assert!(o.full_ok, "verdict and mu within 30 %: {}", o.detail);
}

/// The generator itself: the droop, the patch, the cables and the reversals happen in the
/// cases that name them (so a case tests its mechanism, not an empty run).
#[test]
fn generator_exercises_its_mechanisms() {
    for c in cases() {
        let (rec, s) = generate(&c.gen);
        assert_eq!(rec.len(), 4001, "{}: 40 s at 100 rows/s", c.name);
        match c.name {
            "slippery_patch" => assert!(s.patch_s > 3.0, "patch visited {} s", s.patch_s),
            "cables_wheel_by_wheel" => assert!(s.crossings > 100, "{} crossings", s.crossings),
            "caster_kick" => assert!(s.reversals >= 5, "{} reversals", s.reversals),
            "posture_slip_wlr" => assert!(s.slipping_s > 2.0, "slipping {} s", s.slipping_s),
            _ => {}
        }
    }
}

/// Prints one case's report, identification and candidates (`DIAG_CASE=name`).
#[test]
#[ignore]
fn explain_independent_case() {
    let filter = std::env::var("DIAG_CASE").unwrap_or_default();
    for c in cases().iter().filter(|c| c.name.contains(filter.as_str())) {
        let (rec, _) = generate(&c.gen);
        let r = diagnose(&c.gen.robot, &rec, &Options::default()).unwrap();
        println!("== {}\n{r}", c.name);
        check::explain(&r);
    }
}
