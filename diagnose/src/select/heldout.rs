//! The held-out check: an effect fitted on alternate blocks of time must predict the
//! others better than the model without it; a fit that only bends the residual it was
//! fitted on does not pass.

use super::criteria::evidence_stage;
use super::fit::fit_params;
use crate::effects::{Effect, Model};
use crate::residuals::{Evaluator, Fold};

/// Held-out check: fit the effect on even blocks and score the odd ones, then the other
/// way round, against the model without it (nuisances fitted the same way).
pub(super) fn heldout_ratio(ev: &Evaluator, base: &Model, e: Effect, full_fit: &[f64]) -> f64 {
    let mut with = 0.0;
    let mut without = 0.0;
    // Scored on the effect's evidence stage, as its BIC is: a stage the effect does not
    // touch, far from its noise while its own effect is not yet in the model, would
    // otherwise swamp the held-out gain.
    let stage = evidence_stage(ev, e);
    let score = |ev: &Evaluator, fold: Fold| -> (f64, f64) {
        let (m, _, _) = fit_params(ev, base, &[e], &[full_fit.to_vec()], fold);
        let test = fold.other();
        let c = ev.evaluate(&m, fold);
        let b = ev.evaluate(base, fold);
        let (rc, rb) = (ev.rss(&c, test), ev.rss(&b, test));
        (ev.chi2(&rc, stage), ev.chi2(&rb, stage))
    };
    // The two folds side by side, the odd one on a second evaluator (the caches are
    // per thread); summed in the same order as one after the other.
    let (p, spec) = (ev.p, ev.fork());
    let (even, (odd, odd_runs)) = std::thread::scope(|s| {
        let odd = s.spawn(|| {
            let local = Evaluator::from_fork(p, spec);
            (score(&local, Fold::Odd), local.runs.get())
        });
        let even = score(ev, Fold::Even);
        (
            even,
            odd.join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic)),
        )
    });
    let (g, a) = ev.runs.get();
    ev.runs.set((g + odd_runs.0, a + odd_runs.1));
    for (w, wo) in [even, odd] {
        with += w;
        without += wo;
    }
    if without > 0.0 {
        with / without
    } else {
        1.0
    }
}
