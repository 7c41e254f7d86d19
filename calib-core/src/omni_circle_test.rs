//! The omni circle test: an omni robot's turn in place and its turn law from circles
//! driven both ways and measured by hand, without motion capture.
//!
//! [Redundant omni]'s straight paths fix the wheels' sizes (F_lat, F_lon) but never turn,
//! so they leave the wheels' distance from the centre, which sets how far the robot turns
//! per wheel turn, as drawn; and on arcs the robot turns less per wheel turn than in
//! place (the turn law, [`crate::omni_laws`]: the wheels' distance `1 + l_arc (1 - rho^2)`
//! times that of a turn in place, rho = |omega| L / |v| clamped to 1). Circles of radius
//! R driven N laps with the factors in force show both: the board turns the wheels for
//! 2 pi N of odometric turn, and the robot turns G times that, where
//!
//! ```text
//! 1 / G(R) = (1 + l_arc s) / G_0,   s = 1 - min(1, L / R)^2
//! ```
//!
//! with L the board's mean wheel distance and G_0 the gain of a turn in place. A circle of
//! radius at most L (s = 0: a turn in place as far as the law goes, e.g. `run circle
//! --radius 0.01`) gives G_0 directly; wider ones give the law. 1 / G is linear in s, so
//! the radii's mean gains (both directions averaged, each weighted by its runs' spread)
//! give G_0 and l_arc by weighted least squares. The board then takes wheel distances
//! L / G_0 (its robot file, `robot set`) and `factors set --l-arc`. Each run's gain comes
//! from [`crate::circle_test::heading_gain`]: its measured heading error, or the end's x
//! for a clean circle; a circle under [`MIN_RADIUS_BY_END_M`] needs its heading measured.

use crate::circle_test::{exact_run, gains_each_way, radii_of, CircleError, CircleRun};
use crate::kinematics::{turn_law_share, turn_ratio};
use crate::motion::Direction;
use heapless::Vec;

pub use crate::circle_test::MAX_RADII;

/// Circles narrower than this need their heading measured: their end moves under 2 pi N
/// R per unit of gain, too little to read a turn from (at 1 cm and 2 laps, 0.13 mm per
/// 0.1 % of gain).
pub const MIN_RADIUS_BY_END_M: f64 = 0.1;

/// The least spread of the law's share (1 - rho^2) over the radii: below it the turn in
/// place and the law cannot be told apart.
pub const MIN_SHARE_SPREAD: f64 = 0.2;

/// An omni robot driving circles with the factors in force: the board's mean wheel
/// distance, the gain of a turn in place and the turn law. [`omni_turn_law`] inverts it;
/// tests and examples make exact runs with it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OmniCircleModel {
    /// The board's mean wheel distance from the centre L (m).
    pub wheel_distance_m: f64,
    /// The robot's turn in place over the odometry's.
    pub spin_gain: f64,
    /// The turn law.
    pub l_arc: f64,
}

impl OmniCircleModel {
    /// The heading gain of a circle of `radius_m`: G_0 / (1 + l_arc s).
    pub fn gain(&self, radius_m: f64) -> f64 {
        self.spin_gain / (1.0 + self.l_arc * share(radius_m, self.wheel_distance_m))
    }

    /// The exact run: where a circle rolled at that gain ends, and its heading error.
    pub fn run(&self, dir: Direction, radius_m: f64, laps: u8) -> CircleRun {
        exact_run(dir, radius_m, laps, self.gain(radius_m))
    }
}

/// The law's share on a circle of `radius_m` for a board whose wheels sit `wheel_distance_m`
/// from the centre: 1 - rho^2, rho = min(1, L / R).
pub fn share(radius_m: f64, wheel_distance_m: f64) -> f64 {
    turn_law_share(turn_ratio(radius_m, wheel_distance_m))
}

/// What the circles of one radius show.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct OmniRadius {
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
    /// The two directions' mean.
    pub gain: f64,
    /// Its standard error from the runs' spread.
    pub gain_sigma: f64,
    /// The law's share on this circle, 1 - rho^2 (0: a turn in place).
    pub share: f64,
}

/// The omni circle test's result.
#[derive(Debug, Clone, PartialEq)]
pub struct OmniCircleLaw {
    /// The robot's turn in place over the odometry's, with the factors in force.
    pub spin_gain: f64,
    /// Its standard error.
    pub spin_gain_sigma: f64,
    /// The turn law: the wheels' distance on arcs is 1 + l_arc (1 - rho^2) times that of
    /// a turn in place.
    pub l_arc: f64,
    /// Its standard error.
    pub sigma: f64,
    /// Per radius, in the order first given.
    pub radii: Vec<OmniRadius, MAX_RADII>,
}

impl OmniCircleLaw {
    /// Significant at 3 sigma and within what the board accepts
    /// ([`crate::correction::E_B_ARC_MAX`]).
    pub fn significant(&self) -> bool {
        libm::fabs(self.l_arc) >= 3.0 * self.sigma
            && libm::fabs(self.l_arc) <= crate::correction::E_B_ARC_MAX
    }
}

/// The turn in place and the turn law from circle runs of an omni robot whose board's
/// wheels sit `wheel_distance_m` (their mean) from the centre, measured with the factors
/// in force. Needs two runs or more each way at each radius, a radius whose share is at
/// least [`MIN_SHARE_SPREAD`] above another's (a turn in place, radius at most L, and a
/// circle of about 2 L or more), and a measured heading on circles under
/// [`MIN_RADIUS_BY_END_M`].
pub fn omni_turn_law(
    runs: &[CircleRun],
    wheel_distance_m: f64,
) -> Result<OmniCircleLaw, CircleError> {
    if !(wheel_distance_m.is_finite() && wheel_distance_m > 0.0) {
        return Err(CircleError::BadInput(
            "the wheels' distance from the centre must be positive",
        ));
    }
    if runs
        .iter()
        .any(|r| r.radius_m < MIN_RADIUS_BY_END_M && r.theta_err_rad.is_none())
    {
        return Err(CircleError::BadInput(
            "a circle under 0.1 m (a turn in place) shows its turn by its heading, not its end: measure its heading error",
        ));
    }
    let radii_given = radii_of(runs)?;
    let mut radii: Vec<OmniRadius, MAX_RADII> = Vec::new();
    // Weighted least squares of 1 / G = a + c s: sums of w, w s, w s^2, w y, w s y.
    let (mut sw, mut sx, mut sxx, mut sy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let mut all_exact = true;
    for &radius_m in &radii_given {
        let each = gains_each_way(runs, radius_m)?;
        let (g, sigma_g) = each.mean();
        all_exact &= sigma_g == 0.0;
        let s = share(radius_m, wheel_distance_m);
        let y = 1.0 / g;
        let sigma_y = sigma_g / (g * g);
        // A noiseless run set has no spread: weigh it as very precise, not infinitely.
        let w = 1.0 / f64::max(sigma_y * sigma_y, 1e-24);
        sw += w;
        sx += w * s;
        sxx += w * s * s;
        sy += w * y;
        sxy += w * s * y;
        let [(runs_cw, gain_cw, _), (runs_ccw, gain_ccw, _)] = each.0;
        let _ = radii.push(OmniRadius {
            radius_m,
            runs_cw,
            runs_ccw,
            gain_cw,
            gain_ccw,
            gain: g,
            gain_sigma: sigma_g,
            share: s,
        });
    }
    let shares = radii.iter().map(|r| r.share);
    let spread =
        shares.clone().fold(f64::NEG_INFINITY, f64::max) - shares.fold(f64::INFINITY, f64::min);
    if spread < MIN_SHARE_SPREAD {
        return Err(CircleError::BadInput(
            "the circles cannot tell the turn in place from the turn law: drive a turn in place (a circle of radius at most the wheels' distance from the centre, its heading measured) and circles of at least twice that distance",
        ));
    }
    let det = sw * sxx - sx * sx;
    let a = (sxx * sy - sx * sxy) / det;
    let c = (sw * sxy - sx * sy) / det;
    let (var_a, var_c, cov) = if all_exact {
        (0.0, 0.0, 0.0)
    } else {
        (sxx / det, sw / det, -sx / det)
    };
    let spin_gain = 1.0 / a;
    let l_arc = c / a;
    let spin_gain_sigma = libm::sqrt(var_a) / (a * a);
    // l = c / a: dl/dc = 1 / a, dl/da = -c / a^2.
    let var_l = var_c / (a * a) + c * c * var_a / (a * a * a * a) - 2.0 * c * cov / (a * a * a);
    let sigma = libm::sqrt(var_l.max(0.0));
    if !(spin_gain.is_finite() && l_arc.is_finite() && sigma.is_finite() && spin_gain > 0.0) {
        return Err(CircleError::BadInput(
            "the circles' numbers give no finite turn",
        ));
    }
    Ok(OmniCircleLaw {
        spin_gain,
        spin_gain_sigma,
        l_arc,
        sigma,
        radii,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use core::f64::consts::PI;

    /// The omni3 of `robots/omni3.toml`: wheels 0.15 m from the centre.
    const L: f64 = 0.15;

    fn model(spin_gain: f64, l_arc: f64) -> OmniCircleModel {
        OmniCircleModel {
            wheel_distance_m: L,
            spin_gain,
            l_arc,
        }
    }

    /// Two runs each way of each radius, exact; `by_end` drops the heading of circles
    /// that can be read by their end.
    fn runs(
        m: &OmniCircleModel,
        radii: &[f64],
        laps: u8,
        by_end: bool,
    ) -> std::vec::Vec<CircleRun> {
        let mut out = std::vec::Vec::new();
        for &r in radii {
            for dir in [Direction::Cw, Direction::Ccw] {
                let mut run = m.run(dir, r, laps);
                if by_end && r >= MIN_RADIUS_BY_END_M {
                    run.theta_err_rad = None;
                }
                out.extend([run, run]);
            }
        }
        out
    }

    /// A robot whose wheels sit 3 % further out than its board says (it turns 1 / 1.03 of
    /// the odometry in place) and whose arcs follow a 2 % law (the simulator's scrub on
    /// the omni3): both come back to rounding, from a turn in place (1 cm, its heading)
    /// and circles read by their heading or by their end alone, with one or three radii.
    #[test]
    fn exact_circles_give_back_the_turn_in_place_and_the_law() {
        for (g0, k) in [(1.0 / 1.03, 0.02), (1.0, 0.0), (1.02, -0.01)] {
            let m = model(g0, k);
            for (radii, laps) in [
                (&[0.01, 0.5][..], 2u8),
                (&[0.01, 0.3, 0.6], 1),
                (&[0.15, 1.0], 3),
            ] {
                for by_end in [false, true] {
                    let law = omni_turn_law(&runs(&m, radii, laps, by_end), L).unwrap();
                    assert!((law.spin_gain - g0).abs() < 1e-9, "{law:?}");
                    assert!((law.l_arc - k).abs() < 1e-9, "{law:?}");
                    assert_eq!((law.sigma, law.spin_gain_sigma), (0.0, 0.0));
                    assert_eq!(law.radii.len(), radii.len());
                    assert_eq!(law.radii[0].share, 0.0);
                }
            }
        }
    }

    /// The runs' spread sets the uncertainties: a heading read 0.01 rad apart on repeated
    /// 2-lap runs (about 0.8 mm of gain per lap) gives each radius a gain sigma of
    /// 0.01 / (4 pi) / sqrt(2) per direction, halved over the two directions' root sum;
    /// with one turn in place and one 0.5 m circle (share 0.91), sigma(l_arc) is
    /// sqrt(2) times that over 0.91, and the 2 % law stays significant.
    #[test]
    fn the_spread_of_the_runs_sets_the_uncertainty() {
        let m = model(1.0 / 1.03, 0.02);
        let mut rs = runs(&m, &[0.01, 0.5], 2, false);
        for (i, r) in rs.iter_mut().enumerate() {
            let d = if i % 2 == 0 { 0.005 } else { -0.005 };
            r.theta_err_rad = r.theta_err_rad.map(|t| t + d);
        }
        let law = omni_turn_law(&rs, L).unwrap();
        // Per direction: sd of (+-0.005) pairs is 0.00707 rad, its mean's 0.005 rad, over
        // 4 pi of turn; two directions: 0.5 sqrt(2) of that.
        let sigma_g = 0.5 * 2f64.sqrt() * 0.005 / (4.0 * PI);
        assert!((law.radii[0].gain_sigma - sigma_g).abs() < 1e-12, "{law:?}");
        // l = (y_1 / y_0 - 1) / s with y = 1 / G: dl/dy_1 = 1 / (s y_0), dl/dy_0 = -(1 +
        // l s) / (s y_0), sigma(y) = sigma(G) / G^2.
        let (s, g0, g1) = (share(0.5, L), m.gain(0.01), m.gain(0.5));
        let (sy0, sy1) = (sigma_g / (g0 * g0), sigma_g / (g1 * g1));
        let expected = (sy1 * sy1 + (1.0 + 0.02 * s).powi(2) * sy0 * sy0).sqrt() * g0 / s;
        assert!(
            (law.sigma - expected).abs() < 0.05 * expected,
            "{} against {expected}",
            law.sigma
        );
        assert!((law.l_arc - 0.02).abs() < 1e-6, "{law:?}");
        assert!(law.significant());
    }

    /// What cannot be computed is refused with what to fix: one radius, two circles with
    /// nearly the same share, a turn in place without its heading, a wheel distance that
    /// is not positive, a single run one way.
    #[test]
    fn circles_that_cannot_tell_are_refused_with_what_to_fix() {
        let m = model(1.0, 0.02);
        let said = |rs: &[CircleRun], l: f64, what: &str| {
            let e = format!("{}", omni_turn_law(rs, l).unwrap_err());
            assert!(e.contains(what), "{e}");
        };
        said(
            &runs(&m, &[0.5], 2, false),
            L,
            "cannot tell the turn in place",
        );
        said(
            &runs(&m, &[0.5, 0.7], 2, false),
            L,
            "cannot tell the turn in place",
        );
        let mut rs = runs(&m, &[0.01, 0.5], 2, false);
        rs[0].theta_err_rad = None;
        said(&rs, L, "measure its heading error");
        said(&runs(&m, &[0.01, 0.5], 2, false), 0.0, "must be positive");
        let rs = runs(&m, &[0.01, 0.5], 2, false);
        said(&rs[1..], L, "1 cw run(s)");
    }

    proptest::proptest! {
        /// Any numbers at all, for a turn in place and a circle: an answer with finite
        /// numbers, or an error; never a panic.
        #[test]
        fn any_numbers_give_an_answer_or_an_error(
            x in proptest::num::f64::ANY,
            th in proptest::option::of(proptest::num::f64::ANY),
            spin_th in proptest::num::f64::ANY,
            radius in proptest::num::f64::ANY,
            laps in 0u8..=255,
            l in proptest::num::f64::ANY,
        ) {
            let run = |dir, r: f64, t: Option<f64>, d: f64| CircleRun {
                dir, radius_m: r, laps, x_err_m: x + d, y_err_m: 0.0, theta_err_rad: t.map(|t| t + d),
            };
            let mut runs = std::vec::Vec::new();
            for dir in [Direction::Cw, Direction::Ccw] {
                runs.extend([run(dir, 0.01, Some(spin_th), 0.0), run(dir, 0.01, Some(spin_th), 1e-3)]);
                runs.extend([run(dir, radius, th, 0.0), run(dir, radius, th, -1e-3)]);
            }
            if let Ok(law) = omni_turn_law(&runs, l) {
                proptest::prop_assert!(
                    law.l_arc.is_finite() && law.sigma.is_finite() && law.spin_gain > 0.0 && law.spin_gain_sigma.is_finite(),
                    "{law:?}"
                );
            }
        }
    }
}
