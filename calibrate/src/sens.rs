//! The paths' sensitivities to the geometry: d(x, y, theta)/d(parameter) carried along the
//! integration with the path itself (forward mode), so a Jacobian of the dead-reckoning
//! residuals costs one pass over the rows instead of one model run per parameter.
//!
//! The twist's derivatives are central differences of the per-geometry stepping (linear in
//! the increments for a kinematics matrix, so one matrix of slopes per parameter; per row
//! for a robot stepped by its sides); the arc integration and the residuals are
//! differentiated exactly.

use crate::objective::{pose_segments, PathAt, HEADING_LEVER_M, RES_UNIT_M};
use crate::params::{robot_with, GeomKind, ParamSpec};
use crate::series::{Nuisance, Series};
use crate::step::{self, Stepper};
use crate::turn_law::{SideMotion, Sides, TurnLaw};
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::{Robot, RobotKind};
use std::ops::Range;

/// d/dd of [`arc_coefficients`](calib_core::odometry::arc_coefficients): (d(sin d / d), d((1 - cos d) / d)).
#[inline]
fn arc_slopes(d: f64) -> (f64, f64) {
    if d.abs() < 0.1 {
        // Taylor series of the derivatives; first omitted terms below 1e-13.
        let d2 = d * d;
        let s = -d * (1.0 / 3.0 - d2 * (1.0 / 30.0 - d2 * (1.0 / 840.0 - d2 / 45360.0)));
        let c = 0.5 - d2 * (1.0 / 8.0 - d2 * (1.0 / 144.0 - d2 * (1.0 / 5760.0 - d2 / 403200.0)));
        (s, c)
    } else {
        let (sn, cs) = d.sin_cos();
        ((cs - sn / d) / d, (sn - (1.0 - cs) / d) / d)
    }
}

/// Parameters from which [`Series::sensitivity`] of a kinematics matrix sums the rows
/// between kept rows once for all parameters rather than stepping each parameter row by
/// row (the sums cost about four parameters' steps).
const SUMMED_MIN_PARAMS: usize = 4;

/// How the twist of one row moves with each path parameter.
pub(crate) enum TwistSlopes {
    /// d twist / d q_j = slopes[j] * increments (a kinematics matrix).
    Linear(Vec<Vec<[f64; 3]>>),
    /// Central differences of a robot stepped by its sides, per parameter.
    Sides(Vec<SideSlope>),
    /// Central differences of an omni robot with a turn law (its twist divided at each
    /// row's turn ratio), per parameter: the steppers at q + h and q - h, and 1 / 2h.
    Omni(Vec<(Stepper, Stepper, f64)>),
}

/// A robot's sides and turn law at one geometry.
type SidesAt = (Sides, TurnLaw);

/// The sides at q + h and q - h, and 1 / 2h.
pub(crate) struct SideSlope {
    plus: SidesAt,
    minus: SidesAt,
    k: f64,
}

/// Relative step of the central differences (of the per-geometry stepping, which is
/// linear or rational in the parameters: truncation error ~1e-10 relative).
const STEP: f64 = 1e-5;

impl TwistSlopes {
    /// The slopes of the parameters `path_params` (indices into `specs`) at `geom`; when
    /// `per_row` (a law, or a skid-steer robot), stepped row by row: by its sides, or an
    /// omni robot's twist with its turn law. None when the geometry is singular nearby.
    pub(crate) fn new(
        robot: &Robot,
        specs: &[ParamSpec],
        geom: &[f64],
        known_law: TurnLaw,
        path_params: &[usize],
        per_row: bool,
    ) -> Option<TwistSlopes> {
        let at = |j: usize, h: f64| -> Option<Stepper> {
            let mut q = geom.to_vec();
            q[j] += h;
            let r = robot_with(robot, specs, &q);
            let kin = Kinematics::<f64>::new(&r, &Corrections::None).ok()?;
            Some(Stepper::new(&r, &kin, &TurnLaw::of(specs, &q, known_law)))
        };
        let step = |j: usize| STEP * geom[j].abs().max(1e-2);
        if per_row && robot.kind == RobotKind::Omni {
            let mut v = Vec::new();
            for &j in path_params {
                let h = step(j);
                v.push((at(j, h)?, at(j, -h)?, 0.5 / h));
            }
            return Some(TwistSlopes::Omni(v));
        }
        if per_row {
            let mut v = Vec::new();
            for &j in path_params {
                let h = step(j);
                let (p, m) = (at(j, h)?, at(j, -h)?);
                let sides_of = |s: &Stepper, q: f64| -> SidesAt {
                    let mut g = geom.to_vec();
                    g[j] += q;
                    let r = robot_with(robot, specs, &g);
                    s.sides()
                        .cloned()
                        .unwrap_or_else(|| (Sides::new(&r), TurnLaw::of(specs, &g, known_law)))
                };
                v.push(SideSlope {
                    plus: sides_of(&p, h),
                    minus: sides_of(&m, -h),
                    k: 0.5 / h,
                });
            }
            return Some(TwistSlopes::Sides(v));
        }
        let mut v = Vec::new();
        for &j in path_params {
            let h = step(j);
            let (p, m) = (at(j, h)?, at(j, -h)?);
            v.push(
                p.columns()
                    .iter()
                    .zip(m.columns())
                    .map(|(a, b)| {
                        [
                            (a[0] - b[0]) * 0.5 / h,
                            (a[1] - b[1]) * 0.5 / h,
                            (a[2] - b[2]) * 0.5 / h,
                        ]
                    })
                    .collect(),
            );
        }
        Some(TwistSlopes::Linear(v))
    }

    fn count(&self) -> usize {
        match self {
            TwistSlopes::Linear(v) => v.len(),
            TwistSlopes::Sides(v) => v.len(),
            TwistSlopes::Omni(v) => v.len(),
        }
    }

    /// The twist derivatives of one row into `out` (one per parameter of `params`).
    #[inline]
    fn row(
        &self,
        params: Range<usize>,
        inc: &[f64],
        rho: f64,
        side: SideMotion,
        out: &mut [[f64; 3]],
    ) {
        match self {
            TwistSlopes::Linear(v) => {
                for (o, cols) in out.iter_mut().zip(&v[params]) {
                    let mut t = [0.0; 3];
                    for (c, w) in cols.iter().zip(inc) {
                        t[0] += c[0] * w;
                        t[1] += c[1] * w;
                        t[2] += c[2] * w;
                    }
                    *o = t;
                }
            }
            TwistSlopes::Omni(v) => {
                for (o, (plus, minus, k)) in out.iter_mut().zip(&v[params]) {
                    let (a, b) = (plus.forward_at(inc, rho), minus.forward_at(inc, rho));
                    *o = [
                        (a.vx - b.vx) * k,
                        (a.vy - b.vy) * k,
                        (a.omega - b.omega) * k,
                    ];
                }
            }
            TwistSlopes::Sides(v) => {
                for (o, d) in out.iter_mut().zip(&v[params]) {
                    let (a, b) = (
                        d.plus.0.step(&d.plus.1, rho, side, inc),
                        d.minus.0.step(&d.minus.1, rho, side, inc),
                    );
                    let k = d.k;
                    *o = [
                        (a.vx - b.vx) * k,
                        (a.vy - b.vy) * k,
                        (a.omega - b.omega) * k,
                    ];
                }
            }
        }
    }
}

/// A recording's path and its sensitivities at the path rows `need` (sorted, distinct):
/// values[i] = (x, y, theta) at need[i], slopes[i * p + j] = d(x, y, theta)/d q_j.
pub(crate) struct Sensitivity {
    pub(crate) need: Vec<usize>,
    pub(crate) values: Vec<[f64; 3]>,
    pub(crate) slopes: Vec<[f64; 3]>,
}

impl PathAt for &Sensitivity {
    /// At a kept row only.
    #[inline]
    fn at(&self, k: usize) -> [f64; 3] {
        self.values[self.need.binary_search(&k).expect("row kept")]
    }
}

impl Series {
    /// The path rows the dead-reckoning residuals read: each compared sample's and each
    /// anchor's.
    pub(crate) fn dr_rows(&self) -> Vec<usize> {
        let mut v: Vec<usize> = self
            .samples
            .iter()
            .copied()
            .chain(self.anchors.iter().map(|a| a.sample))
            .map(|j| self.pose_row[j])
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    }

    /// The path of `stepper` (as [`Series::path_by`], to the bit) and its sensitivities
    /// to the parameters of `slopes`, kept at the rows `need`. None for a wheeled-legged
    /// robot (its kinematics follow the legs: not handled here).
    pub(crate) fn sensitivity(
        &self,
        stepper: &Stepper,
        slopes: &TwistSlopes,
        need: Vec<usize>,
    ) -> Option<Sensitivity> {
        if self.legs.is_some() {
            return None;
        }
        if let TwistSlopes::Linear(v) = slopes {
            let sides =
                self.rho.is_some() && (stepper.sides().is_some() || stepper.omni_arc() != 0.0);
            if !sides && v.len() >= SUMMED_MIN_PARAMS {
                return Some(self.sensitivity_summed(stepper, v, need));
            }
        }
        Some(self.sensitivity_stepped(stepper, slopes, need))
    }

    /// [`Series::sensitivity`] stepping every parameter's sensitivities row by row.
    fn sensitivity_stepped(
        &self,
        stepper: &Stepper,
        slopes: &TwistSlopes,
        need: Vec<usize>,
    ) -> Sensitivity {
        let p = slopes.count();
        let mut values = Vec::with_capacity(need.len());
        let mut out = Vec::with_capacity(need.len() * p);
        let mut next = 0usize;
        self.walk_sensitivities(stepper, slopes, 0..p, |k, v, d| {
            if need.get(next) == Some(&k) {
                values.push(v);
                out.extend_from_slice(d);
                next += 1;
            }
        });
        Sensitivity {
            need,
            values,
            slopes: out,
        }
    }

    /// Steps the path of `stepper` (as [`Series::path_by`], to the bit) with its
    /// sensitivities to the parameters `params` of `slopes`, row by row: `visit` gets
    /// each row's index, (x, y, theta) and d(x, y, theta)/d q_j, from row 0 (the origin,
    /// no sensitivity) on.
    fn walk_sensitivities(
        &self,
        stepper: &Stepper,
        slopes: &TwistSlopes,
        params: Range<usize>,
        mut visit: impl FnMut(usize, [f64; 3], &[[f64; 3]]),
    ) {
        let p = params.len();
        let sides = match (&self.rho, stepper.sides()) {
            (Some(rho), Some(s)) => Some((rho, s)),
            _ => None,
        };
        let rows = self.inc.len() / self.wheels.max(1);
        let no_rho = vec![0.0; rows];
        let rho = self.rho.as_deref().unwrap_or(&no_rho);
        let no_motion = vec![SideMotion::default(); rows];
        let motion = self.motion.as_deref().unwrap_or(&no_motion);
        let mut d = vec![[0.0f64; 3]; p];
        let mut dt = vec![[0.0f64; 3]; p];
        let (mut x, mut y, mut h) = (0.0f64, 0.0f64, step::Heading::new());
        visit(0, [x, y, h.th], &d);
        for (k, ((inc, &r), &v)) in self.incs().zip(rho).zip(motion).enumerate() {
            let tw: Twist<f64> = match sides {
                Some((_, (s, law))) => s.step(law, r, v, inc),
                None => stepper.forward_at(inc, r),
            };
            slopes.row(params.clone(), inc, r, v, &mut dt);
            // The arc step (as the path's), with the quantities its derivative needs.
            let (st, ct) = (h.sin, h.cos);
            let (s, c, lx, ly) = step::arc_step(&mut x, &mut y, &mut h, &tw);
            let (ds, dc) = arc_slopes(tw.omega);
            let (ex, ey) = (ct * lx - st * ly, st * lx + ct * ly);
            for (dj, t) in d.iter_mut().zip(&dt) {
                let dlx = (ds * tw.vx - dc * tw.vy) * t[2] + s * t[0] - c * t[1];
                let dly = (dc * tw.vx + ds * tw.vy) * t[2] + c * t[0] + s * t[1];
                dj[0] += -ey * dj[2] + ct * dlx - st * dly;
                dj[1] += ex * dj[2] + st * dlx + ct * dly;
                dj[2] += t[2];
            }
            visit(k + 1, [x, y, h.th], &d);
        }
    }

    /// The Jacobian rows of [`residuals_into`](crate::objective::residuals_into)
    /// (the aligned residuals: start pose and clocks `nu`) with respect to the path
    /// parameters `part` of `cols` (sensitivities stepped along with the path, one pass)
    /// and the marker's that `jac` holds, into `jac`'s rows from `row0`; columns are
    /// parameter indices. The path is read linearly between rows at each pose sample's
    /// time on the encoders' clock, so its sensitivities are too. False for a
    /// wheeled-legged robot (its kinematics follow the legs: not handled here).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn free_jacobian(
        &self,
        stepper: &Stepper,
        slopes: &TwistSlopes,
        cols: &Columns,
        nu: &Nuisance,
        marker: (f64, f64),
        part: Range<usize>,
        jac: &mut ColumnSlab,
        row0: usize,
    ) -> bool {
        if self.legs.is_some() {
            return false;
        }
        let path_params = &cols.path[part.clone()];
        let marker_params = (
            cols.marker.0.filter(|c| jac.holds(*c)),
            cols.marker.1.filter(|c| jac.holds(*c)),
        );
        let p = path_params.len();
        let n = self.t.len();
        let u = 1.0 / RES_UNIT_M;
        let lever = HEADING_LEVER_M * u;
        let (c, sn) = (nu.theta0_rad.cos(), nu.theta0_rad.sin());
        // Each pose sample with the row at which its path point is known (its segment's
        // end; the first or last row outside the rows' span) and the weight of that row
        // (1 - f of the row before). Samples come in order of time, so of rows.
        let mut samples = pose_segments(self, nu)
            .map(|(j, _, tau, k)| {
                if n < 2 || tau <= self.t[0] {
                    (j, 0, 1.0)
                } else if tau >= self.t[n - 1] {
                    (j, n - 1, 1.0)
                } else {
                    (j, k + 1, (tau - self.t[k]) / (self.t[k + 1] - self.t[k]))
                }
            })
            .peekable();
        // The row before the visited one: its values and sensitivities.
        let (mut prev_v, mut prev_d) = ([0.0f64; 3], vec![[0.0f64; 3]; p]);
        let mut dq = vec![[0.0f64; 3]; p];
        self.walk_sensitivities(stepper, slopes, part, |k, v, d| {
            while let Some(&(j, _, f)) = samples.peek().filter(|s| s.1 == k) {
                samples.next();
                let th = prev_v[2] + (v[2] - prev_v[2]) * f;
                for (o, (a, b)) in dq.iter_mut().zip(prev_d.iter().zip(d)) {
                    *o = [
                        a[0] + (b[0] - a[0]) * f,
                        a[1] + (b[1] - a[1]) * f,
                        a[2] + (b[2] - a[2]) * f,
                    ];
                }
                // d(wx, wy)/d theta of the marker's offset (zero without one).
                let (sm, cm) = (nu.theta0_rad + th).sin_cos();
                let (mx, my) = if marker != (0.0, 0.0) {
                    (
                        -sm * marker.0 - cm * marker.1,
                        cm * marker.0 - sm * marker.1,
                    )
                } else {
                    (0.0, 0.0)
                };
                let row = row0 + 3 * j;
                for (t, &col) in dq.iter().zip(path_params) {
                    jac.set(row, col, (c * t[0] - sn * t[1] + mx * t[2]) * u);
                    jac.set(row + 1, col, (sn * t[0] + c * t[1] + my * t[2]) * u);
                    jac.set(row + 2, col, t[2] * lever);
                }
                if let Some(col) = marker_params.0 {
                    jac.set(row, col, cm * u);
                    jac.set(row + 1, col, sm * u);
                    jac.set(row + 2, col, 0.0);
                }
                if let Some(col) = marker_params.1 {
                    jac.set(row, col, -sm * u);
                    jac.set(row + 1, col, cm * u);
                    jac.set(row + 2, col, 0.0);
                }
            }
            prev_v = v;
            prev_d.copy_from_slice(d);
        });
        true
    }

    /// [`Series::sensitivity`] of a kinematics matrix's slopes `slopes` (per parameter,
    /// per wheel: d(vx, vy, omega)/d q per unit increment), summed between the kept rows.
    ///
    /// A row's twist slope is S_j inc (S_j: the parameter's slopes), and the
    /// sensitivities' step is linear in it: d2 += S_j[2] inc, and d0, d1 move by
    /// -ey d2 + P . (S_j inc) and ex d2 + Q . (S_j inc) with (P, Q, ex, ey) of the row's
    /// arc alone. So the rows between two kept rows sum, once for every parameter, into
    /// the weights of the 3 x wheels entries of S_j (and of d2 before them), and each
    /// parameter is stepped once per kept row: a pass costs about the same whatever the
    /// number of parameters (the same sums as the row-by-row stepping, in another order).
    fn sensitivity_summed(
        &self,
        stepper: &Stepper,
        slopes: &[Vec<[f64; 3]>],
        need: Vec<usize>,
    ) -> Sensitivity {
        let p = slopes.len();
        let nw = self.wheels.max(1);
        let mut values = Vec::with_capacity(need.len());
        let mut out = Vec::with_capacity(need.len() * p);
        let mut d = vec![[0.0f64; 3]; p];
        // Per wheel: the weights of S_j[w] = (vx, vy, omega) slopes in d0 and d1
        // (a0, a1), of the increments summed so far (cum: d2's).
        let mut a0 = vec![[0.0f64; 3]; nw];
        let mut a1 = vec![[0.0f64; 3]; nw];
        let mut cum = vec![0.0f64; nw];
        // d0 and d1's weights of d2 at the segment's start.
        let (mut ey_sum, mut ex_sum) = (0.0f64, 0.0f64);
        let (mut x, mut y, mut h) = (0.0f64, 0.0f64, step::Heading::new());
        let mut next = 0usize;
        if need.first() == Some(&0) {
            values.push([x, y, h.th]);
            out.extend_from_slice(&d);
            next = 1;
        }
        for (k, inc) in self.incs().enumerate() {
            let tw = stepper.forward(inc);
            // The arc step (as the path's), with the quantities its derivative needs.
            let (st, ct) = (h.sin, h.cos);
            let (s, c, lx, ly) = step::arc_step(&mut x, &mut y, &mut h, &tw);
            let (ds, dc) = arc_slopes(tw.omega);
            let (ex, ey) = (ct * lx - st * ly, st * lx + ct * ly);
            let (a, b) = (ds * tw.vx - dc * tw.vy, dc * tw.vx + ds * tw.vy);
            // d0 += -ey d2 + P . t, d1 += ex d2 + Q . t, d2 += t[2] (t = S_j inc).
            let pw = [ct * s - st * c, -(ct * c + st * s), ct * a - st * b];
            let qw = [st * s + ct * c, ct * s - st * c, st * a + ct * b];
            for w in 0..nw {
                let (iw, cw) = (inc[w], cum[w]);
                let (u0, u1) = (&mut a0[w], &mut a1[w]);
                u0[0] += pw[0] * iw;
                u0[1] += pw[1] * iw;
                u0[2] += pw[2] * iw - ey * cw;
                u1[0] += qw[0] * iw;
                u1[1] += qw[1] * iw;
                u1[2] += qw[2] * iw + ex * cw;
                cum[w] = cw + iw;
            }
            ey_sum += ey;
            ex_sum += ex;
            if need.get(next) == Some(&(k + 1)) {
                for (dj, sj) in d.iter_mut().zip(slopes) {
                    let (mut w0, mut w1, mut w2) = (0.0, 0.0, 0.0);
                    for w in 0..nw {
                        let (g, u0, u1) = (&sj[w], &a0[w], &a1[w]);
                        w0 += u0[0] * g[0] + u0[1] * g[1] + u0[2] * g[2];
                        w1 += u1[0] * g[0] + u1[1] * g[1] + u1[2] * g[2];
                        w2 += cum[w] * g[2];
                    }
                    dj[0] += -ey_sum * dj[2] + w0;
                    dj[1] += ex_sum * dj[2] + w1;
                    dj[2] += w2;
                }
                values.push([x, y, h.th]);
                out.extend_from_slice(&d);
                next += 1;
                a0.iter_mut().for_each(|v| *v = [0.0; 3]);
                a1.iter_mut().for_each(|v| *v = [0.0; 3]);
                cum.iter_mut().for_each(|v| *v = 0.0);
                (ey_sum, ex_sum) = (0.0, 0.0);
            }
        }
        Sensitivity {
            need,
            values,
            slopes: out,
        }
    }

    /// The Jacobian rows of [`dr_residuals_into`](crate::objective::dr_residuals_into) (same order) from the
    /// sensitivities `sens` of the path parameters of `cols`, and its marker parameters,
    /// into `jac` rows from `row0`:
    /// columns are parameter indices.
    pub(crate) fn dr_jacobian(
        &self,
        sens: &Sensitivity,
        cols: &Columns,
        marker: (f64, f64),
        lever: f64,
        jac: &mut nalgebra::DMatrix<f64>,
        row0: usize,
    ) {
        let (path_params, marker_params) = (&cols.path, cols.marker);
        let p = path_params.len();
        let at = |k: usize| sens.need.binary_search(&k).expect("row kept");
        let mut seg = 0usize;
        let u = 1.0 / RES_UNIT_M;
        // The marker's terms need the heading's cosine and sine at each sample.
        let turns = marker != (0.0, 0.0) || marker_params != (None, None);
        // The segment whose anchor quantities are set: its kept row, the rotation onto the
        // measured heading there (angle, cos, sin) and the measured heading's cos and sin.
        let mut set = usize::MAX;
        let (mut ia, mut dth, mut c, mut sn, mut ca, mut sa) = (0, 0.0, 1.0, 0.0, 1.0, 0.0);
        for (n, &j) in self.samples.iter().enumerate() {
            while seg + 1 < self.anchors.len() && self.anchors[seg + 1].sample <= j {
                seg += 1;
            }
            if set != seg {
                set = seg;
                let (a, ath) = (self.anchors[seg].sample, self.anchors[seg].pose[2]);
                ia = at(self.pose_row[a]);
                dth = ath - sens.values[ia][2];
                (c, sn) = (dth.cos(), dth.sin());
                (ca, sa) = (ath.cos(), ath.sin());
            }
            let ij = at(self.pose_row[j]);
            let (va, vj) = (sens.values[ia], sens.values[ij]);
            let (dx, dy) = (vj[0] - va[0], vj[1] - va[1]);
            let th = vj[2] + dth;
            let (cm, sm) = if turns {
                (th.cos(), th.sin())
            } else {
                (0.0, 0.0)
            };
            let row = row0 + 3 * n;
            for (q, &col) in path_params.iter().enumerate() {
                let (si, sj) = (sens.slopes[ia * p + q], sens.slopes[ij * p + q]);
                let d_dth = -si[2];
                let (d_dx, d_dy) = (sj[0] - si[0], sj[1] - si[1]);
                let d_th = sj[2] + d_dth;
                let wx = (-sn * dx - c * dy) * d_dth + c * d_dx - sn * d_dy
                    + (-sm * marker.0 - cm * marker.1) * d_th;
                let wy = (c * dx - sn * dy) * d_dth
                    + sn * d_dx
                    + c * d_dy
                    + (cm * marker.0 - sm * marker.1) * d_th;
                jac[(row, col)] = wx * u;
                jac[(row + 1, col)] = wy * u;
                jac[(row + 2, col)] = d_th * lever * u;
            }
            if let Some(col) = marker_params.0 {
                jac[(row, col)] = (cm - ca) * u;
                jac[(row + 1, col)] = (sm - sa) * u;
                jac[(row + 2, col)] = 0.0;
            }
            if let Some(col) = marker_params.1 {
                jac[(row, col)] = (sa - sm) * u;
                jac[(row + 1, col)] = (cm - ca) * u;
                jac[(row + 2, col)] = 0.0;
            }
        }
    }
}

/// The path parameters of `specs` (those the paths depend on) and the marker's.
pub(crate) fn split_params(specs: &[ParamSpec]) -> Columns {
    let path = (0..specs.len())
        .filter(|&i| !matches!(specs[i].kind, GeomKind::MarkerX | GeomKind::MarkerY))
        .collect();
    let at = |k: GeomKind| specs.iter().position(|s| s.kind == k);
    Columns {
        path,
        marker: (at(GeomKind::MarkerX), at(GeomKind::MarkerY)),
    }
}

/// Some whole columns of a column-major Jacobian (nalgebra's layout), from column
/// `first` on: what one thread writes while another writes the columns before them.
pub(crate) struct ColumnSlab<'m> {
    data: &'m mut [f64],
    nrows: usize,
    first: usize,
}

impl<'m> ColumnSlab<'m> {
    /// The columns of `data` (whole columns of `nrows` rows), the first being `first`.
    pub(crate) fn new(data: &'m mut [f64], nrows: usize, first: usize) -> Self {
        ColumnSlab { data, nrows, first }
    }

    /// Whether column `col` is in the slab.
    pub(crate) fn holds(&self, col: usize) -> bool {
        col >= self.first && (col - self.first + 1) * self.nrows <= self.data.len()
    }

    #[inline]
    fn set(&mut self, row: usize, col: usize, v: f64) {
        self.data[(col - self.first) * self.nrows + row] = v;
    }
}

/// Jacobian columns (parameter indices) of the parameters the paths depend on, and of
/// the marker's x and y.
pub(crate) struct Columns {
    pub(crate) path: Vec<usize>,
    pub(crate) marker: (Option<usize>, Option<usize>),
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::{param_specs, turn_law_specs};
    use crate::problem::Problem;
    use nalgebra::DMatrix;
    use sim::{record, Motion, RandomMotion, RecordConfig, Surface};

    fn robot(name: &str) -> Robot {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(format!("{name}.toml"));
        formats::robot_file::load(&p).unwrap()
    }

    fn series(robot: &Robot, seed: u64) -> Series {
        let motion = Motion::Random(RandomMotion {
            duration_s: 20.0,
            ..RandomMotion::default()
        });
        let mut cfg = RecordConfig {
            row_rate_hz: 50.0,
            ..RecordConfig::default()
        };
        cfg.sim.seed = seed;
        let rec = record(robot, &[], Surface::flat(), &motion, &cfg).unwrap();
        Series::new("r", robot, &rec.recording).unwrap()
    }

    /// The analytic Jacobian of the dead-reckoning residuals against central differences
    /// of the residuals themselves, away from nominal, with the prior rows.
    fn agrees(robot: &Robot, specs: &[ParamSpec], geom: &[f64]) {
        let all = [series(robot, 1), series(robot, 2)];
        let mut p = Problem::new(robot, specs, &all);
        p.free_start = false;
        p.prior_scale = 3.0;
        let r = p.residuals(geom, &[], true);
        let mut jac = DMatrix::zeros(0, 0);
        assert!(p.jacobian(geom, &r, &mut jac));
        assert_eq!((jac.nrows(), jac.ncols()), (r.len(), specs.len()));
        for j in 0..specs.len() {
            let h = 1e-6 * geom[j].abs().max(1e-2);
            let (mut a, mut b) = (geom.to_vec(), geom.to_vec());
            a[j] += h;
            b[j] -= h;
            let (ra, rb) = (p.residuals(&a, &[], true), p.residuals(&b, &[], true));
            let scale = (0..r.len())
                .map(|i| ((ra[i] - rb[i]) / (2.0 * h)).abs())
                .fold(1e-9, f64::max);
            for i in 0..r.len() {
                let fd = (ra[i] - rb[i]) / (2.0 * h);
                assert!(
                    (jac[(i, j)] - fd).abs() <= 1e-5 * scale,
                    "{}: row {i}: analytic {} differences {fd}",
                    specs[j].name,
                    jac[(i, j)]
                );
            }
        }
    }

    /// The analytic Jacobian of the aligned residuals (start pose and clocks fitted per
    /// recording), geometry and nuisance columns together with the prior rows, against
    /// central differences of the residuals, off nominal and off the recordings' clocks.
    fn free_agrees(robot: &Robot, specs: &[ParamSpec], geom: &[f64]) {
        let all = [series(robot, 1), series(robot, 2)];
        let mut p = Problem::new(robot, specs, &all);
        p.prior_scale = 3.0;
        let g = specs.len();
        // Start poses a few cm and degrees off, clocks about 20-30 ms and 0.2 % off (not
        // round: no pose sample's time on the encoders' clock falls on a row's, where the
        // interpolated path has a kink that differences straddle).
        let nuis = [
            0.01, -0.02, 0.05, 0.0317, 1.00213, -0.015, 0.01, -0.04, -0.0183, 0.99788,
        ];
        let x = [geom, &nuis[..]].concat();
        let res = |x: &[f64]| p.residuals(&x[..g], &x[g..], true);
        let r = res(&x);
        let mut jac = DMatrix::zeros(0, 0);
        assert!(p.free_jacobian(&x, &r, &mut jac));
        assert_eq!((jac.nrows(), jac.ncols()), (r.len(), x.len()));
        // The parameters' columns split over two threads (the marker's with the second
        // half) are the one thread's, to the bit.
        let (mut one, mut two) = (DMatrix::zeros(0, 0), DMatrix::zeros(0, 0));
        assert!(p.free_jacobian_on(&x, &r, &mut one, Some(1)));
        assert!(p.free_jacobian_on(&x, &r, &mut two, Some(2)));
        let bits = |m: &DMatrix<f64>| m.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&one), bits(&two), "split over two threads");
        assert_eq!(bits(&one), bits(&jac), "as the fit takes it");
        for j in 0..x.len() {
            // The path is piecewise linear in time: a clock's step small enough that no
            // sample's difference straddles a row (1e-9 of 20 s against 20 ms rows).
            let h = if j < g {
                1e-6 * x[j].abs().max(1e-2)
            } else {
                1e-9 * x[j].abs().max(1.0)
            };
            let (mut a, mut b) = (x.clone(), x.clone());
            a[j] += h;
            b[j] -= h;
            let (ra, rb) = (res(&a), res(&b));
            let scale = (0..r.len())
                .map(|i| ((ra[i] - rb[i]) / (2.0 * h)).abs())
                .fold(1e-9, f64::max);
            let name = specs.get(j).map_or("nuisance", |s| s.name.as_str());
            for i in 0..r.len() {
                let fd = (ra[i] - rb[i]) / (2.0 * h);
                assert!(
                    (jac[(i, j)] - fd).abs() <= 1e-5 * scale,
                    "{name} (column {j}): row {i}: analytic {} differences {fd}",
                    jac[(i, j)]
                );
            }
        }
    }

    fn off_nominal(specs: &[ParamSpec]) -> Vec<f64> {
        specs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                s.nominal + 0.3 * (s.plausible.1 - s.nominal) * if i % 2 == 0 { 1.0 } else { -0.7 }
            })
            .collect()
    }

    /// The sensitivities summed between kept rows are the row-by-row ones (to rounding),
    /// on a robot whose kinematics matrix depends on every parameter.
    #[test]
    fn summed_sensitivities_are_the_stepped_ones() {
        let r = robot("omni4");
        let specs = param_specs(&r, false);
        let geom = off_nominal(&specs);
        let s = series(&r, 3);
        let rb = robot_with(&r, &specs, &geom);
        let kin = Kinematics::<f64>::new(&rb, &Corrections::None).unwrap();
        let stepper = Stepper::new(&rb, &kin, &TurnLaw::of(&specs, &geom, TurnLaw::default()));
        let cols = split_params(&specs);
        let slopes =
            TwistSlopes::new(&r, &specs, &geom, TurnLaw::default(), &cols.path, false).unwrap();
        let TwistSlopes::Linear(v) = &slopes else {
            panic!("a kinematics matrix's slopes")
        };
        let need = s.dr_rows();
        let a = s.sensitivity_summed(&stepper, v, need.clone());
        let b = s.sensitivity_stepped(&stepper, &slopes, need);
        assert_eq!(a.values, b.values, "the path itself, to the bit");
        let scale = b
            .slopes
            .iter()
            .flatten()
            .fold(1e-9f64, |m, v| m.max(v.abs()));
        for (x, y) in a.slopes.iter().flatten().zip(b.slopes.iter().flatten()) {
            assert!((x - y).abs() <= 1e-9 * scale, "{x} vs {y}");
        }
    }

    #[test]
    fn omni_jacobian_matches_differences() {
        let r = robot("omni4");
        let specs = param_specs(&r, true);
        agrees(&r, &specs, &off_nominal(&specs));
    }

    /// The aligned fit's Jacobian (diagnose's clock fit, `--free-start`) on an omni robot
    /// with the marker's offset, and on robots stepped by their sides.
    #[test]
    fn free_start_jacobian_matches_differences() {
        let r = robot("omni4");
        let specs = param_specs(&r, true);
        free_agrees(&r, &specs, &off_nominal(&specs));
        for name in ["mobolab", "rover4"] {
            let r = robot(name);
            let specs = turn_law_specs(&r);
            free_agrees(&r, &specs, &off_nominal(&specs));
        }
    }

    #[test]
    fn turn_law_jacobian_matches_differences() {
        for name in ["mobolab", "rover4"] {
            let r = robot(name);
            let specs = turn_law_specs(&r);
            agrees(&r, &specs, &off_nominal(&specs));
        }
    }
}
