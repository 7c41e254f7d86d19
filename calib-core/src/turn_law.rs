//! A differential drive's turn law in odometry: the effective separation grows from a
//! turn in place to an arc (wide tyres' turn slip, fitted by `wheelcal calibrate`), so
//! each tick's turn is divided by 1 + e_b_arc (1 - rho^2) at the tick's turn ratio rho
//! ([`crate::kinematics::turn_law_share`]). One encoder count makes a single tick's ratio
//! noisy, so the sides' travel is smoothed with a time constant of [`TURN_RATIO_TIME_S`]
//! (calibration smooths over the same 0.1 s either side).

use crate::kinematics::{turn_law_share, Twist};
use crate::robot::{Robot, MAX_WHEELS};
use num_traits::Float;

/// Time constant of the turn ratio's smoothing (s).
pub const TURN_RATIO_TIME_S: f64 = 0.1;

/// The law's state: e_b_arc, the wheels' weights in their side's mean travel, and the
/// smoothed travel of each side per tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurnLawOdometry<T> {
    e_b_arc: T,
    /// Per wheel: radius / wheels on its side, on the left (else 0) and on the right.
    left: [T; MAX_WHEELS],
    right: [T; MAX_WHEELS],
    /// Smoothing weight of one tick.
    k: T,
    smooth: (T, T),
}

impl<T: Float> TurnLawOdometry<T> {
    /// The law `e_b_arc` for `robot`'s wheels (nominal radii: rho is a ratio), ticking
    /// every `tick_s` seconds. A law of 0 leaves every twist unchanged.
    pub fn new(robot: &Robot, e_b_arc: f64, tick_s: f64) -> Self {
        let n = robot.wheels.len().min(MAX_WHEELS);
        let nl = robot.wheels.iter().filter(|w| w.is_left()).count().max(1) as f64;
        let nr = (n as f64 - nl).max(1.0);
        let (mut left, mut right) = ([T::zero(); MAX_WHEELS], [T::zero(); MAX_WHEELS]);
        for (i, w) in robot.wheels.iter().take(n).enumerate() {
            let c = |v: f64| T::from(v).unwrap_or_else(T::zero);
            if w.is_left() {
                left[i] = c(w.radius_m / nl);
            } else {
                right[i] = c(w.radius_m / nr);
            }
        }
        let k = tick_s / (TURN_RATIO_TIME_S + tick_s);
        TurnLawOdometry {
            e_b_arc: T::from(e_b_arc).unwrap_or_else(T::zero),
            left,
            right,
            k: T::from(k).unwrap_or_else(T::one),
            smooth: (T::zero(), T::zero()),
        }
    }

    /// The tick's body displacement `d` (from the kinematics at the turn-in-place E_b)
    /// with the law applied, given the tick's wheel rotations `dphi` (rad).
    pub fn apply(&mut self, dphi: &[T], d: Twist<T>) -> Twist<T> {
        if self.e_b_arc == T::zero() {
            return d;
        }
        let (mut l, mut r) = (T::zero(), T::zero());
        for (i, p) in dphi.iter().enumerate().take(MAX_WHEELS) {
            l = l + self.left[i] * *p;
            r = r + self.right[i] * *p;
        }
        let (sl, sr) = self.smooth;
        self.smooth = (sl + self.k * (l - sl), sr + self.k * (r - sr));
        let (sl, sr) = self.smooth;
        let den = sl.abs() + sr.abs();
        // Standing still: no turn to correct (rho is taken as a turn in place).
        let rho = if den > T::zero() {
            (sr - sl).abs() / den
        } else {
            T::one()
        };
        Twist {
            omega: d.omega / (T::one() + self.e_b_arc * turn_law_share(rho)),
            ..d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::presets;

    /// Steady motion at a constant ratio: a turn in place keeps its turn, an arc of turn
    /// ratio 0.2 loses 1 - 1 / (1 + 0.01 (1 - 0.04)) of it, once the smoothing has
    /// settled (after 2 s at 1 kHz, e^-20 of the start remains).
    #[test]
    fn a_law_divides_the_turn_by_its_share() {
        let robot = presets::mobolab();
        let il = robot.wheels.iter().position(|w| w.is_left()).unwrap();
        let ir = 1 - il;
        for (l, r, want) in [
            (-1e-3, 1e-3, 1.0),
            (0.8e-3, 1.2e-3, 1.0 / (1.0 + 0.01 * (1.0 - 0.04))),
        ] {
            let mut law = TurnLawOdometry::<f64>::new(&robot, 0.01, 1e-3);
            let mut dphi = [0.0; 2];
            dphi[il] = l / robot.wheels[il].radius_m;
            dphi[ir] = r / robot.wheels[ir].radius_m;
            let d = Twist::new(1.0, 0.0, 1.0);
            let mut out = d;
            for _ in 0..2000 {
                out = law.apply(&dphi, d);
            }
            assert!((out.omega - want).abs() < 1e-9, "{l} {r}: {}", out.omega);
            assert_eq!(out.vx, 1.0);
        }
        // No law: untouched.
        let mut none = TurnLawOdometry::<f32>::new(&robot, 0.0, 1e-3);
        let d = Twist::new(0.1f32, 0.0, 0.3);
        assert_eq!(none.apply(&[1e-3, 2e-3], d), d);
    }
}
