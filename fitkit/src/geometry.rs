//! The robot a fit's geometry parameters describe.

use calib_core::robot::Robot;

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
