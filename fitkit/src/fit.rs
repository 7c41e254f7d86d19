//! Levenberg-Marquardt on a handful of parameters, with a finite-difference Jacobian or
//! one the model provides.
//!
//! Diagnose's models are simulations (thresholds, clamps, integrations), so analytic
//! Jacobians would be long and fragile; with at most a few parameters, p + 1 model runs
//! per iteration are affordable. Calibration's dead reckoning carries its sensitivities
//! and passes them in ([`Jacobian`]). Bounds: a parameter on its bound whose step points
//! beyond it is held for that step (an active set), and every step is clamped.

use nalgebra::{DMatrix, DVector};

/// Outcome of a fit.
#[derive(Debug, Clone)]
pub struct FitResult {
    /// Parameters in the optimiser's coordinates.
    pub x: Vec<f64>,
    /// Sum of squared (noise-weighted) residuals at `x`.
    pub cost: f64,
    /// One standard deviation per parameter (optimiser coordinates) from
    /// s^2 (J^T J)^-1, with s^2 the reduced chi-square so over-noise residuals widen it;
    /// infinite where the data do not constrain the parameter.
    pub sigma: Vec<f64>,
    /// Number of evaluations of the residual function (model runs).
    pub evaluations: usize,
}

/// Least Levenberg-Marquardt damping: below it a step is Gauss-Newton's to 1e-9
/// relative, and the damping can still grow back within a few rejected steps.
const MIN_LAMBDA: f64 = 1e-9;

/// A fit has converged when an accepted step lowers the cost by less than this share:
/// calibration's fits, whose parameters are the product.
pub const CONVERGED_REL: f64 = 1e-7;

/// Diagnose's candidate fits stop at this share: a candidate's BIC change is
/// n_eff ln(c1 / c0), so a cost this close to its minimum moves it by 1e-5 n_eff (under
/// 0.1 for the effective sample sizes of a 10-minute recording, against a threshold of
/// 10), and its parameters sit within a small part of their sigma (unit test below).
/// Near the minimum the steps shrink quadratically, so this saves the last step or two.
pub const SCREENING_REL: f64 = 1e-5;

/// Minimises the sum of squares of `f(x)` from `x0` within `[lo, hi]`, until a step
/// lowers the cost by less than `rel_tol` of it ([`CONVERGED_REL`], [`SCREENING_REL`]).
pub fn levenberg_marquardt(
    f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_iter: usize,
    rel_tol: f64,
) -> FitResult {
    levenberg_marquardt_jacobian(f, x0, lo, hi, max_iter, rel_tol).0
}

/// As [`levenberg_marquardt`], also returning the Jacobian at the solution (for
/// identifiability: correlations and unconstrained directions).
pub fn levenberg_marquardt_jacobian(
    f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_iter: usize,
    rel_tol: f64,
) -> (FitResult, DMatrix<f64>) {
    let r = levenberg_marquardt_with(f, &mut Differences, x0, lo, hi, max_iter, rel_tol, true);
    let sigma = covariance_sigma(&r.jac, r.cost, r.jac.nrows());
    (
        FitResult {
            x: r.x,
            cost: r.cost,
            sigma,
            evaluations: r.evaluations,
        },
        r.jac,
    )
}

/// The Jacobian of the residuals at a point, when the model has one cheaper than forward
/// differences (calibration's paths carry their sensitivities).
pub trait Jacobian {
    /// Fills `jac` (resized as needed) at `x`, whose residuals are `r`. False when it
    /// cannot: forward differences are used instead.
    fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool;
    /// What one Jacobian costs, in model runs (for the run count).
    fn runs(&self) -> usize;
    /// Whether the normal equations (J^T J, J^T r) are summed as dot products of the
    /// Jacobian's columns: several times faster on a tall Jacobian (thousands of rows), the
    /// same sums in another order (so rounded differently from the matrix product).
    fn column_dots(&self) -> bool {
        false
    }
    /// Whether the Jacobian is block-sparse: columns nonzero on a span of rows each (a
    /// joint fit of several recordings, each with its own nuisance). The normal
    /// equations then take each pair of columns' dot product over the rows both span
    /// (`block_normal_equations`): the dense product would spend almost all its time
    /// multiplying zeros.
    fn block_sparse(&self) -> bool {
        false
    }
}

/// J^T J and J^T r from each pair of columns' dot product over the rows both can be
/// nonzero on (from a column's first nonzero row to its last): the same sums as the
/// dense products less the zero terms, for a block-sparse Jacobian in a fraction of the
/// time (m (g + k)^2 instead of m (g + b k)^2 for g shared columns and b blocks of k).
pub fn block_normal_equations(jac: &DMatrix<f64>, r: &[f64]) -> (DMatrix<f64>, DVector<f64>) {
    let (m, n) = jac.shape();
    let col = |j: usize| &jac.as_slice()[j * m..(j + 1) * m];
    let span: Vec<(usize, usize)> = (0..n)
        .map(|j| {
            let c = col(j);
            let first = c.iter().position(|v| *v != 0.0).unwrap_or(m);
            let end = c.iter().rposition(|v| *v != 0.0).map_or(first, |i| i + 1);
            (first, end)
        })
        .collect();
    let mut jtj = DMatrix::zeros(n, n);
    let mut g = DVector::zeros(n);
    for a in 0..n {
        let (fa, ea) = span[a];
        g[a] = dot(&col(a)[fa..ea], &r[fa..ea]);
        for b in a..n {
            let (lo, hi) = (fa.max(span[b].0), ea.min(span[b].1));
            let v = if lo < hi {
                dot(&col(a)[lo..hi], &col(b)[lo..hi])
            } else {
                0.0
            };
            jtj[(a, b)] = v;
            jtj[(b, a)] = v;
        }
    }
    (jtj, g)
}

/// A dot product with four independent running sums (the loop need not wait on one).
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0f64; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[1]) + (acc[2] + acc[3]) + tail
}

/// No analytic Jacobian: forward differences everywhere.
pub struct Differences;

impl Jacobian for Differences {
    fn at(&mut self, _: &[f64], _: &[f64], _: &mut DMatrix<f64>) -> bool {
        false
    }
    fn runs(&self) -> usize {
        0
    }
}

/// Outcome of [`levenberg_marquardt_with`].
pub struct Fitted {
    /// Parameters in the optimiser's coordinates.
    pub x: Vec<f64>,
    /// Sum of squared residuals at `x`.
    pub cost: f64,
    /// Residual function evaluations, a Jacobian counted as [`Jacobian::runs`] (or one
    /// per parameter for forward differences).
    pub evaluations: usize,
    /// Jacobian of the residuals at `x`.
    pub jac: DMatrix<f64>,
}

/// The one Levenberg-Marquardt loop: minimises the sum of squares of `f(x)` from `x0`
/// within `[lo, hi]` (an active set at the bounds, then clamping), with `jac_fn`'s
/// Jacobian during the iterations. The Jacobian returned at the solution is `jac_fn`'s too
/// unless `final_differences`, then forward differences. Stops when a step lowers the
/// cost by less than `rel_tol` of it.
#[allow(clippy::too_many_arguments)]
pub fn levenberg_marquardt_with(
    f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    jac_fn: &mut dyn Jacobian,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_iter: usize,
    rel_tol: f64,
    final_differences: bool,
) -> Fitted {
    let p = x0.len();
    let clamp = |x: &mut [f64]| {
        for i in 0..x.len() {
            x[i] = x[i].clamp(lo[i], hi[i]);
        }
    };
    let mut x = x0.to_vec();
    clamp(&mut x);
    let mut r = f(&x);
    let mut evaluations = 1;
    let mut cost = sumsq(&r);
    let mut lambda = 1e-3;
    let mut jac = DMatrix::<f64>::zeros(r.len(), p);
    let dots = jac_fn.column_dots();
    let blocks = jac_fn.block_sparse();
    let mut jacobian = |f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
                        x: &[f64],
                        r: &[f64],
                        jac: &mut DMatrix<f64>,
                        differences: bool| {
        if !differences && jac_fn.at(x, r, jac) {
            jac_fn.runs()
        } else {
            forward_differences(f, x, r, hi, jac);
            p
        }
    };
    for _ in 0..max_iter {
        evaluations += jacobian(f, &x, &r, &mut jac, false);
        let (jtj, g) = if blocks {
            block_normal_equations(&jac, &r)
        } else if dots {
            let rv = DVector::from_column_slice(&r);
            (jac.tr_mul(&jac), jac.tr_mul(&rv))
        } else {
            let jt = jac.transpose();
            (&jt * &jac, &jt * DVector::from_column_slice(&r))
        };
        let mut improved = false;
        for _ in 0..8 {
            let Some(step) = bounded_step(&jtj, &g, lambda, &x, lo, hi) else {
                lambda *= 10.0;
                continue;
            };
            let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut xn);
            let rn = f(&xn);
            evaluations += 1;
            let cn = sumsq(&rn);
            if cn.is_finite() && cn < cost {
                let rel = (cost - cn) / cost.max(1e-300);
                x = xn;
                r = rn;
                cost = cn;
                lambda = (lambda * 0.3).max(MIN_LAMBDA);
                improved = true;
                if rel < rel_tol {
                    improved = false; // converged
                }
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    evaluations += jacobian(f, &x, &r, &mut jac, final_differences);
    Fitted {
        x,
        cost,
        evaluations,
        jac,
    }
}

/// The damped Gauss-Newton step (J^T J + lambda diag(J^T J)) s = -J^T r with the
/// parameters held that sit on a bound and would step beyond it (an active set): the
/// others then step for the problem with those fixed. Clamping the full step instead
/// moves the free parameters as if the held ones had moved too, which on correlated
/// parameters raises the cost and makes the fit crawl along the bound.
fn bounded_step(
    jtj: &DMatrix<f64>,
    g: &DVector<f64>,
    lambda: f64,
    x: &[f64],
    lo: &[f64],
    hi: &[f64],
) -> Option<DVector<f64>> {
    let p = x.len();
    let mut held = vec![false; p];
    // Each pass holds at least one more parameter, so at most p + 1 passes.
    loop {
        let mut a = jtj.clone();
        let mut b = -g;
        for i in 0..p {
            if held[i] {
                for k in 0..p {
                    a[(i, k)] = 0.0;
                    a[(k, i)] = 0.0;
                }
                a[(i, i)] = 1.0;
                b[i] = 0.0;
            } else {
                a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
            }
        }
        let step = a.lu().solve(&b)?;
        let mut more = false;
        for i in 0..p {
            let out = (x[i] <= lo[i] && step[i] < 0.0) || (x[i] >= hi[i] && step[i] > 0.0);
            if out && !held[i] {
                held[i] = true;
                more = true;
            }
        }
        if !more {
            return Some(step);
        }
    }
}

fn sumsq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// The forward-difference step of a parameter at `x` below its upper bound `hi`:
/// backwards when a step forwards would cross it.
pub fn difference_step(x: f64, hi: f64) -> f64 {
    let h = 1e-4 * x.abs().max(1e-2);
    if x + h > hi {
        -h
    } else {
        h
    }
}

/// Forward differences, stepping backwards at the upper bound.
pub fn forward_differences(
    f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    x: &[f64],
    r: &[f64],
    hi: &[f64],
    jac: &mut DMatrix<f64>,
) {
    let m = r.len();
    if jac.nrows() != m || jac.ncols() != x.len() {
        *jac = DMatrix::zeros(m, x.len());
    }
    for j in 0..x.len() {
        let h = difference_step(x[j], hi[j]);
        let mut xp = x.to_vec();
        xp[j] += h;
        let rp = f(&xp);
        for i in 0..m {
            jac[(i, j)] = (rp.get(i).copied().unwrap_or(0.0) - r[i]) / h;
        }
    }
}

/// sqrt(diag(s^2 (J^T J)^-1)), s^2 = cost / (m - p) (at least 1: never claim better than
/// the noise model).
pub fn covariance_sigma(jac: &DMatrix<f64>, cost: f64, m: usize) -> Vec<f64> {
    let p = jac.ncols();
    let dof = m.saturating_sub(p).max(1) as f64;
    let s2 = (cost / dof).max(1.0);
    let jtj = jac.transpose() * jac;
    match jtj.clone().try_inverse() {
        Some(inv) => (0..p)
            .map(|i| {
                let v = inv[(i, i)] * s2;
                if v.is_finite() && v >= 0.0 && jtj[(i, i)] > 1e-18 {
                    v.sqrt()
                } else {
                    f64::INFINITY
                }
            })
            .collect(),
        None => vec![f64::INFINITY; p],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The normal equations of a block-sparse Jacobian (shared columns, then each block's
    /// own, zero elsewhere, prior rows below) from the columns' overlaps equal the dense
    /// products to rounding.
    #[test]
    fn block_normal_equations_are_the_dense_ones() {
        let (blocks, rows, shared, own) = (4, 37, 3, 5);
        let (m, n) = (blocks * rows + shared, shared + blocks * own);
        let mut jac = DMatrix::zeros(m, n);
        // A deterministic spread of values, signs and magnitudes.
        let v = |i: usize, j: usize| ((i * 7 + j * 13) % 23) as f64 / 7.0 - 1.5;
        for b in 0..blocks {
            for i in b * rows..(b + 1) * rows {
                for j in 0..shared {
                    jac[(i, j)] = v(i, j);
                }
                for j in shared + b * own..shared + (b + 1) * own {
                    jac[(i, j)] = v(i, j) * 1e3;
                }
            }
        }
        for k in 0..shared {
            jac[(blocks * rows + k, k)] = 2.0;
        }
        let r: Vec<f64> = (0..m).map(|i| v(i, 1) * 10.0).collect();
        let (jtj, g) = block_normal_equations(&jac, &r);
        let dense = jac.transpose() * &jac;
        let gd = jac.transpose() * DVector::from_column_slice(&r);
        let scale = dense.amax();
        for a in 0..n {
            assert!((g[a] - gd[a]).abs() <= 1e-12 * gd.amax(), "g[{a}]");
            for b in 0..n {
                let (x, y) = (jtj[(a, b)], dense[(a, b)]);
                assert!(
                    (x - y).abs() <= 1e-12 * scale,
                    "({a}, {b}): {x} against {y}"
                );
            }
        }
        // The blocks' own columns never meet: exactly zero where the dense product is.
        assert_eq!(jtj[(shared, shared + own)], 0.0);
    }

    /// A minimum beyond a bound: the parameter stays at its bound and the others take the
    /// constrained optimum, found in a few steps. Clamping alone would step the others as
    /// if the bounded one had moved, see the cost rise, and crawl (the mecanum squares'
    /// refit within the plausible ranges took 58 iterations).
    #[test]
    fn a_minimum_beyond_a_bound_is_reached_at_the_bound_in_a_few_steps() {
        // y = 1.5 + 0.8 t - 0.3 t^2 on t in [0, 2): the three columns correlate (0.97 and
        // more), and the constant's upper bound is 1.0.
        let t: Vec<f64> = (0..40).map(|i| i as f64 * 0.05).collect();
        let y: Vec<f64> = t.iter().map(|t| 1.5 + 0.8 * t - 0.3 * t * t).collect();
        let mut f = |x: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| x[0] + x[1] * t + x[2] * t * t - y)
                .collect()
        };
        // The constrained optimum: x0 = 1, (x1, x2) least squares on y - 1.
        let a = DMatrix::from_fn(t.len(), 2, |i, j| t[i].powi(j as i32 + 1));
        let b = DVector::from_iterator(t.len(), y.iter().map(|y| y - 1.0));
        let want = (a.transpose() * &a)
            .lu()
            .solve(&(a.transpose() * b))
            .unwrap();
        let r = levenberg_marquardt(
            &mut f,
            &[0.0, 0.0, 0.0],
            &[-10.0, -10.0, -10.0],
            &[1.0, 10.0, 10.0],
            60,
            CONVERGED_REL,
        );
        assert_eq!(r.x[0], 1.0);
        // The fit stops when a step gains under CONVERGED_REL of the cost (about 2.7):
        // that leaves the parameters up to sqrt(1e-7 x 2.7 / sum t^2) ~ 7e-5 from the
        // optimum; they are asked to be within 1e-6.
        for k in 0..2 {
            assert!(
                (r.x[k + 1] - want[k]).abs() < 1e-6,
                "x{}: {} against {}",
                k + 1,
                r.x[k + 1],
                want[k]
            );
        }
        // A handful of steps, each Jacobian three differences, and the eight damped tries
        // that cannot improve on the optimum: 20 evaluations measured (the bound). Clamping
        // alone stopped short of the optimum (x1 1.344).
        assert!(r.evaluations <= 20, "{} evaluations", r.evaluations);
    }

    #[test]
    fn fits_an_exponential() {
        // y = 2 exp(-0.7 t) sampled without noise: LM finds (2, 0.7).
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-0.7 * t).exp()).collect();
        let mut f = |x: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| x[0] * (-x[1] * t).exp() - y)
                .collect()
        };
        let r = levenberg_marquardt(
            &mut f,
            &[1.0, 0.1],
            &[0.0, 0.0],
            &[10.0, 10.0],
            100,
            CONVERGED_REL,
        );
        assert!(
            (r.x[0] - 2.0).abs() < 1e-6 && (r.x[1] - 0.7).abs() < 1e-6,
            "{:?}",
            r.x
        );
    }

    #[test]
    fn uncertainty_of_a_mean() {
        // Residuals x - y_i with unit noise weights: sigma of the mean = 1 / sqrt(n) when
        // the scatter matches the weights.
        let y: Vec<f64> = (0..100)
            .map(|i| if i % 2 == 0 { 1.0 } else { -1.0 })
            .collect();
        let mut f = |x: &[f64]| -> Vec<f64> { y.iter().map(|v| x[0] - v).collect() };
        let r = levenberg_marquardt(&mut f, &[0.5], &[-10.0], &[10.0], 50, CONVERGED_REL);
        assert!(r.x[0].abs() < 1e-6);
        assert!((r.sigma[0] - 0.1).abs() < 0.002, "{}", r.sigma[0]);
    }

    #[test]
    fn a_screening_fit_lands_within_a_tenth_of_a_sigma_of_the_converged_one() {
        // y = 2 exp(-0.7 t) with noise of sigma 0.05 on 2,000 samples, from a far start:
        // the screening tolerance stops sooner, its cost within its tolerance of the
        // converged one and its parameters within a tenth of their sigma.
        let t: Vec<f64> = (0..2000).map(|i| i as f64 * 0.0025).collect();
        let mut state = 12345u64;
        let mut noise = || {
            // Sum of 12 uniforms (Irwin-Hall) minus 6: unit variance.
            let mut s = 0.0;
            for _ in 0..12 {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                s += (state >> 11) as f64 / (1u64 << 53) as f64;
            }
            s - 6.0
        };
        let y: Vec<f64> = t
            .iter()
            .map(|t| 2.0 * (-0.7 * t).exp() + 0.05 * noise())
            .collect();
        let mut f = |x: &[f64]| -> Vec<f64> {
            t.iter()
                .zip(&y)
                .map(|(t, y)| (x[0] * (-x[1] * t).exp() - y) / 0.05)
                .collect()
        };
        let (lo, hi) = ([0.0, 0.0], [10.0, 10.0]);
        let tight = levenberg_marquardt(&mut f, &[0.5, 3.0], &lo, &hi, 100, CONVERGED_REL);
        let loose = levenberg_marquardt(&mut f, &[0.5, 3.0], &lo, &hi, 100, SCREENING_REL);
        assert!(
            loose.evaluations < tight.evaluations,
            "{} {}",
            loose.evaluations,
            tight.evaluations
        );
        assert!((loose.cost - tight.cost) / tight.cost < SCREENING_REL);
        for i in 0..2 {
            assert!(
                (loose.x[i] - tight.x[i]).abs() < 0.1 * tight.sigma[i],
                "{i}: {} {} sigma {}",
                loose.x[i],
                tight.x[i],
                tight.sigma[i]
            );
        }
    }
}
