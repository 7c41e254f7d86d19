//! What one evaluation of the calibration model steps the paths with: the parts of the
//! geometry that do not change from row to row (the kinematics' least-squares matrix, a
//! robot's sides), computed once per geometry instead of once per row. The twists are the
//! same, to the bit, as [`Kinematics::forward`] and the per-row side stepping give.

use crate::turn_law::{Sides, TurnLaw};
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::{Robot, RobotKind};

/// The body twist of one row's wheel increments at one geometry.
#[derive(Debug, Clone)]
pub(crate) struct Stepper {
    /// Per wheel: its column of the kinematics' least-squares matrix (vx, vy, omega per
    /// unit increment).
    columns: Vec<[f64; 3]>,
    /// A robot stepped by its sides (skid-steer, or a differential drive with a turn
    /// law), on recordings that carry the turn ratio.
    sides: Option<(Sides, TurnLaw)>,
    /// An omni robot's turn law ([`TurnLaw::arc_rel`]: its wheels' distance from the
    /// centre longer on arcs), applied to the twist at each row's turn ratio; 0 for none.
    omni_arc: f64,
    /// The turn ratios the omni turn law was fitted on: beyond them it holds its edge.
    omni_rho: (f64, f64),
}

impl Stepper {
    /// The stepping of `robot`, whose kinematics at its geometry are `kin`, with `law`.
    pub(crate) fn new(robot: &Robot, kin: &Kinematics<f64>, law: &TurnLaw) -> Stepper {
        let n = robot.wheels.len();
        // Column i of the matrix is the twist of a unit increment of wheel i alone: exact
        // (every other term adds a signed zero).
        let mut e = vec![0.0; n];
        let columns = (0..n)
            .map(|i| {
                e[i] = 1.0;
                let t = kin.forward(&e);
                e[i] = 0.0;
                [t.vx, t.vy, t.omega]
            })
            .collect();
        // A skid-steer robot always steps by its sides; a differential drive only with a
        // law (otherwise its exact kinematics, the same to rounding).
        let omni = robot.kind == RobotKind::Omni;
        let sides = (robot.kind == RobotKind::SkidSteer || (!omni && law.has_terms()))
            .then(|| (Sides::new(robot), *law));
        let omni_arc = if omni { law.arc_rel } else { 0.0 };
        Stepper {
            columns,
            sides,
            omni_arc,
            omni_rho: (law.range.rho_min as f64, law.range.rho_max as f64),
        }
    }

    /// An omni robot's turn law at this geometry (0: none).
    pub(crate) fn omni_arc(&self) -> f64 {
        self.omni_arc
    }

    /// [`Stepper::forward`] with an omni robot's turn law at turn ratio `rho`: the turn
    /// divided by 1 + arc (1 - rho^2), as calib-core's omni law odometry divides it. The
    /// same bits as `forward` without a law.
    #[inline]
    pub(crate) fn forward_at(&self, inc: &[f64], rho: f64) -> Twist<f64> {
        let t = self.forward(inc);
        if self.omni_arc == 0.0 {
            return t;
        }
        let share =
            calib_core::kinematics::turn_law_share(rho.clamp(self.omni_rho.0, self.omni_rho.1));
        Twist::new(t.vx, t.vy, t.omega / (1.0 + self.omni_arc * share))
    }

    /// The matrix's columns, one per wheel.
    pub(crate) fn columns(&self) -> &[[f64; 3]] {
        &self.columns
    }

    /// The sides' stepping, when the robot steps by its sides.
    pub(crate) fn sides(&self) -> Option<&(Sides, TurnLaw)> {
        self.sides.as_ref()
    }

    /// [`Kinematics::forward`] of one row's increments: each component summed over the
    /// wheels in order, as it does.
    #[inline]
    pub(crate) fn forward(&self, inc: &[f64]) -> Twist<f64> {
        let mut o = [0.0; 3];
        for (c, w) in self.columns.iter().zip(inc) {
            o[0] += c[0] * w;
            o[1] += c[1] * w;
            o[2] += c[2] * w;
        }
        Twist::new(o[0], o[1], o[2])
    }
}

/// Steps between exact recomputations of the heading's cosine and sine in [`Heading`]
/// (the rotations in between lose about one ulp each).
const HEADING_RESYNC: u32 = 16;

/// The heading along a path and its cosine and sine: each step rotates them by the step's
/// angle, whose sine and 1 - cosine the arc coefficients already give (omega S and
/// omega C), and every [`HEADING_RESYNC`] steps they are recomputed from the heading, so
/// a path costs one `sin_cos` per 16 rows instead of one per row. The heading itself is
/// summed as [`integrate_arc`](calib_core::odometry::integrate_arc) sums it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Heading {
    pub(crate) th: f64,
    pub(crate) cos: f64,
    pub(crate) sin: f64,
    steps: u32,
}

impl Heading {
    pub(crate) fn new() -> Heading {
        Heading {
            th: 0.0,
            cos: 1.0,
            sin: 0.0,
            steps: 0,
        }
    }

    /// Turns by `omega`, whose arc coefficients are (`s`, `c`).
    #[inline]
    pub(crate) fn turn(&mut self, omega: f64, s: f64, c: f64) {
        self.th += omega;
        self.steps += 1;
        if self.steps == HEADING_RESYNC {
            self.steps = 0;
            (self.sin, self.cos) = self.th.sin_cos();
        } else {
            let (sw, vw) = (omega * s, omega * c);
            let (c0, s0) = (self.cos, self.sin);
            self.cos = c0 - (c0 * vw + s0 * sw);
            self.sin = s0 + (c0 * sw - s0 * vw);
        }
    }
}

/// One step of the exact arc from (`x`, `y`, `heading`) by the twist `tw` (as
/// [`integrate_arc`](calib_core::odometry::integrate_arc)), returning the arc
/// coefficients (S, C) and the body-frame displacement (lx, ly) used.
#[inline]
pub(crate) fn arc_step(
    x: &mut f64,
    y: &mut f64,
    heading: &mut Heading,
    tw: &Twist<f64>,
) -> (f64, f64, f64, f64) {
    let (s, c) = arc_coefficients(tw.omega);
    let lx = s * tw.vx - c * tw.vy;
    let ly = c * tw.vx + s * tw.vy;
    let (st, ct) = (heading.sin, heading.cos);
    *x = *x + ct * lx - st * ly;
    *y = *y + st * lx + ct * ly;
    heading.turn(tw.omega, s, c);
    (s, c, lx, ly)
}

/// [`arc_coefficients`](calib_core::odometry::arc_coefficients) of an `f64`, inlined into
/// the paths' loops (a call per row cost a tenth of a calibration): the same operations
/// in the same order, so the same bits.
#[inline(always)]
pub(crate) fn arc_coefficients(d: f64) -> (f64, f64) {
    if d.abs() < 0.1 {
        let d2 = d * d;
        let s = 1.0 - d2 * (1.0 / 6.0 - d2 * (1.0 / 120.0 - d2 * (1.0 / 5040.0)));
        let c = d * (0.5 - d2 * (1.0 / 24.0 - d2 * (1.0 / 720.0 - d2 * (1.0 / 40320.0))));
        (s, c)
    } else {
        let h = (d / 2.0).sin();
        (d.sin() / d, 2.0 * h * h / d)
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn arc_coefficients_are_calib_cores_to_the_bit() {
        let mut d = 1e-9f64;
        while d < 4.0 {
            for v in [d, -d, 0.1 * (1.0 - 1e-15), 0.1, -0.1] {
                let (a, b) = (
                    super::arc_coefficients(v),
                    calib_core::odometry::arc_coefficients(v),
                );
                assert_eq!(a.0.to_bits(), b.0.to_bits(), "sin(d)/d at {v}");
                assert_eq!(a.1.to_bits(), b.1.to_bits(), "(1 - cos d)/d at {v}");
            }
            d *= 1.01;
        }
        assert_eq!(
            super::arc_coefficients(0.0),
            calib_core::odometry::arc_coefficients(0.0)
        );
    }
}
