//! A differential drive's laws of motion in odometry ([`DiffLaws`], fitted by `wheelcal
//! calibrate`), applied tick by tick:
//! - the turn law: the effective separation grows from a turn in place to an arc (wide
//!   tyres' turn slip), so each tick's turn is divided by 1 + e_b_arc (1 - rho^2) at the
//!   tick's turn ratio rho ([`crate::kinematics::turn_law_share`]);
//! - the speed law: each side's travel times 1 + speed_rel |v| at the side's speed v;
//! - the acceleration law: each side's travel less accel_slip_s times the change of its
//!   speed (the ground lagging the wheels; over a run from rest to rest it cancels).
//!
//! Each law is applied only within the motion it was fitted on ([`LawRange`]): the
//! smoothed side speed is held at the range's fastest, the change of speed per tick at
//! its largest, and rho within its turn ratios, so beyond the range each law keeps its
//! value at the edge.
//!
//! One encoder count makes a single tick's ratio and speed noisy, so the sides' travel is
//! smoothed with a time constant of [`TURN_RATIO_TIME_S`] (calibration smooths over the
//! same 0.1 s either side). Speeds come from the counts at nominal radii, as in
//! calibration.

use crate::correction::{Corrections, DiffLaws, LawRange};
use crate::kinematics::{turn_law_share, Twist};
use crate::robot::{Robot, MAX_WHEELS};
use num_traits::Float;

/// Time constant of the turn ratio's and the sides' speeds' smoothing (s).
pub const TURN_RATIO_TIME_S: f64 = 0.1;

/// The laws' state: the laws, the wheels' weights in their side's mean travel, and the
/// smoothed travel and speed of each side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DiffLawOdometry<T> {
    e_b_arc: T,
    speed_rel: T,
    accel_slip_s: T,
    /// The fitted range: rho's bounds and the fastest side speed (m/s, infinite when
    /// unbounded).
    rho_min: T,
    rho_max: T,
    speed_max: T,
    /// Any law at all (else every twist passes unchanged, to the bit).
    active: bool,
    /// Per wheel: nominal radius / wheels on its side, on the left (else 0) and on the
    /// right.
    left: [T; MAX_WHEELS],
    right: [T; MAX_WHEELS],
    /// Per wheel: 1 / its corrected radius (the acceleration law's travel in rad).
    inv_radius: [T; MAX_WHEELS],
    /// Smoothing weight of one tick.
    k: T,
    /// 1 / the tick (s^-1).
    per_s: T,
    /// Smoothed travel per tick of the left and right sides (m).
    smooth: (T, T),
}

/// An f32 (the range's type) as T without going through f64 (no soft-float on the
/// board).
fn cast32<T: Float>(v: f32) -> T {
    T::from(v).unwrap_or_else(T::zero)
}

fn cast<T: Float>(v: f64) -> T {
    T::from(v).unwrap_or_else(T::zero)
}

impl<T: Float> DiffLawOdometry<T> {
    /// The laws in `corrections` for `robot`'s wheels (`robot` nominal: speeds and rho
    /// come from nominal radii), ticking every `tick_s` seconds. Corrections without a law
    /// leave every twist unchanged.
    pub fn new(robot: &Robot, corrections: &Corrections, tick_s: f64) -> Self {
        let laws = corrections.laws();
        let n = robot.wheels.len().min(MAX_WHEELS);
        let nl = robot.wheels.iter().filter(|w| w.is_left()).count().max(1) as f64;
        let nr = (n as f64 - nl).max(1.0);
        let (mut left, mut right) = ([T::zero(); MAX_WHEELS], [T::zero(); MAX_WHEELS]);
        let mut inv_radius = [T::zero(); MAX_WHEELS];
        for (i, w) in robot.wheels.iter().take(n).enumerate() {
            if w.is_left() {
                left[i] = cast(w.radius_m / nl);
            } else {
                right[i] = cast(w.radius_m / nr);
            }
            let r = w.radius_m * corrections.radius_scale(robot, i);
            inv_radius[i] = if r > 0.0 { cast(1.0 / r) } else { T::zero() };
        }
        let k = tick_s / (TURN_RATIO_TIME_S + tick_s);
        let range: LawRange = corrections.law_range();
        DiffLawOdometry {
            e_b_arc: cast(laws.e_b_arc),
            speed_rel: cast(laws.speed_rel),
            accel_slip_s: cast(laws.accel_slip_s),
            rho_min: cast32(range.rho_min),
            rho_max: cast32(range.rho_max),
            speed_max: cast32(range.speed_max_m_s),
            active: laws != DiffLaws::default(),
            left,
            right,
            inv_radius,
            k: T::from(k).unwrap_or_else(T::one),
            per_s: if tick_s > 0.0 {
                cast(1.0 / tick_s)
            } else {
                T::zero()
            },
            smooth: (T::zero(), T::zero()),
        }
    }

    /// The tick's body displacement for wheel rotations `dphi` (rad) with the laws
    /// applied: the speed and acceleration laws change the wheels' rotations before
    /// `forward` (the kinematics at the turn-in-place E_b) turns them into a twist, the
    /// turn law divides its turn.
    pub fn apply(&mut self, dphi: &[T], forward: impl FnOnce(&[T]) -> Twist<T>) -> Twist<T> {
        if !self.active {
            return forward(dphi);
        }
        let n = dphi.len().min(MAX_WHEELS);
        let (mut l, mut r) = (T::zero(), T::zero());
        for (i, p) in dphi.iter().enumerate().take(n) {
            l = l + self.left[i] * *p;
            r = r + self.right[i] * *p;
        }
        let (l0, r0) = self.smooth;
        self.smooth = (l0 + self.k * (l - l0), r0 + self.k * (r - r0));
        let (sl, sr) = self.smooth;
        let d = if self.speed_rel != T::zero() || self.accel_slip_s != T::zero() {
            // Per side: speed now and before this tick (signed, m/s), held within the
            // fitted speeds: beyond them the speed law keeps its edge's value and the
            // acceleration law's lag (its changes of speed summed) stops growing, so it
            // still cancels from rest to rest.
            let m = self.speed_max;
            let v = |x: T| (x * self.per_s).max(-m).min(m);
            let (vl, vr) = (v(sl), v(sr));
            let (dvl, dvr) = (vl - v(l0), vr - v(r0));
            let mut law_dphi = [T::zero(); MAX_WHEELS];
            for (i, p) in law_dphi[..n].iter_mut().enumerate() {
                let is_left = self.left[i] != T::zero();
                let (v, dv) = if is_left { (vl, dvl) } else { (vr, dvr) };
                *p = dphi[i] * (T::one() + self.speed_rel * v.abs())
                    - self.accel_slip_s * dv * self.inv_radius[i];
            }
            forward(&law_dphi[..n])
        } else {
            forward(dphi)
        };
        if self.e_b_arc == T::zero() {
            return d;
        }
        let den = sl.abs() + sr.abs();
        // Standing still: no turn to correct (rho is taken as a turn in place).
        let rho = if den > T::zero() {
            (sr - sl).abs() / den
        } else {
            T::one()
        };
        let rho = rho.max(self.rho_min).min(self.rho_max);
        Twist {
            omega: d.omega / (T::one() + self.e_b_arc * turn_law_share(rho)),
            ..d
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Kinematics;
    use crate::robot::presets;

    /// The wheels' rotations for `l` and `r` metres of side travel.
    fn rotations(robot: &Robot, l: f64, r: f64) -> [f64; 2] {
        let mut dphi = [0.0; 2];
        for (i, w) in robot.wheels.iter().enumerate() {
            dphi[i] = if w.is_left() { l } else { r } / w.radius_m;
        }
        dphi
    }

    fn laws(e_b_arc: f64, speed_rel: f64, accel_slip_s: f64) -> Corrections {
        Corrections::diff_drive(
            1.0,
            1.0,
            1.0,
            DiffLaws {
                e_b_arc,
                speed_rel,
                accel_slip_s,
            },
        )
    }

    /// Steady motion at a constant ratio: a turn in place keeps its turn, an arc of turn
    /// ratio 0.2 loses 1 - 1 / (1 + 0.01 (1 - 0.04)) of it, once the smoothing has
    /// settled (after 2 s at 1 kHz, e^-20 of the start remains).
    #[test]
    fn a_turn_law_divides_the_turn_by_its_share() {
        let robot = presets::mobolab();
        for (l, r, want) in [
            (-1e-3, 1e-3, 1.0),
            (0.8e-3, 1.2e-3, 1.0 / (1.0 + 0.01 * (1.0 - 0.04))),
        ] {
            let mut law = DiffLawOdometry::<f64>::new(&robot, &laws(0.01, 0.0, 0.0), 1e-3);
            let dphi = rotations(&robot, l, r);
            let d = Twist::new(1.0, 0.0, 1.0);
            let mut out = d;
            for _ in 0..2000 {
                out = law.apply(&dphi, |_| d);
            }
            assert!((out.omega - want).abs() < 1e-9, "{l} {r}: {}", out.omega);
            assert_eq!(out.vx, 1.0);
        }
    }

    /// Corrections with no law pass the kinematics' twist through to the bit.
    #[test]
    fn no_law_leaves_the_twist_untouched() {
        let robot = presets::mobolab();
        let plain = Corrections::DiffDrive {
            c_l: 1.01,
            c_r: 0.99,
            e_b: 1.02,
        };
        let mut none = DiffLawOdometry::<f32>::new(&robot, &plain, 1e-3);
        let d = Twist::new(0.1f32, 0.0, 0.3);
        assert_eq!(none.apply(&[1e-3, 2e-3], |_| d), d);
    }

    /// Straight at 0.3 m/s with a speed law of 0.1 per m/s: once the smoothing has
    /// settled (2 s at 1 kHz), each tick's travel is 1 + 0.1 x 0.3 = 1.03 times the
    /// kinematics' (to 1e-9), and the robot still does not turn.
    #[test]
    fn a_speed_law_grows_the_travel_at_speed() {
        let robot = presets::mobolab();
        let c = laws(0.0, 0.1, 0.0);
        let kin = Kinematics::<f64>::new(&robot, &c).unwrap();
        let mut law = DiffLawOdometry::<f64>::new(&robot, &c, 1e-3);
        let dphi = rotations(&robot, 0.3e-3, 0.3e-3);
        let plain = kin.forward(&dphi);
        let mut out = plain;
        for _ in 0..2000 {
            out = law.apply(&dphi, |p| kin.forward(p));
        }
        assert!((out.vx / plain.vx - 1.03).abs() < 1e-9, "{out:?}");
        assert!(out.omega.abs() < 1e-12, "{out:?}");
    }

    /// A speed law fitted up to 0.3 m/s (`LawRange::speed_max_m_s`), straight at 0.6 m/s:
    /// once the smoothing has settled the travel is 1 + 0.1 x 0.3 = 1.03 times the
    /// kinematics' (the law held at its edge, to 1e-8: the range is an f32, 0.3 to 1.2e-8),
    /// not 1.06; at 0.2 m/s, within the range, 1.02. In f32 (the board's) the same to
    /// 1e-6.
    #[test]
    fn a_speed_law_is_held_at_the_edge_of_its_range() {
        let robot = presets::mobolab();
        let c = Corrections::diff_drive_within(
            1.0,
            1.0,
            1.0,
            DiffLaws {
                speed_rel: 0.1,
                ..DiffLaws::default()
            },
            LawRange {
                speed_max_m_s: 0.3,
                ..LawRange::UNBOUNDED
            },
        );
        assert!(
            matches!(c, Corrections::DiffDriveLawsInRange { .. }),
            "{c:?}"
        );
        for (v, want) in [(0.6, 1.03), (0.2, 1.02)] {
            let kin = Kinematics::<f64>::new(&robot, &c).unwrap();
            let mut law = DiffLawOdometry::<f64>::new(&robot, &c, 1e-3);
            let dphi = rotations(&robot, v * 1e-3, v * 1e-3);
            let plain = kin.forward(&dphi);
            let mut out = plain;
            for _ in 0..3000 {
                out = law.apply(&dphi, |p| kin.forward(p));
            }
            assert!((out.vx / plain.vx - want).abs() < 1e-8, "{v}: {out:?}");
            let kin = Kinematics::<f32>::new(&robot, &c).unwrap();
            let mut law = DiffLawOdometry::<f32>::new(&robot, &c, 1e-3);
            let dphi = [dphi[0] as f32, dphi[1] as f32];
            let plain = kin.forward(&dphi);
            let mut out = plain;
            for _ in 0..3000 {
                out = law.apply(&dphi, |p| kin.forward(p));
            }
            assert!(
                ((out.vx / plain.vx) as f64 - want).abs() < 1e-6,
                "f32 {v}: {out:?}"
            );
        }
    }

    /// A turn law fitted on arcs with rho 0.2..0.6 only: a turn in place (rho 1) is
    /// corrected as at rho 0.6, 1 / (1 + 0.01 (1 - 0.36)), not left alone.
    #[test]
    fn a_turn_law_is_held_at_the_edge_of_its_turn_ratios() {
        let robot = presets::mobolab();
        let c = Corrections::diff_drive_within(
            1.0,
            1.0,
            1.0,
            DiffLaws {
                e_b_arc: 0.01,
                ..DiffLaws::default()
            },
            LawRange {
                rho_min: 0.2,
                rho_max: 0.6,
                ..LawRange::UNBOUNDED
            },
        );
        let mut law = DiffLawOdometry::<f64>::new(&robot, &c, 1e-3);
        let dphi = rotations(&robot, -1e-3, 1e-3);
        let d = Twist::new(0.0, 0.0, 1.0);
        let mut out = d;
        for _ in 0..2000 {
            out = law.apply(&dphi, |_| d);
        }
        let want = 1.0 / (1.0 + 0.01 * (1.0 - 0.36));
        assert!((out.omega - want).abs() < 1e-9, "{}", out.omega);
    }

    /// From rest to 0.3 m/s in 0.5 s, then 2 s at 0.3 m/s, with an acceleration law of
    /// 0.05 s: the travel summed is the kinematics' less 0.05 x the side speed reached
    /// (the changes of speed telescope to the smoothed speed, 0.3 m/s to e^-20), 15 mm,
    /// to 1e-9 m; with c_l = c_r = 1.02 the same metres are taken off (the law is in
    /// travel, not in counts).
    #[test]
    fn an_acceleration_law_takes_the_lag_off_the_travel() {
        let robot = presets::mobolab();
        for scale in [1.0, 1.02] {
            let c = Corrections::diff_drive(
                scale,
                scale,
                1.0,
                DiffLaws {
                    accel_slip_s: 0.05,
                    ..DiffLaws::default()
                },
            );
            let kin = Kinematics::<f64>::new(&robot, &c).unwrap();
            let mut law = DiffLawOdometry::<f64>::new(&robot, &c, 1e-3);
            let (mut plain, mut with) = (0.0, 0.0);
            for k in 0..2500 {
                let v = 0.3 * (k as f64 / 500.0).min(1.0);
                let dphi = rotations(&robot, v * 1e-3, v * 1e-3);
                plain += kin.forward(&dphi).vx;
                with += law.apply(&dphi, |p| kin.forward(p)).vx;
            }
            let lag = plain - with;
            assert!(
                (lag - 0.05 * 0.3).abs() < 1e-9,
                "scale {scale}: lag {lag} m"
            );
        }
    }
}
