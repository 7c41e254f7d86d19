//! Findings named by their signature alone: whole electrical cycles lost by a stepper
//! (missed steps) and travel lost over one stretch of the floor (floor bumps in a
//! region). No mechanism need fit them fully; the signature is said beside a fitted
//! finding of the same effect, or added as a partial finding of its own.

use super::rounds::Selection;
use crate::effects::{Effect, Model, Stage};
use crate::finding::{Finding, Fit};
use crate::residuals::Evaluator;
use crate::signature;
use formats::catalogue as cat;

/// Names the effects their signatures show in what the selection left: a stepper's
/// quanta (missed steps) and travel lost over one stretch of the floor (floor bumps in
/// a region). The signature is said on the fitted finding of its effect, or added as a
/// partial finding whose share is `left` (what the fitted findings leave).
pub(super) fn name_by_signature(
    ev: &Evaluator,
    sel: &Selection,
    findings: &mut Vec<Finding>,
    left: f64,
) {
    let steps = signature::stepper_steps(ev, &sel.nominal_eval).filter(|s| s.clear());
    // The region signature is looked for in what is left without any floor bumps the
    // selection fitted: bumps in the model would hide the very loss that names them.
    let without_bumps = Model {
        effects: sel
            .model
            .effects
            .iter()
            .filter(|(e, _)| e.base() != Effect::FloorBumps)
            .cloned()
            .collect(),
    };
    let region = signature::region_loss(ev, &without_bumps).filter(|r| r.clear());
    let stage_rmse = |s: Stage| match s {
        Stage::Ground => (sel.nominal.ground_rmse(), sel.final_rss.ground_rmse()),
        Stage::Actuator => (sel.nominal.actuator_rmse(), sel.final_rss.actuator_rmse()),
    };
    if let Some(st) = &steps {
        let text = stepper_words(st);
        match findings.iter_mut().find(|f| f.effect == cat::MISSED_STEPS) {
            Some(f) => f.signature = Some(text),
            None => {
                let (b, a) = stage_rmse(Stage::Actuator);
                findings.push(partial(
                    cat::MISSED_STEPS,
                    "quanta",
                    Stage::Actuator,
                    b,
                    a,
                    left,
                    text,
                ));
            }
        }
    }
    if let Some(r) = &region {
        let text = region_words(r);
        match findings.iter_mut().find(|f| f.effect == cat::FLOOR_BUMPS) {
            Some(f) => f.signature = Some(text),
            None => {
                let (b, a) = stage_rmse(Stage::Ground);
                let mut f = partial(cat::FLOOR_BUMPS, "region", Stage::Ground, b, a, left, text);
                f.parameters.insert("start_m".into(), r.start_m);
                f.parameters.insert("end_m".into(), r.end_m);
                f.parameters.insert("loss_per_m".into(), r.loss_per_m);
                for k in ["start_m", "end_m", "loss_per_m"] {
                    f.uncertainties.insert(k.into(), None);
                }
                findings.push(f);
            }
        }
    }
}

/// What a stepper's quanta say.
fn stepper_words(st: &signature::StepSignature) -> String {
    format!(
        "{} jumps of whole electrical cycles (off by {:.2} cycle on average), {:.0} % at high commanded acceleration",
        st.jumps,
        st.off_cycle,
        st.at_high_accel * 100.0
    )
}

/// What travel lost over a stretch of the floor says.
fn region_words(r: &signature::RegionSignature) -> String {
    format!(
        "travel lost {:.2} % of distance for world x in [{:.2}, {:.2}] m ({:.0} sigma), {:.2} % outside",
        r.loss_per_m * 100.0,
        r.start_m,
        r.end_m,
        r.sigma,
        r.outside_per_m * 100.0
    )
}

/// A finding named by its signature alone.
pub(super) fn partial(
    effect: &str,
    mechanism: &str,
    stage: Stage,
    before: f64,
    after: f64,
    share: f64,
    signature: String,
) -> Finding {
    Finding {
        effect: effect.into(),
        stage,
        rmse_stage: stage,
        parameters: Default::default(),
        uncertainties: Default::default(),
        rmse_before_m: before,
        rmse_after_m: after,
        delta_bic: f64::NAN,
        heldout_ratio: f64::NAN,
        mechanism: mechanism.into(),
        fit: Fit::Partial,
        explained_share: share.clamp(0.0, 1.0),
        signature: Some(signature),
        residual_left_m: Some(after),
        implausible_sign: false,
    }
}
