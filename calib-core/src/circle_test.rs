//! The circle test: a differential drive's turn law from circles driven both ways and
//! measured by hand, as UMBmark measures squares.
//!
//! UMBmark's squares turn only in place, so they fix the wheelbase of a turn in place
//! (E_b). Wide tyres scrub less on an arc, so the effective separation there is wider
//! (the turn law, [`crate::diff_laws`]: E_b (1 + e_b_arc (1 - rho^2))). A circle of radius
//! R driven N times with the factors the squares were measured with shows it without
//! motion capture: the board turns the wheels for 2 pi N of odometric turn, and the robot
//! turns G times that, where (for a right wheel e larger than the left, relative)
//!
//! ```text
//! G_ccw = (1 + e R / b) / (E_b (1 + e_b_arc s)),   G_cw = (1 - e R / b) / (E_b (1 + e_b_arc s))
//! ```
//!
//! with b the nominal separation and s = 1 - rho^2, rho = E_b b / (2 R) the turn ratio the
//! board sees on that circle. The mean of the two directions gives the law, their
//! difference the diameter ratio again (a check on the squares' E_d). The path is a
//! circle of radius R / G, so it ends at x = (R / G) sin(2 pi N (G - 1)) along the start
//! heading: stopping short of the start (x < 0) is turning too little. A measured heading
//! error gives G directly, whatever the path's shape; without one, the end's x does,
//! assuming the robot rolled a clean circle from the start (the board's `run circle`
//! does).

use crate::motion::Direction;
use crate::stats;
use core::f64::consts::PI;
use core::fmt;
use heapless::Vec;

/// Radii one computation can hold (each needs its own cw and ccw runs).
pub const MAX_RADII: usize = 8;

/// The largest turn error a run's end position can be read back from (rad): beyond it the
/// end is no longer a single-valued function of the turn.
pub const MAX_TURN_ERROR_RAD: f64 = 1.2;

/// The largest radius taken (m): a circle is driven in a room.
pub const MAX_RADIUS_M: f64 = 1000.0;

/// One circle measured by hand: its end error, measured minus odometry, in the start
/// frame (x along the start heading, y to its left).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleRun {
    /// The way it was driven.
    pub dir: Direction,
    /// Commanded radius (m).
    pub radius_m: f64,
    /// Commanded laps.
    pub laps: u8,
    /// End error along the start heading (m).
    pub x_err_m: f64,
    /// End error to the left of the start heading (m).
    pub y_err_m: f64,
    /// End heading error (rad), when measured: it gives the turn directly.
    pub theta_err_rad: Option<f64>,
}

/// Why the circle test could not be computed; the message says what to fix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CircleError {
    /// A radius without at least two runs in one direction.
    TooFewRuns {
        /// The radius concerned (m).
        radius_m: f64,
        /// The direction short of runs.
        dir: Direction,
        /// Runs given in that direction.
        got: usize,
    },
    /// A circle no wider than half the wheelbase: a wheel stops or runs backwards.
    TooTight {
        /// The radius (m).
        radius_m: f64,
        /// Half the effective wheelbase (m).
        half_track_m: f64,
    },
    /// A run's end (or heading) says it turned more than [`MAX_TURN_ERROR_RAD`] off its
    /// laps: too far to be read as a turn error.
    TooFar {
        /// The radius (m).
        radius_m: f64,
        /// The run's x error (m).
        x_err_m: f64,
        /// The run's y error (m).
        y_err_m: f64,
    },
    /// A number that is not finite, a radius or separation not positive, or no laps.
    BadInput(&'static str),
    /// More radii than [`MAX_RADII`].
    TooManyRadii,
}

impl fmt::Display for CircleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CircleError::TooFewRuns { radius_m, dir, got } => write!(
                f,
                "the circles of radius {radius_m} m have {got} {} run(s): the circle test needs at least 2 runs in each direction at each radius",
                dir.as_str()
            ),
            CircleError::TooTight {
                radius_m,
                half_track_m,
            } => write!(
                f,
                "a circle of radius {radius_m} m is not wider than half the wheelbase ({half_track_m:.4} m): one wheel would stand or run backwards; drive circles of at least twice that"
            ),
            CircleError::TooFar {
                radius_m,
                x_err_m,
                y_err_m,
            } => write!(
                f,
                "a circle of radius {radius_m} m that ends ({x_err_m}, {y_err_m}) m from where odometry says turned more than {MAX_TURN_ERROR_RAD} rad off its laps: check the run (measured minus odometry, metres, the direction driven), or drive fewer laps"
            ),
            CircleError::BadInput(what) => write!(f, "{what}"),
            CircleError::TooManyRadii => write!(
                f,
                "more than {MAX_RADII} radii: compute them in groups"
            ),
        }
    }
}

impl core::error::Error for CircleError {}

/// +1 for ccw, -1 for cw.
fn sign(d: Direction) -> f64 {
    match d {
        Direction::Ccw => 1.0,
        Direction::Cw => -1.0,
    }
}

/// Where a circle of radius `radius_m` driven `laps` times ends along its start heading
/// when the robot turns `gain` times the odometry's turn (m, relative to the start).
pub fn end_x(radius_m: f64, laps: u8, gain: f64) -> f64 {
    let turns = 2.0 * PI * f64::from(laps);
    radius_m / gain * libm::sin(turns * (gain - 1.0))
}

/// The module's model of a robot driving circles with the factors its squares were
/// measured with: its nominal wheelbase, its in-place E_b relative to those factors,
/// the turn law and the right wheel's size over the left's. [`turn_law`] inverts it;
/// tests and examples make exact runs with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CircleModel {
    /// Nominal wheelbase b (m).
    pub separation_m: f64,
    /// Wheelbase of a turn in place over the factors' (UMBmark's E_b).
    pub e_b: f64,
    /// The turn law.
    pub e_b_arc: f64,
    /// Right wheel's size over the left's (UMBmark's E_d).
    pub e_d: f64,
}

impl CircleModel {
    /// The heading gain of a circle of `radius_m` driven `dir`: (1 ± e R / b) / (E_b (1 +
    /// e_b_arc s)), e = E_d - 1, s the law's share at rho = E_b b / 2R.
    pub fn gain(&self, dir: Direction, radius_m: f64) -> f64 {
        let b = self.separation_m;
        let s = crate::kinematics::turn_law_share(self.e_b * b / 2.0 / radius_m);
        (1.0 + sign(dir) * (self.e_d - 1.0) * radius_m / b) / (self.e_b * (1.0 + self.e_b_arc * s))
    }

    /// The exact run: where a circle rolled at that gain ends, and its heading error.
    pub fn run(&self, dir: Direction, radius_m: f64, laps: u8) -> CircleRun {
        exact_run(dir, radius_m, laps, self.gain(dir, radius_m))
    }
}

/// A circle of `radius_m` driven `laps` times `dir` by odometry, the robot turning `gain`
/// times that: it rolls a clean circle of radius R / gain, and ends (x, y, heading) off
/// the odometry's end, measured minus odometry.
pub fn exact_run(dir: Direction, radius_m: f64, laps: u8, gain: f64) -> CircleRun {
    let u = 2.0 * PI * f64::from(laps) * (gain - 1.0);
    CircleRun {
        dir,
        radius_m,
        laps,
        x_err_m: end_x(radius_m, laps, gain),
        y_err_m: sign(dir) * radius_m / gain * (1.0 - libm::cos(u)),
        theta_err_rad: Some(sign(dir) * u),
    }
}

/// The heading gain of one run: the robot's turn over the odometry's. From the heading
/// error when measured, else from the end's x (bisection on the turn error, where
/// [`end_x`] is monotonic).
pub fn heading_gain(run: &CircleRun) -> Result<f64, CircleError> {
    let CircleRun {
        radius_m,
        laps,
        x_err_m: x,
        y_err_m: y,
        ..
    } = *run;
    if !(radius_m.is_finite() && radius_m > 0.0 && radius_m <= MAX_RADIUS_M) {
        return Err(CircleError::BadInput(
            "a circle's radius must be positive and at most 1 km",
        ));
    }
    if laps == 0 || laps > crate::protocol::MAX_LAPS {
        return Err(CircleError::BadInput("a circle has 1 to 10 laps"));
    }
    if !(x.is_finite() && y.is_finite()) {
        return Err(CircleError::BadInput("an end error is not finite"));
    }
    let too_far = CircleError::TooFar {
        radius_m,
        x_err_m: x,
        y_err_m: y,
    };
    let turns = 2.0 * PI * f64::from(laps);
    if let Some(th) = run.theta_err_rad {
        if !th.is_finite() {
            return Err(CircleError::BadInput("a heading error is not finite"));
        }
        if libm::fabs(th) > MAX_TURN_ERROR_RAD {
            return Err(too_far);
        }
        return Ok(1.0 + sign(run.dir) * th / turns);
    }
    let at = |u: f64| end_x(radius_m, laps, 1.0 + u / turns);
    let (mut lo, mut hi) = (-MAX_TURN_ERROR_RAD, MAX_TURN_ERROR_RAD);
    if !(at(lo) <= x && x <= at(hi)) {
        return Err(too_far);
    }
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if at(mid) < x {
            lo = mid;
        } else {
            hi = mid;
        }
        if hi - lo <= 1e-15 {
            break;
        }
    }
    let u = 0.5 * (lo + hi);
    let gain = 1.0 + u / turns;
    // The end's x alone cannot tell a turn error u from pi - u; the end's place can: a
    // circle rolled u off its laps ends on a chord at angle u / 2 to its start heading,
    // so 2 atan2(y, x) (y towards the turn) is u to within whole laps, whatever the
    // radius. Once the end is far enough for that angle to mean something (a chord of
    // over half the radius: |u| >= 1.2 rad puts it beyond 0.87 R), it must agree.
    let y_turn = sign(run.dir) * y;
    if libm::hypot(x, y) > 0.5 * radius_m {
        let mut u_end = 2.0 * libm::atan2(y_turn, x);
        if u_end > PI {
            u_end -= 2.0 * PI;
        } else if u_end < -PI {
            u_end += 2.0 * PI;
        }
        if libm::fabs(u_end) > MAX_TURN_ERROR_RAD {
            return Err(too_far);
        }
    }
    Ok(gain)
}

/// What the circles of one radius show.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct RadiusLaw {
    /// The radius (m).
    pub radius_m: f64,
    /// Runs clockwise.
    pub runs_cw: usize,
    /// Runs counter-clockwise.
    pub runs_ccw: usize,
    /// Mean heading gain clockwise (robot's turn over the odometry's).
    pub gain_cw: f64,
    /// Mean heading gain counter-clockwise.
    pub gain_ccw: f64,
    /// The turn ratio's share of the law on this circle, 1 - rho^2.
    pub share: f64,
    /// The law these circles alone give.
    pub e_b_arc: f64,
    /// Its standard error from the runs' spread (the squares' E_b not counted).
    pub sigma: f64,
    /// The right wheel's size over the left's that these circles show, relative to the
    /// factors in force (as UMBmark's E_d).
    pub e_d: f64,
}

/// The circle test's result.
#[derive(Debug, Clone, PartialEq)]
pub struct CircleLaw {
    /// The turn law: the effective wheelbase on arcs is 1 + e_b_arc times the squares'.
    pub e_b_arc: f64,
    /// Its standard error: the runs' spread and the squares' E_b uncertainty.
    pub sigma: f64,
    /// Per radius, in the order first given.
    pub radii: Vec<RadiusLaw, MAX_RADII>,
}

impl CircleLaw {
    /// Significant at 3 sigma and within what the board accepts
    /// ([`crate::correction::E_B_ARC_MAX`]).
    pub fn significant(&self) -> bool {
        libm::fabs(self.e_b_arc) >= 3.0 * self.sigma
            && libm::fabs(self.e_b_arc) <= crate::correction::E_B_ARC_MAX
    }

    /// With two radii or more, the largest distance of one radius's law from the
    /// combined law, in that radius's sigmas: the law's shape (1 - rho^2, which sets how
    /// much of it each circle shows) holds when it is at most 3. None with one radius.
    pub fn shape_misfit(&self) -> Option<f64> {
        (self.radii.len() >= 2).then(|| {
            self.radii
                .iter()
                .map(|r| libm::fabs(r.e_b_arc - self.e_b_arc) / f64::max(r.sigma, 1e-9))
                .fold(0.0, f64::max)
        })
    }
}

/// The turn law from circle runs measured with the factors UMBmark's squares were
/// measured with, given the squares' `e_b` (and its standard error `e_b_sigma`) and the
/// robot's nominal `separation_m`. Each radius needs two runs or more each way; radii are
/// combined by their runs' spread.
pub fn turn_law(
    runs: &[CircleRun],
    e_b: f64,
    e_b_sigma: f64,
    separation_m: f64,
) -> Result<CircleLaw, CircleError> {
    use crate::correction::{FACTOR_MAX, FACTOR_MIN};
    if !((FACTOR_MIN..=FACTOR_MAX).contains(&e_b) && separation_m.is_finite() && separation_m > 0.0)
    {
        return Err(CircleError::BadInput(
            "E_b must be within [0.5, 2] and the wheelbase positive",
        ));
    }
    if !(e_b_sigma.is_finite() && e_b_sigma >= 0.0) {
        return Err(CircleError::BadInput("E_b's uncertainty must be finite"));
    }
    let radii = radii_of(runs)?;
    let mut out: Vec<RadiusLaw, MAX_RADII> = Vec::new();
    // Weighted sums for the combined law and its slope in E_b.
    let (mut sw, mut swk, mut swd) = (0.0, 0.0, 0.0);
    for &radius_m in &radii {
        let half_track_m = e_b * separation_m / 2.0;
        if radius_m <= half_track_m {
            return Err(CircleError::TooTight {
                radius_m,
                half_track_m,
            });
        }
        let each = gains_each_way(runs, radius_m)?;
        let [(_, g_cw, _), (_, g_ccw, _)] = each.0;
        let (g, sigma_g) = each.mean();
        let rho = half_track_m / radius_m;
        let share = crate::kinematics::turn_law_share(rho);
        let e_b_arc = (1.0 / (g * e_b) - 1.0) / share;
        let sigma = sigma_g / (g * g * e_b * share);
        let e_d = 1.0 + separation_m / radius_m * (g_ccw - g_cw) / (g_ccw + g_cw);
        // A noiseless run set has no spread: weigh it as very precise, not infinitely.
        let w = 1.0 / f64::max(sigma * sigma, 1e-24);
        sw += w;
        swk += w * e_b_arc;
        swd += w * (-1.0 / (g * e_b * e_b * share));
        let _ = out.push(RadiusLaw {
            radius_m,
            runs_cw: each.0[0].0,
            runs_ccw: each.0[1].0,
            gain_cw: g_cw,
            gain_ccw: g_ccw,
            share,
            e_b_arc,
            sigma,
            e_d,
        });
    }
    let e_b_arc = swk / sw;
    let from_runs = if out.iter().all(|r| r.sigma == 0.0) {
        0.0
    } else {
        1.0 / sw
    };
    let from_e_b = swd / sw * e_b_sigma;
    let sigma = libm::sqrt(from_runs + from_e_b * from_e_b);
    if !(e_b_arc.is_finite() && sigma.is_finite()) {
        return Err(CircleError::BadInput(
            "the circles' numbers give no finite law",
        ));
    }
    Ok(CircleLaw {
        e_b_arc,
        sigma,
        radii: out,
    })
}

/// The radii of `runs`, in the order first given, each run's heading gain checked.
pub(crate) fn radii_of(runs: &[CircleRun]) -> Result<Vec<f64, MAX_RADII>, CircleError> {
    let mut radii: Vec<f64, MAX_RADII> = Vec::new();
    for r in runs {
        heading_gain(r)?;
        if !radii
            .iter()
            .any(|&q| libm::fabs(q - r.radius_m) <= 1e-9 * q)
        {
            radii
                .push(r.radius_m)
                .map_err(|_| CircleError::TooManyRadii)?;
        }
    }
    if radii.is_empty() {
        return Err(CircleError::BadInput("no circle runs"));
    }
    Ok(radii)
}

/// The heading gains of one radius's runs, clockwise and counter-clockwise: (runs, mean,
/// standard error of the mean) each.
pub(crate) struct EachWay(pub [(usize, f64, f64); 2]);

impl EachWay {
    /// The mean of the two directions' gains and its standard error.
    pub(crate) fn mean(&self) -> (f64, f64) {
        let [(_, g_cw, se_cw), (_, g_ccw, se_ccw)] = self.0;
        (
            0.5 * (g_cw + g_ccw),
            0.5 * libm::sqrt(se_cw * se_cw + se_ccw * se_ccw),
        )
    }
}

/// [`EachWay`] of the runs of `radius_m`; two runs or more each way.
pub(crate) fn gains_each_way(runs: &[CircleRun], radius_m: f64) -> Result<EachWay, CircleError> {
    // Per direction (cw, ccw): runs, mean gain and sum of squared deviations (Welford's
    // running form: no cap on the runs, no storage).
    let mut acc = [(0usize, 0.0f64, 0.0f64); 2];
    for r in runs
        .iter()
        .filter(|r| libm::fabs(r.radius_m - radius_m) <= 1e-9 * radius_m)
    {
        let (n, mean, m2) = &mut acc[usize::from(r.dir == Direction::Ccw)];
        let g = heading_gain(r)?;
        *n += 1;
        let d = g - *mean;
        *mean += d / *n as f64;
        *m2 += d * (g - *mean);
    }
    let mut stat = [(0, 0.0, 0.0); 2];
    for (k, dir) in [Direction::Cw, Direction::Ccw].into_iter().enumerate() {
        let (got, mean, m2) = acc[k];
        if got < 2 {
            return Err(CircleError::TooFewRuns { radius_m, dir, got });
        }
        let sd = libm::sqrt(m2 / (got - 1) as f64);
        stat[k] = (got, mean, sd / libm::sqrt(got as f64));
    }
    Ok(EachWay(stat))
}

/// E_b's standard error from UMBmark's squares: the two directions' x centroids give
/// alpha = -(x_cw + x_ccw) / (4 L) and E_b = 1 / (1 - 2 alpha / pi) (first order), so
/// sigma(E_b) = E_b^2 sqrt(se_x_cw^2 + se_x_ccw^2) / (2 pi L), the standard errors those
/// of the centroids' x.
pub fn umbmark_e_b_sigma(cw_x_m: &[f64], ccw_x_m: &[f64], side_m: f64, e_b: f64) -> Option<f64> {
    let se = |xs: &[f64]| -> Option<f64> {
        Some(stats::sample_std_dev(xs).ok()? / libm::sqrt(xs.len() as f64))
    };
    let (a, b) = (se(cw_x_m)?, se(ccw_x_m)?);
    (side_m > 0.0).then(|| e_b * e_b * libm::sqrt(a * a + b * b) / (2.0 * PI * side_m))
}

#[cfg(test)]
mod tests {
    use super::*;

    const B: f64 = 0.2;

    /// The exact run of a robot with turn law `k`, diameter ratio `1 + e` and in-place
    /// wheelbase `e_b` ([`CircleModel`]).
    fn run(dir: Direction, radius_m: f64, laps: u8, k: f64, e: f64, e_b: f64) -> CircleRun {
        let model = CircleModel {
            separation_m: B,
            e_b,
            e_b_arc: k,
            e_d: 1.0 + e,
        };
        model.run(dir, radius_m, laps)
    }

    fn both_ways(radius_m: f64, laps: u8, k: f64, e: f64, e_b: f64) -> [CircleRun; 4] {
        let cw = run(Direction::Cw, radius_m, laps, k, e, e_b);
        let ccw = run(Direction::Ccw, radius_m, laps, k, e, e_b);
        [cw, cw, ccw, ccw]
    }

    #[test]
    fn exact_circles_give_back_the_law_and_the_diameter_ratio() {
        // A 4 % law (the simulator's scrub), wheels 0.2 % apart, an in-place E_b 1 % wide:
        // the model is exact, so the law comes back to rounding, from the end's x alone and
        // from the heading alone.
        for laps in [1u8, 2, 3] {
            for (k, e, e_b) in [(0.04, 0.002, 1.01), (0.005, -0.001, 1.0), (0.0, 0.0, 0.99)] {
                let runs = both_ways(0.5, laps, k, e, e_b);
                let from_x: [CircleRun; 4] = runs.map(|r| CircleRun {
                    theta_err_rad: None,
                    ..r
                });
                for (what, rs) in [("heading", &runs), ("x", &from_x)] {
                    let law = turn_law(rs, e_b, 0.0, B).unwrap();
                    assert!(
                        (law.e_b_arc - k).abs() < 1e-9,
                        "{what}, {laps} laps: {} against {k}",
                        law.e_b_arc
                    );
                    assert!((law.radii[0].e_d - (1.0 + e)).abs() < 1e-9, "{what}: e_d");
                    assert_eq!(law.sigma, 0.0);
                }
            }
        }
    }

    #[test]
    fn stopping_short_is_turning_too_little() {
        // A robot that turns 1 % too little on one 0.5 m lap stops 2 pi x 0.5 x 0.01 =
        // 31.4 mm short (first order; exact: R/G sin(-2 pi 0.01)).
        let x = end_x(0.5, 1, 0.99);
        assert!((x + 0.0317).abs() < 2e-4, "{x}");
        let g = heading_gain(&CircleRun {
            dir: Direction::Cw,
            radius_m: 0.5,
            laps: 1,
            x_err_m: x,
            y_err_m: 0.0,
            theta_err_rad: None,
        })
        .unwrap();
        assert!((g - 0.99).abs() < 1e-12, "{g}");
    }

    #[test]
    fn the_spread_of_the_runs_sets_the_uncertainty() {
        // Heading errors of +-d around the exact ones: each direction's mean stays exact;
        // two runs at +-d have a sample sd of d sqrt(2), a standard error of d, so each
        // direction's gain has d / (2 pi N), their mean sigma_g = d / (2 pi N) / sqrt(2),
        // and the law sigma_g / (g^2 E_b s).
        let (k, d) = (0.01, 0.004);
        let mut runs = both_ways(0.4, 2, k, 0.0, 1.0);
        for (i, r) in runs.iter_mut().enumerate() {
            let th = r.theta_err_rad.unwrap();
            r.theta_err_rad = Some(th + if i % 2 == 0 { d } else { -d });
        }
        let law = turn_law(&runs, 1.0, 0.0, B).unwrap();
        let s = crate::kinematics::turn_law_share(0.1 / 0.4);
        let g = 1.0 / (1.0 + k * s);
        let want = d / (4.0 * PI) / 2f64.sqrt() / (g * g * s);
        assert!((law.e_b_arc - k).abs() < 1e-12);
        assert!(
            (law.sigma - want).abs() < 1e-9 * want,
            "{} {want}",
            law.sigma
        );
        // The squares' E_b uncertainty adds: 0.001 on E_b is about 0.001 / s on the law.
        let with_e_b = turn_law(&runs, 1.0, 0.001, B).unwrap();
        let from_e_b = 0.001 / (g * s);
        let both = (want * want + from_e_b * from_e_b).sqrt();
        assert!((with_e_b.sigma - both).abs() < 1e-9, "{}", with_e_b.sigma);
    }

    #[test]
    fn two_radii_combine_and_each_is_reported() {
        let mut runs = std::vec::Vec::new();
        runs.extend(both_ways(0.3, 2, 0.02, 0.001, 1.0));
        runs.extend(both_ways(0.8, 1, 0.02, 0.001, 1.0));
        let law = turn_law(&runs, 1.0, 0.0, B).unwrap();
        assert_eq!(law.radii.len(), 2);
        assert!((law.e_b_arc - 0.02).abs() < 1e-9);
        // The share is larger on the wider circle: 1 - (0.1/0.3)^2 against 1 - (0.1/0.8)^2.
        assert!((law.radii[0].share - (1.0 - 1.0 / 9.0)).abs() < 1e-12);
        assert!((law.radii[1].share - (1.0 - 1.0 / 64.0)).abs() < 1e-12);
        assert!(law.significant());
        // Noiseless, one law: the radii agree exactly. A robot whose arcs widen by 2 % on
        // the tight circle and 4 % on the wide one does not follow 1 - rho^2: with a
        // spread of 0.002 rad on each run's heading (sigma about 1.6e-4 a radius) the two
        // are over 3 sigmas from their mean.
        assert!(
            law.shape_misfit().unwrap() < 1e-3,
            "{:?}",
            law.shape_misfit()
        );
        let mut runs = std::vec::Vec::new();
        runs.extend(both_ways(0.3, 2, 0.02, 0.0, 1.0));
        runs.extend(both_ways(0.8, 2, 0.04, 0.0, 1.0));
        for (i, r) in runs.iter_mut().enumerate() {
            let th = r.theta_err_rad.unwrap();
            r.theta_err_rad = Some(th + if i % 2 == 0 { 0.002 } else { -0.002 });
        }
        let law = turn_law(&runs, 1.0, 0.0, B).unwrap();
        assert!(law.shape_misfit().unwrap() > 3.0, "{law:?}");
        assert_eq!(
            turn_law(&runs[..4], 1.0, 0.0, B).unwrap().shape_misfit(),
            None
        );
    }

    #[test]
    fn bad_runs_are_refused_with_what_to_fix() {
        let runs = both_ways(0.5, 1, 0.01, 0.0, 1.0);
        let one_way = [runs[0], runs[1], runs[2]];
        match turn_law(&one_way, 1.0, 0.0, B) {
            Err(CircleError::TooFewRuns { dir, got: 1, .. }) => assert_eq!(dir, Direction::Ccw),
            other => panic!("{other:?}"),
        }
        let tight = both_ways(0.1, 1, 0.0, 0.0, 1.0);
        assert!(matches!(
            turn_law(&tight, 1.0, 0.0, B),
            Err(CircleError::TooTight { .. })
        ));
        let mut far = runs;
        far[0].theta_err_rad = None;
        far[0].x_err_m = 0.6;
        assert!(matches!(
            turn_law(&far, 1.0, 0.0, B),
            Err(CircleError::TooFar { .. })
        ));
        let mut nan = runs;
        nan[3].theta_err_rad = Some(f64::NAN);
        assert!(matches!(
            turn_law(&nan, 1.0, 0.0, B),
            Err(CircleError::BadInput(_))
        ));
        assert!(turn_law(&runs, f64::NAN, 0.0, B).is_err());
        assert!(turn_law(&runs, 1.0, 0.0, 0.0).is_err());
        let msg = format!(
            "{}",
            CircleError::TooTight {
                radius_m: 0.1,
                half_track_m: 0.1
            }
        );
        assert!(msg.contains("0.1 m"), "{msg}");
    }

    #[test]
    fn e_b_sigma_follows_the_squares_spread() {
        // Centroid standard errors of 3 mm each on 4 m squares: 1 x sqrt(2) x 0.003 /
        // (2 pi 4) = 1.69e-4.
        let cw = [0.003, -0.003];
        let ccw = [0.003, -0.003];
        // Two runs at +-3 mm: sd 3 sqrt(2) mm, standard error 3 mm.
        let s = umbmark_e_b_sigma(&cw, &ccw, 4.0, 1.0).unwrap();
        assert!((s - 2f64.sqrt() * 0.003 / (8.0 * PI)).abs() < 1e-12, "{s}");
        assert!(umbmark_e_b_sigma(&[0.0], &ccw, 4.0, 1.0).is_none());
    }

    proptest::proptest! {
        /// The law comes back from exact ends for any law, diameter ratio, in-place E_b,
        /// radius and laps (1e-8: the bisection's and the model's rounding), as long as
        /// each run turned at most MAX_TURN_ERROR_RAD off its laps; a run further off (but
        /// not a whole lap off, which no end can show) is refused, never misread.
        #[test]
        fn any_law_comes_back_from_its_ends_or_is_refused(
            k in -0.09f64..0.09,
            e in -0.01f64..0.01,
            e_b in 0.95f64..1.05,
            radius in 0.3f64..3.0,
            laps in 1u8..=4,
        ) {
            let runs = both_ways(radius, laps, k, e, e_b).map(|r| CircleRun {
                theta_err_rad: None,
                ..r
            });
            let turn_off = |d: Direction| libm::fabs(run(d, radius, laps, k, e, e_b).theta_err_rad.unwrap());
            let worst = f64::max(turn_off(Direction::Cw), turn_off(Direction::Ccw));
            let result = turn_law(&runs, e_b, 0.0, B);
            if worst <= MAX_TURN_ERROR_RAD {
                let law = result.unwrap();
                proptest::prop_assert!((law.e_b_arc - k).abs() < 1e-8, "{} against {k}", law.e_b_arc);
            } else if worst < 2.0 * PI - MAX_TURN_ERROR_RAD {
                proptest::prop_assert!(matches!(result, Err(CircleError::TooFar { .. })), "{worst} rad off: {result:?}");
            }
        }

        /// Any numbers at all: an answer with finite numbers, or an error; never a panic.
        #[test]
        fn any_numbers_give_an_answer_or_an_error(
            x in proptest::num::f64::ANY,
            y in proptest::num::f64::ANY,
            th in proptest::option::of(proptest::num::f64::ANY),
            radius in proptest::num::f64::ANY,
            laps in 0u8..=255,
            e_b in proptest::num::f64::ANY,
        ) {
            let run = |dir, dx: f64| CircleRun { dir, radius_m: radius, laps, x_err_m: x + dx, y_err_m: y, theta_err_rad: th };
            let runs = [run(Direction::Cw, 0.0), run(Direction::Cw, 1e-3), run(Direction::Ccw, 0.0), run(Direction::Ccw, -1e-3)];
            if let Ok(law) = turn_law(&runs, e_b, 0.0, B) {
                proptest::prop_assert!(law.e_b_arc.is_finite() && law.sigma.is_finite(), "{law:?}");
            }
        }
    }
}
