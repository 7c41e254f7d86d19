//! The selection's rounds: each round fits every remaining effect on top of the model so
//! far ([`super::gate`] says which mechanisms, [`super::pool`] fits them), orders them by
//! their discounted BIC change (the simplest adequate mechanism first) and examines the
//! best three catalogue effects until one is accepted ([`super::accept`]). The run's
//! state travels from phase to phase as one value, [`Run`].

use super::accept::{joint_refit, rejection, Examined};
use super::criteria::{delta_bic, evidence_stage, named, stage_chi2, BIC_THRESHOLD};
use super::gate::{settled, DefaultScore, Gate};
use super::heldout::heldout_ratio;
use super::pool::{fit_candidates, Fitted, Todo, Tried};
use super::region::{region_grid, region_seeds};
use super::simpler::prefer_simpler_mechanisms;
use crate::effects::{Effect, Model, Stage};
use crate::residuals::{Eval, Evaluator, Fold, StageRss};
use serde::Serialize;

/// Most effects selected.
pub const MAX_EFFECTS: usize = 3;

/// One effect tried in one round.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    /// The selection round (0 first).
    pub round: usize,
    /// The effect tried.
    pub effect: Effect,
    /// Its fitted parameters, (name, value).
    pub parameters: Vec<(String, f64)>,
    /// Discounted BIC change against the round's model (negative favours the effect).
    pub delta_bic: f64,
    /// Held-out sum of squares with the effect over without it (only computed for the
    /// round's best candidate).
    pub heldout_ratio: Option<f64>,
    /// Whether it was added to the model.
    pub accepted: bool,
    /// Why it was rejected, if it was examined and rejected; empty otherwise.
    pub note: String,
}

/// An accepted effect, in the order chosen.
#[derive(Debug, Clone)]
pub struct Step {
    /// The effect added.
    pub effect: Effect,
    /// Its discounted BIC change when added.
    pub delta_bic: f64,
    /// Held-out chi-square with the effect over without it.
    pub heldout_ratio: f64,
    /// Sums of squares of the model before the effect was added.
    pub before: StageRss,
    /// Sums of squares after adding it (and refitting the effects it interacts with).
    pub after: StageRss,
}

/// The result of selection.
#[derive(Debug, Clone)]
pub struct Selection {
    /// The final model: the nominal one plus every accepted effect.
    pub model: Model,
    /// 1-sigma uncertainty per effect parameter (value units), same order as `model`.
    pub sigma: Vec<(Effect, Vec<f64>)>,
    /// The accepted effects, in the order chosen.
    pub steps: Vec<Step>,
    /// Every effect tried, round by round.
    pub candidates: Vec<Candidate>,
    /// Sums of squares of the nominal model.
    pub nominal: StageRss,
    /// Sums of squares of the final model.
    pub final_rss: StageRss,
    /// Residuals of the nominal model.
    pub nominal_eval: Eval,
    /// Residuals of the final model.
    pub final_eval: Eval,
}

/// Runs the selection: forward selection over the catalogue. `identified`: the catalogue effects that
/// identification of the nominal residual names ([`crate::identify::named_effects`]);
/// their other mechanisms are fitted whatever their default's score.
pub fn select(ev: &Evaluator, max_effects: usize, identified: &[Effect]) -> Selection {
    let mut run = Run::new(ev, identified);
    let nominal_eval = run.base_eval.clone();
    let nominal = ev.rss(&nominal_eval, Fold::All);
    for round in 0..max_effects {
        let fitted = run.fit_round(round);
        let tried = run.record(round, fitted);
        if !run.examine(round, tried) {
            break;
        }
    }
    run.finish(nominal, nominal_eval)
}

/// The selection's state from round to round.
struct Run<'a> {
    ev: &'a Evaluator<'a>,
    /// The catalogue effects identification of the nominal residual names.
    identified: &'a [Effect],
    /// The model so far: the nominal one plus every accepted effect.
    model: Model,
    /// 1-sigma uncertainty per effect parameter of `model`.
    sigma: Vec<(Effect, Vec<f64>)>,
    /// Residuals of `model`.
    base_eval: Eval,
    /// The accepted effects, in the order chosen.
    steps: Vec<Step>,
    /// Every effect tried, round by round.
    candidates: Vec<Candidate>,
    /// Effects examined and rejected: not tried again.
    rejected: Vec<Effect>,
    /// Each effect's parameters at its last fit (a later round starts there).
    previous: Vec<(Effect, Vec<f64>)>,
    /// The last round's fits, which the next round may keep.
    last_fits: Vec<(Effect, Model, Vec<Vec<f64>>)>,
    /// The effect the last round added.
    last_added: Option<Effect>,
}

impl<'a> Run<'a> {
    fn new(ev: &'a Evaluator<'a>, identified: &'a [Effect]) -> Self {
        let model = Model::default();
        let base_eval = ev.evaluate(&model, Fold::All);
        Run {
            ev,
            identified,
            model,
            sigma: Vec::new(),
            base_eval,
            steps: Vec::new(),
            candidates: Vec::new(),
            rejected: Vec::new(),
            previous: Vec::new(),
            last_fits: Vec::new(),
            last_added: None,
        }
    }

    /// Fits the round's candidates on top of the model so far: the fits kept from the
    /// last round, then the defaults, the grid-searched defaults the others do not settle
    /// ([`settled`]), and the other mechanisms the gate lets through. Sorted by effect.
    fn fit_round(&mut self, round: usize) -> Vec<Fitted> {
        let ev = self.ev;
        let reused = self.reused();
        let todo = self.todo(&reused);
        let mut fitted: Vec<Fitted> = reused;
        // Catalogue mechanisms first; the other mechanisms of an effect only when the data
        // lean towards that effect at all (its default mechanism lowers the BIC), or when
        // its default does not apply here. Keeps the larger catalogue's cost near the old.
        let (defaults, variants): (Vec<_>, Vec<_>) =
            todo.into_iter().partition(|(e, _)| e.base() == *e);
        // Round 0's grid-searched ground defaults (floor bumps, traction slip: dozens of
        // runs each) go after the others, and wait for round 1 when one of those already
        // brings the stage from far above its noise back to it (`settled`).
        let (searched, defaults): (Vec<_>, Vec<_>) = defaults
            .into_iter()
            .partition(|(e, start)| round == 0 && e.stage() == Stage::Ground && start.len() > 2);
        // Identify before fitting the other mechanisms (`variant_worth_fitting`).
        let mut scored: Vec<DefaultScore> = Vec::new();
        self.score(self.fit(&defaults), &mut scored, &mut fitted);
        let base_rss = ev.rss(&self.base_eval, Fold::All);
        let base_chi2 = |s: Stage| stage_chi2(ev, &base_rss, s);
        let (deferred, searched): (Vec<_>, Vec<_>) = searched
            .into_iter()
            .partition(|(e, _)| settled(evidence_stage(ev, *e), &scored, base_chi2));
        self.score(self.fit(&searched), &mut scored, &mut fitted);
        let gate = Gate {
            ev,
            identified: self.identified,
            scored: &scored,
            base_chi2: &base_chi2,
            deferred: &deferred,
            defaults: &defaults,
            searched: &searched,
            fitted: &fitted,
        };
        let variants: Vec<_> = variants
            .into_iter()
            .filter(|(e, _)| gate.wants(e))
            .collect();
        for (e, m, sig, ce, _) in self.fit(&variants) {
            fitted.push((e, m, sig, ce));
        }
        fitted.sort_by_key(|f| f.0);
        self.last_fits = fitted
            .iter()
            .map(|(e, m, sig, _)| (*e, m.clone(), sig.clone()))
            .collect();
        fitted
    }

    /// Later rounds start from the previous round's fit plus a thinned grid: the base
    /// model changed only by one effect. A candidate of the other stage than the effect
    /// just added keeps its fit when the stages are independent (every wheel with
    /// commands also has an encoder): only the added effect's parameters change under it.
    fn reused(&self) -> Vec<Fitted> {
        let (ev, model) = (self.ev, &self.model);
        let mut reused: Vec<Fitted> = Vec::new();
        if let (Some(added), false) = (self.last_added, ev.ground_uses_actuator()) {
            for (e, m_prev, sig_prev) in &self.last_fits {
                if e.stage() != added.stage()
                    && !model.effects.iter().any(|(x, _)| x.base() == e.base())
                    && !self.rejected.contains(e)
                {
                    let mut m = m_prev.clone();
                    for (x, p) in &model.effects {
                        if x.stage() == added.stage() {
                            m = m.with(*x, p.clone());
                        }
                    }
                    let ce = ev.evaluate(&m, Fold::All);
                    reused.push((*e, m, sig_prev.clone(), ce));
                }
            }
        }
        reused
    }

    /// The effects left to fit this round (one mechanism per catalogue effect, none
    /// rejected or kept from the last round) and their starting points.
    fn todo(&self, reused: &[Fitted]) -> Vec<Todo> {
        let (ev, model) = (self.ev, &self.model);
        let robot = &ev.p.robot;
        let has_cmd = ev.p.has_commands();
        Effect::candidates(robot)
            .into_iter()
            .filter(|&e| {
                // One mechanism per catalogue effect.
                !model.effects.iter().any(|(x, _)| x.base() == e.base())
                    && !self.rejected.contains(&e)
                    && e.applies(robot, has_cmd)
                    && crate::ground::variants::applies(ev.p, e)
                    && !reused.iter().any(|r| r.0 == e)
            })
            .map(|e| {
                let grid = if e == Effect::BumpsRegion {
                    let mut g = region_seeds(ev, model);
                    g.extend(region_grid(ev.p));
                    g
                } else {
                    e.start_grid(robot)
                };
                let start = match self.previous.iter().find(|(x, _)| *x == e) {
                    Some((_, p)) => {
                        let mut s = vec![p.clone()];
                        s.extend(grid.iter().step_by(3).cloned());
                        s
                    }
                    None => grid,
                };
                (e, start)
            })
            .collect()
    }

    /// Fits `todo` on top of the model so far.
    fn fit(&self, todo: &[Todo]) -> Vec<Tried> {
        fit_candidates(self.ev, &self.model, &self.base_eval, todo)
    }

    /// Scores default mechanisms' `fits` (their BIC change and the chi-square they leave
    /// in their evidence stage) into `scored`, and adds them to `fitted`.
    fn score(&self, fits: Vec<Tried>, scored: &mut Vec<DefaultScore>, fitted: &mut Vec<Fitted>) {
        let ev = self.ev;
        for (e, m, sig, ce, _) in fits {
            let k = e.params(&ev.p.robot).len();
            let stage = evidence_stage(ev, e);
            scored.push(DefaultScore {
                effect: e,
                stage,
                delta_bic: delta_bic(ev, &self.base_eval, &ce, k, stage),
                chi2_left: stage_chi2(ev, &ev.rss(&ce, Fold::All), stage),
            });
            fitted.push((e, m, sig, ce));
        }
    }

    /// Records the round's fits as candidates (and as the next round's starts), with
    /// their BIC change; returns them best first, the simplest adequate mechanism of an
    /// effect before its richer siblings.
    fn record(&mut self, round: usize, fitted: Vec<Fitted>) -> Vec<Tried> {
        let ev = self.ev;
        let robot = &ev.p.robot;
        let mut tried: Vec<Tried> = Vec::new();
        for (e, m, sig, cand_eval) in fitted {
            if let Some(v) = m.get(e) {
                self.previous.retain(|(x, _)| *x != e);
                self.previous.push((e, v.to_vec()));
            }
            let k = e.params(robot).len();
            let d = delta_bic(ev, &self.base_eval, &cand_eval, k, evidence_stage(ev, e));
            self.candidates.push(Candidate {
                round,
                effect: e,
                parameters: named(robot, e, m.get(e).unwrap_or(&[])),
                delta_bic: d,
                heldout_ratio: None,
                accepted: false,
                note: String::new(),
            });
            tried.push((e, m, sig, cand_eval, d));
        }
        tried.sort_by(|a, b| a.4.total_cmp(&b.4));
        prefer_simpler_mechanisms(&mut tried, |e| e.params(robot).len());
        tried
    }

    /// Examines the round's best three catalogue effects, each with all its mechanisms
    /// (siblings of a rejected mechanism usually fail the same test), in order, and adds
    /// the first that passes. Whether one was added.
    fn examine(&mut self, round: usize, tried: Vec<Tried>) -> bool {
        let ev = self.ev;
        let mut bases: Vec<Effect> = Vec::new();
        let one_values: Vec<(Effect, Vec<f64>)> = tried
            .iter()
            .filter_map(|t| t.1.get(t.0).map(|p| (t.0, p.to_vec())))
            .collect();
        for (e, m, sig, cand_eval, d) in tried.into_iter() {
            if !bases.contains(&e.base()) {
                if bases.len() == 3 {
                    break;
                }
                bases.push(e.base());
            }
            let idx = self
                .candidates
                .iter()
                .rposition(|c| c.round == round && c.effect == e)
                .expect("recorded above");
            if d > BIC_THRESHOLD {
                self.candidates[idx].note = "BIC does not favour it".into();
                break;
            }
            let stage = evidence_stage(ev, e);
            let before = ev.rss(&self.base_eval, Fold::All);
            let after = ev.rss(&cand_eval, Fold::All);
            let ratio = heldout_ratio(ev, &self.model, e, m.get(e).unwrap_or(&[]));
            self.candidates[idx].heldout_ratio = Some(ratio);
            let examined = Examined {
                effect: e,
                model: &m,
                stage,
                before: &before,
                after: &after,
                heldout_ratio: ratio,
            };
            if let Some(note) = rejection(ev, &self.model, &examined, &one_values) {
                self.candidates[idx].note = note;
                self.rejected.push(e);
                continue;
            }
            self.candidates[idx].accepted = true;
            let (model, eval) = joint_refit(ev, e, m, sig, cand_eval, after, &mut self.sigma);
            self.steps.push(Step {
                effect: e,
                delta_bic: d,
                heldout_ratio: ratio,
                before,
                after: ev.rss(&eval, Fold::All),
            });
            self.model = model;
            self.base_eval = eval;
            self.last_added = Some(e);
            return true;
        }
        false
    }

    /// The selection: the final model and how it was reached.
    fn finish(self, nominal: StageRss, nominal_eval: Eval) -> Selection {
        let final_rss = self.ev.rss(&self.base_eval, Fold::All);
        Selection {
            model: self.model,
            sigma: self.sigma,
            steps: self.steps,
            candidates: self.candidates,
            nominal,
            final_rss,
            nominal_eval,
            final_eval: self.base_eval,
        }
    }
}
