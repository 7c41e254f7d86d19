//! Wheel-ground contact and the body's planar motion, one tick at a time.
//!
//! Each driven wheel wants its contact point to move by r cos(gamma) dphi along its
//! rolling direction. Before the body follows:
//! - floor roughness adds a random walk to that travel (non-systematic error);
//! - a wheel that has just rolled onto a cable gives up `loss_m` of travel (spread over
//!   the next ticks until paid): it turns without advancing while it climbs over;
//! - traction: a wheel's contact speed can change by at most mu * g * s per second, s the
//!   share of the weight on the driven wheels, so the body's acceleration is bounded by
//!   mu * g * s (the catalogue's `longitudinal_slip`), with mu scaled by low-friction
//!   patches under each wheel; a wheel asked for more spins (its encoder counts, the body
//!   does not follow).
//!
//! The body then takes the least-squares twist of those contact speeds
//! ([`crate::body::Geometry`]), plus the lateral slip v_y = -k v_x omega of turning
//! (`side_slip_s`) and a tilted floor's drift, and moves along the exact arc. Free wheels
//! roll with the ground: their angle follows the body's motion at their contact.
//!
//! The body's own inertia is not modelled beyond the traction limit (a kinematic model
//! with bounded acceleration): the motors are not slowed by the load. That is the model
//! the diagnose catalogue is phrased in, so a fitted parameter means the same thing here.

use crate::body::Geometry;
use crate::effects::Mechanism;
use crate::surface::Surface;
use calib_core::kinematics::Twist;
use calib_core::odometry::{integrate_arc, Pose};
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

/// How fast a body that no driven wheel holds (all motors off) rolls to a stop: the
/// rolling resistance and gear drag of back-driven wheels, m/s^2 and rad/s^2. Only the
/// directions no driven wheel constrains feel it (see [`crate::body`]).
const COAST_DECEL_M_S2: f64 = 1.0;
const COAST_DECEL_RAD_S2: f64 = 5.0;

/// Ground-stage parameters (from [`crate::Faults`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundParams {
    /// Friction coefficient; `None` = unlimited traction (pure rolling).
    pub mu: Option<f64>,
    /// Share of the weight on the driven wheels (0..1).
    pub driven_load_share: f64,
    /// k in v_y = -k v_x omega (s).
    pub side_slip_s: f64,
    /// Random walk of each wheel's travel, metres per square-root metre travelled.
    pub travel_noise_m_per_sqrt_m: f64,
    /// Mechanisms of the traction and side-slip effects.
    pub mech: crate::effects::MechanismFaults,
    /// Tyre friction of a skid-steer robot's contacts.
    pub tyre: crate::skid::Tyre,
    /// Growth of a wheeled robot's effective separation from a turn in place to a wide
    /// arc (wide tyres' contact moving across the tread); 0 for none.
    pub turn_scrub: f64,
    /// Growth of a driven wheel's rolling radius per m/s of its rolling speed; 0 for none.
    pub speed_scale: f64,
    /// Rolling speed (m/s) beyond which the growth by `speed_scale` stops.
    pub speed_scale_top_m_s: f64,
}

/// The body's state on the ground.
#[derive(Debug, Clone)]
pub struct Ground {
    /// Pose in the world frame (m, m, rad).
    pub pose: Pose<f64>,
    /// Twist imposed by the wheels (before side slip and drift), body frame.
    pub wheel_twist: Twist<f64>,
    /// Twist the body actually moved with over the last tick, body frame.
    pub body_twist: Twist<f64>,
    /// Travel still owed to cables, per wheel, m.
    pending_loss: Vec<f64>,
    /// Cable crossings so far, per wheel.
    pub crossings: Vec<u64>,
    contacts: Vec<f64>,
    /// The left and right sides' contact speeds smoothed over
    /// `calib_core::diff_laws::TURN_RATIO_TIME_S` (m/s): how the robot turns, for the
    /// turn scrub. A stepper's wheels move in pulses, one wheel per tick at times, so a
    /// single tick's ratio says nothing about the turn.
    sides: (f64, f64),
    /// An omni robot's twist (vx, vy, omega times its wheels' lever) smoothed likewise
    /// (m/s), for its turn scrub.
    twist_smooth: [f64; 3],
    /// Each wheel's rolling speed smoothed likewise (m/s), for the speed scale: a
    /// stepper's single tick moves a whole step or none, which is not its speed.
    rolling: Vec<f64>,
}

impl Ground {
    /// A body at rest at `start` with `n_wheels` wheels.
    pub fn new(start: Pose<f64>, n_wheels: usize) -> Self {
        Ground {
            pose: start,
            wheel_twist: Twist::zero(),
            body_twist: Twist::zero(),
            pending_loss: vec![0.0; n_wheels],
            crossings: vec![0; n_wheels],
            contacts: vec![0.0; n_wheels],
            sides: (0.0, 0.0),
            twist_smooth: [0.0; 3],
            rolling: vec![0.0; n_wheels],
        }
    }

    /// Advances one tick. `dphi` holds the driven wheels' angle increments on entry; on
    /// return the free wheels' entries hold theirs.
    pub fn step(
        &mut self,
        geom: &Geometry,
        params: &GroundParams,
        surface: &Surface,
        dphi: &mut [f64],
        dt: f64,
        rng: &mut ChaCha8Rng,
    ) {
        let (st, ct) = self.pose.theta.sin_cos();
        let mut moving = false;
        for (i, g) in geom.wheels.iter().enumerate() {
            if !g.driven {
                continue;
            }
            let mut d = g.r_eff * dphi[i];
            if params.speed_scale != 0.0 {
                let k = dt / (calib_core::diff_laws::TURN_RATIO_TIME_S + dt);
                let v = &mut self.rolling[i];
                *v += k * (d / dt - *v);
                d *= 1.0 + params.speed_scale * v.abs().min(params.speed_scale_top_m_s);
            }
            moving |= d != 0.0;
            if params.travel_noise_m_per_sqrt_m > 0.0 && d != 0.0 {
                let n: f64 = rng.sample(StandardNormal);
                d += params.travel_noise_m_per_sqrt_m * d.abs().sqrt() * n;
            }
            let owed = self.pending_loss[i];
            if owed > 0.0 && d != 0.0 {
                let take = owed.min(d.abs());
                d -= take.copysign(d);
                self.pending_loss[i] = owed - take;
            }
            let want = d / dt;
            self.contacts[i] = match params.mu {
                _ if params.mech.creep_s > 0.0 => {
                    // Creep: the contact follows the wheel with slip = creep_s * its
                    // acceleration (first-order, exact for a held wheel speed).
                    let now = geom.contact_speed(i, &self.wheel_twist);
                    now + (want - now) * (1.0 - (-dt / params.mech.creep_s).exp())
                }
                Some(_) if params.mech.slip == Mechanism::Body => want,
                None => want,
                Some(mu) => {
                    let mut a = mu * crate::G * params.driven_load_share;
                    if !surface.patches.is_empty() {
                        let wx = self.pose.x + ct * g.x - st * g.y;
                        let wy = self.pose.y + st * g.x + ct * g.y;
                        a *= surface.mu_scale_at(wx, wy);
                    }
                    let now = geom.contact_speed(i, &self.wheel_twist);
                    now + (want - now).clamp(-a * dt, a * dt)
                }
            };
        }
        let toward_zero = |v: f64, a: f64| v - v.clamp(-a * dt, a * dt);
        let coast = Twist::new(
            toward_zero(self.wheel_twist.vx, COAST_DECEL_M_S2),
            toward_zero(self.wheel_twist.vy, COAST_DECEL_M_S2),
            toward_zero(self.wheel_twist.omega, COAST_DECEL_RAD_S2),
        );
        let prev = self.wheel_twist;
        self.wheel_twist = if geom.skid_steer {
            params.tyre.balance(geom, &self.contacts, &coast)
        } else {
            geom.twist_from_contacts(&self.contacts, &coast)
        };
        if let (Some(mu), Mechanism::Body) = (params.mu, params.mech.slip) {
            // The body's linear acceleration is bounded (its heading is not).
            let a = mu * crate::G * params.driven_load_share * dt;
            let (dx, dy) = (self.wheel_twist.vx - prev.vx, self.wheel_twist.vy - prev.vy);
            let d = dx.hypot(dy);
            if d > a {
                self.wheel_twist.vx = prev.vx + dx * a / d;
                self.wheel_twist.vy = prev.vy + dy * a / d;
            }
        }
        let mut w = self.wheel_twist;
        if let (true, Some(lever)) = (params.turn_scrub != 0.0, geom.turn_lever) {
            // An omni robot whose wheels' effective distance from the centre grows from a
            // turn in place to an arc (the contact moving across the rollers), by
            // `turn_scrub` in the share `calib_core::kinematics::turn_law_share` gives at
            // the smoothed twist's turn ratio.
            let k = dt / (calib_core::diff_laws::TURN_RATIO_TIME_S + dt);
            let now = [w.vx, w.vy, w.omega * lever];
            for (s, v) in self.twist_smooth.iter_mut().zip(now) {
                *s += k * (v - *s);
            }
            let [vx, vy, turn] = self.twist_smooth;
            let rho = calib_core::kinematics::turn_ratio(vx.hypot(vy), turn);
            w.omega /= 1.0 + params.turn_scrub * calib_core::kinematics::turn_law_share(rho);
        } else if params.turn_scrub != 0.0 && !geom.skid_steer {
            // Wide tyres: the contact patches sit at the inner edges in a turn in place and
            // roll on their centres on arcs and straight lines, so the effective
            // separation grows by `turn_scrub` from the first to the second, in the share
            // `calib_core::kinematics::turn_law_share` gives.
            let (mut l, mut r, mut nl, mut nr) = (0.0, 0.0, 0.0, 0.0);
            for (g, c) in geom.wheels.iter().zip(&self.contacts) {
                if g.driven && g.y >= 0.0 {
                    l += c;
                    nl += 1.0;
                } else if g.driven {
                    r += c;
                    nr += 1.0;
                }
            }
            let (l, r) = (l / f64::max(nl, 1.0), r / f64::max(nr, 1.0));
            let k = dt / (calib_core::diff_laws::TURN_RATIO_TIME_S + dt);
            let (sl, sr) = self.sides;
            self.sides = (sl + k * (l - sl), sr + k * (r - sr));
            let (l, r) = self.sides;
            let den = l.abs() + r.abs();
            let rho = if den > 0.0 { (r - l).abs() / den } else { 1.0 };
            w.omega /= 1.0 + params.turn_scrub * calib_core::kinematics::turn_law_share(rho);
        }
        let side = match params.mech.lateral {
            Mechanism::Saturating if params.mech.lateral_sat_m_s.is_finite() => {
                let s = params.mech.lateral_sat_m_s;
                s * (params.side_slip_s * w.vx * w.omega / s).tanh()
            }
            _ => params.side_slip_s * w.vx * w.omega,
        };
        let mut body = Twist::new(w.vx, w.vy - side, w.omega);
        if let (Some(tilt), true) = (surface.tilt, moving) {
            // World drift expressed in the body frame.
            let (sd, cd) = (tilt.direction_rad - self.pose.theta).sin_cos();
            body.vx += tilt.drift_m_s * cd;
            body.vy += tilt.drift_m_s * sd;
        }
        self.body_twist = body;
        let before = self.pose;
        self.pose = integrate_arc(before, &body.scale(dt));
        for (i, g) in geom.wheels.iter().enumerate() {
            if !g.driven {
                dphi[i] = geom.contact_speed(i, &body) * dt / g.r_eff;
            }
        }
        if let Some(cables) = &surface.cables {
            let (nx, ny) = cables.normal();
            let (st1, ct1) = self.pose.theta.sin_cos();
            for (i, g) in geom.wheels.iter().enumerate() {
                let s0 =
                    nx * (before.x + ct * g.x - st * g.y) + ny * (before.y + st * g.x + ct * g.y);
                let s1 = nx * (self.pose.x + ct1 * g.x - st1 * g.y)
                    + ny * (self.pose.y + st1 * g.x + ct1 * g.y);
                let k = cables.crossings(s0, s1);
                if k > 0 {
                    self.crossings[i] += k as u64;
                    // Only the part of the climb along the rolling direction costs travel
                    // (an omni wheel crossing on its rollers is not held back).
                    let (dx, dy) = g.direction();
                    let along = (nx * (ct1 * dx - st1 * dy) + ny * (st1 * dx + ct1 * dy)).abs();
                    if g.driven {
                        self.pending_loss[i] += k as f64 * cables.loss_m * along;
                    }
                }
            }
        }
    }
}
