//! Wheel kinematics after Siegwart & Nourbakhsh: inverse (body twist -> wheel rates, the
//! n x 3 Jacobian of [Redundant omni] with its 1/(r cos gamma) prefactor) and forward
//! (wheel increments -> body motion by least squares).
//!
//! The least-squares pseudo-inverse is computed once at construction so the 1 kHz tick
//! only does a 3 x n product. Standard wheels also contribute their sliding constraint
//! (zero sideways velocity), which is what makes a two-wheel differential drive solvable
//! exactly; Swedish wheels do not have one.

use crate::correction::Corrections;
use crate::linalg::inverse3;
use crate::robot::{Robot, MAX_WHEELS};
use num_traits::Float;

/// Share of a differential drive's turn law (the effective separation on arcs against a
/// turn in place) that acts at turn ratio `rho` = |v_r - v_l| / (|v_r| + |v_l|): 1 - rho^2.
/// It is 0 in a turn in place (rho = 1) and near 1 on every arc wider than the track,
/// because a tyre's turn slip (the twist of its contact patch) falls as one over the turn
/// radius. Measured on the OptiOdom robot, this shape gives the same law on two days
/// (0.0057 ± 0.0006 in June, 0.0044 ± 0.0013 in December); the smooth (1 - rho)^2 did
/// not (0.0104 ± 0.0011 against 0.0059 ± 0.0017).
pub fn turn_law_share<T: Float>(rho: T) -> T {
    T::one() - rho * rho
}

/// Turn ratio of a body motion: `turn` / max(`speed`, `turn`), where `speed` is the
/// body's |(vx, vy)| and `turn` its |omega| times a lever (the wheels' mean distance from
/// the centre): 1 in a turn in place, 0 on a straight line, 1 when standing still (no
/// turn to correct). For a differential drive (speed |v_r + v_l| / 2, turn
/// |v_r - v_l| / 2) it is |v_r - v_l| / (|v_r| + |v_l|) exactly, so one law's share
/// ([`turn_law_share`]) serves every robot.
pub fn turn_ratio<T: Float>(speed: T, turn: T) -> T {
    let (v, w) = (speed.abs(), turn.abs());
    let den = if v > w { v } else { w };
    if den > T::zero() {
        w / den
    } else {
        T::one()
    }
}

/// A planar body velocity (or displacement over a tick) in the body frame.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    postcard_schema::Schema,
)]
pub struct Twist<T> {
    /// Forward velocity, body x (m/s; m for a displacement).
    pub vx: T,
    /// Sideways velocity, body y (m/s; m for a displacement).
    pub vy: T,
    /// Yaw rate (rad/s; rad for a displacement).
    pub omega: T,
}

impl<T: Float> Twist<T> {
    /// A twist from its three components.
    pub fn new(vx: T, vy: T, omega: T) -> Self {
        Twist { vx, vy, omega }
    }

    /// The zero twist.
    pub fn zero() -> Self {
        Twist {
            vx: T::zero(),
            vy: T::zero(),
            omega: T::zero(),
        }
    }

    /// Every component multiplied by `k` (e.g. a velocity times dt gives a displacement).
    pub fn scale(self, k: T) -> Self {
        Twist {
            vx: self.vx * k,
            vy: self.vy * k,
            omega: self.omega * k,
        }
    }
}

/// Per-wheel values (rates in rad/s, or angle increments in rad), in the robot's wheel
/// order.
pub type WheelValues<T> = heapless::Vec<T, MAX_WHEELS>;

/// Precomputed inverse and forward kinematics of one robot with one set of corrections.
#[derive(Debug, Clone, PartialEq)]
pub struct Kinematics<T> {
    n: usize,
    /// Row i: wheel rate per unit body twist, rolling_row / (r cos gamma).
    jacobian: [[T; 3]; MAX_WHEELS],
    /// Least-squares solution: body twist = pinv * wheel rates (wheel columns only; the
    /// sliding constraints' right-hand side is zero).
    pinv: [[T; MAX_WHEELS]; 3],
}

/// The robot's geometry cannot resolve the body twist.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SingularGeometry;

impl<T: Float> Kinematics<T> {
    /// Kinematics of `robot` with `corr` applied (use [`Corrections::None`] for nominal).
    pub fn new(robot: &Robot, corr: &Corrections) -> Result<Self, SingularGeometry> {
        let n = robot.wheels.len();
        let (m, rolling) = robot.normal_matrix(
            |i| robot.wheels[i].radius_m * corr.radius_scale(robot, i),
            corr.wheelbase_scale(),
        );
        let inv = inverse3(&m).ok_or(SingularGeometry)?;
        let cast = |v: f64| T::from(v).unwrap_or_else(T::zero);
        let mut jacobian = [[T::zero(); 3]; MAX_WHEELS];
        let mut pinv = [[T::zero(); MAX_WHEELS]; 3];
        for i in 0..n {
            for a in 0..3 {
                jacobian[i][a] = cast(rolling[i][a]);
                pinv[a][i] = cast((0..3).map(|b| inv[a][b] * rolling[i][b]).sum());
            }
        }
        Ok(Kinematics { n, jacobian, pinv })
    }

    /// Number of wheels.
    pub fn wheel_count(&self) -> usize {
        self.n
    }

    /// Wheel i's rate for a body twist.
    pub fn wheel_rate(&self, i: usize, t: &Twist<T>) -> T {
        let j = &self.jacobian[i];
        j[0] * t.vx + j[1] * t.vy + j[2] * t.omega
    }

    /// Inverse kinematics: wheel rates (rad/s) for a body twist (m/s, rad/s).
    pub fn inverse(&self, t: &Twist<T>) -> WheelValues<T> {
        (0..self.n).map(|i| self.wheel_rate(i, t)).collect()
    }

    /// Inverse kinematics into a caller's slice (no allocation of a Vec on the hot path).
    pub fn inverse_into(&self, t: &Twist<T>, out: &mut [T]) {
        for (i, o) in out.iter_mut().enumerate().take(self.n) {
            *o = self.wheel_rate(i, t);
        }
    }

    /// Forward kinematics: least-squares body twist (or displacement) from wheel rates (or
    /// angle increments). Exact when the wheels agree; a redundant robot's disagreeing
    /// wheels are averaged in the least-squares sense.
    pub fn forward(&self, wheels: &[T]) -> Twist<T> {
        let mut out = [T::zero(); 3];
        for (a, o) in out.iter_mut().enumerate() {
            for (i, w) in wheels.iter().enumerate().take(self.n) {
                *o = *o + self.pinv[a][i] * *w;
            }
        }
        Twist {
            vx: out[0],
            vy: out[1],
            omega: out[2],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::robot::presets;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn turn_ratio_is_a_differential_drives_side_ratio() {
        // Sides (l, r): |r - l| / (|l| + |r|) against speed |r + l| / 2 and turn |r - l| / 2.
        for (l, r) in [
            (1.0f64, 1.0f64),
            (0.5, 1.5),
            (-1.0, 1.0),
            (-0.2, 1.0),
            (0.0, 0.3),
            (2.0, -0.5),
        ] {
            let side = (r - l).abs() / (l.abs() + r.abs());
            let t = turn_ratio((r + l) / 2.0, (r - l) / 2.0);
            assert!(close(t, side, 1e-15), "({l}, {r}): {t} against {side}");
        }
        // An omni robot on an arc of radius R with wheels at L from the centre: L / R.
        assert!(close(turn_ratio(0.7, 0.195), 0.195 / 0.7, 1e-15));
        assert_eq!(turn_ratio(0.0, 0.0), 1.0);
        assert_eq!(turn_ratio(0.0, -0.3), 1.0);
        assert_eq!(turn_ratio(0.4f32, 0.0), 0.0);
    }

    #[test]
    fn diff_drive_by_hand() {
        let r = presets::mobolab(); // r = 0.05, b = 0.40
        let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
        let w = k.inverse(&Twist::new(0.5, 0.0, 1.0));
        // left (0.5 - 0.2)/0.05 = 6, right (0.5 + 0.2)/0.05 = 14
        assert!(close(w[0], 6.0, 1e-12) && close(w[1], 14.0, 1e-12));
        let t = k.forward(&[6.0, 14.0]);
        assert!(close(t.vx, 0.5, 1e-12) && close(t.vy, 0.0, 1e-12) && close(t.omega, 1.0, 1e-12));
    }

    #[test]
    fn skid_steer_drives_each_side_together() {
        // Track 0.4 m, r = 0.1 m: a twist (0.5 m/s, 1 rad/s) asks (0.5 -+ 0.2) / 0.1 of
        // each side's wheels; with E_b = 1.6 the lever is 0.32 m.
        let r = presets::skid4("rover", 0.1, 0.4, 0.31, Default::default());
        let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
        let w = k.inverse(&Twist::new(0.5, 0.0, 1.0));
        assert!(close(w[0], 3.0, 1e-12) && close(w[1], 3.0, 1e-12));
        assert!(close(w[2], 7.0, 1e-12) && close(w[3], 7.0, 1e-12));
        let c = Corrections::DiffDrive {
            c_l: 1.0,
            c_r: 1.0,
            e_b: 1.6,
        };
        let k = Kinematics::<f64>::new(&r, &c).unwrap();
        let w = k.inverse(&Twist::new(0.5, 0.0, 1.0));
        assert!(close(w[0], 1.8, 1e-12) && close(w[3], 8.2, 1e-12), "{w:?}");
        // Forward: the sliding rows of the front and rear wheels disagree in a turn, but
        // at weight 1e-3 they move omega by ~1e-6 relative.
        let t = k.forward(&w);
        assert!(
            close(t.vx, 0.5, 1e-9) && close(t.omega, 1.0, 1e-5) && t.vy.abs() < 1e-9,
            "{t:?}"
        );
    }

    #[test]
    fn omni4_paths_use_two_wheels() {
        // [Redundant omni]: path 4W-1 (along x) turns wheels 1 and 3 only; 4W-2 (along y)
        // wheels 2 and 4.
        let k = Kinematics::<f64>::new(&presets::omni4(), &Corrections::None).unwrap();
        let w = k.inverse(&Twist::new(0.1, 0.0, 0.0));
        assert!(close(w[0], 0.1 / 0.03, 1e-12) && close(w[2], -0.1 / 0.03, 1e-12));
        assert!(close(w[1], 0.0, 1e-12) && close(w[3], 0.0, 1e-12));
        let w = k.inverse(&Twist::new(0.0, 0.1, 0.0));
        assert!(close(w[0], 0.0, 1e-12) && close(w[2], 0.0, 1e-12));
        assert!(close(w[1], 0.1 / 0.03, 1e-12) && close(w[3], -0.1 / 0.03, 1e-12));
    }

    #[test]
    fn omni_correction_scales_commands() {
        let robot = presets::omni4();
        let f_lat = heapless::Vec::from_slice(&[1.08, 0.96, 1.02, 0.98]).unwrap();
        let c = Corrections::Omni { f_lat, f_lon: 0.94 };
        let k0 = Kinematics::<f64>::new(&robot, &Corrections::None).unwrap();
        let k = Kinematics::<f64>::new(&robot, &c).unwrap();
        let t = Twist::new(0.1, 0.05, 0.3);
        let (n, f) = (k0.inverse(&t), k.inverse(&t));
        for (i, fl) in [1.08, 0.96, 1.02, 0.98].iter().enumerate() {
            // [Redundant omni] eq. 6: final rate = F_lon * F_lat * J * twist.
            assert!(close(f[i], 0.94 * fl * n[i], 1e-12));
        }
    }
}
