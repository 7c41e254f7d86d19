//! The joint problem ([`Problem`]): the geometry shared by the recordings, a start pose
//! and clocks per recording, a weak prior at nominal (and alike wheels held alike). It
//! evaluates the [`objective`](crate::objective)'s residuals over all the
//! recordings (in parallel), keeps the paths of the last geometry, and gives the analytic
//! Jacobians: the geometry's from the paths' sensitivities ([`sens`]) when
//! dead-reckoning; those and the nuisance's when aligning.

use crate::objective::{
    dr_residuals_into, huber_rows, nuisance_jacobian_into, residuals_into, PathAt,
    DR_HEADING_LEVER_M,
};
use crate::params::{alike_priors, robot_with, GeomKind, ParamSpec};
use crate::pool::{par_jobs, threads_for};
use crate::sens::{self, ColumnSlab};
use crate::series::{Nuisance, Path, Series, NUIS};
use crate::step::Stepper;
use crate::turn_law::TurnLaw;
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::robot::{Robot, RobotKind};
use nalgebra::DMatrix;
use std::cell::RefCell;

/// The joint problem: geometry shared, nuisance per recording.
pub(super) struct Problem<'a> {
    robot: &'a Robot,
    pub(super) specs: &'a [ParamSpec],
    /// The recordings, borrowed (a fold's problem holds some of them).
    pub(super) series: Vec<&'a Series>,
    /// Prior rows: (weights over the geometry parameters, target, sigma).
    pub(super) priors: Vec<(Vec<f64>, f64, f64)>,
    /// Prior rows are multiplied by this: sqrt(residual variance x autocorrelation
    /// inflation) once known, so the prior weighs against what the data really tell.
    pub(super) prior_scale: f64,
    cache: RefCell<(Vec<f64>, Vec<Path>)>,
    /// The geometry and its paths at the dead-reckoning rows with their sensitivities
    /// ([`Problem::sensitivities`]).
    sens: RefCell<(Vec<f64>, Vec<sens::Sensitivity>)>,
    /// Residuals are evaluated with the sensitivities (dead reckoning only): set while a
    /// fit with the analytic Jacobian runs, whose next Jacobian is most likely at the point
    /// just evaluated (one pass over the rows then serves both).
    pub(super) speculate: std::cell::Cell<bool>,
    /// Bound the geometry to the plausible ranges (else 10 times wider).
    pub(super) plausible_bounds: bool,
    /// Fit each recording's start pose and clocks (else dead-reckon from the anchors).
    pub(super) free_start: bool,
    /// Huber scale of the data residuals (residual units), when the loss is robust.
    pub(super) huber: Option<f64>,
    /// Lever arm of the dead-reckoning heading residuals, m.
    pub(super) dr_lever: f64,
    /// Known laws, for the terms the specs do not fit (zero: none).
    pub(super) known_law: TurnLaw,
    /// The Jacobian of a fit's solution (its covariance, the cross-validation's steps)
    /// by forward differences, as the iterations' used to be; else the analytic one.
    pub(super) differences_at_solution: bool,
}

impl<'a> Problem<'a> {
    /// Where motion capture tracks on the body in `geom` ((0, 0) when not fitted).
    fn marker(&self, geom: &[f64]) -> (f64, f64) {
        let get = |k: GeomKind| {
            self.specs
                .iter()
                .position(|s| s.kind == k)
                .map_or(0.0, |i| geom[i])
        };
        (get(GeomKind::MarkerX), get(GeomKind::MarkerY))
    }

    pub(super) fn new(
        robot: &'a Robot,
        specs: &'a [ParamSpec],
        series: impl IntoIterator<Item = &'a Series>,
    ) -> Self {
        let series: Vec<&'a Series> = series.into_iter().collect();
        let n = series.len();
        // A weak prior at nominal (one plausible half-range) keeps directions the data
        // do not constrain where they are; it is negligible against thousands of
        // millimetre residuals wherever the data speak.
        let g = specs.len();
        let mut priors: Vec<(Vec<f64>, f64, f64)> = specs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let mut w = vec![0.0; g];
                w[i] = 1.0;
                (w, s.nominal, s.plausible.1 - s.nominal)
            })
            .collect();
        // Alike wheels held to their mean (the ladder's per-wheel rungs).
        priors.extend(alike_priors(specs));
        Problem {
            robot,
            specs,
            series,
            priors,
            prior_scale: 1.0,
            plausible_bounds: false,
            free_start: true,
            huber: None,
            dr_lever: DR_HEADING_LEVER_M,
            known_law: TurnLaw::default(),
            differences_at_solution: true,
            cache: RefCell::new((vec![f64::NAN], vec![Path::default(); n])),
            sens: RefCell::new((vec![f64::NAN], Vec::new())),
            speculate: std::cell::Cell::new(false),
        }
    }

    /// The same problem (recordings, priors, settings) with empty caches: a copy for
    /// another thread, whose evaluations equal this one's bit for bit.
    pub(super) fn twin(&self) -> Problem<'a> {
        let mut q = Problem::new(self.robot, self.specs, self.series.iter().copied());
        q.priors = self.priors.clone();
        q.prior_scale = self.prior_scale;
        q.plausible_bounds = self.plausible_bounds;
        q.free_start = self.free_start;
        q.huber = self.huber;
        q.dr_lever = self.dr_lever;
        q.known_law = self.known_law;
        q.differences_at_solution = self.differences_at_solution;
        q
    }

    fn paths(&self, geom: &[f64]) -> bool {
        let mut c = self.cache.borrow_mut();
        if c.0.as_slice() == geom {
            return true;
        }
        let r = robot_with(self.robot, self.specs, geom);
        let law = TurnLaw::of(self.specs, geom, self.known_law);
        let Ok(kin) = Kinematics::<f64>::new(&r, &Corrections::None) else {
            c.0 = vec![f64::NAN];
            return false;
        };
        let stepper = Stepper::new(&r, &kin, &law);
        let mut jobs: Vec<(&Series, &mut Path)> =
            self.series.iter().copied().zip(c.1.iter_mut()).collect();
        let ok = par_each(&mut jobs, |(s, p)| s.path_by(&r, &stepper, p));
        if ok.iter().all(|v| *v) {
            c.0 = geom.to_vec();
            true
        } else {
            c.0 = vec![f64::NAN];
            false
        }
    }

    /// The analytic Jacobian of [`Problem::residuals`] with the prior rows (dead
    /// reckoning only) at `geom`, the data rows through Huber's loss when robust (`r`:
    /// the residuals at `geom` as the fit sees them). False when it has none (fitted start
    /// poses, a wheeled-legged robot, a singular geometry).
    pub(super) fn jacobian(&self, geom: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
        if !self.sensitivities(geom) {
            return false;
        }
        let g = self.specs.len();
        let m = self.data_len();
        let cached = self.sens.borrow();
        let cols = sens::split_params(self.specs);
        if jac.nrows() != m + self.priors.len() || jac.ncols() != g {
            *jac = DMatrix::zeros(m + self.priors.len(), g);
        }
        jac.fill(0.0);
        let marker = self.marker(geom);
        let mut row = 0;
        for (s, sens) in self.series.iter().zip(&cached.1) {
            s.dr_jacobian(sens, &cols, marker, self.dr_lever, jac, row);
            row += 3 * s.samples.len();
        }
        if let Some(c) = self.huber {
            huber_rows(jac, &r[..m], c, g);
        }
        for (i, (w, _, sigma)) in self.priors.iter().enumerate() {
            for a in 0..g {
                jac[(m + i, a)] = w[a] / sigma * self.prior_scale;
            }
        }
        true
    }

    /// The paths at the dead-reckoning rows and their sensitivities at `geom` into
    /// [`Problem::sens`] (kept while `geom` stays). False when there are none (fitted
    /// start poses, a wheeled-legged robot, a singular geometry).
    fn sensitivities(&self, geom: &[f64]) -> bool {
        if self.free_start {
            return false;
        }
        if self.sens.borrow().0.as_slice() == geom {
            return true;
        }
        let Some((stepper, slopes, _)) = self.stepping(geom) else {
            return false;
        };
        let mut jobs: Vec<(&Series, Option<sens::Sensitivity>)> =
            self.series.iter().map(|s| (*s, None)).collect();
        par_each(&mut jobs, |(s, out)| {
            *out = s.sensitivity(&stepper, &slopes, s.dr_rows());
        });
        let Some(all) = jobs.into_iter().map(|j| j.1).collect::<Option<Vec<_>>>() else {
            return false;
        };
        *self.sens.borrow_mut() = (geom.to_vec(), all);
        true
    }

    /// The stepping at `geom`, the twist's slopes of its path parameters and the
    /// Jacobian's columns. None when the geometry is singular nearby.
    fn stepping(&self, geom: &[f64]) -> Option<(Stepper, sens::TwistSlopes, sens::Columns)> {
        let robot = robot_with(self.robot, self.specs, geom);
        let law = TurnLaw::of(self.specs, geom, self.known_law);
        let kin = Kinematics::<f64>::new(&robot, &Corrections::None).ok()?;
        let stepper = Stepper::new(&robot, &kin, &law);
        let cols = sens::split_params(self.specs);
        let per_row = self.robot.kind == RobotKind::SkidSteer
            || self.known_law.has_terms()
            || self.specs.iter().any(|s| {
                matches!(
                    s.kind,
                    GeomKind::EbArc | GeomKind::IcrX | GeomKind::SpeedRel | GeomKind::AccelSlip
                )
            });
        let slopes = sens::TwistSlopes::new(
            self.robot,
            self.specs,
            geom,
            self.known_law,
            &cols.path,
            per_row,
        )?;
        Some((stepper, slopes, cols))
    }

    /// The analytic Jacobian of [`Problem::residuals`] with the prior rows when the start
    /// poses and clocks are fitted, at `x` = [geometry, every recording's nuisance]: the
    /// geometry's columns from the sensitivities stepped along each path (one pass per
    /// recording instead of one model run per parameter), the nuisance's as
    /// [`Problem::nuisance_jacobian`]; the data rows through Huber's loss when robust
    /// (`r`: the residuals at `x` as the fit sees them). False when it has none (start
    /// poses not fitted, a wheeled-legged robot, a singular geometry).
    pub(super) fn free_jacobian(&self, x: &[f64], r: &[f64], jac: &mut DMatrix<f64>) -> bool {
        self.free_jacobian_on(x, r, jac, None)
    }

    /// [`Problem::free_jacobian`] with each recording's parameter columns split over
    /// `threads` (1 or 2) threads, or as many as its rows are worth ([`threads_for`])
    /// when `None`: the same numbers, to the bit (each parameter's sensitivity is stepped
    /// on its own; both threads step the path itself).
    pub(super) fn free_jacobian_on(
        &self,
        x: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
        threads: Option<usize>,
    ) -> bool {
        let g = self.specs.len();
        if !self.free_start || x.len() != g + NUIS * self.series.len() {
            return false;
        }
        let (geom, nuis) = x.split_at(g);
        if !self.paths(geom) {
            return false;
        }
        let Some((stepper, slopes, cols)) = self.stepping(geom) else {
            return false;
        };
        let m = self.data_len();
        if jac.nrows() != m + self.priors.len() || jac.ncols() != x.len() {
            *jac = DMatrix::zeros(m + self.priors.len(), x.len());
        }
        jac.fill(0.0);
        let marker = self.marker(geom);
        let c = self.cache.borrow();
        let mut row = 0;
        let p = cols.path.len();
        let nrows = jac.nrows();
        for (i, s) in self.series.iter().enumerate() {
            let nu = Nuisance::from(&nuis[i * NUIS..(i + 1) * NUIS]);
            let walk = |part: std::ops::Range<usize>, out: &mut ColumnSlab| {
                s.free_jacobian(&stepper, &slopes, &cols, &nu, marker, part, out, row)
            };
            let threads = threads.unwrap_or_else(|| threads_for(s.t.len(), 2));
            let ok = if threads > 1 && p >= 2 {
                // The columns before the second half's first to this thread, the rest to
                // the other; each writes the marker's columns its slab holds (the
                // nuisance's are written below, on this thread).
                let half = p / 2;
                let (left, right) = jac.as_mut_slice().split_at_mut(cols.path[half] * nrows);
                let mut a = ColumnSlab::new(left, nrows, 0);
                let mut b = ColumnSlab::new(right, nrows, cols.path[half]);
                std::thread::scope(|sc| {
                    let other = sc.spawn(|| walk(half..p, &mut b));
                    let mine = walk(0..half, &mut a);
                    let theirs = other
                        .join()
                        .unwrap_or_else(|e| std::panic::resume_unwind(e));
                    mine && theirs
                })
            } else {
                walk(0..p, &mut ColumnSlab::new(jac.as_mut_slice(), nrows, 0))
            };
            if !ok {
                return false;
            }
            nuisance_jacobian_into(s, &c.1[i], &nu, marker, jac, row, g + i * NUIS);
            row += 3 * s.pose_samples();
        }
        if let Some(h) = self.huber {
            huber_rows(jac, &r[..m], h, x.len());
        }
        for (i, (w, _, sigma)) in self.priors.iter().enumerate() {
            for a in 0..g {
                jac[(m + i, a)] = w[a] / sigma * self.prior_scale;
            }
        }
        true
    }

    /// The analytic Jacobian of the data residuals with respect to every recording's
    /// nuisance at the geometry `geom` (fixed), through Huber's loss when robust (`r`:
    /// the residuals as the fit sees them). False when the start poses are not fitted or
    /// the geometry is singular.
    pub(super) fn nuisance_jacobian(
        &self,
        geom: &[f64],
        nuis: &[f64],
        r: &[f64],
        jac: &mut DMatrix<f64>,
    ) -> bool {
        if !self.free_start || !self.paths(geom) {
            return false;
        }
        let m = self.data_len();
        let np = nuis.len();
        if jac.nrows() != m || jac.ncols() != np {
            *jac = DMatrix::zeros(m, np);
        }
        jac.fill(0.0);
        let c = self.cache.borrow();
        let marker = self.marker(geom);
        let mut row = 0;
        for (i, s) in self.series.iter().enumerate() {
            let nu = Nuisance::from(&nuis[i * NUIS..(i + 1) * NUIS]);
            nuisance_jacobian_into(s, &c.1[i], &nu, marker, jac, row, i * NUIS);
            row += 3 * s.pose_samples();
        }
        if let Some(h) = self.huber {
            huber_rows(jac, &r[..m], h, np);
        }
        true
    }

    /// Data residuals of every recording, then prior rows.
    pub(super) fn residuals(&self, geom: &[f64], nuis: &[f64], with_prior: bool) -> Vec<f64> {
        let mut out = Vec::new();
        let cached = !self.free_start && self.sens.borrow().0.as_slice() == geom;
        if cached || (self.speculate.get() && self.sensitivities(geom)) {
            // The paths at the dead-reckoning rows, as the sensitivities carry them.
            let c = self.sens.borrow();
            self.dr_residuals_all(c.1.iter().collect(), self.marker(geom), &mut out);
            if with_prior {
                self.prior_rows(geom, &mut out);
            }
            return out;
        }
        if !self.paths(geom) {
            let m = self.data_len();
            return vec![1e12; m + if with_prior { self.priors.len() } else { 0 }];
        }
        let c = self.cache.borrow();
        let marker = self.marker(geom);
        if self.free_start {
            for (i, s) in self.series.iter().enumerate() {
                let nu = Nuisance::from(&nuis[i * NUIS..(i + 1) * NUIS]);
                residuals_into(s, &c.1[i], &nu, marker, &mut out);
            }
        } else {
            self.dr_residuals_all(c.1.iter().collect(), marker, &mut out);
        }
        if with_prior {
            self.prior_rows(geom, &mut out);
        }
        out
    }

    /// The dead-reckoning residuals of every recording along `paths` (one per series):
    /// each recording's on its own (in parallel), then in order onto `out`.
    fn dr_residuals_all<P: Copy + PathAt + Send>(
        &self,
        paths: Vec<P>,
        marker: (f64, f64),
        out: &mut Vec<f64>,
    ) {
        let lever = self.dr_lever;
        let mut jobs: Vec<(&Series, P)> = self.series.iter().copied().zip(paths).collect();
        let parts = par_jobs(
            &mut jobs,
            |j| 20 * j.0.samples.len(),
            |(s, path)| {
                let mut v = Vec::with_capacity(3 * s.samples.len());
                dr_residuals_into(s, *path, marker, lever, &mut v);
                v
            },
        );
        out.reserve(parts.iter().map(|v| v.len()).sum());
        for v in parts {
            out.extend_from_slice(&v);
        }
    }

    /// The prior rows at `geom` onto `out`.
    fn prior_rows(&self, geom: &[f64], out: &mut Vec<f64>) {
        for (w, target, sigma) in &self.priors {
            let v: f64 = w.iter().zip(geom).map(|(a, b)| a * b).sum();
            out.push((v - target) / sigma * self.prior_scale);
        }
    }

    pub(super) fn data_len(&self) -> usize {
        self.series
            .iter()
            .map(|s| {
                3 * if self.free_start {
                    s.pose_samples()
                } else {
                    s.samples.len()
                }
            })
            .sum()
    }
}

/// Runs `f` on every job (a recording and its output), on up to
/// `available_parallelism` threads when the recordings are long enough to pay for them;
/// each job's result is the same as run alone. The jobs are split in contiguous runs of
/// about equal rows.
fn par_each<'s, J: Send, R: Send>(
    jobs: &mut [(&'s Series, J)],
    f: impl Fn(&mut (&'s Series, J)) -> R + Sync,
) -> Vec<R> {
    par_jobs(jobs, |j| j.0.t.len(), f)
}
