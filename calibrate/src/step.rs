//! What one evaluation of the calibration model steps the paths with: the parts of the
//! geometry that do not change from row to row (the kinematics' least-squares matrix, a
//! robot's sides), computed once per geometry instead of once per row. The twists are the
//! same, to the bit, as [`Kinematics::forward`] and the per-row side stepping give.

use crate::turn_law::{Sides, TurnLaw};
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::odometry::Chord;
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

/// One step of the exact arc from (`x`, `y`, `heading`) by the twist `tw`: calib-core's
/// [`Chord`] (the exact-arc step the firmware's odometry and
/// [`integrate_arc`](calib_core::odometry::integrate_arc) take) turned by the carried
/// heading, returning the arc coefficients (S, C) and the body-frame displacement
/// (lx, ly) used.
#[inline]
pub(crate) fn arc_step(
    x: &mut f64,
    y: &mut f64,
    heading: &mut Heading,
    tw: &Twist<f64>,
) -> (f64, f64, f64, f64) {
    let chord = Chord::of(tw);
    (*x, *y) = chord.moved(*x, *y, heading.cos, heading.sin);
    heading.turn(tw.omega, chord.s, chord.c);
    (chord.s, chord.c, chord.lx, chord.ly)
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::odometry::{integrate_arc, Pose};

    /// From a heading whose cosine and sine are exact (the start, and every
    /// [`HEADING_RESYNC`] steps), one step is calib-core's `integrate_arc` to the bit, over
    /// turns from 1e-9 rad to 4 rad each way and across the series' edge at 0.1 rad.
    #[test]
    fn a_step_is_calib_cores_exact_arc_to_the_bit() {
        let mut d = 1e-9f64;
        while d < 4.0 {
            for w in [d, -d, 0.1 * (1.0 - 1e-15), 0.1, -0.1] {
                for th in [0.0, 0.7, -2.9] {
                    let tw = Twist::new(0.013, -0.002, w);
                    let (sin, cos) = f64::sin_cos(th);
                    let mut h = Heading {
                        th,
                        cos,
                        sin,
                        steps: 0,
                    };
                    let (mut x, mut y) = (1.5, -0.25);
                    arc_step(&mut x, &mut y, &mut h, &tw);
                    let p = integrate_arc(Pose::new(1.5, -0.25, th), &tw);
                    assert_eq!(x.to_bits(), p.x.to_bits(), "x at turn {w}, heading {th}");
                    assert_eq!(y.to_bits(), p.y.to_bits(), "y at turn {w}, heading {th}");
                    assert_eq!(h.th.to_bits(), p.theta.to_bits(), "heading at turn {w}");
                }
            }
            d *= 1.01;
        }
    }
}
