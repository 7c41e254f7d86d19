//! An omni robot's turn law in odometry ([`Corrections::OmniTurnLaw`]), applied tick by
//! tick: the wheels' effective distance from the centre is longer on arcs than in a turn
//! in place (the contact moving across the rollers), so each tick's turn is divided by
//! 1 + l_arc (1 - rho^2) at the tick's turn ratio rho ([`turn_ratio`] of the body's speed
//! and its turn times the wheels' mean distance L from the centre;
//! [`turn_law_share`]).
//!
//! The twist's (vx, vy, omega L) are smoothed with a time constant of
//! [`TURN_RATIO_TIME_S`] before rho is taken, as the simulator does and as the
//! differential drive's law does ([`crate::diff_laws`]): one encoder count makes a single
//! tick's ratio noisy.

use crate::correction::Corrections;
use crate::diff_laws::TURN_RATIO_TIME_S;
use crate::kinematics::{turn_law_share, turn_ratio, Twist};
use crate::robot::Robot;
use num_traits::Float;

/// The turn law's state: l_arc, the lever L and the smoothed (vx, vy, omega L) per tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OmniLawOdometry<T> {
    l_arc: T,
    /// A law at all (else every twist passes unchanged, to the bit).
    active: bool,
    /// The wheels' mean distance from the centre (m, nominal).
    lever: T,
    /// Smoothing weight of one tick.
    k: T,
    /// Smoothed vx, vy (m per tick) and omega L (m per tick).
    smooth: [T; 3],
}

fn cast<T: Float>(v: f64) -> T {
    T::from(v).unwrap_or_else(T::zero)
}

impl<T: Float> OmniLawOdometry<T> {
    /// The turn law in `corrections` for `robot` (nominal: L is its wheels' mean
    /// distance from the centre), ticking every `tick_s` seconds. Corrections without an
    /// omni turn law leave every twist unchanged.
    pub fn new(robot: &Robot, corrections: &Corrections, tick_s: f64) -> Self {
        let l_arc = corrections.l_arc();
        let lever = robot.mean_wheel_distance_m();
        let k = tick_s / (TURN_RATIO_TIME_S + tick_s);
        OmniLawOdometry {
            l_arc: cast(l_arc),
            active: l_arc != 0.0 && lever.is_finite() && lever > 0.0,
            lever: cast(lever),
            k: T::from(k).unwrap_or_else(T::one),
            smooth: [T::zero(); 3],
        }
    }

    /// The tick's body displacement for wheel rotations `dphi` (rad): `forward`'s twist
    /// (the kinematics with the plain factors, as in a turn in place) with its turn
    /// divided by the law at the smoothed turn ratio.
    pub fn apply(&mut self, dphi: &[T], forward: impl FnOnce(&[T]) -> Twist<T>) -> Twist<T> {
        let d = forward(dphi);
        if !self.active {
            return d;
        }
        let now = [d.vx, d.vy, d.omega * self.lever];
        for (s, v) in self.smooth.iter_mut().zip(now) {
            *s = *s + self.k * (v - *s);
        }
        let [vx, vy, turn] = self.smooth;
        // sqrt rather than hypot: one FPU instruction on the board, and per-tick
        // displacements are far from overflow.
        let rho = turn_ratio((vx * vx + vy * vy).sqrt(), turn);
        Twist {
            omega: d.omega / (T::one() + self.l_arc * turn_law_share(rho)),
            ..d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Kinematics;
    use crate::robot::presets;
    use heapless::Vec;

    /// An omni3-like robot: three wheels at L = 0.15 m.
    fn omni3() -> Robot {
        presets::omni3(0.04, 0.15)
    }

    fn law(l_arc: f64) -> Corrections {
        Corrections::omni(Vec::from_slice(&[1.0, 1.0, 1.0]).unwrap(), 1.0, l_arc)
    }

    /// The odometry's and the kinematics' twist (m/s, rad/s) after 2 s of 1 ms ticks of
    /// the body twist (vx, vy, omega) through the robot's own kinematics (e^-20 of the
    /// filter's start remains); the law never touches vx, vy.
    fn settled<T: Float>(l_arc: f64, vx: f64, vy: f64, omega: f64) -> (Twist<f64>, Twist<f64>) {
        let robot = omni3();
        let c = law(l_arc);
        let kin = Kinematics::<T>::new(&robot, &c).unwrap();
        let mut odo = OmniLawOdometry::<T>::new(&robot, &c, 1e-3);
        let dt = 1e-3;
        let dphi = kin.inverse(&Twist::new(cast(vx * dt), cast(vy * dt), cast(omega * dt)));
        let plain = kin.forward(&dphi);
        let mut out = plain;
        for _ in 0..2000 {
            out = odo.apply(&dphi, |p| kin.forward(p));
        }
        assert!(out.vx == plain.vx && out.vy == plain.vy);
        let f = |t: Twist<T>| {
            let g = |v: T| v.to_f64().unwrap_or(f64::NAN) / dt;
            Twist::new(g(t.vx), g(t.vy), g(t.omega))
        };
        (f(out), f(plain))
    }

    /// A held arc of radius 0.7 m (0.3 m/s, L = 0.15 m: rho = 0.15 / 0.7) with l_arc 0.02
    /// turns 1 / (1 + 0.02 (1 - (0.15/0.7)^2)) = 0.981276 of the kinematics' turn, in f64
    /// to 1e-9 and f32 to 1e-5 (the f32 twist's rounding); forward or sideways alike (the
    /// law is in the speed, not its direction).
    #[test]
    fn an_arc_turns_less_by_the_law() {
        let want = 1.0 / (1.0 + 0.02 * (1.0 - (0.15f64 / 0.7).powi(2)));
        assert!((want - 0.981276).abs() < 5e-7, "{want}");
        let (v, w) = (0.3, 0.3 / 0.7);
        for (vx, vy) in [(v, 0.0), (0.0, -v)] {
            let (out, plain) = settled::<f64>(0.02, vx, vy, w);
            let r = out.omega / plain.omega;
            std::println!("arc f64 ({vx}, {vy}): {r:.9} against {want:.9}");
            assert!((r - want).abs() < 1e-9, "f64 ({vx}, {vy}): {r}");
            let (out, plain) = settled::<f32>(0.02, vx, vy, w);
            let r = out.omega / plain.omega;
            std::println!("arc f32 ({vx}, {vy}): {r:.9}");
            assert!((r - want).abs() < 1e-5, "f32 ({vx}, {vy}): {r}");
        }
    }

    /// Straight, sideways and diagonal motion keep their speed and turn no more than the
    /// kinematics' rounding (under 1e-6 rad/s); a spin in place (rho 1: share 0) keeps
    /// its turn, in f64 and f32.
    #[test]
    fn straights_and_spins_are_unchanged() {
        for (vx, vy) in [(0.3, 0.0), (0.0, 0.3), (0.2, -0.2)] {
            let (out, _) = settled::<f64>(0.02, vx, vy, 0.0);
            assert!(
                (out.vx - vx).abs() < 1e-12 && (out.vy - vy).abs() < 1e-12,
                "{out:?}"
            );
            assert!(out.omega.abs() < 1e-12, "{out:?}");
            let (out, _) = settled::<f32>(0.02, vx, vy, 0.0);
            assert!(
                (out.vx - vx).abs() < 1e-5 && (out.vy - vy).abs() < 1e-5,
                "{out:?}"
            );
            assert!(out.omega.abs() < 1e-6, "{out:?}");
        }
        let (out, plain) = settled::<f64>(0.02, 0.0, 0.0, 2.0);
        assert!(
            (out.omega / plain.omega - 1.0).abs() < 1e-12,
            "spin f64 {out:?}"
        );
        let (out, plain) = settled::<f32>(0.02, 0.0, 0.0, 2.0);
        assert!(
            (out.omega / plain.omega - 1.0).abs() < 1e-6,
            "spin f32 {out:?}"
        );
    }

    /// Without a law (plain omni factors, or l_arc 0, or a differential drive's turn law)
    /// every twist passes through to the bit.
    #[test]
    fn no_law_leaves_the_twist_untouched() {
        let robot = omni3();
        let dd = Corrections::diff_drive(
            1.0,
            1.0,
            1.0,
            crate::correction::DiffLaws {
                e_b_arc: 0.01,
                ..Default::default()
            },
        );
        for c in [law(0.0), Corrections::None, dd] {
            let mut odo = OmniLawOdometry::<f32>::new(&robot, &c, 1e-3);
            let d = Twist::new(0.3e-3f32, 0.1e-3, 0.4e-3);
            for _ in 0..100 {
                assert_eq!(odo.apply(&[1e-3, 2e-3, 3e-3], |_| d), d, "{c:?}");
            }
        }
    }
}
