//! Whether the travel a `floor_bumps` finding explains is lost where its bumps are.
//!
//! Cables (or any bumps) sit at places on the floor: a wheel loses travel crossing them
//! and nowhere else. A loss of a fixed share of every metre rolled, wherever and whichever
//! way the wheel rolls, is a wheel smaller than its nominal size or a uniform slip: bumps
//! spread evenly over the whole floor look exactly like that. So a bumps finding is
//! evidence for bumps only if the measured travel shortfall follows the pattern its
//! bumps predict (inside their region; across the cables, i.e. on travel along world x)
//! better than any uniform loss per metre rolled, per wheel, can.
//!
//! Two tests, by where the finding's loss comes from:
//!
//! - Bumps fitted in the model (either mechanism): per driven wheel, along the measured
//!   poses, the cumulative shortfall D of the travel along the wheel's rolling row that
//!   the measured poses imply (summed pose step by pose step, each through its own mid
//!   heading) against the model without the bumps, the cumulative travel T of that
//!   model, and the cumulative loss B the finding's bumps take. Cumulative sums carry
//!   the pose noise once (each sample's own) rather than twice per step, so the
//!   regression is on nearly white noise. Least squares D = o_(wheel, stretch) +
//!   r_wheel T + c B, per wheel and stretch between pose gaps; the loss is localised when
//!   c / sigma_c >= [`LOCALISED_SIGMA`], sigma_c from the residuals' robust scatter
//!   inflated by their lag-1 autocorrelation. A uniform loss gives c ~ 0 (the r take
//!   it); bumps the data cannot tell from a uniform loss (a cable field always crossed
//!   the same way, a strip the robot never leaves) give a large sigma_c: neither is
//!   localised.
//! - A region named by its signature alone ([`crate::signature::region_loss`], no
//!   mechanism fits it): the loss per metre inside the stretch against outside, with the
//!   signature's own significance; the localised part is the inside rate less the outside
//!   one, its significance the signature's scaled by that share. The same holds for
//!   fitted bumps whose own pattern fails the first test while the residual without them
//!   shows a clear region signature overlapping their stretch (a fit bent by motion the
//!   catalogue does not model, as the 4-wheel omni's heading over cables): the loss is
//!   in one stretch of the floor all the same.
//!
//! What this cannot tell: whole-floor cables are told from a wheel scale only by their
//! direction (travel along world x loses, along y does not), not by single crossings, so
//! anything else that loses travel along world x only (a motion-capture scale error along
//! x) passes as well.

use crate::effects::{Effect, Model};
use crate::finding::Finding;
use crate::residuals::{robust_sigma, Evaluator};
use fitkit::noise::{ar1_inflation, lag1_autocorrelation};
use nalgebra::{DMatrix, DVector};

/// Least significance (c / sigma_c) of the bumps' own loss pattern beyond a per-wheel
/// uniform loss for a `floor_bumps` finding to be localised: the selection's own evidence
/// bar (a BIC drop of 10 is about 4.5 sigma for one parameter) rounded up, as the wheels'
/// series share the pose noise and are counted as independent.
pub const LOCALISED_SIGMA: f64 = 5.0;

/// Least pose samples for the test to say anything.
const MIN_SAMPLES: usize = 40;
/// A pose step longer than this (s) is a gap: the cumulative series restart after it.
const GAP_S: f64 = 0.6;
/// Largest lag-1 autocorrelation counted (a residual that is all drift still leaves
/// (1 - 0.995) / (1 + 0.995) of its samples as independent evidence).
const MAX_RHO: f64 = 0.995;

/// How a finding's localisation was judged.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Method {
    /// Cumulative travel shortfall against the model's bumps and a uniform loss per wheel.
    Travel,
    /// The region signature's loss inside against outside.
    RegionSignature,
}

/// How much of a `floor_bumps` finding's travel loss is where its bumps are.
#[derive(Debug, Clone, PartialEq)]
pub struct Localisation {
    /// How it was judged.
    pub method: Method,
    /// Share of the finding's loss that is localised: the multiplier of the bumps' own
    /// loss that fits the shortfall best alongside a uniform loss per wheel
    /// ([`Method::Travel`]; 1: the bumps as fitted, 0: none of it is where they are), or
    /// 1 - outside rate / inside rate ([`Method::RegionSignature`]).
    pub localised_share: f64,
    /// One sigma of `localised_share`.
    pub localised_share_sigma: f64,
    /// Significance of the localised loss, sigmas: `localised_share` /
    /// `localised_share_sigma`.
    pub sigma: f64,
    /// Uniform loss per metre rolled, per wheel index, fitted alongside
    /// ([`Method::Travel`] only).
    pub uniform_per_m: Vec<(usize, f64)>,
}

impl Localisation {
    /// Whether the loss is where the bumps are (see [`LOCALISED_SIGMA`]).
    pub fn localised(&self) -> bool {
        self.sigma >= LOCALISED_SIGMA
    }
}

/// The localisation of a `floor_bumps` finding: of its bumps in `model` (either
/// mechanism) by [`Method::Travel`], or, for a finding named by its region signature
/// alone, by [`Method::RegionSignature`]. `None` when the finding is no floor_bumps, or
/// the recording has too few pose samples (or no clear region) to tell.
pub fn floor_bumps(ev: &Evaluator, model: &Model, finding: &Finding) -> Option<Localisation> {
    if finding.effect != Effect::FloorBumps.id() {
        return None;
    }
    let Some((_, _, lo, hi)) = crate::ground::variants::cables(model) else {
        return region_signature(ev, model, finding);
    };
    let t = travel(ev, model);
    if t.as_ref().is_some_and(|l| l.localised()) {
        return t;
    }
    // The data may show a localised loss the fitted bumps do not follow (a fit bent by
    // heading the catalogue does not model): the region signature of the residual
    // without the bumps, if clear and overlapping the finding's stretch, says the loss is
    // in one stretch of the floor all the same.
    let without = without_bumps(model);
    match crate::signature::region_loss(ev, &without) {
        Some(r) if r.clear() && r.start_m <= hi && r.end_m >= lo => Some(from_signature(&r)),
        _ => t,
    }
}

/// The model with its floor_bumps (either mechanism) taken out.
fn without_bumps(model: &Model) -> Model {
    Model {
        effects: model
            .effects
            .iter()
            .filter(|(e, _)| e.base() != Effect::FloorBumps)
            .cloned()
            .collect(),
    }
}

/// [`Method::RegionSignature`] from a region signature.
fn from_signature(r: &crate::signature::RegionSignature) -> Localisation {
    let share = 1.0 - r.outside_per_m.max(0.0) / r.loss_per_m;
    Localisation {
        method: Method::RegionSignature,
        localised_share: share,
        localised_share_sigma: if r.sigma > 0.0 {
            share / r.sigma
        } else {
            f64::INFINITY
        },
        sigma: r.sigma * share,
        uniform_per_m: Vec::new(),
    }
}

/// [`Method::RegionSignature`]: the region the signature finds on `model` (the one the
/// finding was named from), if it is the finding's.
fn region_signature(ev: &Evaluator, model: &Model, finding: &Finding) -> Option<Localisation> {
    let r = crate::signature::region_loss(ev, model)?;
    let same = |k: &str, v: f64| {
        finding
            .parameters
            .get(k)
            .is_some_and(|x| (x - v).abs() <= 1e-9 * (1.0 + v.abs()))
    };
    if !(same("start_m", r.start_m) && same("end_m", r.end_m)) || r.loss_per_m <= 0.0 {
        return None;
    }
    Some(from_signature(&r))
}

/// [`Method::Travel`] for the bumps of `model`.
fn travel(ev: &Evaluator, model: &Model) -> Option<Localisation> {
    let without = without_bumps(model);
    let p = ev.p;
    let ps = &p.poses;
    if ps.len() < MIN_SAMPLES {
        return None;
    }
    let p0 = ev.path_per_row(&without);
    let p1 = ev.path_per_row(model);
    let along = |path: &crate::ground::Path, row: [f64; 3], a: usize, b: usize| -> f64 {
        let n = path.step.len();
        let (mut mx, mut my, mut mw) = (0.0, 0.0, 0.0);
        for st in &path.step[a.min(n)..b.min(n)] {
            mx += st.vx;
            my += st.vy;
            mw += st.omega;
        }
        row[0] * mx + row[1] * my + row[2] * mw
    };
    // Observations: (series id, wheel, D, T, B); a series is one wheel over one stretch
    // between pose gaps.
    let mut obs: Vec<(usize, usize, f64, f64, f64)> = Vec::new();
    let mut series = 0usize;
    for (i, w) in p.robot.wheels.iter().enumerate() {
        if !w.driven {
            continue;
        }
        let row = w.rolling_row();
        let (mut d, mut t, mut bl) = (0.0, 0.0, 0.0);
        let mut len = 0usize;
        for k in 0..ps.len() - 1 {
            let (ra, rb) = (ps.row[k], ps.row[k + 1]);
            // A step across a gap in the pose stream is not resolved through one mid
            // heading: a new stretch starts after it.
            if p.t[rb] - p.t[ra] > GAP_S {
                if len > 0 {
                    series += 1;
                }
                (d, t, bl, len) = (0.0, 0.0, 0.0, 0);
                continue;
            }
            let (sn, cs) = (0.5 * (ps.theta[k] + ps.theta[k + 1])).sin_cos();
            let (dx, dy) = (ps.x[k + 1] - ps.x[k], ps.y[k + 1] - ps.y[k]);
            let implied = row[0] * (cs * dx + sn * dy)
                + row[1] * (-sn * dx + cs * dy)
                + row[2] * (ps.theta[k + 1] - ps.theta[k]);
            let t0 = along(&p0, row, ra, rb);
            let b = t0 - along(&p1, row, ra, rb);
            d += t0 - implied;
            t += t0;
            bl += b;
            len += 1;
            if d.is_finite() && t.is_finite() && bl.is_finite() {
                obs.push((series, i, d, t, bl));
            }
        }
        if len > 0 {
            series += 1;
        }
    }
    if obs.len() < MIN_SAMPLES {
        return None;
    }
    // One offset per series (its first sample's pose noise is in all of it): taken out by
    // subtracting each series' means (the within transformation; same estimate as
    // fitting the offsets).
    let mut j0 = 0;
    while j0 < obs.len() {
        let mut j1 = j0;
        while j1 < obs.len() && obs[j1].0 == obs[j0].0 {
            j1 += 1;
        }
        let n = (j1 - j0) as f64;
        let (md, mt, mb) = obs[j0..j1].iter().fold((0.0, 0.0, 0.0), |acc, o| {
            (acc.0 + o.2 / n, acc.1 + o.3 / n, acc.2 + o.4 / n)
        });
        for o in &mut obs[j0..j1] {
            o.2 -= md;
            o.3 -= mt;
            o.4 -= mb;
        }
        j0 = j1;
    }
    // Columns: one uniform rate per wheel, the bumps' scale.
    let mut wheels: Vec<usize> = obs.iter().map(|o| o.1).collect();
    wheels.sort_unstable();
    wheels.dedup();
    let k = wheels.len() + 1;
    let wcol = |wheel: usize| wheels.iter().position(|&x| x == wheel).unwrap_or(0);
    let row_of = |o: &(usize, usize, f64, f64, f64)| [(wcol(o.1), o.3), (k - 1, o.4)];
    let mut a = DMatrix::<f64>::zeros(k, k);
    let mut y = DVector::<f64>::zeros(k);
    for o in &obs {
        let cols = row_of(o);
        for &(i, xi) in &cols {
            y[i] += xi * o.2;
            for &(j, xj) in &cols {
                a[(i, j)] += xi * xj;
            }
        }
    }
    let not_localised = || Localisation {
        method: Method::Travel,
        localised_share: 0.0,
        localised_share_sigma: f64::INFINITY,
        sigma: 0.0,
        uniform_per_m: wheels.iter().map(|&w| (w, f64::NAN)).collect(),
    };
    // No bump loss at all, or exactly a uniform loss: the normal matrix is singular and
    // nothing is localised.
    let Some(chol) = a.cholesky() else {
        return Some(not_localised());
    };
    let beta = chol.solve(&y);
    let inv = chol.inverse();
    let inv_c = inv[(k - 1, k - 1)];
    let res: Vec<f64> = obs
        .iter()
        .map(|o| o.2 - row_of(o).iter().map(|&(j, x)| beta[j] * x).sum::<f64>())
        .collect();
    let sigma_e = robust_sigma(&mut res.clone());
    // Pairs only within one group (wheel and stretch): the runs of equal `obs[j].0`.
    let mut runs = Vec::new();
    let mut start = 0;
    for j in 1..=res.len() {
        if j == res.len() || obs[j - 1].0 != obs[j].0 {
            runs.push(&res[start..j]);
            start = j;
        }
    }
    let rho = lag1_autocorrelation(runs, MAX_RHO);
    let c = beta[k - 1];
    let sigma_c = sigma_e * inv_c.max(0.0).sqrt() * ar1_inflation(rho).sqrt();
    if !(sigma_c > 0.0 && sigma_c.is_finite() && c.is_finite()) {
        return Some(not_localised());
    }
    Some(Localisation {
        method: Method::Travel,
        localised_share: c,
        localised_share_sigma: sigma_c,
        sigma: c / sigma_c,
        uniform_per_m: wheels.iter().map(|&w| (w, beta[wcol(w)])).collect(),
    })
}
