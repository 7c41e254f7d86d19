//! Lateral / longitudinal corrective factors for omnidirectional robots from straight-path
//! runs ([Redundant omni] sec. III: F_lat eq. 4, F_lon eq. 5, final wheel speeds F_lon
//! F_lat J twist eq. 6; paths 4W-1 and 4W-2; secondary factors from a repeated test).
//!
//! [Redundant omni] gives the factors only loosely, so this module makes them exact under
//! one stated model: during a run every wheel turns at a constant rate, so the body twist
//! is constant and the body moves along an exact constant-curvature arc (arc length s,
//! heading change theta, body-frame velocity direction constant). From the measured end
//! point (and heading, when measured) the arc is inferred, each driven wheel's actual
//! ground travel follows from its rolling row, and k_i = actual / nominal travel. Then
//! `f_lon * f_lat[i] = 1/k_i` makes each wheel deliver its nominal travel. This works for
//! any number of wheels and any wheel geometry, not only the 4-wheel robot of
//! [Redundant omni].
//!
//! Error convention (docs/formats.md §3): measured minus odometry, in the start frame with
//! x along the commanded direction of the path and y to its left.
//!
//! # Idle wheels: released or held
//! [Redundant omni] describes its two paths differently: on 4W-1 "the other wheels have no
//! angular velocity" (held at zero by their controllers), on 4W-2 "the actuators of wheels
//! 1 and 3 are turned off" (released, free to turn). Released wheels add no constraint:
//! each driven wheel's travel is its rolling row times the body motion, read straight off
//! the arc. Held wheels are rolling constraints with zero wheel speed that fight the driven
//! ones; the body then moves as the least-squares solution of all rolling constraints,
//! driven and held weighted alike (how the sim crate resolves an over-determined wheel
//! set): motion = P c with P the pseudo-inverse of the stacked rows and c the contact
//! travels (k_j times nominal for driven wheels, 0 for held ones). The k_j are then the
//! least-squares solution of that linear relation ([`IdleWheels::Held`] paths).

use crate::linalg::sinc;
use crate::stats;
use core::f64::consts::PI;
use core::fmt;

/// Most wheels a robot may have here (fixed-size arrays: no allocator).
pub const MAX_WHEELS: usize = 8;
/// Most test paths per calibration.
pub const MAX_PATHS: usize = 4;

/// End error of one straight-path run: measured minus odometry, path start frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OmniRun {
    /// End error along the commanded direction (m), measured minus odometry.
    pub x_err_m: f64,
    /// End error to the left of the commanded direction (m), measured minus odometry.
    pub y_err_m: f64,
    /// Measured heading error; when absent the arc is assumed tangent to the commanded
    /// direction (no sideways body velocity) and theta is inferred from the chord.
    pub theta_err_rad: Option<f64>,
}

/// Rolling row of a wheel (Siegwart eq. 3.19): [sin(a+b+g), -cos(a+b+g), -l cos(b+g)],
/// so that row . (vx, vy, omega)_body = r cos(g) phidot.
pub fn rolling_row(alpha_rad: f64, beta_rad: f64, gamma_rad: f64, l_m: f64) -> [f64; 3] {
    let abg = alpha_rad + beta_rad + gamma_rad;
    [
        libm::sin(abg),
        -libm::cos(abg),
        -l_m * libm::cos(beta_rad + gamma_rad),
    ]
}

/// A wheel driven on a test path.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct DrivenWheel {
    /// Index of the wheel in the robot file's order.
    pub index: usize,
    /// Rolling row [a, b, c] (see [`rolling_row`]); a, b dimensionless, c in metres.
    pub row: [f64; 3],
    /// Ground travel (r cos(g) phi) the wheel is commanded to make on this path; its sign
    /// says which way it turns.
    pub nominal_travel_m: f64,
}

impl DrivenWheel {
    /// Driven wheel of a straight path of `length_m` along body direction `direction_rad`
    /// (0: body +x, pi/2: body +y): nominal travel = row . (L cos, L sin, 0).
    pub fn on_straight_path(
        index: usize,
        row: [f64; 3],
        direction_rad: f64,
        length_m: f64,
    ) -> Self {
        let nominal_travel_m =
            length_m * (row[0] * libm::cos(direction_rad) + row[1] * libm::sin(direction_rad));
        DrivenWheel {
            index,
            row,
            nominal_travel_m,
        }
    }
}

/// How the wheels a path does not drive behave while it runs.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    postcard_schema::Schema,
)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdleWheels {
    /// Drive cut: free to turn, no constraint on the body ([Redundant omni]'s 4W-2).
    #[default]
    Released,
    /// Velocity loop at zero: a rolling constraint with zero wheel speed
    /// ([Redundant omni]'s 4W-1).
    Held,
}

impl IdleWheels {
    /// The name used in robot files, flags and JSON.
    pub fn as_str(self) -> &'static str {
        match self {
            IdleWheels::Released => "released",
            IdleWheels::Held => "held",
        }
    }
}

/// One test path with its runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PathRuns<'a> {
    /// Commanded straight length L.
    pub length_m: f64,
    /// Commanded direction in the body frame (0 for 4W-1 along +x, pi/2 for 4W-2).
    pub direction_rad: f64,
    /// Wheels driven on this path (at least one).
    pub driven: &'a [DrivenWheel],
    /// Measured runs (at least one).
    pub runs: &'a [OmniRun],
    /// Rolling rows of the wheels held at zero speed while this path ran; empty when the
    /// idle wheels were released.
    pub held: &'a [[f64; 3]],
}

/// The arc a run followed, inferred from its end error.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct ArcMotion {
    /// Distance travelled along the arc.
    pub arc_length_m: f64,
    /// Body heading change (positive to the left).
    pub heading_change_rad: f64,
    /// Angle of the (constant) body-frame velocity from the commanded direction; 0 when
    /// the heading was not measured.
    pub sideways_angle_rad: f64,
}

/// Corrective factors: wheel i is commanded `f_lon * f_lat[i]` times its nominal speed
/// ([Redundant omni] eq. 6: F_lon F_lat J twist).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OmniCorrection {
    /// Number of valid entries in `f_lat`.
    pub wheel_count: usize,
    /// Longitudinal factor: the common speed-up that makes the robot go the full length.
    pub f_lon: f64,
    /// Lateral factors (diagonal of F_lat), 1 for wheels never driven.
    pub f_lat: [f64; MAX_WHEELS],
}

impl OmniCorrection {
    /// No correction.
    pub fn identity(wheel_count: usize) -> Self {
        OmniCorrection {
            wheel_count,
            f_lon: 1.0,
            f_lat: [1.0; MAX_WHEELS],
        }
    }

    /// Per-wheel speed multipliers `f_lon * f_lat[i]` (entries past `wheel_count` are 1).
    pub fn wheel_multipliers(&self) -> [f64; MAX_WHEELS] {
        let mut m = [1.0; MAX_WHEELS];
        for (i, v) in m.iter_mut().enumerate().take(self.wheel_count) {
            *v = self.f_lon * self.f_lat[i];
        }
        m
    }
}

/// Summary of one path.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PathResult {
    /// Commanded straight length L (m).
    pub length_m: f64,
    /// Number of runs of this path.
    pub run_count: usize,
    /// Mean end error (x along the path, y to its left).
    pub mean_x_err_m: f64,
    /// Mean end error to the left of the path (m).
    pub mean_y_err_m: f64,
    /// Mean inferred (or measured) heading change.
    pub mean_heading_change_rad: f64,
    /// Longitudinal factor from this path alone: mean of 1/k over its driven wheels.
    pub f_lon: f64,
    /// [Redundant omni] eq. 5 with our sign convention: L / sqrt((L + xbar)^2 + ybar^2).
    /// Reported for comparison; it ignores the curvature of the path.
    pub f_lon_eq5: f64,
    /// Mean radial error ([Redundant omni] eq. 7).
    pub mean_radial_error_m: f64,
}

/// Result of [`calibrate`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct OmniCalibration {
    /// The factors to apply.
    pub correction: OmniCorrection,
    /// Effective ratio actual/nominal travel per wheel; None for wheels never driven.
    pub k: [Option<f64>; MAX_WHEELS],
    /// Per-path summaries in input order; None past the number of paths.
    pub paths: [Option<PathResult>; MAX_PATHS],
    /// Mean radial error ([Redundant omni] eq. 7) over all runs of all paths.
    pub mean_radial_error_m: f64,
}

/// Why the omni calibration could not be computed; paths and runs are numbered from 1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum OmniCalError {
    /// No path given.
    NoPaths,
    /// More paths than [`MAX_PATHS`].
    TooManyPaths {
        /// Most paths supported.
        max: usize,
        /// Paths given.
        got: usize,
    },
    /// Wheel count zero or above [`MAX_WHEELS`].
    InvalidWheelCount {
        /// Most wheels supported.
        max: usize,
        /// Wheel count given.
        got: usize,
    },
    /// A path without runs.
    NoRuns {
        /// Path number (from 1).
        path: usize,
    },
    /// A path that lists no driven wheels.
    NoDrivenWheels {
        /// Path number (from 1).
        path: usize,
    },
    /// A commanded length that is not a positive finite number of metres.
    InvalidLength {
        /// Path number (from 1).
        path: usize,
        /// The length given (m).
        value: f64,
    },
    /// The direction, a wheel row or a nominal travel is NaN or infinite.
    NonFiniteParameter {
        /// Path number (from 1).
        path: usize,
        /// Which parameter.
        what: &'static str,
    },
    /// A run's end error is NaN or infinite.
    NonFiniteRun {
        /// Path number (from 1).
        path: usize,
        /// Run number within the path (from 1).
        run: usize,
    },
    /// A driven wheel's index is not a wheel of the robot.
    WheelIndexOutOfRange {
        /// Path number (from 1).
        path: usize,
        /// The wheel index given (0-based).
        index: usize,
        /// Wheels the robot has.
        wheel_count: usize,
    },
    /// A wheel is listed twice on one path.
    DuplicateWheel {
        /// Path number (from 1).
        path: usize,
        /// The repeated wheel index (0-based).
        index: usize,
    },
    /// A listed wheel has zero nominal travel on the path (it is not driven).
    ZeroNominalTravel {
        /// Path number (from 1).
        path: usize,
        /// The wheel index (0-based).
        index: usize,
    },
    /// The end point cannot be reached by an arc (e.g. the robot ended at the start).
    ImpossibleRun {
        /// Path number (from 1).
        path: usize,
        /// Run number within the path (from 1).
        run: usize,
    },
    /// The inferred travel of a wheel has the wrong sign: it would need a negative factor.
    NonPositiveRatio {
        /// Path number (from 1).
        path: usize,
        /// The wheel index (0-based).
        index: usize,
        /// The inferred ratio actual/nominal travel (not positive or not finite).
        k: f64,
    },
    /// [`compose`] was given corrections for different wheel counts.
    WheelCountMismatch {
        /// Wheel count of the first correction.
        first: usize,
        /// Wheel count of the second correction.
        second: usize,
    },
}

impl fmt::Display for OmniCalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use OmniCalError::*;
        match *self {
            NoPaths => write!(f, "no test paths given"),
            TooManyPaths { max, got } => write!(f, "at most {max} paths supported, got {got}"),
            InvalidWheelCount { max, got } => {
                write!(f, "wheel count must be 1..={max}, got {got}")
            }
            NoRuns { path } => write!(f, "path {path} has no runs; need at least 1"),
            NoDrivenWheels { path } => write!(f, "path {path} lists no driven wheels"),
            InvalidLength { path, value } => write!(
                f,
                "path {path}: commanded length must be a positive length in metres, got {value}"
            ),
            NonFiniteParameter { path, what } => {
                write!(f, "path {path}: {what} is NaN or infinite")
            }
            NonFiniteRun { path, run } => write!(
                f,
                "path {path} run {run} has a NaN or infinite value; fix or remove that row"
            ),
            WheelIndexOutOfRange {
                path,
                index,
                wheel_count,
            } => write!(
                f,
                "path {path}: wheel index {index} out of range for a {wheel_count}-wheel robot"
            ),
            DuplicateWheel { path, index } => {
                write!(f, "path {path}: wheel {index} listed twice")
            }
            ZeroNominalTravel { path, index } => write!(
                f,
                "path {path}: wheel {index} has zero nominal travel, so it is not driven on this path"
            ),
            ImpossibleRun { path, run } => write!(
                f,
                "path {path} run {run}: end error not reachable by a forward arc (did the robot move? check the sign: measured minus odometry)"
            ),
            NonPositiveRatio { path, index, k } => write!(
                f,
                "path {path}: wheel {index} would have travelled {k} times its nominal distance; check wheel directions and the error sign"
            ),
            WheelCountMismatch { first, second } => write!(
                f,
                "cannot compose corrections for {first} and {second} wheels"
            ),
        }
    }
}

impl core::error::Error for OmniCalError {}

fn wrap_pi(a: f64) -> f64 {
    let mut w = libm::remainder(a, 2.0 * PI);
    if w <= -PI {
        w += 2.0 * PI;
    }
    w
}

/// Infers the arc a run followed. The end point is (L + x_err, y_err). A constant twist
/// makes the chord point along sideways_angle + theta/2 and have length
/// s sin(theta/2)/(theta/2); without a measured heading the sideways angle is taken as 0,
/// so theta = 2 atan2(y_end, x_end).
pub fn infer_arc(length_m: f64, run: &OmniRun) -> Option<ArcMotion> {
    let xe = length_m + run.x_err_m;
    let ye = run.y_err_m;
    let chord = libm::hypot(xe, ye);
    if !(chord > 0.0 && chord.is_finite()) {
        return None;
    }
    let psi = libm::atan2(ye, xe);
    let theta = match run.theta_err_rad {
        Some(t) if t.is_finite() => t,
        Some(_) => return None,
        None => 2.0 * psi,
    };
    let sc = sinc(theta / 2.0);
    // |theta| >= 2 pi: a full turn or more cannot be told from the end point.
    let reachable = sc > 1e-9 && libm::fabs(theta) < 2.0 * PI;
    if !reachable {
        return None;
    }
    Some(ArcMotion {
        arc_length_m: chord / sc,
        heading_change_rad: theta,
        sideways_angle_rad: if run.theta_err_rad.is_some() {
            wrap_pi(psi - theta / 2.0)
        } else {
            0.0
        },
    })
}

/// Ground travel (row . integrated body twist) a wheel makes along `arc` on a path in
/// body direction `direction_rad`.
fn wheel_travel(row: &[f64; 3], arc: &ArcMotion, direction_rad: f64) -> f64 {
    let m = arc_motion(arc, direction_rad);
    row[0] * m[0] + row[1] * m[1] + row[2] * m[2]
}

/// Body motion (dx, dy, dtheta in the body frame) integrated along `arc`.
fn arc_motion(arc: &ArcMotion, direction_rad: f64) -> [f64; 3] {
    let dir = direction_rad + arc.sideways_angle_rad;
    [
        arc.arc_length_m * libm::cos(dir),
        arc.arc_length_m * libm::sin(dir),
        arc.heading_change_rad,
    ]
}

/// The driven wheels' k with the idle wheels held (module doc): the body motion is
/// P c, c = (k_j n_j for driven wheels, 0 for held), so motion = A k with column j of A
/// = P's driven column j times n_j; k solves A k = motion in least squares.
fn held_ratios(path: &PathRuns<'_>, arc: &ArcMotion) -> Option<[f64; MAX_WHEELS]> {
    let m = path.driven.len();
    let rows = path.driven.iter().map(|w| &w.row).chain(path.held.iter());
    // Normal matrix of all rolling rows (equal weights) and its inverse.
    let mut nm = [[0.0; 3]; 3];
    for r in rows {
        for a in 0..3 {
            for b in 0..3 {
                nm[a][b] += r[a] * r[b];
            }
        }
    }
    let inv = crate::linalg::inverse3(&nm)?;
    // A[:, j] = inv * row_j * n_j.
    let mut cols = [[0.0; 3]; MAX_WHEELS];
    for (j, w) in path.driven.iter().enumerate() {
        for a in 0..3 {
            cols[j][a] = (0..3).map(|b| inv[a][b] * w.row[b]).sum::<f64>() * w.nominal_travel_m;
        }
    }
    let motion = arc_motion(arc, path.direction_rad);
    // Normal equations (A^T A) k = A^T motion, m x m, by Gaussian elimination.
    let mut g = [[0.0; MAX_WHEELS + 1]; MAX_WHEELS];
    for i in 0..m {
        for j in 0..m {
            g[i][j] = (0..3).map(|a| cols[i][a] * cols[j][a]).sum();
        }
        g[i][m] = (0..3).map(|a| cols[i][a] * motion[a]).sum();
    }
    solve_in_place(&mut g, m)
}

/// Solves the m x m system in the first m columns of `g` (right-hand side in column m)
/// by Gaussian elimination with partial pivoting; `None` when singular.
fn solve_in_place(
    g: &mut [[f64; MAX_WHEELS + 1]; MAX_WHEELS],
    m: usize,
) -> Option<[f64; MAX_WHEELS]> {
    let scale = (0..m).map(|i| libm::fabs(g[i][i])).fold(0.0, f64::max);
    for c in 0..m {
        let piv = (c..m).max_by(|&a, &b| libm::fabs(g[a][c]).total_cmp(&libm::fabs(g[b][c])))?;
        // NaN fails too.
        if libm::fabs(g[piv][c]).partial_cmp(&(1e-12 * scale)) != Some(core::cmp::Ordering::Greater)
        {
            return None;
        }
        g.swap(c, piv);
        let pivot_row = g[c];
        for (r, row) in g.iter_mut().enumerate().take(m) {
            if r != c {
                let f = row[c] / pivot_row[c];
                for (x, p) in row[c..=m].iter_mut().zip(&pivot_row[c..=m]) {
                    *x -= f * p;
                }
            }
        }
    }
    let mut x = [0.0; MAX_WHEELS];
    for i in 0..m {
        x[i] = g[i][m] / g[i][i];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

fn validate_path(p: usize, path: &PathRuns<'_>, wheel_count: usize) -> Result<(), OmniCalError> {
    if !(path.length_m.is_finite() && path.length_m > 0.0) {
        return Err(OmniCalError::InvalidLength {
            path: p,
            value: path.length_m,
        });
    }
    if !path.direction_rad.is_finite() {
        return Err(OmniCalError::NonFiniteParameter {
            path: p,
            what: "direction",
        });
    }
    if path.runs.is_empty() {
        return Err(OmniCalError::NoRuns { path: p });
    }
    if path.driven.is_empty() {
        return Err(OmniCalError::NoDrivenWheels { path: p });
    }
    for (j, w) in path.driven.iter().enumerate() {
        if w.index >= wheel_count {
            return Err(OmniCalError::WheelIndexOutOfRange {
                path: p,
                index: w.index,
                wheel_count,
            });
        }
        if path.driven[..j].iter().any(|o| o.index == w.index) {
            return Err(OmniCalError::DuplicateWheel {
                path: p,
                index: w.index,
            });
        }
        if !(w.row.iter().all(|v| v.is_finite()) && w.nominal_travel_m.is_finite()) {
            return Err(OmniCalError::NonFiniteParameter {
                path: p,
                what: "driven wheel row or nominal travel",
            });
        }
        if w.nominal_travel_m == 0.0 {
            return Err(OmniCalError::ZeroNominalTravel {
                path: p,
                index: w.index,
            });
        }
    }
    for (r, run) in path.runs.iter().enumerate() {
        let theta_ok = run.theta_err_rad.is_none_or(|t| t.is_finite());
        if !(run.x_err_m.is_finite() && run.y_err_m.is_finite() && theta_ok) {
            return Err(OmniCalError::NonFiniteRun {
                path: p,
                run: r + 1,
            });
        }
    }
    Ok(())
}

/// Computes per-wheel ratios k_i and the corrective factors from straight-path runs.
///
/// Per path, k_i is the mean over runs of (implied travel / nominal travel). A wheel
/// driven on several paths gets the mean of its 1/k. Then f_lon = mean over driven wheels
/// of 1/k_i and `f_lat[i] = (1/k_i)/f_lon`, so `f_lon f_lat[i] = 1/k_i`: every wheel delivers
/// its nominal travel. A robot that stops short (x_err < 0) gets f_lon > 1.
pub fn calibrate(
    paths: &[PathRuns<'_>],
    wheel_count: usize,
) -> Result<OmniCalibration, OmniCalError> {
    if wheel_count == 0 || wheel_count > MAX_WHEELS {
        return Err(OmniCalError::InvalidWheelCount {
            max: MAX_WHEELS,
            got: wheel_count,
        });
    }
    if paths.is_empty() {
        return Err(OmniCalError::NoPaths);
    }
    if paths.len() > MAX_PATHS {
        return Err(OmniCalError::TooManyPaths {
            max: MAX_PATHS,
            got: paths.len(),
        });
    }
    // Sum of 1/k per wheel over the paths that drive it, and how many such paths.
    let mut inv_k_sum = [0.0; MAX_WHEELS];
    let mut inv_k_n = [0usize; MAX_WHEELS];
    let mut path_results: [Option<PathResult>; MAX_PATHS] = [None; MAX_PATHS];
    let mut radial_sum = 0.0;
    let mut run_total = 0usize;

    for (pi_, path) in paths.iter().enumerate() {
        let p = pi_ + 1;
        validate_path(p, path, wheel_count)?;
        let n = path.runs.len() as f64;
        // k of each driven wheel on this path, in `driven` order.
        let mut k_sum = [0.0; MAX_WHEELS];
        let mut theta_sum = 0.0;
        for (r, run) in path.runs.iter().enumerate() {
            let arc = infer_arc(path.length_m, run).ok_or(OmniCalError::ImpossibleRun {
                path: p,
                run: r + 1,
            })?;
            theta_sum += arc.heading_change_rad;
            if path.held.is_empty() {
                for (j, w) in path.driven.iter().enumerate() {
                    k_sum[j] += wheel_travel(&w.row, &arc, path.direction_rad) / w.nominal_travel_m;
                }
            } else {
                let k = held_ratios(path, &arc).ok_or(OmniCalError::ImpossibleRun {
                    path: p,
                    run: r + 1,
                })?;
                for (j, kj) in k.iter().take(path.driven.len()).enumerate() {
                    k_sum[j] += kj;
                }
            }
        }
        let mut path_inv_k_sum = 0.0;
        for (j, w) in path.driven.iter().enumerate() {
            let k = k_sum[j] / n;
            if !(k > 0.0 && k.is_finite()) {
                return Err(OmniCalError::NonPositiveRatio {
                    path: p,
                    index: w.index,
                    k,
                });
            }
            inv_k_sum[w.index] += 1.0 / k;
            inv_k_n[w.index] += 1;
            path_inv_k_sum += 1.0 / k;
        }
        let stat = |e: stats::StatsError| -> OmniCalError {
            // Unreachable after validation (runs non-empty and finite); keep it an error.
            let _ = e;
            OmniCalError::NoRuns { path: p }
        };
        let mean_x = stats::mean_by(path.runs, |r| r.x_err_m).map_err(stat)?;
        let mean_y = stats::mean_by(path.runs, |r| r.y_err_m).map_err(stat)?;
        let radial =
            stats::mean_radial_error_by(path.runs, |r| (r.x_err_m, r.y_err_m)).map_err(stat)?;
        let l = path.length_m;
        let eq5_den = libm::hypot(l + mean_x, mean_y);
        path_results[pi_] = Some(PathResult {
            length_m: l,
            run_count: path.runs.len(),
            mean_x_err_m: mean_x,
            mean_y_err_m: mean_y,
            mean_heading_change_rad: theta_sum / n,
            f_lon: path_inv_k_sum / path.driven.len() as f64,
            f_lon_eq5: if eq5_den > 0.0 {
                l / eq5_den
            } else {
                f64::INFINITY
            },
            mean_radial_error_m: radial,
        });
        radial_sum += radial * n;
        run_total += path.runs.len();
    }

    let mut k = [None; MAX_WHEELS];
    let mut g = [1.0; MAX_WHEELS];
    let (mut g_sum, mut g_n) = (0.0, 0usize);
    for i in 0..wheel_count {
        if inv_k_n[i] > 0 {
            g[i] = inv_k_sum[i] / inv_k_n[i] as f64;
            k[i] = Some(1.0 / g[i]);
            g_sum += g[i];
            g_n += 1;
        }
    }
    // g_n >= 1: every path has a driven wheel.
    let f_lon = g_sum / g_n as f64;
    let mut f_lat = [1.0; MAX_WHEELS];
    for i in 0..wheel_count {
        if inv_k_n[i] > 0 {
            f_lat[i] = g[i] / f_lon;
        }
    }
    Ok(OmniCalibration {
        correction: OmniCorrection {
            wheel_count,
            f_lon,
            f_lat,
        },
        k,
        paths: path_results,
        mean_radial_error_m: radial_sum / run_total as f64,
    })
}

/// Applies secondary factors (measured with `first` already applied) on top of `first`
/// ([Redundant omni] sec. IV.B: "two sets of corrective factors"): the speed multipliers
/// multiply.
pub fn compose(
    first: &OmniCorrection,
    second: &OmniCorrection,
) -> Result<OmniCorrection, OmniCalError> {
    if first.wheel_count != second.wheel_count {
        return Err(OmniCalError::WheelCountMismatch {
            first: first.wheel_count,
            second: second.wheel_count,
        });
    }
    let mut f_lat = [1.0; MAX_WHEELS];
    for (i, v) in f_lat.iter_mut().enumerate().take(first.wheel_count) {
        *v = first.f_lat[i] * second.f_lat[i];
    }
    Ok(OmniCorrection {
        wheel_count: first.wheel_count,
        f_lon: first.f_lon * second.f_lon,
        f_lat,
    })
}

#[cfg(test)]
// Tests walk several parallel per-wheel arrays by index; that reads clearer here.
#[allow(clippy::needless_range_loop)]
mod tests {
    extern crate std;
    use super::*;
    use core::f64::consts::FRAC_PI_2;

    const L_WHEEL: f64 = 0.035;
    const LEN: f64 = 1.0;

    /// Rolling rows of [Redundant omni]'s robot: wheels 1..4 at alpha 90, 180, 270, 0 deg.
    fn rows() -> [[f64; 3]; 4] {
        [90.0f64, 180.0, 270.0, 0.0].map(|a| rolling_row(a.to_radians(), 0.0, 0.0, L_WHEEL))
    }

    /// Path 4W-1 (body +x, wheels 1 and 3) or 4W-2 (body +y, wheels 2 and 4).
    fn driven(path: usize) -> [DrivenWheel; 2] {
        let r = rows();
        let (dir, i, j) = if path == 1 {
            (0.0, 0, 2)
        } else {
            (FRAC_PI_2, 1, 3)
        };
        [
            DrivenWheel::on_straight_path(i, r[i], dir, LEN),
            DrivenWheel::on_straight_path(j, r[j], dir, LEN),
        ]
    }

    fn direction(path: usize) -> f64 {
        if path == 1 {
            0.0
        } else {
            FRAC_PI_2
        }
    }

    /// Exact run for two driven wheels with true ratios `k`, body velocity at `sideways`
    /// from the commanded direction: solve travel_i = s (row_i . u) + c_i theta for
    /// (s, theta), then place the end of the arc.
    fn synth_run(path: usize, k: [f64; 2], sideways: f64, with_theta: bool) -> OmniRun {
        let w = driven(path);
        let u = direction(path) + sideways;
        let (a0, c0) = (
            w[0].row[0] * libm::cos(u) + w[0].row[1] * libm::sin(u),
            w[0].row[2],
        );
        let (a1, c1) = (
            w[1].row[0] * libm::cos(u) + w[1].row[1] * libm::sin(u),
            w[1].row[2],
        );
        let (t0, t1) = (k[0] * w[0].nominal_travel_m, k[1] * w[1].nominal_travel_m);
        let det = a0 * c1 - a1 * c0;
        let s = (t0 * c1 - t1 * c0) / det;
        let theta = (a0 * t1 - a1 * t0) / det;
        let chord = s * sinc(theta / 2.0);
        let ang = sideways + theta / 2.0;
        OmniRun {
            x_err_m: chord * libm::cos(ang) - LEN,
            y_err_m: chord * libm::sin(ang),
            theta_err_rad: if with_theta { Some(theta) } else { None },
        }
    }

    #[test]
    fn rolling_rows_of_001_robot() {
        // alpha 90: [1, 0, -l]; 180: [0, 1, -l]; 270: [-1, 0, -l]; 0: [0, -1, -l].
        let r = rows();
        let expect = [[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]];
        for i in 0..4 {
            assert!(
                (r[i][0] - expect[i][0]).abs() < 1e-15 && (r[i][1] - expect[i][1]).abs() < 1e-15
            );
            assert!((r[i][2] + L_WHEEL).abs() < 1e-15);
        }
        // 4W-1 drives wheels 1 and 3 in opposite senses ("same and opposite").
        let d = driven(1);
        assert!((d[0].nominal_travel_m - LEN).abs() < 1e-15);
        assert!((d[1].nominal_travel_m + LEN).abs() < 1e-15);
    }

    /// The scenario of the brief: wheel 1 3 % fast, wheel 3 1 % slow, all 5 % short
    /// (cable crossings); on 4W-2 wheel 2 2 % fast, wheel 4 nominal.
    const K1: [f64; 2] = [1.03 * 0.95, 0.99 * 0.95];
    const K2: [f64; 2] = [1.02 * 0.95, 1.00 * 0.95];

    fn scenario(with_theta: bool, sideways: f64) -> OmniCalibration {
        let runs1 = [synth_run(1, K1, sideways, with_theta); 3];
        let runs2 = [synth_run(2, K2, sideways, with_theta); 3];
        let (d1, d2) = (driven(1), driven(2));
        let paths = [
            PathRuns {
                length_m: LEN,
                direction_rad: 0.0,
                driven: &d1,
                runs: &runs1,
                held: &[],
            },
            PathRuns {
                length_m: LEN,
                direction_rad: FRAC_PI_2,
                driven: &d2,
                runs: &runs2,
                held: &[],
            },
        ];
        calibrate(&paths, 4).unwrap()
    }

    #[test]
    fn recovers_wheel_ratios_noise_free() {
        let truth = [K1[0], K2[0], K1[1], K2[1]];
        // Chord-only inference (no heading measured, no sideways motion): the model is
        // exact, so only rounding remains: 1e-9 (brief: 1e-6).
        let cal = scenario(false, 0.0);
        for i in 0..4 {
            assert!(
                (cal.k[i].unwrap() - truth[i]).abs() < 1e-9,
                "wheel {i}: {:?}",
                cal.k[i]
            );
        }
        // With a measured heading the sideways body motion is recovered too.
        let cal_t = scenario(true, 0.03);
        for i in 0..4 {
            assert!(
                (cal_t.k[i].unwrap() - truth[i]).abs() < 1e-9,
                "wheel {i}: {:?}",
                cal_t.k[i]
            );
        }
        // Factors: f_lon f_lat[i] = 1/k_i exactly; f_lon = mean of 1/k_i.
        let c = cal.correction;
        let m = c.wheel_multipliers();
        for i in 0..4 {
            assert!((m[i] * truth[i] - 1.0).abs() < 1e-9);
        }
        let f_lon = truth.iter().map(|k| 1.0 / k).sum::<f64>() / 4.0;
        assert!((c.f_lon - f_lon).abs() < 1e-9);
        // Fast wheel 1 gets the smallest lateral factor. Hand: 1/k = 1.021972 (wheel 1),
        // 1.031992 (2), 1.063264 (3), 1.052632 (4); mean 1.042465 = f_lon;
        // f_lat1 = 1.021972/1.042465 = 0.98034 (5 digits: tolerance 1e-5).
        assert!(
            (c.f_lat[0] - 0.980_34).abs() < 1e-5,
            "f_lat1 {}",
            c.f_lat[0]
        );
        assert!(c.f_lat[0] < c.f_lat[1] && c.f_lat[1] < c.f_lat[3] && c.f_lat[3] < c.f_lat[2]);
        // Path-level f_lon for 4W-1 alone: mean(1/0.9785, 1/0.9405) = 1.04262.
        let p1 = cal.paths[0].unwrap();
        assert!((p1.f_lon - 0.5 * (1.0 / K1[0] + 1.0 / K1[1])).abs() < 1e-9);
        assert!(cal.paths[2].is_none());
        assert_eq!(p1.run_count, 3);
    }

    #[test]
    fn stopping_short_needs_f_lon_above_one() {
        // Straight but 4 cm short: k = 0.96 on both wheels, f_lon = 1/0.96.
        let runs = [OmniRun {
            x_err_m: -0.04,
            y_err_m: 0.0,
            theta_err_rad: None,
        }; 2];
        let d = driven(1);
        let paths = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &d,
            runs: &runs,
            held: &[],
        }];
        let cal = calibrate(&paths, 4).unwrap();
        assert!(cal.correction.f_lon > 1.0);
        assert!((cal.correction.f_lon - 1.0 / 0.96).abs() < 1e-12);
        assert!((cal.correction.f_lat[0] - 1.0).abs() < 1e-12);
        // Undriven wheels keep f_lat = 1 and have no k.
        assert_eq!(cal.correction.f_lat[1], 1.0);
        assert_eq!(cal.k[1], None);
        // [Redundant omni] eq. 5 with our sign: L / (L + xbar) = 1/0.96 for a straight run.
        let p = cal.paths[0].unwrap();
        assert!((p.f_lon_eq5 - 1.0 / 0.96).abs() < 1e-12);
        assert!((p.mean_radial_error_m - 0.04).abs() < 1e-12);
        assert!((cal.mean_radial_error_m - 0.04).abs() < 1e-12);
        // Overshooting gives f_lon < 1.
        let runs = [OmniRun {
            x_err_m: 0.05,
            y_err_m: 0.0,
            theta_err_rad: None,
        }; 2];
        let paths = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &d,
            runs: &runs,
            held: &[],
        }];
        assert!(calibrate(&paths, 4).unwrap().correction.f_lon < 1.0);
    }

    #[test]
    fn eq5_and_arc_model_agree_to_first_order() {
        // Eq. 5 uses the chord, the arc model the arc length: they differ by the factor
        // sinc(theta/2) = 1 - theta^2/24 (with a common mean ratio). For the 4W-1 scenario
        // theta = -(t1 + t3)/(2l) = -0.543 rad, so the gap is ~1.2 %, within 2 %.
        let cal = scenario(false, 0.0);
        let p = cal.paths[0].unwrap();
        let gap = (p.f_lon_eq5 - p.f_lon).abs() / p.f_lon;
        let theta = p.mean_heading_change_rad;
        assert!((theta + (K1[0] - K1[1]) * LEN / (2.0 * L_WHEEL)).abs() < 1e-9);
        assert!(gap < 2.0 * theta * theta / 24.0, "gap {gap}");
    }

    #[test]
    fn second_pass_composes() {
        // First pass measured on data whose ratios were 1 % off the truth (e.g. a
        // different floor); the robot then runs with those factors, so its effective
        // ratios are k_true * multiplier_1, and a second pass fixes the rest.
        let off = [K1[0] * 1.01, K1[1] * 0.995];
        let runs_a = [synth_run(1, off, 0.0, false); 2];
        let d = driven(1);
        let pa = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &d,
            runs: &runs_a,
            held: &[],
        }];
        let first = calibrate(&pa, 4).unwrap().correction;
        let m1 = first.wheel_multipliers();
        let eff = [K1[0] * m1[0], K1[1] * m1[2]];
        let runs_b = [synth_run(1, eff, 0.0, false); 2];
        let pb = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &d,
            runs: &runs_b,
            held: &[],
        }];
        let second = calibrate(&pb, 4).unwrap().correction;
        let total = compose(&first, &second).unwrap();
        assert!((total.f_lon - first.f_lon * second.f_lon).abs() < 1e-15);
        for i in 0..4 {
            assert!((total.f_lat[i] - first.f_lat[i] * second.f_lat[i]).abs() < 1e-15);
        }
        // The composed multipliers are the true inverse ratios (exact model: 1e-9).
        let m = total.wheel_multipliers();
        assert!((m[0] * K1[0] - 1.0).abs() < 1e-9 && (m[2] * K1[1] - 1.0).abs() < 1e-9);
        // Composing with the identity changes nothing.
        assert_eq!(
            compose(&total, &OmniCorrection::identity(4)).unwrap(),
            total
        );
        assert!(compose(&total, &OmniCorrection::identity(3)).is_err());
    }

    #[test]
    fn bad_input_is_an_error() {
        let d = driven(1);
        let ok = [OmniRun {
            x_err_m: -0.01,
            y_err_m: 0.002,
            theta_err_rad: None,
        }];
        let mk = |len, runs| {
            [PathRuns {
                length_m: len,
                direction_rad: 0.0,
                driven: &d,
                runs,
                held: &[],
            }]
        };
        assert_eq!(calibrate(&[], 4).unwrap_err(), OmniCalError::NoPaths);
        assert_eq!(
            calibrate(&mk(LEN, &[]), 4).unwrap_err(),
            OmniCalError::NoRuns { path: 1 }
        );
        assert_eq!(
            std::format!("{}", OmniCalError::NoRuns { path: 1 }),
            "path 1 has no runs; need at least 1"
        );
        for len in [0.0, -1.0, f64::NAN] {
            assert!(matches!(
                calibrate(&mk(len, &ok), 4),
                Err(OmniCalError::InvalidLength { path: 1, .. })
            ));
        }
        let nan = [OmniRun {
            x_err_m: f64::NAN,
            y_err_m: 0.0,
            theta_err_rad: None,
        }];
        assert_eq!(
            calibrate(&mk(LEN, &nan), 4).unwrap_err(),
            OmniCalError::NonFiniteRun { path: 1, run: 1 }
        );
        let nan_t = [
            ok[0],
            OmniRun {
                theta_err_rad: Some(f64::INFINITY),
                ..ok[0]
            },
        ];
        assert_eq!(
            calibrate(&mk(LEN, &nan_t), 4).unwrap_err(),
            OmniCalError::NonFiniteRun { path: 1, run: 2 }
        );
        // Ended exactly at the start: no arc.
        let stuck = [OmniRun {
            x_err_m: -LEN,
            y_err_m: 0.0,
            theta_err_rad: None,
        }];
        assert_eq!(
            calibrate(&mk(LEN, &stuck), 4).unwrap_err(),
            OmniCalError::ImpossibleRun { path: 1, run: 1 }
        );
        // Went backwards (sign convention swapped?): negative ratio.
        let back = [OmniRun {
            x_err_m: -1.5 * LEN,
            y_err_m: 0.0,
            theta_err_rad: Some(0.0),
        }];
        assert!(matches!(
            calibrate(&mk(LEN, &back), 4),
            Err(OmniCalError::NonPositiveRatio { .. })
        ));
        assert!(matches!(
            calibrate(&mk(LEN, &ok), 2),
            Err(OmniCalError::WheelIndexOutOfRange { .. })
        ));
        assert!(matches!(
            calibrate(&mk(LEN, &ok), 0),
            Err(OmniCalError::InvalidWheelCount { .. })
        ));
        assert!(matches!(
            calibrate(&mk(LEN, &ok), 9),
            Err(OmniCalError::InvalidWheelCount { .. })
        ));
        let dup = [d[0], d[0]];
        let p = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &dup,
            runs: &ok,
            held: &[],
        }];
        assert!(matches!(
            calibrate(&p, 4),
            Err(OmniCalError::DuplicateWheel { .. })
        ));
        let zero = [DrivenWheel {
            nominal_travel_m: 0.0,
            ..d[0]
        }];
        let p = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &zero,
            runs: &ok,
            held: &[],
        }];
        assert!(matches!(
            calibrate(&p, 4),
            Err(OmniCalError::ZeroNominalTravel { .. })
        ));
        let p = [PathRuns {
            length_m: LEN,
            direction_rad: 0.0,
            driven: &[],
            runs: &ok,
            held: &[],
        }];
        assert_eq!(
            calibrate(&p, 4).unwrap_err(),
            OmniCalError::NoDrivenWheels { path: 1 }
        );
        let five = [mk(LEN, &ok)[0]; 5];
        assert!(matches!(
            calibrate(&five, 4),
            Err(OmniCalError::TooManyPaths { .. })
        ));
    }
}
