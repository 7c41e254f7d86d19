//! How a skid-steer robot's body moves when its wheels disagree with any rigid motion.
//!
//! A skid-steer robot cannot turn without its wheels sliding sideways, so the body
//! moves with the twist at which the contacts' friction forces balance: no net force and
//! no net moment (quasi-static: the body's own inertia is small against the friction of
//! four contacts at the speeds a calibration runs). Each contact's friction is the
//! gradient of a convex slip potential, so the balance is the minimum of the summed
//! potential over the body twist, found by Newton's method with a line search.
//!
//! Two tyre models, both with a slip scale proportional to the wheel's rolling speed (so
//! the force depends on the slip ratio and slip angle, not on the speed):
//! - [`Tyre::Circle`]: one friction circle, the same along and across the tyre. With
//!   equal loads the effective separation is exactly (1 + (wheelbase / track)^2) times the
//!   track at every turn radius: a constant E_b, the case a differential-drive model with
//!   the right E_b describes completely.
//! - [`Tyre::Independent`]: the longitudinal and lateral forces build up and saturate
//!   independently, each with its own slip scale. In a turn in place the lateral forces
//!   saturate while on a wide arc they stay in their linear range, so the tracks' ICRs
//!   move with the turn radius (the case [Mandow et al.] measure on real rovers).

use crate::body::Geometry;
use calib_core::kinematics::Twist;

/// Rolling speed added to every wheel's before it scales the slip, m/s: a wheel at rest
/// still has a finite (stiff) friction law.
const SPEED_FLOOR_M_S: f64 = 1e-3;
/// Newton stops when the net force and moment (in units of the total load, moment per
/// metre) fall below this.
const BALANCE_TOL: f64 = 1e-12;
/// Most Newton steps per tick (from the previous tick's twist it takes 2-6).
const MAX_STEPS: usize = 60;

/// The tyre-ground friction law of a skid-steer robot's wheels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Tyre {
    /// One friction circle: force = -mu N s / sqrt(c^2 + |s|^2), c = `slip_ratio` x the
    /// wheel's rolling speed.
    Circle {
        /// Slip ratio (slip speed over rolling speed) at which the force reaches 71 % of
        /// mu N.
        slip_ratio: f64,
    },
    /// Longitudinal and lateral forces saturate each on its own scale.
    Independent {
        /// Slip ratio at which the longitudinal force reaches 71 % of mu N.
        slip_ratio: f64,
        /// Slip angle (lateral slip speed over rolling speed, rad) at which the lateral
        /// force reaches 71 % of mu N.
        slip_angle: f64,
    },
}

impl Default for Tyre {
    /// A friction circle reached at 2 % slip: a rubber tyre on a hard floor.
    fn default() -> Self {
        Tyre::Circle { slip_ratio: 0.02 }
    }
}

impl Tyre {
    /// Checks the slip scales are positive and finite.
    pub fn validate(&self) -> Result<(), crate::SimError> {
        let scales = match *self {
            Tyre::Circle { slip_ratio } => [slip_ratio, slip_ratio],
            Tyre::Independent {
                slip_ratio,
                slip_angle,
            } => [slip_ratio, slip_angle],
        };
        for v in scales {
            crate::error::check_range("tyre slip scale", v, 1e-6, 10.0)?;
        }
        Ok(())
    }

    /// Adds the potential, gradient and Hessian (over the twist `q`) of one contact at
    /// (x, y) whose wheel surface moves at v along x, with load share n.
    fn contact(&self, q: &[f64; 3], (x, y, v): (f64, f64, f64), n: f64, acc: &mut Acc) {
        let sx = q[0] - q[2] * y - v;
        let sy = q[1] + q[2] * x;
        let u = v.abs() + SPEED_FLOOR_M_S;
        // d(sx)/d(twist) = (1, 0, -y), d(sy)/d(twist) = (0, 1, x).
        let dx = [1.0, 0.0, -y];
        let dy = [0.0, 1.0, x];
        // Gradient and Hessian with respect to (sx, sy).
        let (p, gx, gy, hxx, hxy, hyy) = match *self {
            Tyre::Circle { slip_ratio } => {
                let c = slip_ratio * u;
                let q = (c * c + sx * sx + sy * sy).sqrt();
                let q3 = q * q * q;
                (
                    q - c,
                    sx / q,
                    sy / q,
                    (c * c + sy * sy) / q3,
                    -sx * sy / q3,
                    (c * c + sx * sx) / q3,
                )
            }
            Tyre::Independent {
                slip_ratio,
                slip_angle,
            } => {
                let one = |s: f64, c: f64| {
                    let q = (c * c + s * s).sqrt();
                    (q - c, s / q, c * c / (q * q * q))
                };
                let (px, gx, hx) = one(sx, slip_ratio * u);
                let (py, gy, hy) = one(sy, slip_angle * u);
                (px + py, gx, gy, hx, 0.0, hy)
            }
        };
        acc.p += n * p;
        for a in 0..3 {
            acc.g[a] += n * (gx * dx[a] + gy * dy[a]);
            for b in 0..3 {
                acc.h[a][b] += n
                    * (hxx * dx[a] * dx[b]
                        + hxy * (dx[a] * dy[b] + dy[a] * dx[b])
                        + hyy * dy[a] * dy[b]);
            }
        }
    }

    /// The body twist at which the driven wheels' friction balances, the wheels' contact
    /// speeds along their rolling direction being `contact` (m/s), starting from `start`.
    /// Loads are equal. Wheels whose motor is off roll freely and carry no force.
    pub fn balance(&self, geom: &Geometry, contact: &[f64], start: &Twist<f64>) -> Twist<f64> {
        let wheels: Vec<(f64, f64, f64)> = geom
            .wheels
            .iter()
            .zip(contact)
            .filter(|(g, _)| g.driven)
            .map(|(g, &v)| (g.x, g.y, v))
            .collect();
        if wheels.is_empty() {
            return *start;
        }
        let n = 1.0 / wheels.len() as f64;
        let eval = |q: &[f64; 3]| {
            let mut acc = Acc::default();
            for &w in &wheels {
                self.contact(q, w, n, &mut acc);
            }
            acc
        };
        let mut q = [start.vx, start.vy, start.omega];
        if !q.iter().all(|v| v.is_finite()) {
            q = [0.0; 3];
        }
        for _ in 0..MAX_STEPS {
            let acc = eval(&q);
            if acc.g.iter().map(|v| v.abs()).fold(0.0, f64::max) < BALANCE_TOL {
                break;
            }
            let Some(inv) = calib_core::linalg::inverse3(&acc.h) else {
                break;
            };
            let step: Vec<f64> = (0..3)
                .map(|a| (0..3).map(|b| inv[a][b] * acc.g[b]).sum())
                .collect();
            let slope: f64 = (0..3).map(|a| acc.g[a] * step[a]).sum();
            let mut t = 1.0;
            loop {
                let trial = [q[0] - t * step[0], q[1] - t * step[1], q[2] - t * step[2]];
                if eval(&trial).p <= acc.p - 1e-4 * t * slope || t < 1e-9 {
                    q = trial;
                    break;
                }
                t *= 0.5;
            }
        }
        Twist::new(q[0], q[1], q[2])
    }
}

#[derive(Default)]
struct Acc {
    p: f64,
    g: [f64; 3],
    h: [[f64; 3]; 3],
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::presets;

    /// Effective separation over the track: (V_r - V_l) / (omega x track).
    fn chi(tyre: Tyre, vl: f64, vr: f64) -> (f64, Twist<f64>) {
        let robot = presets::skid4("rover", 0.1, 0.40, 0.31, Default::default());
        let g = Geometry::new(&robot).unwrap();
        let contact = [vl, vl, vr, vr];
        let start = Twist::new(0.5 * (vl + vr), 0.0, (vr - vl) / 0.40);
        let t = tyre.balance(&g, &contact, &start);
        ((vr - vl) / (t.omega * 0.40), t)
    }

    #[test]
    fn friction_circle_gives_one_plus_aspect_squared_at_every_radius() {
        // Equal loads and a friction circle: the moment balance of the four contacts puts
        // the ICRs at (1 + (0.31 / 0.40)^2) = 1.600625 times half the track.
        let want = 1.0 + (0.31f64 / 0.40).powi(2);
        for (vl, vr) in [
            (-0.3, 0.3),
            (0.0, 0.3),
            (0.1, 0.3),
            (0.25, 0.3),
            (0.29, 0.3),
        ] {
            let (c, t) = chi(Tyre::default(), vl, vr);
            assert!((c - want).abs() < 2e-3, "({vl}, {vr}): chi {c} vs {want}");
            // Symmetric contacts: no sideways speed.
            assert!(t.vy.abs() < 1e-9, "{t:?}");
        }
    }

    #[test]
    fn independent_saturation_moves_the_icrs_with_the_turn() {
        // Lateral force saturates in a turn in place (slip angle ~ 0.8 rad >> 0.1) but
        // stays linear on a wide arc: the effective separation grows with the radius
        // (reference values from an independent Newton solve of the same balance).
        let tyre = Tyre::Independent {
            slip_ratio: 0.05,
            slip_angle: 0.1,
        };
        let (spin, _) = chi(tyre, -0.3, 0.3);
        let (arc, _) = chi(tyre, 0.3 * 0.9 / 1.1, 0.3);
        assert!((spin - 1.064).abs() < 0.01, "spin {spin}");
        assert!((arc - 1.282).abs() < 0.01, "arc {arc}");
    }
}
