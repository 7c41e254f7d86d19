//! What the fit minimises, recording by recording: the residuals (x, y and heading at a
//! lever arm, in [`RES_UNIT_M`]) of a dead-reckoned path against the measured poses,
//! either aligned (start pose and clocks fitted: [`residuals_into`], with the
//! nuisance's analytic Jacobian) or dead-reckoned from the measured pose at each anchor
//! ([`dr_residuals_into`]); Huber's loss on them; their position RMSE. Below the joint
//! problem so that the sensitivities ([`sens`](crate::sens)) differentiate
//! the same residuals.

use crate::series::{Anchor, Nuisance, Path, Series};
use nalgebra::DMatrix;

/// Unit of the position residuals (m): only scales the cost, uncertainties use the
/// observed scatter.
pub(crate) const RES_UNIT_M: f64 = 1e-3;
/// Heading residuals count as position errors at this lever arm (m).
pub(crate) const HEADING_LEVER_M: f64 = 0.1;
/// Default lever arm (m) of the heading residuals in the dead-reckoning objective (as the
/// aligned fit's). On the differential robot's held-out proxy a longer lever transfers
/// better (geometric mean ratio to OptiOdom for 0.1, 1, 3, 10 m: 1.003, 0.969, 0.944,
/// 0.937), because it lowers the heading gain of December's squares the way the arcs'
/// turn law wants; held out within the squares it is no better, and on the mecanum
/// robot's proxy it is worse (0.934, 0.963, 1.021, 1.205), as on omni3's. At 3 m the
/// heading gain dominates and scale/eb are reported not separable even on two-direction
/// squares (sim and real): [`CalOptions::heading_lever_m`] sets it (docs/calibrate.md,
/// `--heading-lever`).
///
/// [`CalOptions::heading_lever_m`]: crate::CalOptions::heading_lever_m
pub const DR_HEADING_LEVER_M: f64 = 0.1;

/// Huber's loss on the Jacobian's data rows: d huber / dr is 1 within `c` and
/// c / |r| beyond (huber is monotone, = c at c), on the first `cols` columns.
pub(super) fn huber_rows(jac: &mut DMatrix<f64>, r: &[f64], c: f64, cols: usize) {
    for (i, v) in r.iter().enumerate() {
        if v.abs() > c {
            let k = c / v.abs();
            for a in 0..cols {
                jac[(i, a)] *= k;
            }
        }
    }
}

/// Each pose sample on the encoders' clock: (sample j, its row time, its time tau on the
/// encoders' clock, the row segment k with t[k] <= tau < t[k + 1] where there is one).
pub(crate) fn pose_segments<'a>(
    s: &'a Series,
    nu: &Nuisance,
) -> impl Iterator<Item = (usize, f64, f64, usize)> + 'a {
    let (t0, n) = (s.t[0], s.t.len());
    let (offset, ratio) = (nu.time_offset_s, nu.clock_ratio);
    let mut k = 0usize;
    (0..s.pose_row.len()).map(move |j| {
        let tj = s.t[s.pose_row[j]];
        let tau = t0 + (tj - t0 - offset) / ratio;
        while k + 2 < n && s.t[k + 1] <= tau {
            k += 1;
        }
        while k > 0 && s.t[k] > tau {
            k -= 1;
        }
        (j, tj, tau, k)
    })
}

/// Residuals (ex, ey, lever * eth per pose sample, in RES_UNIT_M) of one recording.
pub(crate) fn residuals_into(
    s: &Series,
    path: &Path,
    nu: &Nuisance,
    marker: (f64, f64),
    out: &mut Vec<f64>,
) {
    let (c, sn) = (nu.theta0_rad.cos(), nu.theta0_rad.sin());
    let n = s.t.len();
    for (j, _, tau, k) in pose_segments(s, nu) {
        let (x, y, th) = if n < 2 || tau <= s.t[0] {
            (path.x[0], path.y[0], path.th[0])
        } else if tau >= s.t[n - 1] {
            (path.x[n - 1], path.y[n - 1], path.th[n - 1])
        } else {
            let f = (tau - s.t[k]) / (s.t[k + 1] - s.t[k]);
            let l = |v: &[f64]| v[k] + (v[k + 1] - v[k]) * f;
            (l(&path.x), l(&path.y), l(&path.th))
        };
        // The marker sits at `marker` in the body frame: it moves on a circle in a turn.
        let (mut wx, mut wy) = (nu.x0_m + c * x - sn * y, nu.y0_m + sn * x + c * y);
        if marker != (0.0, 0.0) {
            let (sm, cm) = (nu.theta0_rad + th).sin_cos();
            // Term by term, as the whole sum rounds.
            wx = wx + cm * marker.0 - sm * marker.1;
            wy = wy + sm * marker.0 + cm * marker.1;
        }
        out.push((wx - s.px[j]) / RES_UNIT_M);
        out.push((wy - s.py[j]) / RES_UNIT_M);
        out.push((nu.theta0_rad + th - s.pth[j]) * HEADING_LEVER_M / RES_UNIT_M);
    }
}

/// The Jacobian of [`residuals_into`] with respect to the recording's nuisance (x0, y0,
/// theta0, time offset, clock ratio: columns `col0..col0 + NUIS`) into `jac` from row
/// `row0`. The path is interpolated linearly between rows, so its slope in time is its
/// segment's (none before the first row or after the last).
pub(super) fn nuisance_jacobian_into(
    s: &Series,
    path: &Path,
    nu: &Nuisance,
    marker: (f64, f64),
    jac: &mut DMatrix<f64>,
    row0: usize,
    col0: usize,
) {
    let t0 = s.t[0];
    let (c, sn) = (nu.theta0_rad.cos(), nu.theta0_rad.sin());
    let n = s.t.len();
    let u = 1.0 / RES_UNIT_M;
    let lever = HEADING_LEVER_M * u;
    for (j, tj, tau, k) in pose_segments(s, nu) {
        // The path at tau and its slope in tau.
        let ((x, y, th), (vx, vy, vth)) = if n < 2 || tau <= s.t[0] {
            ((path.x[0], path.y[0], path.th[0]), (0.0, 0.0, 0.0))
        } else if tau >= s.t[n - 1] {
            (
                (path.x[n - 1], path.y[n - 1], path.th[n - 1]),
                (0.0, 0.0, 0.0),
            )
        } else {
            let dt = s.t[k + 1] - s.t[k];
            let f = (tau - s.t[k]) / dt;
            let l = |v: &[f64]| v[k] + (v[k + 1] - v[k]) * f;
            let d = |v: &[f64]| (v[k + 1] - v[k]) / dt;
            (
                (l(&path.x), l(&path.y), l(&path.th)),
                (d(&path.x), d(&path.y), d(&path.th)),
            )
        };
        // d(wx, wy)/d theta_total of the marker's offset (zero without one).
        let (mx, my) = if marker != (0.0, 0.0) {
            let (sm, cm) = (nu.theta0_rad + th).sin_cos();
            (
                -sm * marker.0 - cm * marker.1,
                cm * marker.0 - sm * marker.1,
            )
        } else {
            (0.0, 0.0)
        };
        // d tau / d time offset, d tau / d clock ratio.
        let dtau = [
            -1.0 / nu.clock_ratio,
            -(tj - t0 - nu.time_offset_s) / (nu.clock_ratio * nu.clock_ratio),
        ];
        let wx_tau = c * vx - sn * vy + mx * vth;
        let wy_tau = sn * vx + c * vy + my * vth;
        let row = row0 + 3 * j;
        jac[(row, col0)] = u;
        jac[(row + 1, col0 + 1)] = u;
        jac[(row, col0 + 2)] = (-sn * x - c * y + mx) * u;
        jac[(row + 1, col0 + 2)] = (c * x - sn * y + my) * u;
        jac[(row + 2, col0 + 2)] = lever;
        for (q, dq) in dtau.iter().enumerate() {
            jac[(row, col0 + 3 + q)] = wx_tau * dq * u;
            jac[(row + 1, col0 + 3 + q)] = wy_tau * dq * u;
            jac[(row + 2, col0 + 3 + q)] = vth * dq * lever;
        }
    }
}

/// A path's (x, y, theta) at a row.
pub(crate) trait PathAt {
    fn at(&self, row: usize) -> [f64; 3];
}

impl PathAt for &Path {
    #[inline]
    fn at(&self, k: usize) -> [f64; 3] {
        [self.x[k], self.y[k], self.th[k]]
    }
}

/// Dead-reckoning residuals (ex, ey, lever * eth, in RES_UNIT_M) of one recording at its
/// distance samples: the path integrated from the measured pose at each anchor (the first
/// pose sample, and the end of each event), no start pose or clocks fitted.
pub(crate) fn dr_residuals_into(
    s: &Series,
    path: impl PathAt,
    marker: (f64, f64),
    lever: f64,
    out: &mut Vec<f64>,
) {
    let mut seg = 0usize;
    // The segment whose anchor quantities are set: the anchor's path row, the rotation
    // onto the measured heading there (angle, cos, sin) and the body's position.
    let mut set = usize::MAX;
    let (mut pa, mut dth, mut c, mut sn, mut bx, mut by) = ([0.0; 3], 0.0, 1.0, 0.0, 0.0, 0.0);
    for &j in &s.samples {
        while seg + 1 < s.anchors.len() && s.anchors[seg + 1].sample <= j {
            seg += 1;
        }
        if set != seg {
            set = seg;
            let Anchor {
                sample: a,
                pose: [ax, ay, ath],
            } = s.anchors[seg];
            pa = path.at(s.pose_row[a]);
            dth = ath - pa[2];
            (c, sn) = (dth.cos(), dth.sin());
            // Body position at the anchor from the measured marker position.
            let (ca, sa) = (ath.cos(), ath.sin());
            bx = ax - (ca * marker.0 - sa * marker.1);
            by = ay - (sa * marker.0 + ca * marker.1);
        }
        let pj = path.at(s.pose_row[j]);
        let (dx, dy) = (pj[0] - pa[0], pj[1] - pa[1]);
        let th = pj[2] + dth;
        let (mut wx, mut wy) = (bx + c * dx - sn * dy, by + sn * dx + c * dy);
        if marker != (0.0, 0.0) {
            let (cm, sm) = (th.cos(), th.sin());
            // Term by term, as the whole sum rounds.
            wx = wx + cm * marker.0 - sm * marker.1;
            wy = wy + sm * marker.0 + cm * marker.1;
        }
        out.push((wx - s.px[j]) / RES_UNIT_M);
        out.push((wy - s.py[j]) / RES_UNIT_M);
        out.push((th - s.pth[j]) * lever / RES_UNIT_M);
    }
}

/// Huber's loss as a residual: sign(r) sqrt(2 rho(r)), so a least-squares solver
/// minimises sum rho (quadratic within `c`, linear beyond).
pub(super) fn huber(r: f64, c: f64) -> f64 {
    let a = r.abs();
    if a <= c {
        r
    } else {
        r.signum() * (c * (2.0 * a - c)).sqrt()
    }
}

/// Position RMSE (m) from residuals laid out by `residuals_into`.
pub(super) fn position_rmse(r: &[f64]) -> f64 {
    let n = r.len() / 3;
    if n == 0 {
        return 0.0;
    }
    let s: f64 = r.chunks(3).map(|c| c[0] * c[0] + c[1] * c[1]).sum::<f64>();
    (s / n as f64).sqrt() * RES_UNIT_M
}

/// Huber's loss switches from quadratic to linear at this many robust sigmas (1.345: 95 %
/// efficiency on Gaussian residuals).
pub const HUBER_K: f64 = 1.345;
