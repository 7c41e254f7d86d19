//! The verdict, decided once, here: how much of each stage's excess over the noise the
//! findings explain, each finding's share of it, the findings their signatures name,
//! which findings are implausible, and then the rule ([`super::decide`]) on the best
//! plausible one.

use super::by_signature::name_by_signature;
use super::criteria::stage_chi2;
use super::decide::{decide, Outcome};
use super::rounds::Selection;
use crate::effects::Stage;
use crate::finding::{Finding, Fit, Verdict};
use crate::identify::Term;
use crate::plausibility::Implausible;
use crate::residuals::Evaluator;
use crate::signature;
use crate::thresholds::{MISMATCH_CHI2, RESIDUAL_CHI2};

/// The verdict and the explained fraction; fills each finding's `explained_share`,
/// `implausible_sign`, signature and `fit`, adds findings named by signature alone, and
/// orders the findings by explained share. `left_terms` is the identification of what the
/// findings leave ([`decide`] weighs it).
pub fn verdict(
    ev: &Evaluator,
    sel: &Selection,
    findings: &mut Vec<Finding>,
    left_terms: &[Term],
    nominal_terms: &[Term],
) -> Decided {
    let excess = Excess::count(ev, sel, findings, left_terms);
    let explained_fraction = excess.explained_fraction();
    excess.share_out(ev, sel, findings);
    name_by_signature(ev, sel, findings, 1.0 - explained_fraction);
    findings.sort_by(|a, b| b.explained_share.total_cmp(&a.explained_share));
    // The verdict is decided here only: a finding outside its physical range,
    // or floor bumps whose loss is not where the bumps are, is listed, never the verdict.
    let implausible = implausible(ev, sel, findings);
    let verdict = weigh(
        findings,
        &implausible,
        &excess,
        explained_fraction,
        left_terms,
        nominal_terms,
    );
    // The verdict's fit: partial when the findings leave a counted stage far outside the
    // noise (what is left is said under `depends_on`).
    let far = excess.mismatch && excess.worst_final > RESIDUAL_CHI2;
    let fit = match verdict {
        Verdict::Effect(_) if far => Some(Fit::Partial),
        Verdict::Effect(_) => Some(Fit::Full),
        _ => None,
    };
    // A named effect whose fit leaves the residual far outside the noise is partial.
    for f in findings.iter_mut() {
        if f.signature.is_some() && excess.worst_final > RESIDUAL_CHI2 && f.fit == Fit::Full {
            f.fit = Fit::Partial;
            f.residual_left_m = Some(f.rmse_after_m);
        }
    }
    Decided {
        verdict,
        fit,
        explained_fraction,
        implausible,
    }
}

/// What [`verdict`] decided.
#[derive(Debug, Clone)]
pub struct Decided {
    /// The verdict.
    pub verdict: Verdict,
    /// How far the verdict's family explains the excess: `Partial` when a remainder is
    /// left far outside the noise; `None` for `none` and `unexplained`.
    pub fit: Option<Fit>,
    /// Share of the excess over noise the findings explain.
    pub explained_fraction: f64,
    /// Findings outside their physical range.
    pub implausible: Vec<Implausible>,
}

/// The excess over the noise of the stages the verdict counts, before and after the
/// findings.
struct Excess {
    /// Sum over the counted stages of the nominal chi-square per residual over 1.
    before: f64,
    /// The same after the findings (a remainder that is noise counts nothing).
    after: f64,
    /// The largest chi-square per residual a counted stage is left with.
    worst_final: f64,
    /// Some counted stage started outside the noise.
    mismatch: bool,
    /// The stages counted: outside the noise at the start.
    counted: Vec<Stage>,
}

impl Excess {
    /// Counts each stage's excess over the noise before and after the findings.
    fn count(ev: &Evaluator, sel: &Selection, findings: &[Finding], left_terms: &[Term]) -> Self {
        let mut x = Excess {
            before: 0.0,
            after: 0.0,
            worst_final: 0.0,
            mismatch: false,
            counted: Vec::new(),
        };
        for s in [Stage::Ground, Stage::Actuator] {
            let (Some(c0), Some(c1)) = (
                stage_chi2(ev, &sel.nominal, s),
                stage_chi2(ev, &sel.final_rss, s),
            ) else {
                continue;
            };
            // The actuator stage starts from its timing floor (the nominal model with the best
            // sub-quarter-row delay, see `act_floor_rss`): what such a delay explains is
            // logging, not physics.
            let c0 = if s == Stage::Actuator {
                c0.min(ev.act_floor_rss.get() / sel.nominal.act.max(1e-300) * c0)
            } else {
                c0
            };
            let c1 = c1.min(c0);
            // A stage nothing was found on whose residual does not drift is noise, however
            // coloured (motion capture correlated over a second, jittered sample times).
            let found_here = findings.iter().any(|f| f.rmse_stage == s);
            if !found_here && signature::stage_is_noise(ev, &sel.nominal_eval, s == Stage::Ground) {
                continue;
            }
            if c0 > MISMATCH_CHI2 {
                x.mismatch = true;
                x.before += c0 - 1.0;
                // What the findings leave on a stage, when it does not drift, is noise however
                // coloured: the short-interval noise estimate misses correlated motion-capture
                // noise (3 mm correlated over a second read as 0.5 mm), and the remainder is
                // then no evidence of physics left out, provided the findings took the stage
                // out of that noise's own level (the nominal chi-square over the final one
                // above MISMATCH_CHI2: a finding that barely moved it explains nothing) and
                // identification ties nothing left to the motion (a tilted floor's remainder
                // after a slip fit, 62 mm, does not drift either, but follows the heading).
                let remainder_is_noise = found_here
                    && left_terms.is_empty()
                    && c0 > MISMATCH_CHI2 * c1
                    && signature::stage_is_noise(ev, &sel.final_eval, s == Stage::Ground);
                if !remainder_is_noise {
                    x.after += (c1 - 1.0).max(0.0);
                    x.worst_final = x.worst_final.max(c1);
                }
                x.counted.push(s);
            }
        }
        x
    }

    /// Share of the excess the findings explain.
    fn explained_fraction(&self) -> f64 {
        if self.before > 0.0 {
            (1.0 - self.after / self.before).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// Each finding's share: the drop of the counted stages' chi-square when it was
    /// added. Also marks a side-slip coefficient below zero as implausible.
    fn share_out(&self, ev: &Evaluator, sel: &Selection, findings: &mut [Finding]) {
        for (f, st) in findings.iter_mut().zip(&sel.steps) {
            let mut d = 0.0;
            for &s in &self.counted {
                if let (Some(b), Some(a)) =
                    (stage_chi2(ev, &st.before, s), stage_chi2(ev, &st.after, s))
                {
                    d += b - a;
                }
            }
            f.explained_share = if self.before > 0.0 {
                (d / self.before).clamp(0.0, 1.0)
            } else {
                0.0
            };
            // Physical signs: a side-slip coefficient is not negative (the log-fitted
            // parameters cannot be).
            f.implausible_sign = f.parameters.get("side_slip_s").is_some_and(|k| *k < 0.0);
        }
    }
}

/// Findings that are listed, never the verdict: outside their physical range, floor
/// bumps whose loss is not where the bumps are, play that does not sit at reversals.
fn implausible(ev: &Evaluator, sel: &Selection, findings: &[Finding]) -> Vec<Implausible> {
    let mut implausible = crate::plausibility::check(findings);
    implausible.extend(crate::plausibility::bumps_not_localised(
        ev, &sel.model, findings,
    ));
    implausible.extend(crate::plausibility::play_not_at_reversals(
        ev,
        &sel.nominal_eval,
        findings,
    ));
    implausible
}

/// The verdict ([`decide`]) on the best plausible finding of `findings` (ordered by
/// share), with the share of the excess its family explains and whether identification
/// of the nominal residual (`nominal_terms`) names it.
fn weigh(
    findings: &[Finding],
    implausible: &[Implausible],
    excess: &Excess,
    explained_fraction: f64,
    left_terms: &[Term],
    nominal_terms: &[Term],
) -> Verdict {
    let plausible =
        |f: &Finding| !f.implausible_sign && !implausible.iter().any(|i| i.effect == f.effect);
    let top = findings.iter().find(|f| plausible(f));
    // The share of the excess the top finding's family explains (its mechanisms together).
    let family_share = top.map_or(0.0, |t| {
        findings
            .iter()
            .filter(|f| f.effect == t.effect && plausible(f))
            .map(|f| f.explained_share)
            .sum::<f64>()
    });
    let named = crate::identify::named_effects(nominal_terms);
    let family_identified = top.is_some_and(|t| named.iter().any(|e| e.id() == t.effect));
    let outcome = Outcome {
        family_identified,
        mismatch: excess.mismatch,
        explained_fraction,
        worst_final: excess.worst_final,
        left_outside_catalogue: left_terms
            .iter()
            .any(|t| !crate::identify::regressor_has_physics(&t.regressor)),
        family_share,
    };
    decide(top, &outcome)
}
