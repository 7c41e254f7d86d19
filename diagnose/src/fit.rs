//! Levenberg-Marquardt on a handful of parameters, with a finite-difference Jacobian or
//! one the model provides.
//!
//! Diagnose's models are simulations (thresholds, clamps, integrations), so analytic
//! Jacobians would be long and fragile; with at most a few parameters, p + 1 model runs
//! per iteration are affordable. Calibration's dead reckoning carries its sensitivities
//! and passes them in ([`Jacobian`]). Bounds are enforced by clamping.

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
/// within `[lo, hi]` (bounds by clamping), with `jac_fn`'s Jacobian during the
/// iterations. The Jacobian returned at the solution is `jac_fn`'s too unless
/// `final_differences`, then forward differences. Stops when a step lowers the cost by
/// less than `rel_tol` of it.
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
        let (jtj, g) = if dots {
            let rv = DVector::from_column_slice(&r);
            (jac.tr_mul(&jac), jac.tr_mul(&rv))
        } else {
            let jt = jac.transpose();
            (&jt * &jac, &jt * DVector::from_column_slice(&r))
        };
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for i in 0..p {
                a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
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

fn sumsq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// The forward-difference step of a parameter at `x` below its upper bound `hi`:
/// backwards when a step forwards would cross it.
pub(crate) fn difference_step(x: f64, hi: f64) -> f64 {
    let h = 1e-4 * x.abs().max(1e-2);
    if x + h > hi {
        -h
    } else {
        h
    }
}

/// Forward differences, stepping backwards at the upper bound.
pub(crate) fn forward_differences(
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
