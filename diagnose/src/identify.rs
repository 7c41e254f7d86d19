//! Identification: what a stage's residual depends on, before any mechanism is
//! fitted. The residual's increments over short intervals are regressed on a library of
//! physical regressors (commanded speed and its sign, reversals, acceleration, turn,
//! position on the floor, leg posture, time), each integrated over the same intervals,
//! and a sparse set of terms is chosen by sequentially thresholded least squares (STLSQ,
//! as SINDy does) validated on held-out blocks of time: the sparsest support whose
//! held-out error is within one standard error of the best wins (the simplest adequate
//! explanation). The surviving terms are mapped to physics by [`PHYSICS`]; a term the
//! table does not name is reported by what it is ("heading error per reversal of the
//! forward command"), which says more than `unexplained`.
//!
//! Increments, not the cumulative residual: a cumulative error is a random walk of the
//! model's errors, so neighbouring samples are not independent; increments over half a
//! second are nearly so, and held-out blocks of them test the terms honestly.

use crate::replay::Prepared;
use crate::residuals::Eval;
use formats::catalogue as cat;
use serde::Serialize;

/// One column of the regressor library, already integrated over the intervals.
#[derive(Debug, Clone)]
pub struct Regressor {
    /// Short name, used in the physics table (e.g. `reversals_fwd`).
    pub name: String,
    /// What it measures, in words, for the description of a surviving term.
    pub words: String,
    /// Value per interval.
    pub values: Vec<f64>,
    /// A kinematic term (the propagation of an earlier error), fitted but never reported.
    pub nuisance: bool,
}

/// A term that survived the selection.
#[derive(Debug, Clone, Serialize, PartialEq)]
pub struct Term {
    /// The residual it was found in (`heading`, `along_track`, `actuator_<wheel>`...).
    pub target: String,
    /// The regressor's short name.
    pub regressor: String,
    /// Coefficient in the residual's unit per the regressor's unit.
    pub coefficient: f64,
    /// Share of the held-out variance of the residual the whole support explains.
    pub heldout_share: f64,
    /// The physics the table maps it to, or `None` (outside the catalogue).
    pub physics: Option<String>,
    /// What the residual depends on, in words.
    pub depends_on: String,
}

/// Physics table: (target prefix, regressor prefix, physics). The first match names it.
pub const PHYSICS: &[(&str, &str, &str)] = &[
    (
        "actuator",
        "sign_time",
        "coulomb_friction (a constant, sign-following shortfall: dead zone or droop)",
    ),
    (
        "actuator",
        "wheel_reversals",
        "backlash (travel lost after each reversal of the wheel)",
    ),
    (
        "actuator",
        "cmd_accel",
        "motor_lag (travel behind in proportion to the change of command)",
    ),
    ("actuator", "cmd_travel", "a wheel or encoder scale"),
    (
        "along_track",
        "accel",
        "longitudinal_slip (loss that follows acceleration)",
    ),
    (
        "along_track",
        "floor_",
        "floor (loss that follows position on the floor)",
    ),
    (
        "along_track",
        "distance",
        "wheel_scale (loss per metre rolled)",
    ),
    (
        "along_track",
        "posture",
        "longitudinal_slip (traction set by the leg posture)",
    ),
    (
        "heading",
        "accel",
        "longitudinal_slip per wheel (heading error that follows acceleration: the wheels' traction differs)",
    ),
    (
        "heading",
        "turn",
        "wheelbase_error (heading error that follows the turn)",
    ),
    (
        "heading",
        "distance",
        "wheel_diameter_mismatch (heading error per metre rolled)",
    ),
    (
        "cross_track",
        "lateral_accel",
        "lateral_slip (side motion that follows v omega)",
    ),
];

/// The catalogue effects the surviving terms name (by the first word of their physics:
/// `floor` is the floor bumps' family), each once, in the terms' order.
pub fn named_effects(terms: &[Term]) -> Vec<crate::effects::Effect> {
    use crate::effects::Effect;
    let mut out: Vec<Effect> = Vec::new();
    for t in terms {
        let Some(word) = t.physics.as_deref().and_then(|p| p.split(' ').next()) else {
            continue;
        };
        let effect = if word == "floor" {
            Some(Effect::FloorBumps)
        } else if word == cat::LONGITUDINAL_SLIP && t.target == "heading" {
            // A heading error that follows acceleration: the wheels' traction differs.
            Some(Effect::SlipPerWheel)
        } else {
            Effect::ALL
                .into_iter()
                .find(|e| e.base() == *e && e.id() == word)
        };
        if let Some(e) = effect.filter(|e| !out.contains(e)) {
            out.push(e);
        }
    }
    out
}

/// The physics a (target, regressor) pair maps to.
pub fn physics_of(target: &str, regressor: &str) -> Option<&'static str> {
    PHYSICS
        .iter()
        .find(|(t, r, _)| target.starts_with(t) && regressor.starts_with(r))
        .map(|(_, _, p)| *p)
}

/// Whether any catalogue physics follows this regressor, for whichever residual: a
/// heading error that follows the acceleration is unmapped as a pair, but acceleration
/// is what slip follows; one that follows reversals of the forward command follows
/// nothing the catalogue knows.
pub fn regressor_has_physics(regressor: &str) -> bool {
    PHYSICS.iter().any(|(_, r, _)| regressor.starts_with(r))
}

/// Number of held-out blocks of time.
pub const BLOCKS: usize = 5;
/// A support must explain at least this share of the held-out variance to be reported
/// (below it the residual is noise as far as identification can tell).
pub const MIN_HELDOUT_SHARE: f64 = 0.2;

/// Ordinary least squares on the columns `support` (normal equations, ridge 1e-9 of the
/// diagonal for rank safety). Returns one coefficient per support column.
fn ols(x: &[Vec<f64>], y: &[f64], rows: &[usize], support: &[usize]) -> Vec<f64> {
    let k = support.len();
    if k == 0 {
        return Vec::new();
    }
    let mut a = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut b = nalgebra::DVector::<f64>::zeros(k);
    for &r in rows {
        for (i, &ci) in support.iter().enumerate() {
            b[i] += x[ci][r] * y[r];
            for (j, &cj) in support.iter().enumerate() {
                a[(i, j)] += x[ci][r] * x[cj][r];
            }
        }
    }
    for i in 0..k {
        a[(i, i)] += 1e-9 * a[(i, i)].max(1e-300);
    }
    match a.clone().cholesky() {
        Some(c) => c.solve(&b).iter().copied().collect(),
        None => a
            .pseudo_inverse(1e-12)
            .map(|p| (p * b).iter().copied().collect())
            .unwrap_or_else(|_| vec![0.0; k]),
    }
}

/// STLSQ on standardised columns: least squares, drop terms whose standardised
/// coefficient is below `threshold` (in units of the residual's standard deviation),
/// refit, until the support stops changing. Returns the support.
pub fn stlsq(x: &[Vec<f64>], y: &[f64], rows: &[usize], threshold: f64) -> Vec<usize> {
    let sd = |v: &[f64]| {
        let n = rows.len().max(1) as f64;
        (rows.iter().map(|&r| v[r] * v[r]).sum::<f64>() / n).sqrt()
    };
    let sy = sd(y).max(1e-300);
    let sx: Vec<f64> = x.iter().map(|c| sd(c)).collect();
    let mut support: Vec<usize> = (0..x.len()).filter(|&j| sx[j] > 0.0).collect();
    for _ in 0..20 {
        let c = ols(x, y, rows, &support);
        let next: Vec<usize> = support
            .iter()
            .zip(&c)
            .filter(|(&j, &cj)| (cj * sx[j] / sy).abs() >= threshold)
            .map(|(&j, _)| j)
            .collect();
        if next == support {
            break;
        }
        support = next;
    }
    support
}

/// Held-out mean squared error of a support over `BLOCKS` contiguous blocks of the
/// intervals (fit on the others, predict the block): (mean, standard error).
pub fn heldout_mse(x: &[Vec<f64>], y: &[f64], support: &[usize]) -> (f64, f64) {
    let n = y.len();
    let mut per_block = Vec::new();
    for b in 0..BLOCKS {
        let (lo, hi) = (b * n / BLOCKS, (b + 1) * n / BLOCKS);
        if hi <= lo {
            continue;
        }
        let train: Vec<usize> = (0..n).filter(|&r| r < lo || r >= hi).collect();
        let c = ols(x, y, &train, support);
        let mse = (lo..hi)
            .map(|r| {
                let p: f64 = support.iter().zip(&c).map(|(&j, cj)| x[j][r] * cj).sum();
                (y[r] - p).powi(2)
            })
            .sum::<f64>()
            / (hi - lo) as f64;
        per_block.push(mse);
    }
    let m = per_block.iter().sum::<f64>() / per_block.len().max(1) as f64;
    let var = per_block.iter().map(|v| (v - m).powi(2)).sum::<f64>()
        / (per_block.len().max(2) - 1) as f64;
    (m, (var / per_block.len().max(1) as f64).sqrt())
}

/// The selected support and its held-out share of variance explained: STLSQ along a
/// path of thresholds, each support validated on held-out blocks; the sparsest support
/// within one standard error of the best held-out error wins.
pub fn select(x: &[Vec<f64>], y: &[f64]) -> (Vec<usize>, f64) {
    let n = y.len();
    if n < 2 * BLOCKS || x.is_empty() {
        return (Vec::new(), 0.0);
    }
    let all: Vec<usize> = (0..n).collect();
    let mut supports: Vec<Vec<usize>> = vec![Vec::new()];
    for th in [0.01, 0.02, 0.05, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7] {
        let s = stlsq(x, y, &all, th);
        if !supports.contains(&s) {
            supports.push(s);
        }
    }
    let scored: Vec<(Vec<usize>, f64, f64)> = supports
        .into_iter()
        .map(|s| {
            let (m, se) = heldout_mse(x, y, &s);
            (s, m, se)
        })
        .collect();
    let best = scored
        .iter()
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .expect("the empty support is always scored");
    let bar = best.1 + best.2;
    let chosen = scored
        .iter()
        .filter(|s| s.1 <= bar)
        .min_by(|a, b| a.0.len().cmp(&b.0.len()).then(a.1.total_cmp(&b.1)))
        .expect("the best is within its own bar");
    let empty = scored[0].1.max(1e-300);
    let share = (1.0 - chosen.1 / empty).max(0.0);
    (chosen.0.clone(), share)
}

/// Identifies one target: the terms that survive, described.
pub fn identify(target: &str, y: &[f64], lib: &[Regressor]) -> Vec<Term> {
    let x: Vec<Vec<f64>> = lib.iter().map(|r| r.values.clone()).collect();
    let (support, share) = select(&x, y);
    if share < MIN_HELDOUT_SHARE {
        return Vec::new();
    }
    let all: Vec<usize> = (0..y.len()).collect();
    let c = ols(&x, y, &all, &support);
    support
        .iter()
        .zip(c)
        .filter(|(&j, _)| !lib[j].nuisance)
        .map(|(&j, cj)| {
            let r = &lib[j];
            let physics = physics_of(target, &r.name).map(str::to_string);
            Term {
                target: target.to_string(),
                regressor: r.name.clone(),
                coefficient: cj,
                heldout_share: share,
                depends_on: format!(
                    "{} error proportional to {} ({:.3e} per unit{})",
                    target.replace('_', " "),
                    r.words,
                    cj,
                    physics
                        .as_deref()
                        .map(|p| format!("; physics: {p}"))
                        .unwrap_or_else(|| "; outside the catalogue".into())
                ),
                physics,
            }
        })
        .collect()
}

/// Pose-sample boundaries of intervals of about `span_s` seconds.
fn intervals(p: &Prepared, span_s: f64) -> Vec<(usize, usize)> {
    let ps = &p.poses;
    let mut out = Vec::new();
    let mut k0 = 0;
    for k in 1..ps.len() {
        if p.t[ps.row[k]] - p.t[ps.row[k0]] >= span_s {
            out.push((k0, k));
            k0 = k;
        }
    }
    out
}

/// Commanded (else encoder) body twist per row, from the driven wheels by least squares
/// on the nominal rolling rows: (vx, vy, omega) in the body frame.
fn body_twist(p: &Prepared) -> Vec<(f64, f64, f64)> {
    let n = p.rows();
    let rows: Vec<(usize, [f64; 3], f64)> = p
        .robot
        .wheels
        .iter()
        .enumerate()
        .filter(|(i, w)| w.driven && (p.wheels[*i].cmd.is_some() || p.wheels[*i].enc_rad.is_some()))
        .map(|(i, w)| (i, w.rolling_row(), w.radius_m * w.gamma_rad.cos()))
        .collect();
    let omni = p.robot.kind == calib_core::robot::RobotKind::Omni;
    let cols: Vec<usize> = if omni { vec![0, 1, 2] } else { vec![0, 2] };
    let k = cols.len();
    let mut a = nalgebra::DMatrix::<f64>::zeros(rows.len(), k);
    for (r, (_, row, _)) in rows.iter().enumerate() {
        for (c, &j) in cols.iter().enumerate() {
            a[(r, c)] = row[j];
        }
    }
    let Ok(pinv) = a.pseudo_inverse(1e-9) else {
        return vec![(0.0, 0.0, 0.0); n];
    };
    let rate = |i: usize, k: usize| -> f64 {
        let w = &p.wheels[i];
        if let Some(c) = &w.cmd {
            return c[k];
        }
        let e = w.enc_rad.as_ref().expect("filtered");
        let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
        if b > a {
            (e[b] - e[a]) / (p.t[b] - p.t[a])
        } else {
            0.0
        }
    };
    // One row of the pseudo-inverse per body component, no allocation per row.
    let mut s = vec![0.0; rows.len()];
    (0..n)
        .map(|k| {
            for (o, (i, _, r)) in s.iter_mut().zip(&rows) {
                *o = rate(*i, k) * r;
            }
            let comp = |c: usize| -> f64 { (0..s.len()).map(|j| pinv[(c, j)] * s[j]).sum() };
            if omni {
                (comp(0), comp(1), comp(2))
            } else {
                (comp(0), 0.0, comp(1))
            }
        })
        .collect()
}

/// The ground-stage library over pose intervals and the targets (heading, along-track and
/// cross-track increments of the residual `e`).
pub fn ground_targets(p: &Prepared, e: &Eval) -> (Vec<Regressor>, Vec<(String, Vec<f64>)>) {
    let iv = intervals(p, 0.5);
    let tw = body_twist(p);
    let ps = &p.poses;
    let mut lib: Vec<(String, String, bool, Vec<f64>)> = Vec::new();
    let mut push = |name: &str, words: &str, nuisance: bool, f: &dyn Fn(usize, usize) -> f64| {
        lib.push((
            name.to_string(),
            words.to_string(),
            nuisance,
            iv.iter().map(|&(a, b)| f(a, b)).collect(),
        ));
    };
    let rows = |a: usize, b: usize| ps.row[a]..ps.row[b];
    let dt = |k: usize| p.t[(k + 1).min(p.rows() - 1)] - p.t[k];
    let integ = |a: usize, b: usize, f: &dyn Fn(usize) -> f64| -> f64 {
        rows(a, b).map(|k| f(k) * dt(k)).sum()
    };
    // Reversals of the commanded forward speed (sign changes beyond a small band).
    let mut sign = 0.0;
    let mut rev = vec![0.0; p.rows()];
    for (k, t) in tw.iter().enumerate() {
        if t.0.abs() > 0.02 {
            let s = t.0.signum();
            if sign != 0.0 && s != sign {
                rev[k] = s;
            }
            sign = s;
        }
    }
    push("time", "elapsed time (drift)", false, &|a, b| {
        p.t[ps.row[b]] - p.t[ps.row[a]]
    });
    push("distance", "signed distance travelled", false, &|a, b| {
        integ(a, b, &|k| tw[k].0)
    });
    push("distance_abs", "distance travelled", false, &|a, b| {
        integ(a, b, &|k| tw[k].0.abs())
    });
    push("turn", "signed turn", false, &|a, b| {
        integ(a, b, &|k| tw[k].2)
    });
    push("turn_abs", "turn magnitude", false, &|a, b| {
        integ(a, b, &|k| tw[k].2.abs())
    });
    push(
        "reversals_fwd",
        "reversals of the forward command (signed)",
        false,
        &|a, b| rows(a, b).map(|k| rev[k]).sum(),
    );
    push(
        "reversals_fwd_abs",
        "reversals of the forward command",
        false,
        &|a, b| rows(a, b).map(|k| rev[k].abs()).sum(),
    );
    push("accel", "forward acceleration", false, &|a, b| {
        tw[ps.row[b]].0 - tw[ps.row[a]].0
    });
    push(
        "accel_abs",
        "forward acceleration magnitude",
        false,
        &|a, b| {
            rows(a, b)
                .map(|k| (tw[(k + 1).min(p.rows() - 1)].0 - tw[k].0).abs())
                .sum()
        },
    );
    push(
        "lateral_accel",
        "lateral acceleration v omega",
        false,
        &|a, b| integ(a, b, &|k| tw[k].0 * tw[k].2),
    );
    // Position on the floor: where the distance was rolled, in four bands of measured x.
    let (xmin, xmax) =
        ps.x.iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| {
                (a.min(x), b.max(x))
            });
    let span = (xmax - xmin).max(1e-6);
    for band in 0..4 {
        let lo = xmin + span * band as f64 / 4.0;
        let hi = lo + span / 4.0;
        let name = format!("floor_x{band}");
        let words = format!("distance rolled with x in [{lo:.2}, {hi:.2}] m");
        push(&name, &words, false, &|a, b| {
            rows(a, b)
                .map(|k| {
                    let x = p.pose_at_row[k].0;
                    if (lo..hi).contains(&x) {
                        tw[k].0.abs() * dt(k)
                    } else {
                        0.0
                    }
                })
                .sum()
        });
    }
    if let Some((lf, lr)) = &p.legs {
        push(
            "posture_accel",
            "acceleration times the rear leg's reach",
            false,
            &|a, b| {
                rows(a, b)
                    .map(|k| (tw[(k + 1).min(p.rows() - 1)].0 - tw[k].0).abs() * (lr[k] - lf[k]))
                    .sum()
            },
        );
    }
    // Heading error already made, carried along by the motion (kinematics, not physics).
    push(
        "carried_heading",
        "earlier heading error times distance",
        true,
        &|a, b| e.eth[a] * integ(a, b, &|k| tw[k].0),
    );
    let lib: Vec<Regressor> = lib
        .into_iter()
        .map(|(name, words, nuisance, values)| Regressor {
            name,
            words,
            values,
            nuisance,
        })
        .collect();
    let along: Vec<f64> = iv
        .iter()
        .map(|&(a, b)| {
            let (c, s) = (ps.theta[a].cos(), ps.theta[a].sin());
            (e.ex[b] - e.ex[a]) * c + (e.ey[b] - e.ey[a]) * s
        })
        .collect();
    let cross: Vec<f64> = iv
        .iter()
        .map(|&(a, b)| {
            let (c, s) = (ps.theta[a].cos(), ps.theta[a].sin());
            -(e.ex[b] - e.ex[a]) * s + (e.ey[b] - e.ey[a]) * c
        })
        .collect();
    let heading: Vec<f64> = iv.iter().map(|&(a, b)| e.eth[b] - e.eth[a]).collect();
    (
        lib,
        vec![
            ("heading".into(), heading),
            ("along_track".into(), along),
            ("cross_track".into(), cross),
        ],
    )
}

/// Identification of the ground stage's residual `e` (empty without pose samples).
pub fn ground(p: &Prepared, e: &Eval) -> Vec<Term> {
    if p.poses.len() < 4 * BLOCKS || e.eth.len() != p.poses.len() {
        return Vec::new();
    }
    let (lib, targets) = ground_targets(p, e);
    targets
        .iter()
        .flat_map(|(name, y)| identify(name, y, &lib))
        .collect()
}

/// Identification of the actuator stage's residual per compared wheel: increments of the
/// encoder-minus-model travel over about a quarter second, against the wheel's own
/// command (its sign over time, its travel, its change, its reversals) and time.
pub fn actuator(ev: &crate::residuals::Evaluator, e: &Eval) -> Vec<Term> {
    let p = ev.p;
    let rows = &ev.act_rows;
    if rows.len() < 8 * BLOCKS {
        return Vec::new();
    }
    let mut iv = Vec::new();
    let mut a = 0;
    for b in 1..rows.len() {
        if p.t[rows[b]] - p.t[rows[a]] >= 0.25 {
            iv.push((a, b));
            a = b;
        }
    }
    let mut out = Vec::new();
    for (i, res) in &e.act {
        let w = &p.wheels[*i];
        let Some(cmd) = &w.cmd else { continue };
        let r = w.radius_m;
        let dt = |k: usize| p.t[(k + 1).min(p.rows() - 1)] - p.t[k];
        let col = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> {
            iv.iter().map(|&(a, b)| f(rows[a], rows[b])).collect()
        };
        let mut rev = vec![0.0; p.rows()];
        let mut sign = 0.0;
        for (k, c) in cmd.iter().enumerate() {
            if c.abs() > 1e-6 {
                if sign != 0.0 && c.signum() != sign {
                    rev[k] = c.signum();
                }
                sign = c.signum();
            }
        }
        let reg = |name: &str, words: &str, values: Vec<f64>| Regressor {
            name: name.into(),
            words: words.into(),
            values,
            nuisance: false,
        };
        let lib = vec![
            reg("time", "elapsed time (drift)", col(&|a, b| p.t[b] - p.t[a])),
            reg(
                "sign_time",
                "time spent turning, signed by the command",
                col(&|a, b| (a..b).map(|k| cmd[k].signum() * dt(k)).sum()),
            ),
            reg(
                "cmd_travel",
                "commanded travel",
                col(&|a, b| (a..b).map(|k| cmd[k] * r * dt(k)).sum()),
            ),
            reg(
                "cmd_accel",
                "change of the commanded speed",
                col(&|a, b| (cmd[b] - cmd[a]) * r),
            ),
            reg(
                "wheel_reversals",
                "reversals of the wheel's command (signed)",
                col(&|a, b| (a + 1..=b).map(|k| rev[k]).sum()),
            ),
        ];
        let y: Vec<f64> = iv.iter().map(|&(a, b)| res[b] - res[a]).collect();
        out.extend(identify(&format!("actuator_{}", w.name), &y, &lib));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-noise in [-0.5, 0.5) (no rand in the library's dependencies).
    fn noise(seed: &mut u64) -> f64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*seed >> 11) as f64 / (1u64 << 53) as f64) - 0.5
    }

    fn library(n: usize, seed: &mut u64) -> Vec<Regressor> {
        let names = [
            "time",
            "distance",
            "turn",
            "reversals_fwd",
            "accel",
            "lateral_accel",
        ];
        names
            .iter()
            .map(|nm| Regressor {
                name: nm.to_string(),
                words: nm.to_string(),
                values: (0..n).map(|_| noise(seed)).collect(),
                nuisance: false,
            })
            .collect()
    }

    /// A residual built from two known terms plus noise: STLSQ with held-out blocks keeps
    /// exactly those two and recovers their coefficients to within the noise's error
    /// (0.01 / sqrt(n / 12) ~ 1e-3 for 400 uniform regressors).
    #[test]
    fn recovers_known_terms() {
        let mut seed = 7;
        let n = 400;
        let lib = library(n, &mut seed);
        let y: Vec<f64> = (0..n)
            .map(|k| 0.8 * lib[2].values[k] - 0.3 * lib[3].values[k] + 0.01 * noise(&mut seed))
            .collect();
        let terms = identify("heading", &y, &lib);
        let names: Vec<&str> = terms.iter().map(|t| t.regressor.as_str()).collect();
        assert_eq!(names, ["turn", "reversals_fwd"]);
        assert!((terms[0].coefficient - 0.8).abs() < 5e-3, "{terms:?}");
        assert!((terms[1].coefficient + 0.3).abs() < 5e-3, "{terms:?}");
        assert_eq!(
            terms[0]
                .physics
                .as_deref()
                .map(|p| p.starts_with("wheelbase")),
            Some(true)
        );
        assert!(
            terms[1].physics.is_none(),
            "reversals of heading are outside the table"
        );
        assert!(terms[1].depends_on.contains("reversals"));
    }

    /// Pure noise: nothing survives (the held-out share stays under the bar).
    #[test]
    fn noise_gives_no_terms() {
        let mut seed = 11;
        let n = 300;
        let lib = library(n, &mut seed);
        let y: Vec<f64> = (0..n).map(|_| noise(&mut seed)).collect();
        assert!(identify("along_track", &y, &lib).is_empty());
    }

    /// Hand-made candidates: two nearly collinear regressors (one the other plus 1 %
    /// noise) and a residual made by one of them; the simplest adequate support has one
    /// term, not both.
    #[test]
    fn one_term_beats_two_that_fit_as_well() {
        let mut seed = 3;
        let n = 300;
        let a: Vec<f64> = (0..n).map(|_| noise(&mut seed)).collect();
        let b: Vec<f64> = a.iter().map(|v| v + 0.01 * noise(&mut seed)).collect();
        let y: Vec<f64> = a
            .iter()
            .map(|v| 2.0 * v + 0.05 * noise(&mut seed))
            .collect();
        let (support, share) = select(&[a, b], &y);
        assert_eq!(support.len(), 1, "{support:?}");
        assert!(share > 0.95, "{share}");
    }

    /// Physics table: the catalogue's mappings, and nothing for a term outside it.
    #[test]
    fn physics_table() {
        assert!(physics_of("actuator_left", "sign_time")
            .unwrap()
            .starts_with("coulomb"));
        assert!(physics_of("actuator_w1", "wheel_reversals")
            .unwrap()
            .starts_with("backlash"));
        assert!(physics_of("along_track", "floor_x2")
            .unwrap()
            .starts_with("floor"));
        assert!(physics_of("heading", "reversals_fwd").is_none());
        // Heading against acceleration: traction that differs between the wheels (a
        // payload off-centre), the only way `longitudinal_slip` by `per_wheel` is tried.
        assert!(physics_of("heading", "accel")
            .unwrap()
            .starts_with("longitudinal_slip per wheel"));
        assert!(physics_of("heading", "lateral_accel").is_none());
        assert!(regressor_has_physics("accel"));
        assert!(regressor_has_physics("floor_x3"));
        assert!(!regressor_has_physics("reversals_fwd"));
        assert!(!regressor_has_physics("reversals_fwd_abs"));
        assert!(!regressor_has_physics("time"));
    }
}
