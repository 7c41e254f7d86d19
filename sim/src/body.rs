//! The actual geometry the simulated robot has (faults applied, legs placed) and the body
//! motion its driven wheels impose.
//!
//! Redundant wheels that disagree ([Redundant omni]'s four omni wheels with slightly
//! different radii) cannot all roll without slipping. The body moves with the least-squares
//! twist of the driven wheels' rolling constraints, so every wheel slips by its residual;
//! standard wheels add their sliding constraints (zero sideways velocity) weighted 1e-3,
//! enough to fix the sideways velocity of a differential drive but not to fight a
//! skid-steer turn. Free-spinning wheels (free in the robot file, or with their motor off
//! this tick) impose nothing: they roll with the ground (see [`crate::ground`]). A
//! direction no driven wheel constrains ([Redundant omni]'s 4W-1 path with wheels 2 and 4
//! off leaves the sideways velocity free) keeps the body's previous velocity, less a little
//! rolling resistance: a tiny Tikhonov term (weight 1e-7) pulls the solution towards it, a
//! stand-in for the body's inertia that changes the constrained directions by ~1e-12
//! relative. With every motor off the robot coasts to a stop (see [`crate::ground`]).

use crate::SimError;
use calib_core::kinematics::Twist;
use calib_core::robot::{Robot, RobotKind, Wheel, SLIDING_WEIGHT};

/// Squared weights of the pull towards the previous twist (inertia in free directions),
/// the first that leaves the normal equations invertible. The first suits a free
/// direction along an axis ([Redundant omni]'s 4W-1: the sideways velocity); a free
/// direction that mixes two ([Redundant omni]'s paths on a three-wheel omni robot: with
/// one wheel off, a sideways drift and a turn together) needs a heavier pull to stay
/// clear of [`calib_core::linalg::SINGULAR_RATIO`], still 1e-8 relative or less on the
/// constrained directions.
const INERTIA_WEIGHTS2: [f64; 4] = [1e-14, 1e-11, 1e-9, 1e-7];

/// One wheel's actual geometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WheelGeom {
    /// Contact point in the body frame.
    pub x: f64,
    /// Contact point y in the body frame (m).
    pub y: f64,
    /// Siegwart's rolling row: dotted with the body twist gives r cos(gamma) phidot.
    pub row: [f64; 3],
    /// Effective rolling radius r cos(gamma).
    pub r_eff: f64,
    /// Whether a motor drives the wheel.
    pub driven: bool,
}

impl WheelGeom {
    /// Unit rolling direction in the body frame.
    pub fn direction(&self) -> (f64, f64) {
        (self.row[0], self.row[1])
    }
}

/// Geometry plus the precomputed least-squares gains.
#[derive(Debug, Clone, PartialEq)]
pub struct Geometry {
    /// The wheels, in the robot's order.
    pub wheels: Vec<WheelGeom>,
    /// Body twist = sum over driven wheels of gain[i] * contact speed[i] + hold * previous.
    gain: Vec<[f64; 3]>,
    hold: [[f64; 3]; 3],
    /// Wheels whose motor is off this tick (bit i), besides those free in the file.
    pub off_mask: u32,
    /// A skid-steer robot: the body moves where the contacts' friction balances
    /// ([`crate::skid`]), not with the least-squares twist.
    pub skid_steer: bool,
    /// An omni robot: its wheels' mean distance from the centre (m), the lever at which
    /// its turn counts against its speed in the turn ratio
    /// ([`calib_core::kinematics::turn_ratio`]). `None` for robots with a left and a
    /// right side, whose ratio comes from the sides.
    pub turn_lever: Option<f64>,
}

impl Geometry {
    /// Geometry of an (actual) robot description, all its driven wheels driving.
    pub fn new(robot: &Robot) -> Result<Self, SimError> {
        Self::with_motors_off(robot, 0)
    }

    /// Geometry with the wheels in `off_mask` (bit i = wheel i) rolling freely.
    pub fn with_motors_off(robot: &Robot, off_mask: u32) -> Result<Self, SimError> {
        INERTIA_WEIGHTS2
            .iter()
            .find_map(|&w| Self::with_inertia(robot, off_mask, w).transpose())
            .unwrap_or(Err(SimError::SingularGeometry))
    }

    /// [`Geometry::with_motors_off`] with the inertia's squared weight `inertia2`; `None`
    /// when the normal equations are singular at that weight.
    fn with_inertia(robot: &Robot, off_mask: u32, inertia2: f64) -> Result<Option<Self>, SimError> {
        let mut wheels = Vec::with_capacity(robot.wheels.len());
        let mut m = [[0.0; 3]; 3];
        for (a, row) in m.iter_mut().enumerate() {
            row[a] = inertia2;
        }
        let sliding = robot.kind.wheels_have_sliding_constraint();
        for (i, w) in robot.wheels.iter().enumerate() {
            let (x, y) = w.position();
            let g = WheelGeom {
                x,
                y,
                row: w.rolling_row(),
                r_eff: w.radius_m * w.gamma_rad.cos(),
                driven: w.driven && off_mask & (1 << i) == 0,
            };
            for a in 0..3 {
                for b in 0..3 {
                    if g.driven {
                        m[a][b] += g.row[a] * g.row[b];
                    }
                    if sliding {
                        let s = w.sliding_row();
                        m[a][b] += SLIDING_WEIGHT * SLIDING_WEIGHT * s[a] * s[b];
                    }
                }
            }
            wheels.push(g);
        }
        let Some(inv) = calib_core::linalg::inverse3(&m) else {
            return Ok(None);
        };
        let gain = wheels
            .iter()
            .map(|g| {
                if g.driven {
                    let mut p = [0.0; 3];
                    for (a, pa) in p.iter_mut().enumerate() {
                        *pa = (0..3).map(|b| inv[a][b] * g.row[b]).sum();
                    }
                    p
                } else {
                    [0.0; 3]
                }
            })
            .collect();
        let mut hold = inv;
        for row in hold.iter_mut() {
            for v in row.iter_mut() {
                *v *= inertia2;
            }
        }
        Ok(Some(Geometry {
            wheels,
            gain,
            hold,
            off_mask,
            skid_steer: robot.kind == RobotKind::SkidSteer,
            turn_lever: (robot.kind == RobotKind::Omni).then(|| robot.mean_wheel_distance_m()),
        }))
    }

    /// Least-squares body twist from the driven wheels' contact speeds (free wheels'
    /// entries are ignored), unconstrained directions keeping `previous`.
    pub fn twist_from_contacts(&self, contact: &[f64], previous: &Twist<f64>) -> Twist<f64> {
        let p = [previous.vx, previous.vy, previous.omega];
        let mut t = [0.0; 3];
        for (a, ta) in t.iter_mut().enumerate() {
            *ta = self.hold[a][0] * p[0] + self.hold[a][1] * p[1] + self.hold[a][2] * p[2];
        }
        for (g, c) in self.gain.iter().zip(contact) {
            t[0] += g[0] * c;
            t[1] += g[1] * c;
            t[2] += g[2] * c;
        }
        Twist::new(t[0], t[1], t[2])
    }

    /// Contact speed of wheel i for a body twist (row . twist).
    pub fn contact_speed(&self, i: usize, t: &Twist<f64>) -> f64 {
        let r = &self.wheels[i].row;
        r[0] * t.vx + r[1] * t.vy + r[2] * t.omega
    }
}

/// The robot as it really is: radii and distances scaled by the faults.
pub fn actual_robot(nominal: &Robot, radius_scale: &[f64], wheelbase_scale: f64) -> Robot {
    let mut r = nominal.clone();
    for (i, w) in r.wheels.iter_mut().enumerate() {
        w.radius_m *= radius_scale.get(i).copied().unwrap_or(1.0);
        w.l_m *= wheelbase_scale;
    }
    r
}

/// Moves a wheeled-legged robot's wheels to the leg angles (docs/formats.md §1: front pair at
/// +body_length/2 + length cos(leg_front), rear at -body_length/2 + length cos(leg_rear)),
/// keeping each wheel's y and rolling direction. Other robots are returned unchanged.
pub fn place_legs(robot: &Robot, leg_front: f64, leg_rear: f64) -> Robot {
    let Some(legs) = robot.legs else {
        return robot.clone();
    };
    if robot.kind != RobotKind::WheeledLegged {
        return robot.clone();
    }
    let (xf, xr) = legs.wheel_x(leg_front, leg_rear);
    let mut r = robot.clone();
    for w in r.wheels.iter_mut() {
        let (x, y) = w.position();
        let nx = if x >= 0.0 { xf } else { xr };
        *w = moved(w, nx, y);
    }
    r
}

fn moved(w: &Wheel, x: f64, y: f64) -> Wheel {
    let heading = w.alpha_rad + w.beta_rad;
    let alpha = y.atan2(x);
    Wheel {
        alpha_rad: alpha,
        l_m: x.hypot(y),
        beta_rad: heading - alpha,
        ..w.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::correction::Corrections;
    use calib_core::kinematics::Kinematics;
    use calib_core::robot::presets;

    #[test]
    fn matches_calib_core_forward_kinematics() {
        for robot in [
            presets::mobolab(),
            presets::omni4(),
            presets::omni3(0.04, 0.15),
        ] {
            let g = Geometry::new(&robot).unwrap();
            let k = Kinematics::<f64>::new(&robot, &Corrections::None).unwrap();
            let t = Twist::new(
                0.2,
                if robot.kind == RobotKind::Omni {
                    -0.1
                } else {
                    0.0
                },
                0.7,
            );
            let rates = k.inverse(&t);
            let contacts: Vec<f64> = rates
                .iter()
                .zip(&g.wheels)
                .map(|(w, geo)| w * geo.r_eff)
                .collect();
            let back = g.twist_from_contacts(&contacts, &t);
            assert!((back.vx - t.vx).abs() < 1e-12 && (back.vy - t.vy).abs() < 1e-12);
            assert!((back.omega - t.omega).abs() < 1e-12);
        }
    }

    #[test]
    fn legs_move_contacts_and_keep_directions() {
        let text =
            std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../robots/wlr.toml"))
                .unwrap();
        let wlr = formats::robot_file::parse(&text, std::path::Path::new("wlr.toml")).unwrap();
        let v = std::f64::consts::FRAC_PI_2;
        let same = place_legs(&wlr, v, v);
        for (a, b) in same.wheels.iter().zip(&wlr.wheels) {
            assert!((a.position().0 - b.position().0).abs() < 1e-6);
        }
        let moved = place_legs(&wlr, 30f64.to_radians(), 150f64.to_radians());
        let (xf, xr) = wlr
            .legs
            .unwrap()
            .wheel_x(30f64.to_radians(), 150f64.to_radians());
        assert!((moved.wheels[0].position().0 - xf).abs() < 1e-12);
        assert!((moved.wheels[3].position().0 - xr).abs() < 1e-12);
        assert!((moved.wheels[3].position().1 - wlr.wheels[3].position().1).abs() < 1e-12);
        for w in &moved.wheels {
            let r = w.rolling_row();
            assert!((r[0] - 1.0).abs() < 1e-9 && r[1].abs() < 1e-9);
        }
        assert!(Geometry::new(&moved).is_ok());
    }
}
