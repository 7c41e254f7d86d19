//! The checks every diagnose suite makes of a report against its case's truth, in one
//! place so the suites (sim, generator, mechanisms, independent, blind) judge alike.

// Each suite uses part of this module.
#![allow(dead_code)]

use calib_core::robot::Robot;
use diagnose::report::Report;

/// A robot file of the repository's `robots/` folder by name (`mobolab`, `omni3`...).
pub fn robot_file(name: &str) -> Robot {
    let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

/// Prints what identification found and every candidate diagnose tried, round by round
/// (the suites' explain tests).
pub fn explain(r: &Report) {
    for t in &r.identification {
        println!("  identified: {}", t.depends_on);
    }
    for x in &r.candidates {
        println!(
            "  round {} {:24} dBIC {:10.1} held-out {:?} {:?} {}",
            x.round,
            format!("{:?}", x.effect),
            x.delta_bic,
            x.heldout_ratio,
            x.parameters,
            x.note
        );
    }
}

/// A parameter to check: (effect, parameter, truth, tolerance, relative?). The parameter
/// `loss_per_spacing` is the travel lost per metre of floor bumps (loss_m / spacing_m):
/// spacing and loss separate only when single crossings stand out of the pose noise, their
/// ratio always does.
pub type ParamCheck = (&'static str, &'static str, f64, f64, bool);

/// Whether the verdict is right (`any`: one of `also`), and what else is wrong: effects of
/// `also` not found, parameters outside their tolerance.
pub fn verdict_and_params(
    r: &Report,
    verdict: &str,
    also: &[&str],
    params: &[ParamCheck],
) -> (bool, Vec<String>) {
    let found: Vec<&str> = r.findings.iter().map(|f| f.effect.as_str()).collect();
    let mut problems = Vec::new();
    let verdict_ok = if verdict == "any" {
        also.contains(&r.verdict.as_str())
    } else {
        r.verdict == verdict
    };
    if !verdict_ok {
        problems.push(format!("verdict {} (expected {verdict})", r.verdict));
    }
    for e in also {
        if !found.contains(e) {
            problems.push(format!("{e} not found"));
        }
    }
    for (e, p, truth, tol, rel) in params {
        let Some(f) = r.findings.iter().find(|f| f.effect == *e) else {
            continue;
        };
        let get = |k: &str| f.parameters.get(k).copied().unwrap_or(f64::NAN);
        let v = if *p == "loss_per_spacing" {
            get("loss_m") / get("spacing_m")
        } else {
            get(p)
        };
        let err = if *rel {
            (v / truth - 1.0).abs()
        } else {
            (v - truth).abs()
        };
        if err.is_nan() || err > *tol {
            problems.push(format!("{e}.{p} = {v:.5}, truth {truth:.5} (tol {tol})"));
        }
    }
    (verdict_ok, problems)
}

/// Every finding must lower its stage's RMSE (the sim and generator suites ask it; the
/// mechanisms suite judges partial fits by their signature instead).
#[allow(dead_code)]
pub fn every_finding_improves(r: &Report) -> Vec<String> {
    r.findings
        .iter()
        .filter(|f| f.rmse_after_m.is_nan() || f.rmse_after_m >= f.rmse_before_m)
        .map(|f| format!("{} does not improve its RMSE", f.effect))
        .collect()
}

/// The cases whose name contains `DIAG_CASE` (all when unset), run on two workers (the
/// machine has two cores), outcomes in case order.
pub fn run_selected<C: Sync, O: Send>(
    all: &[C],
    name: impl Fn(&C) -> &str,
    run: impl Fn(&C) -> O + Sync,
) -> Vec<O> {
    let filter = std::env::var("DIAG_CASE").ok();
    let selected: Vec<&C> = all
        .iter()
        .filter(|c| filter.as_ref().is_none_or(|f| name(c).contains(f.as_str())))
        .collect();
    let run = &run;
    std::thread::scope(|s| {
        let half = selected.len().div_ceil(2).max(1);
        let hs: Vec<_> = selected
            .chunks(half)
            .map(|chunk| s.spawn(move || chunk.iter().map(|c| run(c)).collect::<Vec<_>>()))
            .collect();
        hs.into_iter().flat_map(|h| h.join().unwrap()).collect()
    })
}

/// One case's result in a suite that scores verdicts (blind, habits).
pub struct Outcome {
    pub name: String,
    /// A noise-only case (its right verdict is `none`).
    pub control: bool,
    pub verdict: String,
    pub verdict_ok: bool,
    /// The verdict and every check of the case right.
    pub full_ok: bool,
    /// A catalogue effect named as the verdict where another (or none) was right.
    pub wrong_effect: bool,
    pub seconds: f64,
    pub detail: String,
}

/// Whether a wrong verdict named a catalogue effect (not `none` or `unexplained`): the
/// worst miss, an answer a user would act on.
pub fn wrong_effect(verdict: &str, verdict_ok: bool) -> bool {
    !verdict_ok && verdict != "none" && verdict != "unexplained"
}

/// A suite's counts over its outcomes.
pub struct Score {
    pub n: usize,
    pub full: usize,
    pub verdicts: usize,
    pub wrong: usize,
    pub controls: usize,
    pub controls_ok: usize,
}

/// Prints each outcome (tagged `ok`, `part`: the verdict right, `FAIL`) and the suite's
/// SCORE line, started at `t0`; returns the counts.
pub fn score(outcomes: &[Outcome], t0: std::time::Instant) -> Score {
    for o in outcomes {
        let tag = match (o.full_ok, o.verdict_ok) {
            (true, _) => "ok  ",
            (false, true) => "part",
            _ => "FAIL",
        };
        println!(
            "{tag} {:34} {:5.1} s verdict {}; {}",
            o.name, o.seconds, o.verdict, o.detail
        );
    }
    let count = |f: &dyn Fn(&Outcome) -> bool| outcomes.iter().filter(|o| f(o)).count();
    let s = Score {
        n: outcomes.len(),
        full: count(&|o| o.full_ok),
        verdicts: count(&|o| o.verdict_ok),
        wrong: count(&|o| o.wrong_effect),
        controls: count(&|o| o.control),
        controls_ok: count(&|o| o.control && o.verdict_ok),
    };
    println!(
        "SCORE: {}/{n} fully right, {}/{n} right verdicts, {}/{} controls none, {} wrong effects named; {:.1} s",
        s.full,
        s.verdicts,
        s.controls_ok,
        s.controls,
        s.wrong,
        t0.elapsed().as_secs_f64(),
        n = s.n
    );
    s
}
