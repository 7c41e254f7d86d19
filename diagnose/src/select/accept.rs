//! Whether a round's candidate joins the model, and how: it must improve its stage's
//! RMSE visibly (beyond half an encoder count on the actuator stage), not be a lag a
//! logging convention explains, predict held-out data, and as a per-wheel form hold
//! out clearly better than one value for every wheel. An accepted effect is refitted
//! jointly with the effects it interacts with.

use super::criteria::{stage_rmse, HELDOUT_MIN_GAIN, RMSE_MIN_GAIN};
use super::fit::fit_params;
use super::heldout::heldout_ratio;
use super::per_wheel::{one_value_form, PER_WHEEL_HELDOUT_SHARE};
use crate::effects::{Effect, Model, Stage};
use crate::residuals::{Eval, Evaluator, Fold, StageRss};

/// A candidate under examination: its fit and what it does to the model's residuals.
pub(super) struct Examined<'a> {
    /// The effect.
    pub effect: Effect,
    /// The round's model with the effect fitted.
    pub model: &'a Model,
    /// Its evidence stage.
    pub stage: Stage,
    /// Sums of squares of the round's model.
    pub before: &'a StageRss,
    /// Sums of squares with the effect.
    pub after: &'a StageRss,
    /// Its held-out ratio.
    pub heldout_ratio: f64,
}

/// Why the candidate `c` is rejected, if it is. `base`: the round's model;
/// `one_values`: the parameters of every mechanism fitted this round (a per-wheel form's
/// one-value form is held out from them).
pub(super) fn rejection(
    ev: &Evaluator,
    base: &Model,
    c: &Examined,
    one_values: &[(Effect, Vec<f64>)],
) -> Option<String> {
    let (e, m, stage, ratio) = (c.effect, c.model, c.stage, c.heldout_ratio);
    let (before, after) = (c.before, c.after);
    let gain = 1.0 - stage_rmse(after, stage) / stage_rmse(before, stage).max(1e-300);
    // Below an encoder count the actuator stage cannot tell a physical effect from
    // the simulation or logging of the command (a control tick's delay).
    let quantum = ev.actuator_quantum_m();
    if stage == Stage::Actuator
        && stage_rmse(before, stage) - stage_rmse(after, stage) < 0.5 * quantum
    {
        return Some(format!(
            "improves the actuator RMSE by less than half an encoder count ({:.3} mm)",
            0.5 * quantum * 1e3
        ));
    }
    if matches!(e, Effect::MotorLag | Effect::LagDelay)
        && m.get(e).is_some_and(|p| p[0] < 0.25 * ev.p.row_dt_s())
    {
        return Some("a lag under a quarter row is a logging convention, not physics".into());
    }
    if gain < RMSE_MIN_GAIN {
        return Some(format!(
            "improves the {stage} RMSE by only {:.1} %",
            gain * 100.0
        ));
    }
    if ratio > 1.0 - HELDOUT_MIN_GAIN {
        return Some("does not predict held-out data".into());
    }
    // A per-wheel form must hold out better than one value for every wheel, which
    // is then examined next.
    let one = one_value_form(e)
        .and_then(|o| one_values.iter().find(|(x, _)| *x == o))
        .map(|(o, p)| (*o, heldout_ratio(ev, base, *o, p)));
    if let Some((_, r1)) = one.filter(|(_, r1)| ratio > PER_WHEEL_HELDOUT_SHARE * r1) {
        return Some(format!(
            "holds out no better than one value for every wheel (held-out ratio {ratio:.4} against {r1:.4})"
        ));
    }
    None
}

/// Joint refit of the accepted effect `e` (its fit: model `m`, uncertainties `sig`,
/// residuals `cand_eval` with sums of squares `after`) with those it interacts with: the
/// same stage, or everything when some wheel's motion comes from the actuator model. The
/// joint fit is kept when it lowers the chi-square. Returns the new model and its
/// residuals; `sigma` takes the new uncertainties.
pub(super) fn joint_refit(
    ev: &Evaluator,
    e: Effect,
    m: Model,
    sig: Vec<Vec<f64>>,
    cand_eval: Eval,
    after: StageRss,
    sigma: &mut Vec<(Effect, Vec<f64>)>,
) -> (Model, Eval) {
    let coupled: Vec<Effect> = m
        .effects
        .iter()
        .map(|(x, _)| *x)
        .filter(|x| x.stage() == e.stage() || ev.ground_uses_actuator())
        .collect();
    let start: Vec<f64> = coupled
        .iter()
        .flat_map(|x| m.get(*x).unwrap_or(&[]).to_vec())
        .collect();
    sigma.push((e, sig.into_iter().next().unwrap_or_default()));
    if coupled.len() <= 1 {
        return (m, cand_eval);
    }
    let (mj, sj, _) = fit_params(ev, &m, &coupled, &[start], Fold::All);
    let joint_eval = ev.evaluate(&mj, Fold::All);
    let (rj, ra) = (ev.rss(&joint_eval, Fold::All), after);
    if ev.chi2(&rj, Stage::Ground) + ev.chi2(&rj, Stage::Actuator)
        <= ev.chi2(&ra, Stage::Ground) + ev.chi2(&ra, Stage::Actuator)
    {
        for (x, sx) in coupled.iter().zip(sj) {
            sigma.retain(|(y, _)| y != x);
            sigma.push((*x, sx));
        }
        (mj, joint_eval)
    } else {
        (m, cand_eval)
    }
}
