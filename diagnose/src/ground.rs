//! Ground stage: wheel angles -> body motion, with the fitted geometry and the ground
//! effects (traction limit, side slip, floor bumps) applied to each sample's body
//! displacement before it is integrated as an exact arc.
//!
//! The nominal model is what the firmware's odometry does: least-squares forward
//! kinematics of all wheels, integrated per sample.

use crate::effects::{Effect, Model};
use crate::replay::{Prepared, G};
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::odometry::{integrate_arc, Pose};
use calib_core::robot::Robot;

/// Predicted poses, starting at the origin with heading 0.
#[derive(Debug, Clone, Default)]
pub struct Path {
    /// At every row.
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub theta: Vec<f64>,
    /// Body displacement over each interval (row k to k+1), body frame.
    pub step: Vec<Twist<f64>>,
}

/// The robot with radius and wheelbase multipliers and (wheeled-legged) the wheel
/// contacts moved along x by the leg angles. The wheel plane direction alpha + beta is
/// kept, so each wheel still rolls the way it did.
pub fn geometry_at(base: &Robot, scales: &[f64], eb: f64, legs: Option<(f64, f64)>) -> Robot {
    let mut r = base.clone();
    for (i, w) in r.wheels.iter_mut().enumerate() {
        w.radius_m *= scales.get(i).copied().unwrap_or(1.0);
        w.l_m *= eb;
    }
    if let (Some((lf, lr)), Some(geom)) = (legs, base.legs) {
        let (xf, xr) = geom.wheel_x(lf, lr);
        for w in r.wheels.iter_mut() {
            let (x0, y) = w.position();
            let x = if x0 > 0.0 { xf } else { xr };
            let plane = w.alpha_rad + w.beta_rad;
            w.alpha_rad = y.atan2(x);
            w.l_m = x.hypot(y);
            w.beta_rad = plane - w.alpha_rad;
        }
    }
    r
}

/// Only the driven wheels (what a traction-limited model reads its wheel speed from).
fn driven_only(r: &Robot) -> Option<Robot> {
    let mut d = r.clone();
    d.wheels.retain(|w| w.driven);
    (d.wheels.len() >= 2 && d.wheels.len() < r.wheels.len()).then_some(d)
}

/// Forward kinematics that follows the leg angles, rebuilt only when they move.
struct KinCache {
    base: Robot,
    scales: Vec<f64>,
    eb: f64,
    legs: Option<(f64, f64)>,
    all: Option<Kinematics<f64>>,
    driven: Option<(Kinematics<f64>, Vec<usize>)>,
}

impl KinCache {
    fn new(base: &Robot, scales: Vec<f64>, eb: f64) -> Self {
        KinCache {
            base: base.clone(),
            scales,
            eb,
            legs: None,
            all: None,
            driven: None,
        }
    }

    fn update(&mut self, legs: Option<(f64, f64)>, want_driven: bool) {
        let stale = match (self.legs, legs) {
            (Some(a), Some(b)) => (a.0 - b.0).abs() > 1e-4 || (a.1 - b.1).abs() > 1e-4,
            (None, None) => self.all.is_none(),
            _ => true,
        };
        if !stale {
            return;
        }
        self.legs = legs;
        let g = geometry_at(&self.base, &self.scales, self.eb, legs);
        self.all = Kinematics::new(&g, &Corrections::None).ok();
        self.driven = if want_driven {
            driven_only(&g).and_then(|d| {
                let idx = g
                    .wheels
                    .iter()
                    .enumerate()
                    .filter(|(_, w)| w.driven)
                    .map(|(i, _)| i)
                    .collect();
                Kinematics::new(&d, &Corrections::None).ok().map(|k| (k, idx))
            })
        } else {
            None
        };
    }
}

/// Integrates the model over the recording. `angles[i]` is wheel i's angle per row (from
/// its encoder or from the actuator model); `None` for a wheel nobody measured or
/// commanded (it then contributes a zero increment, which only happens for undriven
/// wheels without encoders).
pub fn simulate(p: &Prepared, angles: &[Option<&[f64]>], model: &Model, out: &mut Path) {
    let n = p.rows();
    out.x.clear();
    out.y.clear();
    out.theta.clear();
    out.step.clear();
    let (scales, eb) = model.geometry(&p.robot);
    // Wheels without any angle series must not vote in the least squares.
    let mut robot = p.robot.clone();
    let known: Vec<usize> = (0..angles.len()).filter(|&i| angles[i].is_some()).collect();
    let mut scales_known = scales.clone();
    if known.len() < robot.wheels.len() {
        let keep: Vec<_> = known.iter().map(|&i| robot.wheels[i].clone()).collect();
        robot.wheels.clear();
        for w in keep {
            let _ = robot.wheels.push(w);
        }
        scales_known = known.iter().map(|&i| scales[i]).collect();
    }
    let mu = model.get(Effect::LongitudinalSlip).map(|v| v[0]);
    let side = model.get(Effect::LateralSlip).map(|v| v[0]);
    let bumps = model.get(Effect::FloorBumps).map(|v| (v[0], v[1]));
    let mut cache = KinCache::new(&robot, scales_known, eb);
    let mut pose = Pose::new(0.0, 0.0, 0.0);
    out.x.reserve(n);
    out.y.reserve(n);
    out.theta.reserve(n);
    out.step.reserve(n);
    out.x.push(0.0);
    out.y.push(0.0);
    out.theta.push(0.0);
    let mut inc = vec![0.0; known.len()];
    let mut v_body: Option<f64> = None;
    let mut travelled = 0.0;
    let mut crossings_done = 0.0;
    let mut owed = 0.0;
    for k in 0..n.saturating_sub(1) {
        let dt = p.t[k + 1] - p.t[k];
        cache.update(p.leg_angles(k), mu.is_some());
        for (j, &i) in known.iter().enumerate() {
            let a = angles[i].expect("known wheels have angles");
            inc[j] = a[k + 1] - a[k];
        }
        let mut d = match &cache.all {
            Some(kin) => kin.forward(&inc),
            None => Twist::zero(),
        };
        if let Some(mu) = mu {
            // Traction limit: the body's forward speed follows what the driven wheels
            // roll, but cannot change faster than mu * g * (load share on them).
            let wheel_d = match &cache.driven {
                Some((kin, idx)) => {
                    let sub: Vec<f64> = idx
                        .iter()
                        .map(|&i| known.iter().position(|&q| q == i).map_or(0.0, |j| inc[j]))
                        .collect();
                    kin.forward(&sub)
                }
                None => d,
            };
            let v_in = wheel_d.vx / dt;
            let a_max = mu * G * p.driven_share[k];
            let v = match v_body {
                None => v_in,
                Some(v) => v + (v_in - v).clamp(-a_max * dt, a_max * dt),
            };
            v_body = Some(v);
            d = Twist::new(v * dt, wheel_d.vy, wheel_d.omega);
        }
        if let Some(k_side) = side {
            // v_y = -k v_x omega, as a displacement over the interval.
            d.vy += -k_side * d.vx * d.omega / dt;
        }
        if let Some((spacing, loss)) = bumps {
            let ds = d.vx.hypot(d.vy);
            if ds > 0.0 && spacing > 0.0 {
                travelled += ds;
                // Crossings at travelled = spacing/2, 3 spacing/2, ...
                let crossings = (travelled / spacing + 0.5).floor();
                // Travel lost at a crossing is taken from this and the next samples.
                owed += (crossings - crossings_done) * loss;
                crossings_done = crossings;
                if owed > 0.0 {
                    let take = owed.min(ds);
                    owed -= take;
                    d.vx *= 1.0 - take / ds;
                    d.vy *= 1.0 - take / ds;
                }
            }
        }
        pose = integrate_arc(pose, &d);
        out.x.push(pose.x);
        out.y.push(pose.y);
        out.theta.push(pose.theta);
        out.step.push(d);
    }
}
