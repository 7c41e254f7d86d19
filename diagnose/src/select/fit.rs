//! Fitting the parameters of one or more effects on top of a model: a starting grid, a
//! zoom into the best cell for one-parameter effects with rugged costs, the local
//! optimiser, and for the region mechanism of floor bumps a scan of its bounds, which
//! the optimiser cannot move. Every candidate, joint refit and held-out check fits
//! through here.

use super::region::region_bound_candidates;
use crate::effects::{Effect, Model, ParamSpec, Scale};
use crate::residuals::{Evaluator, Fold};
use fitkit::fit::{levenberg_marquardt, FitResult, SCREENING_REL};

/// Passes of the zoom into a grid's best cell, each a third as wide as the one before.
pub(super) const ZOOM_PASSES: usize = 4;
/// Points tried across the cell in each zoom pass.
pub(super) const ZOOM_POINTS: usize = 7;

/// The residual function's values at a point of the optimiser's coordinates.
type Cost<'f> = &'f mut dyn FnMut(&[f64]) -> Vec<f64>;

/// A start in the optimiser's coordinates and its cost.
type Start = (Vec<f64>, f64);

/// Fits the parameters of `effects` (all others fixed as in `base`) on a fold.
/// Returns the model and the 1-sigma uncertainties in value units.
pub(super) fn fit_params(
    ev: &Evaluator,
    base: &Model,
    effects: &[Effect],
    start: &[Vec<f64>],
    fold: Fold,
) -> (Model, Vec<Vec<f64>>, f64) {
    let robot = &ev.p.robot;
    let specs: Vec<Vec<ParamSpec>> = effects.iter().map(|e| e.params(robot)).collect();
    let build = |u: &[f64]| -> Model {
        let mut m = base.clone();
        let mut i = 0;
        for (e, sp) in effects.iter().zip(&specs) {
            let vals = sp
                .iter()
                .map(|s| {
                    i += 1;
                    s.value(u[i - 1])
                })
                .collect();
            m = m.with(*e, vals);
        }
        m
    };
    let mut buf = Vec::new();
    let mut f = |u: &[f64]| -> Vec<f64> {
        let m = build(u);
        let e = ev.evaluate(&m, fold);
        ev.weighted(&e, fold, &mut buf);
        buf.clone()
    };
    let flat_specs: Vec<&ParamSpec> = specs.iter().flatten().collect();
    let (lo, hi): (Vec<f64>, Vec<f64>) = flat_specs.iter().map(|s| s.bounds()).unzip();
    // The region mechanism's parameters start at this offset; its best start per cable
    // spacing is kept (the cost is a comb in the spacing: each has its own valley).
    let region_off = effects
        .iter()
        .position(|e| *e == Effect::BumpsRegion)
        .map(|k| specs[..k].iter().map(|s| s.len()).sum::<usize>());
    // Starting grid (only for a single effect; joint refits start from the current values).
    let (mut best, per_spacing) = grid_start(&mut f, &flat_specs, start, region_off);
    // One-parameter effects with rugged costs (thresholds, traction limits): zoom in on
    // the best grid cell before the local optimiser takes over.
    if zooms(effects[0], flat_specs.len(), start.len()) {
        if let Some(b) = best.clone() {
            best = Some(zoom_in(&mut f, flat_specs[0], start, b));
        }
    }
    let u0 = best.map(|b| b.0).unwrap_or_else(|| {
        flat_specs
            .iter()
            .map(|s| s.internal(s.null.clamp(s.min, s.max)))
            .collect()
    });
    let mut r = levenberg_marquardt(&mut f, &u0, &lo, &hi, 20, SCREENING_REL);
    if let Some(off) = region_off {
        let cands = region_bound_candidates(ev.p);
        // From a grid, the best start of each other spacing is tried too.
        let others = if start.len() > 2 {
            per_spacing
        } else {
            Vec::new()
        };
        r = refine_region_bounds(&mut f, r, off, &cands, others, (&lo, &hi));
    }
    let model = build(&r.x);
    (model, sigma_in_values(&specs, &r), r.cost)
}

/// The starting grid's best point, and with the region mechanism at `region_off` the
/// best point of each cable spacing.
fn grid_start(
    f: Cost,
    flat_specs: &[&ParamSpec],
    start: &[Vec<f64>],
    region_off: Option<usize>,
) -> (Option<Start>, Vec<Start>) {
    let mut best: Option<Start> = None;
    let mut per_spacing: Vec<Start> = Vec::new();
    for s in start {
        let u: Vec<f64> = flat_specs
            .iter()
            .zip(s)
            .map(|(sp, v)| sp.internal(*v))
            .collect();
        let c: f64 = f(&u).iter().map(|v| v * v).sum();
        if let (Some(off), true) = (region_off, c.is_finite()) {
            match per_spacing
                .iter_mut()
                .find(|p| (p.0[off] - u[off]).abs() < 1e-9)
            {
                Some(p) if c < p.1 => *p = (u.clone(), c),
                Some(_) => {}
                None => per_spacing.push((u.clone(), c)),
            }
        }
        if c.is_finite() && best.as_ref().is_none_or(|b| c < b.1) {
            best = Some((u, c));
        }
    }
    (best, per_spacing)
}

/// Zooms into the cell of the one-parameter grid `start` around its best point
/// `(bu, bc)`: [`ZOOM_PASSES`] passes of [`ZOOM_POINTS`] points, each a third as wide.
fn zoom_in(f: Cost, spec: &ParamSpec, start: &[Vec<f64>], (bu, bc): Start) -> Start {
    let grid_u: Vec<f64> = start.iter().map(|s| spec.internal(s[0])).collect();
    let (lo_u, hi_u) = grid_u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
            (a.min(u), b.max(u))
        });
    let mut half = (hi_u - lo_u) / (grid_u.len() - 1) as f64;
    let (mut cu, mut cc) = (bu[0], bc);
    for _ in 0..ZOOM_PASSES {
        let centre = cu;
        for i in 1..=ZOOM_POINTS {
            let u = centre - half + 2.0 * half * i as f64 / (ZOOM_POINTS + 1) as f64;
            let c: f64 = f(&[u]).iter().map(|v| v * v).sum();
            if c.is_finite() && c < cc {
                (cu, cc) = (u, c);
            }
        }
        half /= 3.0;
    }
    (vec![cu], cc)
}

/// The region mechanism's bounds: the cost is flat in a bound between two cables, so
/// the local optimiser keeps them where it started. Scan each bound over where the
/// robot went (`cands`: 5 cm steps, then 1 cm around the best) from the optimum `r`;
/// refit from there and from the best start of each other spacing (`others`) moved to
/// those bounds; scan the best once more within 4 cm of its bounds and refit.
fn refine_region_bounds(
    f: Cost,
    mut r: FitResult,
    off: usize,
    cands: &[f64],
    others: Vec<Start>,
    (lo, hi): (&[f64], &[f64]),
) -> FitResult {
    let bounds = [off + 2, off + 3];
    let mut u = r.x.clone();
    scan_bounds(f, &mut u, bounds, cands);
    let mut starts = vec![u.clone()];
    for (mut p, _) in others {
        if (p[off] - u[off]).abs() > 1e-9 {
            p[off + 2] = u[off + 2];
            p[off + 3] = u[off + 3];
            starts.push(p);
        }
    }
    let mut best_cost = sum_sq(&f(&r.x));
    for pass in 0..2 {
        if pass == 1 {
            // Once more around the best bounds, the loss now fitted inside them.
            let mut u = r.x.clone();
            scan_bounds(f, &mut u, bounds, &[]);
            starts = vec![u];
        }
        for u in &starts {
            let rr = levenberg_marquardt(f, u, lo, hi, 20, SCREENING_REL);
            let c = sum_sq(&f(&rr.x));
            if c.is_finite() && c < best_cost {
                (best_cost, r) = (c, rr);
            }
        }
    }
    r
}

/// The fit's 1-sigma uncertainties in value units, per effect.
fn sigma_in_values(specs: &[Vec<ParamSpec>], r: &FitResult) -> Vec<Vec<f64>> {
    let mut sig = Vec::new();
    let mut i = 0;
    for sp in specs {
        sig.push(
            sp.iter()
                .map(|s| {
                    let v = s.value(r.x[i]);
                    let su = r.sigma[i];
                    i += 1;
                    match s.scale {
                        Scale::Linear => su,
                        Scale::Log => v * su,
                    }
                })
                .collect(),
        );
    }
    sig
}

fn sum_sq(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum()
}

/// Moves each of the two bounds `idx` of `u` to the candidate (then to the 1 cm step
/// within 4 cm of it) that lowers the cost most, one bound after the other.
fn scan_bounds(f: Cost, u: &mut Vec<f64>, idx: [usize; 2], cands: &[f64]) {
    let mut c_u = sum_sq(&f(u));
    for i in idx {
        let mut try_at = |x: f64, u: &mut Vec<f64>, c_u: &mut f64| {
            let mut v = u.clone();
            v[i] = x;
            let c = sum_sq(&f(&v));
            if c.is_finite() && c < *c_u {
                (*c_u, *u) = (c, v);
            }
        };
        for &x in cands {
            try_at(x, u, &mut c_u);
        }
        let centre = u[i];
        for k in (-4..=4).filter(|k| *k != 0) {
            try_at(centre + 0.01 * k as f64, u, &mut c_u);
        }
    }
}

/// Whether `fit_params` zooms into the best cell of `e`'s start grid: a one-parameter
/// effect with a rugged cost ([`Effect::rugged_cost`]) and a grid of more than two starts.
pub(super) fn zooms(e: Effect, params: usize, starts: usize) -> bool {
    params == 1 && starts > 2 && e.rugged_cost()
}
