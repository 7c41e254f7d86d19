//! The third suite: the same physics made by other mechanisms. Every catalogue
//! effect under every mechanism the sim crate has (`mechanism:<name>`), random parameters
//! and trajectories, pairs of effects, and noise-only controls with harder noise
//! (coloured motion-capture noise, jittered sample times, gaps in the pose stream) that
//! must give `none`.
//!
//! Seeds and tolerances were written before the first run and are not tuned afterwards;
//! the first and the current scores are in docs/diagnose.md and below.
//!
//! A case passes fully when the verdict is right, the finding names an accepted
//! mechanism, its parameters are within tolerance with their physical sign, and findings
//! are ordered by explained share. Hard assertions: every noise-only control gives
//! `none`, and at least 80 % of the other cases get the right verdict.
//!
//! First run (commit 'mechanisms suite written...', before any diagnose change of issue
//! 11): SCORE 10/25 fully right, 12/25 right verdicts; 1 of 5 noise controls `none`.
//! Now: SCORE 23/25 fully right, 24/25 right verdicts; 5 of 5 controls `none`.
//! `DIAG_CASE=name` runs only the cases whose name contains it.

mod check;

use calib_core::robot::{presets, Drive, Robot};
use diagnose::{diagnose, Options};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use sim::{record, Effect, Motion, RandomMotion, RecordConfig, Surface};

fn dc_diff() -> Robot {
    presets::diff_drive("dc_diff", 0.05, 0.40, Drive::default())
}

/// (effect, parameter, truth, tolerance, relative?). `loss_per_spacing` = loss / spacing.
type Check = (&'static str, &'static str, f64, f64, bool);

/// Harder noise applied to the recording after simulation.
#[derive(Debug, Clone, Copy, Default)]
struct Harder {
    /// AR(1) motion-capture noise per pose sample: (rho, stationary sigma m, sigma rad).
    coloured: Option<(f64, f64, f64)>,
    /// Logged row times off by up to this many seconds (uniform).
    jitter_s: f64,
    /// Number of gaps (1.5 .. 3 s each) in the pose stream.
    gaps: usize,
}

struct Case {
    name: String,
    /// "effect/mechanism" of the first true effect, for the confusion matrix.
    truth: String,
    robot: Robot,
    effects: Vec<String>,
    seed: u64,
    /// Expected verdict; "any" = one of `also`.
    verdict: &'static str,
    also: Vec<&'static str>,
    /// Accepted mechanisms for (effect).
    mechanisms: Vec<(&'static str, Vec<&'static str>)>,
    params: Vec<Check>,
    a_max: f64,
    harder: Harder,
}

fn cases() -> Vec<Case> {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut out: Vec<Case> = Vec::new();
    let mut seed = 5000;
    #[allow(clippy::too_many_arguments)]
    let mut add = |truth: &str,
                   robot: Robot,
                   effects: Vec<String>,
                   verdict: &'static str,
                   also: Vec<&'static str>,
                   mechanisms: Vec<(&'static str, Vec<&'static str>)>,
                   params: Vec<Check>,
                   a_max: f64,
                   harder: Harder| {
        seed += 1;
        out.push(Case {
            name: format!("{}_{}", truth.replace('/', "_"), seed),
            truth: truth.to_string(),
            robot,
            effects,
            seed,
            verdict,
            also,
            mechanisms,
            params,
            a_max,
            harder,
        });
    };
    let none = Harder::default();
    let r = &mut rng;
    let mut u = |lo: f64, hi: f64| r.random_range(lo..hi);

    // longitudinal_slip: wheel traction limit, body acceleration bound, creep.
    let mu = u(0.025, 0.045);
    add(
        "longitudinal_slip/wheel",
        dc_diff(),
        vec![format!("longitudinal_slip=mu:{mu}")],
        "longitudinal_slip",
        vec![],
        vec![("longitudinal_slip", vec!["wheel"])],
        vec![("longitudinal_slip", "mu", mu, 0.15, true)],
        0.5,
        none,
    );
    let mu = u(0.03, 0.06);
    add(
        "longitudinal_slip/body",
        dc_diff(),
        vec![format!("longitudinal_slip=mu:{mu},mechanism:body")],
        "longitudinal_slip",
        vec![],
        vec![("longitudinal_slip", vec!["body"])],
        vec![("longitudinal_slip", "mu", mu, 0.2, true)],
        1.0,
        none,
    );
    let c = u(0.05, 0.15);
    add(
        "longitudinal_slip/creep",
        dc_diff(),
        vec![format!("longitudinal_slip=mechanism:creep,creep_s:{c}")],
        "longitudinal_slip",
        vec![],
        vec![("longitudinal_slip", vec!["creep"])],
        vec![("longitudinal_slip", "creep_s", c, 0.3, true)],
        1.0,
        none,
    );
    // lateral_slip: linear, saturating.
    let k = u(0.02, 0.08);
    add(
        "lateral_slip/linear",
        dc_diff(),
        vec![format!("lateral_slip=side_slip_s:{k}")],
        "lateral_slip",
        vec![],
        vec![("lateral_slip", vec!["linear"])],
        vec![("lateral_slip", "side_slip_s", k, 0.15, true)],
        0.5,
        none,
    );
    let (k, sat) = (u(0.05, 0.1), u(0.004, 0.008));
    add(
        "lateral_slip/saturating",
        dc_diff(),
        vec![format!(
            "lateral_slip=side_slip_s:{k},mechanism:saturating,sat_m_s:{sat}"
        )],
        "lateral_slip",
        vec![],
        vec![("lateral_slip", vec!["saturating"])],
        vec![("lateral_slip", "sat_m_s", sat, 0.3, true)],
        0.5,
        none,
    );
    // floor_bumps: whole floor, a region (the omni case), irregular spacing.
    let s = u(0.03, 0.06);
    let l = s * u(0.01, 0.03);
    add(
        "floor_bumps/whole",
        dc_diff(),
        vec![format!("floor_bumps=spacing_m:{s},loss_m:{l}")],
        "floor_bumps",
        vec![],
        vec![("floor_bumps", vec!["whole"])],
        vec![("floor_bumps", "loss_per_spacing", l / s, 0.2, true)],
        0.5,
        none,
    );
    let s = u(0.03, 0.06);
    let l = s * u(0.015, 0.03);
    let a = u(-0.2, 0.1);
    let b = a + u(0.4, 0.8);
    add(
        "floor_bumps/region",
        presets::omni4(),
        vec![format!(
            "floor_bumps=spacing_m:{s},loss_m:{l},mechanism:region,start_m:{a},end_m:{b}"
        )],
        "floor_bumps",
        vec![],
        vec![("floor_bumps", vec!["region"])],
        vec![
            ("floor_bumps", "loss_per_spacing", l / s, 0.3, true),
            ("floor_bumps", "start_m", a, 0.1, false),
            ("floor_bumps", "end_m", b, 0.1, false),
        ],
        0.5,
        none,
    );
    let s = u(0.03, 0.06);
    let l = s * u(0.01, 0.03);
    // Irregular spacing keeps the mean loss per metre; single crossings under 1 mm vision
    // noise are not resolved, so the whole-floor mechanism is accepted too.
    add(
        "floor_bumps/irregular",
        dc_diff(),
        vec![format!(
            "floor_bumps=spacing_m:{s},loss_m:{l},mechanism:irregular,jitter:0.4"
        )],
        "floor_bumps",
        vec![],
        vec![("floor_bumps", vec!["irregular", "whole"])],
        vec![("floor_bumps", "loss_per_spacing", l / s, 0.3, true)],
        0.5,
        none,
    );
    // backlash: symmetric, asymmetric.
    let bl = u(0.02, 0.08);
    add(
        "backlash/symmetric",
        dc_diff(),
        vec![format!("backlash=backlash_rad:{bl}")],
        "backlash",
        vec![],
        vec![("backlash", vec!["symmetric"])],
        vec![("backlash", "backlash_rad", bl, 0.1, true)],
        0.5,
        none,
    );
    let (bl, asy) = (u(0.03, 0.08), u(0.3, 0.6));
    add(
        "backlash/asymmetric",
        dc_diff(),
        vec![format!(
            "backlash=backlash_rad:{bl},mechanism:asymmetric,asymmetry:{asy}"
        )],
        "backlash",
        vec![],
        vec![("backlash", vec!["asymmetric"])],
        vec![
            ("backlash", "backlash_rad", bl, 0.15, true),
            ("backlash", "asymmetry", asy, 0.15, false),
        ],
        0.5,
        none,
    );
    // missed_steps: pull-out, quanta of one electrical cycle, full stall (mobolab stepper).
    let am = u(9.0, 16.0);
    add(
        "missed_steps/pull_out",
        check::robot_file("mobolab"),
        vec![format!("missed_steps=max_accel_rad_s2:{am}")],
        "missed_steps",
        vec![],
        vec![("missed_steps", vec!["pull_out"])],
        vec![("missed_steps", "max_accel_rad_s2", am, 0.15, true)],
        0.5,
        none,
    );
    let (am, rate) = (u(6.0, 10.0), u(10.0, 30.0));
    add(
        "missed_steps/quanta",
        check::robot_file("mobolab"),
        vec![format!(
            "missed_steps=max_accel_rad_s2:{am},mechanism:quanta,rate_hz:{rate}"
        )],
        "missed_steps",
        vec![],
        vec![("missed_steps", vec!["quanta"])],
        vec![("missed_steps", "max_accel_rad_s2", am, 0.3, true)],
        0.5,
        none,
    );
    let am = u(9.0, 14.0);
    add(
        "missed_steps/stall",
        check::robot_file("mobolab"),
        vec![format!(
            "missed_steps=max_accel_rad_s2:{am},mechanism:stall"
        )],
        "missed_steps",
        vec![],
        vec![("missed_steps", vec!["stall"])],
        vec![("missed_steps", "max_accel_rad_s2", am, 0.3, true)],
        0.5,
        none,
    );
    // motor_lag: first order, transport delay, slew-rate limit.
    let tau = u(0.03, 0.15);
    add(
        "motor_lag/first_order",
        dc_diff(),
        vec![format!("motor_lag=tau_s:{tau}")],
        "motor_lag",
        vec![],
        vec![("motor_lag", vec!["first_order"])],
        vec![("motor_lag", "tau_s", tau, 0.1, true)],
        0.5,
        none,
    );
    let tau = u(0.04, 0.15);
    add(
        "motor_lag/delay",
        dc_diff(),
        vec![format!("motor_lag=tau_s:{tau},mechanism:delay")],
        "motor_lag",
        vec![],
        vec![("motor_lag", vec!["delay"])],
        vec![("motor_lag", "tau_s", tau, 0.15, true)],
        0.5,
        none,
    );
    let slew = u(3.0, 8.0);
    add(
        "motor_lag/slew",
        dc_diff(),
        vec![format!("motor_lag=mechanism:slew,slew_rad_s2:{slew}")],
        "motor_lag",
        vec![],
        vec![("motor_lag", vec!["slew"])],
        vec![("motor_lag", "slew_rad_s2", slew, 0.2, true)],
        0.5,
        none,
    );
    // coulomb_friction: dead band.
    let d = u(0.5, 2.0);
    add(
        "coulomb_friction/dead_band",
        dc_diff(),
        vec![format!("coulomb_friction=deadband_rad_s:{d}")],
        "coulomb_friction",
        vec![],
        vec![("coulomb_friction", vec!["dead_band"])],
        vec![("coulomb_friction", "deadband_rad_s", d, 0.1, true)],
        0.5,
        none,
    );
    // Pairs. A large diameter mismatch with a small side slip: the mismatch explains the
    // larger share and must be the verdict (the fourth point).
    let k = u(0.02, 0.04);
    add(
        "pair/ed+lateral",
        dc_diff(),
        vec![
            "wheel_diameter_mismatch=ed:1.015".into(),
            format!("lateral_slip=side_slip_s:{k}"),
        ],
        "wheel_diameter_mismatch",
        vec!["wheel_diameter_mismatch", "lateral_slip"],
        vec![("lateral_slip", vec!["linear", "saturating"])],
        vec![
            ("wheel_diameter_mismatch", "ed", 1.015, 0.001, false),
            ("lateral_slip", "side_slip_s", k, 0.25, true),
        ],
        0.5,
        none,
    );
    let (bl, mu) = (u(0.03, 0.08), u(0.03, 0.06));
    add(
        "pair/backlash+body_slip",
        dc_diff(),
        vec![
            format!("backlash=backlash_rad:{bl}"),
            format!("longitudinal_slip=mu:{mu},mechanism:body"),
        ],
        "any",
        vec!["backlash", "longitudinal_slip"],
        vec![
            ("longitudinal_slip", vec!["body"]),
            ("backlash", vec!["symmetric"]),
        ],
        vec![
            ("backlash", "backlash_rad", bl, 0.15, true),
            ("longitudinal_slip", "mu", mu, 0.25, true),
        ],
        1.0,
        none,
    );
    let tau = u(0.04, 0.12);
    let s = u(0.03, 0.06);
    let l = s * u(0.015, 0.03);
    add(
        "pair/delay+region_bumps",
        presets::omni4(),
        vec![
            format!("motor_lag=tau_s:{tau},mechanism:delay"),
            format!("floor_bumps=spacing_m:{s},loss_m:{l},mechanism:region,start_m:-0.2,end_m:0.4"),
        ],
        "any",
        vec!["motor_lag", "floor_bumps"],
        vec![
            ("motor_lag", vec!["delay"]),
            ("floor_bumps", vec!["region"]),
        ],
        vec![("motor_lag", "tau_s", tau, 0.2, true)],
        0.5,
        none,
    );
    // Noise-only controls with harder noise.
    let coloured = Some((0.97, 0.002, 0.004));
    add(
        "none/coloured",
        dc_diff(),
        vec![],
        "none",
        vec![],
        vec![],
        vec![],
        0.5,
        Harder { coloured, ..none },
    );
    add(
        "none/jitter",
        check::robot_file("mobolab"),
        vec![],
        "none",
        vec![],
        vec![],
        vec![],
        0.5,
        Harder {
            jitter_s: 0.004,
            ..none
        },
    );
    add(
        "none/gaps",
        presets::omni4(),
        vec![],
        "none",
        vec![],
        vec![],
        vec![],
        0.5,
        Harder { gaps: 3, ..none },
    );
    add(
        "none/all",
        dc_diff(),
        vec![],
        "none",
        vec![],
        vec![],
        vec![],
        1.0,
        Harder {
            coloured,
            jitter_s: 0.004,
            gaps: 3,
        },
    );
    add(
        "none/all",
        check::robot_file("omni3"),
        vec![],
        "none",
        vec![],
        vec![],
        vec![],
        0.5,
        Harder {
            coloured,
            jitter_s: 0.004,
            gaps: 3,
        },
    );
    out
}

/// Applies the harder noise to a recording (seeded from the case).
fn harden(rec: &mut formats::recording::Recording, h: Harder, seed: u64) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0xc0105ed);
    if let Some((rho, sxy, sth)) = h.coloured {
        let innov = (1.0 - rho * rho).sqrt();
        let (nxy, nth) = (
            Normal::new(0.0, sxy * innov).unwrap(),
            Normal::new(0.0, sth * innov).unwrap(),
        );
        let (mut ex, mut ey, mut et) = (0.0, 0.0, 0.0);
        for k in 0..rec.t.len() {
            if rec.x[k].is_none() {
                continue;
            }
            ex = rho * ex + nxy.sample(&mut rng);
            ey = rho * ey + nxy.sample(&mut rng);
            et = rho * et + nth.sample(&mut rng);
            rec.x[k] = rec.x[k].map(|v| v + ex);
            rec.y[k] = rec.y[k].map(|v| v + ey);
            rec.theta[k] = rec.theta[k].map(|v| v + et);
        }
    }
    if h.jitter_s > 0.0 {
        for t in rec.t.iter_mut().skip(1) {
            *t += rng.random_range(-h.jitter_s..h.jitter_s);
        }
    }
    let end = rec.t.last().copied().unwrap_or(0.0);
    for _ in 0..h.gaps {
        let a = rng.random_range(2.0..end - 5.0);
        let b = a + rng.random_range(1.5..3.0);
        for k in 0..rec.t.len() {
            if rec.t[k] > a && rec.t[k] < b {
                rec.x[k] = None;
                rec.y[k] = None;
                rec.theta[k] = None;
            }
        }
    }
}

fn simulate(case: &Case) -> formats::recording::Recording {
    let effects: Vec<Effect> = case
        .effects
        .iter()
        .map(|s| Effect::parse(s).unwrap())
        .collect();
    let mut cfg = RecordConfig::default();
    cfg.sim.seed = case.seed;
    cfg.row_rate_hz = 50.0;
    let motion = Motion::Random(RandomMotion {
        duration_s: 40.0,
        v_max_m_s: 0.3,
        a_max_m_s2: case.a_max,
        ..RandomMotion::default()
    });
    let mut rec = record(&case.robot, &effects, Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording;
    harden(&mut rec, case.harder, case.seed);
    rec
}

struct Outcome {
    name: String,
    truth: String,
    got: String,
    control: bool,
    verdict_ok: bool,
    full_ok: bool,
    detail: String,
}

fn run(case: &Case) -> Outcome {
    let rec = simulate(case);
    let r = diagnose(&case.robot, &rec, &Options::default()).expect("diagnosable");
    let (verdict_ok, mut problems) =
        check::verdict_and_params(&r, case.verdict, &case.also, &case.params);
    for (e, ok) in &case.mechanisms {
        if let Some(f) = r.findings.iter().find(|f| f.effect == *e) {
            if !ok.contains(&f.mechanism.as_str()) {
                problems.push(format!("{e} mechanism {} (expected {ok:?})", f.mechanism));
            }
            if f.implausible_sign {
                problems.push(format!("{e} marked implausible"));
            }
        }
    }
    if r.findings
        .windows(2)
        .any(|w| w[0].explained_share < w[1].explained_share)
    {
        problems.push("findings not ordered by explained_share".into());
    }
    let detail = format!(
        "{:?} {:?} ground {:.2}->{:.2} mm, actuator {:.3}->{:.3} mm",
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
        name: case.name.clone(),
        truth: case.truth.clone(),
        got: r.verdict.to_string(),
        control: case.verdict == "none",
        verdict_ok,
        full_ok: problems.is_empty(),
        detail: if problems.is_empty() {
            detail
        } else {
            format!("{}; {detail}", problems.join("; "))
        },
    }
}

/// Confusion matrix by mechanism (rows: first true effect/mechanism, columns: verdict).
fn confusion(outcomes: &[Outcome]) {
    let mut cols: Vec<String> = outcomes.iter().map(|o| o.got.clone()).collect();
    cols.sort();
    cols.dedup();
    let mut rows: Vec<String> = outcomes.iter().map(|o| o.truth.clone()).collect();
    rows.sort();
    rows.dedup();
    let short = |s: &str| s.chars().take(10).collect::<String>();
    println!("\nconfusion matrix by mechanism (rows: truth, columns: verdict)");
    print!("{:30}", "");
    for c in &cols {
        print!("{:>11}", short(c));
    }
    println!();
    for t in &rows {
        print!("{t:30}");
        for c in &cols {
            let n = outcomes
                .iter()
                .filter(|o| &o.truth == t && &o.got == c)
                .count();
            print!("{:>11}", if n == 0 { ".".into() } else { n.to_string() });
        }
        println!();
    }
    println!();
}

/// Prints one case's full report and every candidate tried (`DIAG_CASE=name`).
#[test]
#[ignore]
fn explain_mechanism_case() {
    let filter = std::env::var("DIAG_CASE").unwrap_or_default();
    for c in cases().iter().filter(|c| c.name.contains(filter.as_str())) {
        let rec = simulate(c);
        let r = diagnose(&c.robot, &rec, &Options::default()).unwrap();
        println!("== {} {:?}\n{r}", c.name, c.effects);
        check::explain(&r);
    }
}

#[test]
fn other_mechanisms() {
    let all = cases();
    let outcomes: Vec<Outcome> = check::run_selected(&all, |c| c.name.as_str(), run);
    confusion(&outcomes);
    for o in &outcomes {
        let tag = match (o.full_ok, o.verdict_ok) {
            (true, _) => "ok  ",
            (false, true) => "part",
            _ => "FAIL",
        };
        println!("{tag} {:34} {}", o.name, o.detail);
    }
    let n = outcomes.len();
    let full = outcomes.iter().filter(|o| o.full_ok).count();
    let verdicts = outcomes.iter().filter(|o| o.verdict_ok).count();
    println!("SCORE: {full}/{n} fully right, {verdicts}/{n} right verdicts");
    let bad_controls: Vec<&str> = outcomes
        .iter()
        .filter(|o| o.control && !o.verdict_ok)
        .map(|o| o.name.as_str())
        .collect();
    assert!(
        bad_controls.is_empty(),
        "controls not none: {bad_controls:?}"
    );
    let effects: Vec<&Outcome> = outcomes.iter().filter(|o| !o.control).collect();
    let right = effects.iter().filter(|o| o.verdict_ok).count();
    assert!(
        effects.is_empty() || right as f64 >= 0.8 * effects.len() as f64,
        "only {right}/{} effect cases get the right verdict",
        effects.len()
    );
}
