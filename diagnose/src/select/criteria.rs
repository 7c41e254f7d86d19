//! What a candidate is measured by: the stage whose data speak for an effect, that
//! stage's RMSE and chi-square per residual, the discounted BIC change, and the
//! thresholds a fitted effect must pass. Every other part of the selection (the fits,
//! the choice among them, the verdict) measures with these, so they sit below all of it.

use crate::effects::{Effect, Stage};
use crate::residuals::{Eval, Evaluator, Fold, StageRss};

/// Accept an effect only if the BIC drops by more than this ("very strong" evidence on
/// Kass and Raftery's scale).
pub const BIC_THRESHOLD: f64 = -10.0;
/// Held-out sum of squares must drop by at least this fraction.
pub const HELDOUT_MIN_GAIN: f64 = 0.02;
/// The effect's stage RMSE must drop by at least this fraction.
pub const RMSE_MIN_GAIN: f64 = 0.03;

/// Which stage's data speak for an effect.
pub fn evidence_stage(ev: &Evaluator, e: Effect) -> Stage {
    if e.stage() == Stage::Actuator && !ev.actuator_wheels().is_empty() {
        Stage::Actuator
    } else {
        Stage::Ground
    }
}

pub(super) fn stage_rmse(r: &StageRss, s: Stage) -> f64 {
    match s {
        Stage::Ground => r.ground_rmse(),
        Stage::Actuator => r.actuator_rmse(),
    }
}

/// Discounted BIC change of `cand` against `base` (negative favours `cand`).
pub(super) fn delta_bic(ev: &Evaluator, base: &Eval, cand: &Eval, k: usize, stage: Stage) -> f64 {
    let (rb, rc) = (ev.rss(base, Fold::All), ev.rss(cand, Fold::All));
    let mut total = 0.0;
    let mut n_penalty = 1.0;
    for s in [Stage::Ground, Stage::Actuator] {
        let n = match s {
            Stage::Ground => 3 * rc.n_pose + rc.n_free,
            Stage::Actuator => rc.n_act,
        } as f64;
        let (c0, c1) = (ev.chi2(&rb, s), ev.chi2(&rc, s));
        if n < 1.0 || c0 <= 0.0 || c1 <= 0.0 {
            continue;
        }
        let rho = ev.autocorrelation(cand, s);
        let n_eff = (n * (1.0 - rho) / (1.0 + rho)).max(1.0);
        if (c1 - c0).abs() > 1e-12 * c0 {
            total += n_eff * (c1 / c0).ln();
        }
        if s == stage {
            n_penalty = n_eff.max(2.0);
        }
    }
    total + k as f64 * n_penalty.ln()
}

/// Parameter names and values of an effect for this robot.
pub fn named(robot: &calib_core::Robot, e: Effect, vals: &[f64]) -> Vec<(String, f64)> {
    e.params(robot)
        .into_iter()
        .zip(vals)
        .map(|(s, v)| (s.name, *v))
        .collect()
}

/// Chi-square per residual of each stage for `r`, as the verdict counts it: the ground
/// stage against the pose noise, the actuator stage against at least sqrt(2) encoder
/// counts (below that a mismatch is not resolved from the sampling within a row).
pub(super) fn stage_chi2(ev: &Evaluator, r: &StageRss, s: Stage) -> Option<f64> {
    let n = match s {
        Stage::Ground => 3 * r.n_pose + r.n_free,
        Stage::Actuator => r.n_act,
    } as f64;
    if n < 1.0 {
        return None;
    }
    Some(match s {
        Stage::Ground => ev.chi2(r, s) / n,
        Stage::Actuator => {
            let sigma2 = ev
                .noise
                .actuator_sigma_m
                .max(ev.actuator_quantum_m() * 2f64.sqrt())
                .powi(2);
            r.act / sigma2 / n
        }
    })
}
