//! Solving the joint problem: bounded Levenberg-Marquardt over the geometry, the
//! nuisance or both ([`solve`]), from the starts and within the bounds given here; and
//! what a solution's Jacobian tells: the covariance with the residuals' autocorrelation
//! counted, the correlations, the noise scale the prior is weighed by. Also a
//! recording's aligned RMSE at a given geometry ([`aligned_rmse`]).

use crate::objective::{huber, position_rmse};
use crate::params::ParamSpec;
use crate::pool::{deal, threads_for};
use crate::problem::Problem;
use crate::series::{Series, NUIS};
use calib_core::robot::Robot;
use nalgebra::DMatrix;

/// Search bounds of the per-recording nuisance (x0, y0, theta0 in m and rad, time offset
/// in s, clock ratio): far outside the plausible values, so an implausible one is seen
/// and reported rather than clamped.
const NUISANCE_LO: [f64; NUIS] = [-10.0, -10.0, -10.0, -2.0, 0.8];
/// Upper search bounds of the nuisance (see [`NUISANCE_LO`]).
const NUISANCE_HI: [f64; NUIS] = [10.0, 10.0, 10.0, 2.0, 1.25];

fn nuisance_bounds(n: usize) -> (Vec<f64>, Vec<f64>) {
    let (lo, hi) = (NUISANCE_LO, NUISANCE_HI);
    (
        (0..n).flat_map(|_| lo).collect(),
        (0..n).flat_map(|_| hi).collect(),
    )
}

pub(super) fn geom_bounds(specs: &[ParamSpec]) -> (Vec<f64>, Vec<f64>) {
    // Bounds far outside the plausible range: an implausible value must be seen to be
    // reported, not clamped away.
    specs
        .iter()
        .map(|s| {
            let h = 10.0 * (s.plausible.1 - s.nominal);
            (s.nominal - h, s.nominal + h)
        })
        .unzip()
}

/// The joint fit: geometry (free or fixed) and every recording's nuisance.
pub(super) struct Solved {
    pub(super) geom: Vec<f64>,
    pub(super) nuis: Vec<f64>,
    /// Jacobian of the data residuals with respect to [geometry, nuisance] (free ones).
    pub(super) jac: DMatrix<f64>,
    pub(super) data_cost: f64,
    pub(super) evaluations: usize,
}

pub(super) fn solve(p: &Problem, geom0: &[f64], nuis0: &[f64], fit_geom: bool) -> Solved {
    solve_iter(p, geom0, nuis0, fit_geom, 60)
}

/// [`solve`] with at most `max_iter` iterations (none: the residuals and Jacobian at the
/// start, as a fit ending there returns them).
pub(super) fn solve_iter(
    p: &Problem,
    geom0: &[f64],
    nuis0: &[f64],
    fit_geom: bool,
    max_iter: usize,
) -> Solved {
    let g = p.specs.len();
    let (nlo, nhi) = nuisance_bounds(p.series.len());
    let (glo, ghi) = if p.plausible_bounds {
        p.specs.iter().map(|s| s.plausible).unzip()
    } else {
        geom_bounds(p.specs)
    };
    let (x0, lo, hi) = if fit_geom {
        (
            [geom0, nuis0].concat(),
            [glo.as_slice(), &nlo].concat(),
            [ghi.as_slice(), &nhi].concat(),
        )
    } else {
        (nuis0.to_vec(), nlo, nhi)
    };
    let m = p.data_len();
    let mut f = |x: &[f64]| -> Vec<f64> { objective_at(p, fit_geom, geom0, x) };
    if x0.is_empty() {
        // Nothing free (dead reckoning with the geometry given).
        let data = p.residuals(geom0, nuis0, false);
        return Solved {
            geom: geom0.to_vec(),
            nuis: nuis0.to_vec(),
            jac: DMatrix::zeros(m, 0),
            data_cost: data.iter().map(|v| v * v).sum(),
            evaluations: 1,
        };
    }
    /// The geometry's analytic Jacobian; whether the last one was (else differences).
    struct Analytic<'a, 'b>(&'b Problem<'a>, usize, bool);
    impl fitkit::fit::Jacobian for Analytic<'_, '_> {
        fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
            self.2 = self.0.jacobian(&x[..self.1], r, jac);
            self.2
        }
        fn runs(&self) -> usize {
            // One pass over the rows carrying the sensitivities: about three model runs.
            3
        }
        fn column_dots(&self) -> bool {
            true
        }
    }
    /// The start poses and clocks alone (the geometry given): their analytic Jacobian.
    struct Nuisances<'a, 'b>(&'b Problem<'a>, &'b [f64]);
    impl fitkit::fit::Jacobian for Nuisances<'_, '_> {
        fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
            self.0.nuisance_jacobian(self.1, x, r, jac)
        }
        fn runs(&self) -> usize {
            // One pass over the pose samples, the paths as they are: one model run.
            1
        }
        fn column_dots(&self) -> bool {
            true
        }
        fn block_sparse(&self) -> bool {
            self.0.series.len() > 1
        }
    }
    /// The geometry and every recording's start pose and clocks: their analytic Jacobian.
    struct Aligned<'a, 'b>(&'b Problem<'a>);
    impl fitkit::fit::Jacobian for Aligned<'_, '_> {
        fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
            self.0.free_jacobian(x, r, jac)
        }
        fn runs(&self) -> usize {
            // One pass over the rows carrying the sensitivities, counted as the dead
            // reckoning's is (its cost grows with the parameters: each one's
            // sensitivity is stepped at every row).
            3
        }
        fn column_dots(&self) -> bool {
            true
        }
        fn block_sparse(&self) -> bool {
            // Each recording's start pose and clocks move its rows alone.
            self.0.series.len() > 1
        }
    }
    let analytic = fit_geom && !p.free_start;
    // A wheeled-legged robot's paths carry no sensitivities: differences, split below.
    let aligned = fit_geom && p.free_start && p.series.iter().all(|s| s.legs.is_none());
    let r = if aligned || analytic {
        // Dead reckoning: each point evaluated carries its sensitivities, so the
        // Jacobian that follows an accepted step costs no pass over the rows.
        p.speculate.set(analytic);
        let (mut dr, mut al) = (Analytic(p, g, false), Aligned(p));
        let jac_fn: &mut dyn fitkit::fit::Jacobian = if aligned { &mut al } else { &mut dr };
        let mut r = fitkit::fit::levenberg_marquardt_with(
            &mut f,
            jac_fn,
            &x0,
            &lo,
            &hi,
            max_iter,
            fitkit::fit::CONVERGED_REL,
            false,
        );
        p.speculate.set(false);
        // Aligned, the analytic Jacobian at the solution too: exact where forward
        // differences are not, one pass instead of one run per parameter.
        if p.differences_at_solution && dr.2 {
            // Forward differences at the solution, as the fit gives them (its analytic
            // Jacobian there is counted as its runs; the differences as one per parameter).
            let at = f(&r.x);
            fitkit::fit::forward_differences(&mut f, &r.x, &at, &hi, &mut r.jac);
            r.evaluations = r.evaluations - fitkit::fit::Jacobian::runs(&dr) + r.x.len();
        }
        r
    } else {
        // One long recording: its evaluations cannot be split by recording, so the
        // differences' columns are (the same numbers, sooner).
        let threads = if fit_geom && p.series.len() == 1 {
            threads_for(p.series[0].t.len(), x0.len())
        } else {
            1
        };
        let mut jac_fn: Box<dyn fitkit::fit::Jacobian> = if !fit_geom && p.free_start {
            Box::new(Nuisances(p, geom0))
        } else if threads > 1 {
            Box::new(SplitDifferences {
                p,
                geom0,
                hi: &hi,
                threads,
                cols: x0.len(),
            })
        } else {
            Box::new(fitkit::fit::Differences)
        };
        // Split differences are differences: at the solution too.
        let final_differences = p.differences_at_solution && threads < 2;
        fitkit::fit::levenberg_marquardt_with(
            &mut f,
            jac_fn.as_mut(),
            &x0,
            &lo,
            &hi,
            max_iter,
            fitkit::fit::CONVERGED_REL,
            final_differences,
        )
    };
    let (geom, nuis) = if fit_geom {
        (r.x[..g].to_vec(), r.x[g..].to_vec())
    } else {
        (geom0.to_vec(), r.x)
    };
    // The data rows kept in place (a copy would double the largest matrix of diagnose's
    // recording stage for a moment).
    let mut jac = r.jac;
    let priors = jac.nrows() - m;
    if priors > 0 {
        jac = jac.remove_rows(m, priors);
    }
    let data = p.residuals(&geom, &nuis, false);
    let data_cost = data.iter().map(|v| v * v).sum();
    Solved {
        geom,
        nuis,
        jac,
        data_cost,
        evaluations: r.evaluations,
    }
}

/// The residuals a fit of the joint problem minimises at `x` (the geometry then the
/// nuisance when `fit_geom`, else the nuisance at `geom0`), through Huber's loss when
/// robust.
fn objective_at(p: &Problem, fit_geom: bool, geom0: &[f64], x: &[f64]) -> Vec<f64> {
    let g = p.specs.len();
    let m = p.data_len();
    let mut r = if fit_geom {
        p.residuals(&x[..g], &x[g..], true)
    } else {
        p.residuals(geom0, x, false)
    };
    if let Some(c) = p.huber {
        r[..m].iter_mut().for_each(|v| *v = huber(*v, c));
    }
    r
}

/// Forward differences of [`objective_at`] with `fit::forward_differences`'s steps, their
/// columns dealt over `threads` threads, each with its own copy of the problem: the same
/// Jacobian, bit for bit, from one long recording in about 1 / threads of the time.
struct SplitDifferences<'a, 'b> {
    p: &'b Problem<'a>,
    geom0: &'b [f64],
    hi: &'b [f64],
    threads: usize,
    /// Parameters (columns).
    cols: usize,
}

impl fitkit::fit::Jacobian for SplitDifferences<'_, '_> {
    fn at(&mut self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
        let (m, n) = (r.len(), x.len());
        if jac.nrows() != m || jac.ncols() != n {
            *jac = DMatrix::zeros(m, n);
        }
        let twins: Vec<Problem> = (0..self.threads).map(|_| self.p.twin()).collect();
        let columns: Vec<(usize, &mut [f64])> = jac
            .as_mut_slice()
            .chunks_mut(m.max(1))
            .enumerate()
            .collect();
        let (geom0, hi) = (self.geom0, self.hi);
        deal(twins, columns, |q, (j, col)| {
            let h = fitkit::fit::difference_step(x[j], hi[j]);
            let mut xp = x.to_vec();
            xp[j] += h;
            let rp = objective_at(q, true, geom0, &xp);
            for (i, c) in col.iter_mut().enumerate() {
                *c = (rp.get(i).copied().unwrap_or(0.0) - r[i]) / h;
            }
        });
        true
    }
    fn runs(&self) -> usize {
        self.cols
    }
}

/// A dead-reckoning fit's normal equations at its solution (squared loss, the prior rows
/// included), from which the fit without some recordings is one Gauss-Newton step with
/// their rows taken out: cross-validation's folds and the model ladder's, at next to no
/// cost instead of a refit each (within 0.01 mm of refits on the real squares).
pub(super) struct OneStep<'s> {
    /// J^T J and J^T r over every recording, with the prior rows.
    h: DMatrix<f64>,
    grad: nalgebra::DVector<f64>,
    /// The data residuals at the solution.
    r: Vec<f64>,
    /// First data row of each recording (and the end).
    at: Vec<usize>,
    fitted: &'s Solved,
    lo: Vec<f64>,
    hi: Vec<f64>,
}

impl<'s> OneStep<'s> {
    /// The normal equations of `p` at its solution `fitted` (geometry only: dead
    /// reckoning fits nothing per recording).
    pub(super) fn new(p: &Problem, fitted: &'s Solved) -> OneStep<'s> {
        let g = p.specs.len();
        let r = p.residuals(&fitted.geom, &fitted.nuis, false);
        let jac = &fitted.jac;
        let mut h = jac.transpose() * jac;
        let mut grad = jac.transpose() * nalgebra::DVector::from_column_slice(&r);
        for (w, target, sigma) in &p.priors {
            let v: f64 = w.iter().zip(&fitted.geom).map(|(a, b)| a * b).sum();
            let pr = (v - target) / sigma * p.prior_scale;
            for a in 0..g {
                grad[a] += w[a] / sigma * p.prior_scale * pr;
                for b in 0..g {
                    h[(a, b)] += w[a] * w[b] / (sigma * sigma) * p.prior_scale * p.prior_scale;
                }
            }
        }
        let mut at = vec![0usize];
        for s in &p.series {
            at.push(at.last().copied().unwrap_or(0) + 3 * s.samples.len());
        }
        let (lo, hi) = if p.plausible_bounds {
            p.specs.iter().map(|s| s.plausible).unzip()
        } else {
            geom_bounds(p.specs)
        };
        OneStep {
            h,
            grad,
            r,
            at,
            fitted,
            lo,
            hi,
        }
    }

    /// The geometry fitted without the recordings `out` (indices into the problem's):
    /// one Gauss-Newton step from the solution, within the fit's bounds.
    pub(super) fn without(&self, out: impl IntoIterator<Item = usize>) -> Vec<f64> {
        let g = self.h.nrows();
        let (mut h, mut grad) = (self.h.clone(), self.grad.clone());
        for i in out {
            let (a, b) = (self.at[i], self.at[i + 1]);
            let ji = self.fitted.jac.rows(a, b - a);
            h -= ji.transpose() * ji;
            grad -= ji.transpose() * nalgebra::DVector::from_column_slice(&self.r[a..b]);
        }
        let step = h
            .lu()
            .solve(&(-grad))
            .unwrap_or_else(|| nalgebra::DVector::zeros(g));
        (0..g)
            .map(|a| (self.fitted.geom[a] + step[a]).clamp(self.lo[a], self.hi[a]))
            .collect()
    }
}

/// The recordings borrowed one by one.
pub(super) fn refs(series: &[Series]) -> Vec<&Series> {
    series.iter().collect()
}

/// Nuisance start: start pose at the first measured pose, clocks nominal (none when
/// dead-reckoning: nothing per recording is fitted).
pub(super) fn nuisance_start(series: &[&Series], free_start: bool) -> Vec<f64> {
    if !free_start {
        return vec![];
    }
    series
        .iter()
        .flat_map(|s| {
            // The path starts at row 0; the first pose sample may come later, but the
            // fit moves the start from there.
            [s.px[0], s.py[0], s.pth[0], 0.0, 1.0]
        })
        .collect()
}

/// Fit RMSE of `s` with the geometry fixed, only its start pose and clocks fitted.
pub(super) fn aligned_rmse(robot: &Robot, specs: &[ParamSpec], geom: &[f64], s: &Series) -> f64 {
    let mut p = Problem::new(robot, specs, [s]);
    // Only the residuals are read: the analytic Jacobian at the solution too.
    p.differences_at_solution = false;
    let r = solve(&p, geom, &nuisance_start(&[s], true), false);
    position_rmse(&p.residuals(geom, &r.nuis, false))
}

/// sqrt(residual variance x autocorrelation inflation), in residual units.
pub(super) fn noise_scale(p: &Problem, s: &Solved) -> f64 {
    let m = s.jac.nrows();
    let dof = m.saturating_sub(s.jac.ncols()).max(1) as f64;
    (s.data_cost / dof * autocorrelation_inflation(p, s)).sqrt()
}

/// A refit of [`reweighed`] is made when the noise scale at the solution differs from the
/// one the prior rows were weighed with by more than this share.
pub(super) const PRIOR_SCALE_TOL: f64 = 0.2;
/// Most refits [`reweighed`] makes.
const PRIOR_SCALE_ROUNDS: usize = 4;

/// `f` refitted until the prior rows are weighed by the noise scale at the solution they
/// give (within [`PRIOR_SCALE_TOL`], at most [`PRIOR_SCALE_ROUNDS`] refits), and the
/// model runs the refits took. A prior weighed by the residuals of a fit it held back
/// keeps itself as strong as it made them: on a simulated omni3 with radii 2 % apart,
/// wheels held alike with the scale of the first fit (25-28 against 2.5-2.7 at the
/// solution) held out 6.0 mm where per-wheel radii can reach 3.1 mm.
///
/// Only a problem with an informative prior (wheels held alike) is refitted. The weak
/// prior at nominal keeps the first fit's scale: where it matters, on directions the data
/// leave free, a lighter one lets them fit the simulator's contact details (a simulated
/// mecanum robot's twelve per-wheel parameters then beat its true roller model by a
/// likelihood ratio of 86 against the 24.5 allowed).
pub(super) fn reweighed(p: &mut Problem, mut f: Solved) -> (Solved, usize) {
    let mut runs = 0;
    if p.priors.len() == p.specs.len() {
        return (f, runs);
    }
    for _ in 0..PRIOR_SCALE_ROUNDS {
        let s = noise_scale(p, &f);
        if !(s.is_finite() && s > 0.0) || (s / p.prior_scale - 1.0).abs() <= PRIOR_SCALE_TOL {
            break;
        }
        p.prior_scale = s;
        let g = solve(p, &f.geom, &f.nuis, true);
        runs += g.evaluations;
        f = g;
    }
    (f, runs)
}

/// Lag-1 autocorrelation of the residual series (per component): an AR(1) series' mean
/// has (1 + rho) / (1 - rho) times the variance of independent samples.
fn autocorrelation_inflation(p: &Problem, s: &Solved) -> f64 {
    let m = s.jac.nrows();
    let r = p.residuals(&s.geom, &s.nuis, false);
    let comps: Vec<Vec<f64>> = (0..3)
        .map(|c| r.iter().skip(c).step_by(3).copied().collect())
        .collect();
    let rho = fitkit::noise::lag1_autocorrelation(comps.iter().map(|v| v.as_slice()), 0.999);
    fitkit::noise::ar1_inflation(rho)
        .min(m as f64 / 10.0)
        .max(1.0)
}

/// Covariance of [geometry, nuisance] from what the data tell (the plausibility prior
/// enters only as a ridge 1000 ranges wide, so a direction the data do not constrain
/// shows as one), scaled by the residual variance and the autocorrelation inflation
/// (returned).
pub(super) fn covariance(p: &Problem, s: &Solved) -> (DMatrix<f64>, f64) {
    covariance_with_priors(p, s, 1e-6)
}

/// [`covariance`] with the priors at the weight the fit gave them (the plausibility prior
/// and the wheels-alike prior, each one sigma against the residuals' variance): what the
/// fitted values' spread is, directions the data leave free resting on the priors.
pub(super) fn posterior_covariance(p: &Problem, s: &Solved) -> DMatrix<f64> {
    covariance_with_priors(p, s, 1.0).0
}

/// The covariance with the priors' information scaled by `weight`.
fn covariance_with_priors(p: &Problem, s: &Solved, weight: f64) -> (DMatrix<f64>, f64) {
    let m = s.jac.nrows();
    let np = s.jac.ncols();
    let g = p.specs.len();
    let mut info = s.jac.transpose() * &s.jac;
    let dof = m.saturating_sub(np).max(1) as f64;
    let s2 = (s.data_cost / dof).max(1e-12);
    let inflation = autocorrelation_inflation(p, s);
    for (w, _, sigma) in &p.priors {
        for a in 0..g {
            for b in 0..g {
                info[(a, b)] += w[a] * w[b] / (sigma * sigma) * weight * s2 * inflation;
            }
        }
    }
    let cov = info
        .clone()
        .try_inverse()
        .unwrap_or_else(|| DMatrix::from_element(np, np, f64::INFINITY));
    (cov * (s2 * inflation), inflation)
}

pub(super) fn correlations(cov: &DMatrix<f64>, g: usize) -> Vec<Vec<f64>> {
    (0..g)
        .map(|a| {
            (0..g)
                .map(|b| {
                    let d = (cov[(a, a)] * cov[(b, b)]).sqrt();
                    if a == b {
                        1.0
                    } else if d > 0.0 && d.is_finite() {
                        (cov[(a, b)] / d).clamp(-1.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{param_specs, robot_with};
    use crate::synth;
    use calib_core::odometry::Pose;

    /// A differential drive whose true scale, E_d and E_b are 1.02, 1.01 and 1.05,
    /// recorded noise-free (30 s at 50 Hz, wandering both ways; the poses dead-reckoned
    /// from the encoders with the true robot). The dead-reckoning objective from nominal,
    /// the prior off: the true geometry leaves only rounding (about 1e-13 m on a 9 m path),
    /// while 1e-8 of any parameter moves the path by some 1e-7 m, a million times more, and
    /// Levenberg-Marquardt on a problem that is zero at its optimum converges quadratically
    /// until rounding stops it. So 1e-8, still 1e4 below any geometry error that matters.
    #[test]
    fn solve_recovers_a_known_geometry_from_noise_free_dead_reckoning() {
        let nominal = synth::robot("mobolab");
        let specs = param_specs(&nominal, false);
        let truth = [1.02, 1.01, 1.05];
        let robot = robot_with(&nominal, &specs, &truth);
        let rec = synth::recording(
            &robot,
            1500,
            50.0,
            Pose::new(0.5, -0.3, 0.4),
            synth::wander(&robot),
        );
        let s = Series::new("synthetic", &nominal, &rec).unwrap();
        let mut p = Problem::new(&nominal, &specs, [&s]);
        p.free_start = false;
        p.prior_scale = 0.0;
        let start: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
        let nominal_rmse = position_rmse(&p.residuals(&start, &[], false));
        assert!(nominal_rmse > 0.05, "nominal is far off: {nominal_rmse} m");
        let f = solve(&p, &start, &nuisance_start(&[&s], false), true);
        for ((spec, got), want) in specs.iter().zip(&f.geom).zip(truth) {
            assert!((got - want).abs() < 1e-8, "{}: {got} for {want}", spec.name);
        }
        let rmse = position_rmse(&p.residuals(&f.geom, &f.nuis, false));
        assert!(rmse < 1e-9, "residual {rmse} m");
    }

    /// Correlation = covariance over the product of the standard deviations, 1 on the
    /// diagonal, 0 where a variance is infinite (a direction the data do not fix).
    #[test]
    fn correlations_of_a_known_covariance() {
        let cov = DMatrix::from_row_slice(
            3,
            3,
            &[4.0, 1.2, 0.0, 1.2, 9.0, 0.0, 0.0, 0.0, f64::INFINITY],
        );
        let c = correlations(&cov, 3);
        assert_eq!(c[0][0], 1.0);
        assert!((c[0][1] - 0.2).abs() < 1e-15 && (c[1][0] - 0.2).abs() < 1e-15);
        assert_eq!((c[0][2], c[2][1], c[2][2]), (0.0, 0.0, 1.0));
    }

    /// The free-start fit of one long recording takes its differences' columns on
    /// several threads, each with its own copy of the problem: the Jacobian must be
    /// serial forward differences' bit for bit (the same steps and the same evaluations;
    /// any other rounding would move every free-start result), with Huber's loss too.
    #[test]
    fn split_differences_are_forward_differences_bit_for_bit() {
        let nominal = synth::robot("mobolab");
        let specs = param_specs(&nominal, false);
        let robot = robot_with(&nominal, &specs, &[1.02, 1.01, 1.05]);
        // 25,000 rows: over the rows below which one thread does (PAR_MIN_ROWS).
        let rec = synth::recording(
            &robot,
            25_000,
            50.0,
            Pose::new(0.5, -0.3, 0.4),
            synth::wander(&robot),
        );
        let s = Series::new("synthetic", &nominal, &rec).unwrap();
        for huber in [None, Some(2.0)] {
            let mut p = Problem::new(&nominal, &specs, [&s]);
            p.huber = huber;
            let geom: Vec<f64> = vec![1.01, 1.005, 1.02];
            let x: Vec<f64> = [geom.clone(), nuisance_start(&[&s], true)].concat();
            let hi = vec![f64::INFINITY; x.len()];
            let r = objective_at(&p, true, &geom, &x);
            let mut serial = DMatrix::zeros(0, 0);
            fitkit::fit::forward_differences(
                &mut |x: &[f64]| objective_at(&p, true, &geom, x),
                &x,
                &r,
                &hi,
                &mut serial,
            );
            let mut split = DMatrix::zeros(0, 0);
            let mut j = SplitDifferences {
                p: &p,
                geom0: &geom,
                hi: &hi,
                threads: 2,
                cols: x.len(),
            };
            assert!(fitkit::fit::Jacobian::at(&mut j, &x, &r, &mut split));
            assert_eq!(serial.shape(), split.shape());
            assert!(serial.iter().any(|v| *v != 0.0));
            assert!(
                serial
                    .iter()
                    .zip(split.iter())
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "huber {huber:?}: the split columns differ"
            );
        }
    }
}
