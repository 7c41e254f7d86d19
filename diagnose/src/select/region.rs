//! Where the region mechanism of floor bumps starts and where its bounds may sit: the
//! cost of cables across one stretch of world x is flat in a bound between two cables,
//! so the local optimiser keeps the bounds where it started. Its starting grid comes
//! from where the measured path went and from the region signature of the residual;
//! its bounds are then scanned over where the path went ([`super::fit`]).

use crate::effects::Model;
use crate::replay::Prepared;
use crate::residuals::Evaluator;

/// Starting grid of the region mechanism: bounds from where the measured path went
/// (quantiles of world x), spacing and loss per metre as the whole-floor grid.
pub(super) fn region_grid(p: &Prepared) -> Vec<Vec<f64>> {
    let mut xs: Vec<f64> = p.pose_at_row.iter().map(|q| q.0).collect();
    if xs.is_empty() {
        return Vec::new();
    }
    xs.sort_by(|a, b| a.total_cmp(b));
    let q = |f: f64| xs[((xs.len() - 1) as f64 * f) as usize];
    let cuts: Vec<f64> = [0.0, 0.25, 0.5, 0.75, 1.0].iter().map(|&f| q(f)).collect();
    let mut g = Vec::new();
    for i in 0..cuts.len() {
        for j in i + 1..cuts.len() {
            if i == 0 && j == cuts.len() - 1 {
                continue; // the whole floor is the other mechanism
            }
            for s in [0.02, 0.05] {
                for frac in [0.005, 0.02] {
                    g.push(vec![s, s * frac, cuts[i] - 0.05, cuts[j] + 0.05]);
                }
            }
        }
    }
    g
}

/// Starting points of the region mechanism from the region signature of the residual
/// left by `model` ([`crate::signature::region_loss`]): its stretch of world x, at the
/// grid's spacings with the losses per crossing the signature's loss per metre asks (the
/// quantile grid's losses stop at 2 % of the spacing). The bounds are then scanned
/// ([`super::fit`]), but from a start whose loss is near the data's.
pub(super) fn region_seeds(ev: &Evaluator, model: &Model) -> Vec<Vec<f64>> {
    let Some(r) = crate::signature::region_loss(ev, model) else {
        return Vec::new();
    };
    if !(r.loss_per_m > 0.0 && r.loss_per_m.is_finite() && r.end_m > r.start_m) {
        return Vec::new();
    }
    // A cable takes its toll along the wheel's rolling direction's share of the
    // crossing, and the wheel crosses at all in proportion to its travel along x: the
    // loss per metre rolled is about half the loss per metre across the cables.
    let mut g = Vec::new();
    for s in [0.02, 0.05] {
        for k in [1.0, 2.0, 4.0] {
            g.push(vec![
                s,
                (k * s * r.loss_per_m).clamp(1e-6, 0.05),
                r.start_m,
                r.end_m,
            ]);
        }
    }
    g
}

/// Where a region's bound may sit: world x from 5 cm before the path's lowest to 5 cm
/// past its highest, in 5 cm steps (at most 40 of them: coarser on a longer path).
pub(super) fn region_bound_candidates(p: &Prepared) -> Vec<f64> {
    let (lo, hi) = p
        .pose_at_row
        .iter()
        .map(|q| q.0)
        .filter(|x| x.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(x), b.max(x))
        });
    if lo > hi {
        return Vec::new();
    }
    let (lo, hi) = (lo - 0.05, hi + 0.05);
    let step = ((hi - lo) / 40.0).max(0.05);
    (0..=((hi - lo) / step).ceil() as usize)
        .map(|i| lo + i as f64 * step)
        .collect()
}
