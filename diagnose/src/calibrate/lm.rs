//! Levenberg-Marquardt as [`crate::fit::levenberg_marquardt_jacobian`] does it (the same
//! damping schedule, bounds by clamping, convergence test and iteration limit), with the
//! Jacobian given by the caller: calibration's model has an analytic one (the paths'
//! sensitivities), which costs a few model runs where forward differences cost one per
//! parameter. Without one, the forward differences are [`crate::fit`]'s, to the bit.

use nalgebra::{DMatrix, DVector};

/// Outcome of a fit.
pub(crate) struct Fitted {
    /// Parameters.
    pub(crate) x: Vec<f64>,
    /// Residual function evaluations, the Jacobians' counted as [`Jacobian::runs`] each.
    pub(crate) evaluations: usize,
    /// Jacobian of the residuals at `x`.
    pub(crate) jac: DMatrix<f64>,
}

/// Least Levenberg-Marquardt damping (as [`crate::fit`]).
const MIN_LAMBDA: f64 = 1e-9;

/// The Jacobian of the residuals at a point.
pub(crate) trait Jacobian {
    /// Fills `jac` (resized as needed) at `x`, whose residuals are `r`. False when it
    /// cannot: forward differences are used instead.
    fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool;
    /// What one Jacobian costs, in model runs (for the run count).
    fn runs(&self) -> usize;
}

/// No analytic Jacobian: forward differences everywhere.
pub(crate) struct Differences;

impl Jacobian for Differences {
    fn at(&mut self, _: &[f64], _: &[f64], _: &mut DMatrix<f64>) -> bool {
        false
    }
    fn runs(&self) -> usize {
        0
    }
}

/// Minimises the sum of squares of `f(x)` from `x0` within `[lo, hi]`, with `jac`'s
/// Jacobian during the iterations. The Jacobian returned at the solution is `jac`'s too
/// unless `final_differences`, then forward differences (as [`crate::fit`] returns).
pub(crate) fn levenberg_marquardt(
    f: &mut dyn FnMut(&[f64]) -> Vec<f64>,
    jac_fn: &mut dyn Jacobian,
    x0: &[f64],
    lo: &[f64],
    hi: &[f64],
    max_iter: usize,
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
        let jt = jac.transpose();
        let jtj = &jt * &jac;
        let g = &jt * DVector::from_column_slice(&r);
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
                if rel < 1e-7 {
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
        evaluations,
        jac,
    }
}

fn sumsq(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Forward differences, stepping backwards at the upper bound (as [`crate::fit`]).
fn forward_differences(
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
        let mut h = 1e-4 * x[j].abs().max(1e-2);
        if x[j] + h > hi[j] {
            h = -h;
        }
        let mut xp = x.to_vec();
        xp[j] += h;
        let rp = f(&xp);
        for i in 0..m {
            jac[(i, j)] = (rp.get(i).copied().unwrap_or(0.0) - r[i]) / h;
        }
    }
}
