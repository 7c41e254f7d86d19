//! Fitting a round's candidates: each effect on top of the model so far, spread over the
//! machine's cores (one evaluator per worker: the caches are per thread), the dearest
//! fits started first so that a long fit does not leave the other cores idle. The
//! results keep the order they were asked in, so the pool changes no result.

use super::criteria::{delta_bic, evidence_stage};
use super::fit::{fit_params, zooms, ZOOM_PASSES, ZOOM_POINTS};
use crate::effects::{Effect, Model, Stage};
use crate::residuals::{Eval, Evaluator, Fold};

/// An effect to fit and its starting points (value units).
pub(super) type Todo = (Effect, Vec<Vec<f64>>);

/// A fit of an effect on top of the model: effect, model with it, uncertainties,
/// residuals.
pub(super) type Fitted = (Effect, Model, Vec<Vec<f64>>, Eval);

/// A fitted candidate: effect, model with it, uncertainties, residuals, BIC change (0
/// until computed).
pub(super) type Tried = (Effect, Model, Vec<Vec<f64>>, Eval, f64);

/// Fits each candidate effect on top of `base`, spread over the machine's cores (each
/// worker with its own evaluator: the caches are per thread). Results keep `todo`'s order.
pub(super) fn fit_candidates(
    ev: &Evaluator,
    base: &Model,
    base_eval: &Eval,
    todo: &[Todo],
) -> Vec<Tried> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let threads = std::thread::available_parallelism()
        .map_or(1, |n| n.get())
        .clamp(1, 4)
        .min(todo.len().max(1));
    let (p, spec) = (ev.p, ev.fork());
    let uses_act = ev.ground_uses_actuator();
    let stepper = ev.stepper_cycle_rad().is_some();
    let next = AtomicUsize::new(0);
    // The dearest fits first: a long fit started last would leave the other cores idle
    // (the results are put back in `todo`'s order, so the order changes no result).
    let order = dearest_first(
        todo,
        |e| e.params(&p.robot).len(),
        |e| fit_run_cost(e, uses_act, stepper),
    );
    let mut results: Vec<(usize, Tried)> = Vec::new();
    let mut runs = ev.runs.get();
    std::thread::scope(|s| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                s.spawn(|| {
                    let local = Evaluator::from_fork(p, spec);
                    let mut out = Vec::new();
                    while let Some(&i) = order.get(next.fetch_add(1, Ordering::Relaxed)) {
                        let (e, start) = &todo[i];
                        // Refit the chosen effects the candidate interacts with alongside
                        // it: a greedy fit with them frozen would let the first effect keep
                        // what belongs to the second.
                        let coupled: Vec<Effect> = base
                            .effects
                            .iter()
                            .map(|(x, _)| *x)
                            .filter(|x| x.stage() == e.stage() || uses_act)
                            .collect();
                        let (m, sig, _) = fit_params(&local, base, &[*e], start, Fold::All);
                        let frozen = local.evaluate(&m, Fold::All);
                        let k = e.params(&local.p.robot).len();
                        let d =
                            delta_bic(&local, base_eval, &frozen, k, evidence_stage(&local, *e));
                        // Only a candidate the data already lean towards is worth the joint
                        // refit (it costs several model runs per iteration).
                        let (m, sig) = if coupled.is_empty() || d > 0.0 {
                            (m, sig)
                        } else {
                            let fixed: Vec<f64> = coupled
                                .iter()
                                .flat_map(|x| base.get(*x).unwrap_or(&[]).to_vec())
                                .collect();
                            let cand = m.get(*e).unwrap_or(&[]).to_vec();
                            let starts: Vec<Vec<f64>> =
                                vec![fixed.iter().chain(&cand).copied().collect()];
                            let mut all = coupled.clone();
                            all.push(*e);
                            let (m, mut sig, _) =
                                fit_params(&local, base, &all, &starts, Fold::All);
                            (m, vec![sig.pop().unwrap_or_default()])
                        };
                        let ce = local.evaluate(&m, Fold::All);
                        out.push((i, (*e, m, sig, ce, 0.0)));
                    }
                    (out, local.runs.get())
                })
            })
            .collect();
        for w in workers {
            if let Ok((out, (g, a))) = w.join() {
                results.extend(out);
                runs = (runs.0 + g, runs.1 + a);
            }
        }
    });
    ev.runs.set(runs);
    results.sort_by_key(|r| r.0);
    results.into_iter().map(|(_, t)| t).collect()
}

/// Relative cost of one model run of effect `e`: a ground run integrates the body (about
/// twice an actuator run's wheel integration, measured with `perf` on the 120k-row
/// bench); an actuator effect also reruns the ground stage when the ground stage is
/// driven by the actuator model. On a `stepper` robot an acceleration limit is a rotor
/// sub-stepped wherever it is out of step (measured on the 3.6 M-row bench: 92 ms a run
/// for the pull-out limit against 21 ms for the stall).
fn fit_run_cost(e: Effect, ground_uses_actuator: bool, stepper: bool) -> f64 {
    let rotor = stepper && matches!(e, Effect::MissedSteps | Effect::LagSlew);
    (match (e.stage(), ground_uses_actuator) {
        (Stage::Ground, _) => 2.0,
        (Stage::Actuator, false) => 1.0,
        (Stage::Actuator, true) => 3.0,
    }) * if rotor { ROTOR_RUN_COST } else { 1.0 }
}

/// Cost of a sub-stepped rotor run over a plain actuator run (see [`fit_run_cost`]).
const ROTOR_RUN_COST: f64 = 4.0;

/// The indices of `todo` by the expected cost of their fits, dearest first (ties in
/// `todo`'s order): the starts, the zoom ([`zooms`]: `ZOOM_PASSES` x `ZOOM_POINTS` runs)
/// and the local fit (about 8 iterations of p + 1 runs), times the cost of a run.
fn dearest_first(
    todo: &[Todo],
    params: impl Fn(Effect) -> usize,
    run_cost: impl Fn(Effect) -> f64,
) -> Vec<usize> {
    let cost = |(e, starts): &Todo| -> f64 {
        let k = params(*e);
        let zoom = if zooms(*e, k, starts.len()) {
            ZOOM_PASSES * ZOOM_POINTS
        } else {
            0
        };
        (starts.len() + zoom + 8 * (k + 1)) as f64 * run_cost(*e)
    };
    let mut order: Vec<usize> = (0..todo.len()).collect();
    order.sort_by(|&a, &b| cost(&todo[b]).total_cmp(&cost(&todo[a])).then(a.cmp(&b)));
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bench's first round in the order the pool takes it: the floor bumps' 36
    /// starts on the ground stage before the slip's 12 (+28 zoom: a rugged cost), before
    /// the actuator fits, before the geometry's single start; equal costs keep their
    /// order. On a stepper robot the pull-out limit's sub-stepped rotor goes first.
    #[test]
    fn the_dearest_fits_are_started_first() {
        let one = |n: usize| vec![vec![1.0]; n];
        let todo = vec![
            (Effect::WheelbaseError, one(1)),
            (Effect::LongitudinalSlip, one(12)),
            (Effect::MotorLag, one(10)),
            (Effect::FloorBumps, vec![vec![0.1, 0.001]; 36]),
            (Effect::CoulombFriction, one(12)),
            (Effect::Backlash, one(10)),
            (Effect::MissedSteps, one(64)),
        ];
        let params = |e: Effect| if e == Effect::FloorBumps { 2 } else { 1 };
        let cost = |e: Effect| fit_run_cost(e, false, false);
        // Costs: 17x2, 56x2, 26, (36+24)x2, 56, 26, 108.
        assert_eq!(
            dearest_first(&todo, params, cost),
            vec![3, 1, 6, 4, 0, 2, 5]
        );
        // With the ground stage driven by the actuator model, an actuator run costs 3.
        let cost3 = |e: Effect| fit_run_cost(e, true, false);
        assert_eq!(
            dearest_first(&todo, params, cost3),
            vec![6, 4, 3, 1, 2, 5, 0]
        );
        // A stepper's rotor is sub-stepped wherever it is out of step: 4 runs' worth
        // (92 against 21 ms a run for the pull-out limit and the stall on 1 M rows).
        let stepper = |e: Effect| fit_run_cost(e, false, true);
        assert_eq!(
            dearest_first(&todo, params, stepper),
            vec![6, 3, 1, 4, 0, 2, 5]
        );
    }
}
