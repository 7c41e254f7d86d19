//! Ground-stage mechanism variants: the body-acceleration and creep forms of traction
//! slip (applied to the wheel angles before the ground stage), saturating side slip, and
//! cables over the whole floor or in a region. Each is a variant of a catalogue
//! [`Effect`] (its [`Effect::base`]), fitted like any candidate.

use crate::effects::{Effect, Model};
use crate::replay::Prepared;
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};

/// Side slip of the lateral-slip mechanisms as a displacement over one row: linear
/// v_y = -k v_x omega, or saturating at `sat`: v_y = -sat tanh(k v_x omega / sat).
pub fn side_slip(m: &Model, d: &Twist<f64>, dt: f64) -> f64 {
    let dt = dt.max(1e-12);
    if let Some(p) = m.get(Effect::LateralSaturating) {
        // A saturation speed of a nanometre per second is no side slip at all.
        let (k, sat) = (p[0], p[1].max(1e-9));
        let v = k * (d.vx / dt) * (d.omega / dt);
        return -sat * (v / sat).tanh() * dt;
    }
    match m.get(Effect::LateralSlip) {
        Some(p) => -p[0] * d.vx * d.omega / dt,
        None => 0.0,
    }
}

/// Cables (spacing, loss) of either floor_bumps mechanism, with the region's bounds in
/// world x (infinite for the whole floor).
pub fn cables(m: &Model) -> Option<(f64, f64, f64, f64)> {
    if let Some(p) = m.get(Effect::BumpsRegion) {
        return Some((p[0], p[1], p[2].min(p[3]), p[2].max(p[3])));
    }
    m.get(Effect::FloorBumps)
        .map(|p| (p[0], p[1], f64::NEG_INFINITY, f64::INFINITY))
}

/// The cable cell of world x within [lo, hi] (x clamped to them): the cables crossed
/// between two points within [lo, hi] are the difference of their cells, so a path's walk
/// computes each point's cell once.
pub fn cable_cell(x: f64, spacing: f64, lo: f64, hi: f64) -> f64 {
    (x.max(lo).min(hi) / spacing).floor()
}

/// Whether a mechanism variant can act on this recording. Creep rewrites the driven
/// wheels' angles and needs every wheel driven (a free wheel would report the body). The
/// body bound needs every wheel's angles, and, with free wheels, driven wheels that
/// resolve the body twist on their own (what the drive asks for).
pub fn applies(p: &Prepared, e: Effect) -> bool {
    let all_driven = p.robot.wheels.iter().all(|w| w.driven);
    let all_known = p.wheels.iter().all(|w| w.enc_rad.is_some());
    match e {
        Effect::SlipCreep => all_driven,
        Effect::SlipBody => all_driven || (all_known && driven_kinematics(&p.robot).is_some()),
        _ => true,
    }
}

/// The driven wheels' kinematics (indices into the robot's wheels), when they resolve the
/// body twist on their own.
fn driven_kinematics(robot: &calib_core::Robot) -> Option<(Kinematics<f64>, Vec<usize>)> {
    let idx: Vec<usize> = (0..robot.wheels.len())
        .filter(|&i| robot.wheels[i].driven)
        .collect();
    if idx.is_empty() {
        return None;
    }
    let mut sub = robot.clone();
    sub.wheels.clear();
    for &i in &idx {
        let _ = sub.wheels.push(robot.wheels[i].clone());
    }
    Kinematics::<f64>::new(&sub, &Corrections::None)
        .ok()
        .map(|k| (k, idx))
}

/// What the drive asks of the body: the driven wheels' rolling rows fix the motion they
/// can; every standard wheel's sliding row, free ones included, fixes the rest, as in the
/// ground stage's least squares. The driven front pair of a wheeled-legged robot alone
/// would put the body's sideways velocity at its own axle (vy = -omega x_front), which
/// the body never does while its rear axle holds too; under a traction bound that
/// phantom sideways speed would spend grip the robot does not spend.
struct DriveAsks {
    /// Inverse of the normal matrix: driven rolling rows and all sliding rows.
    inv: calib_core::linalg::Mat3,
    /// Driven wheels: index and rolling row in rad per metre.
    driven: Vec<(usize, [f64; 3])>,
}

impl DriveAsks {
    fn new(robot: &calib_core::Robot) -> Option<Self> {
        let sliding = robot.kind.wheels_have_sliding_constraint();
        let mut n = [[0.0; 3]; 3];
        let mut driven = Vec::new();
        for (i, w) in robot.wheels.iter().enumerate() {
            let (roll, slide) = w.constraint_rows(w.radius_m, 1.0);
            for a in 0..3 {
                for b in 0..3 {
                    if w.driven {
                        n[a][b] += roll[a] * roll[b];
                    }
                    if sliding {
                        n[a][b] += slide[a] * slide[b];
                    }
                }
            }
            if w.driven {
                driven.push((i, roll));
            }
        }
        let inv = calib_core::linalg::inverse3(&n)?;
        Some(DriveAsks { inv, driven })
    }

    /// The body twist for the driven wheels' rates (rad/s, in `driven`'s order).
    fn twist(&self, rates: &[f64]) -> Twist<f64> {
        let mut b = [0.0; 3];
        for ((_, row), r) in self.driven.iter().zip(rates) {
            for a in 0..3 {
                b[a] += row[a] * r;
            }
        }
        let x = |a: usize| -> f64 { (0..3).map(|c| self.inv[a][c] * b[c]).sum() };
        Twist::new(x(0), x(1), x(2))
    }
}

/// The wheel angles the ground stage should use under the body-bound or creep forms of
/// traction slip (`None`: the model has neither, use the measured angles).
pub fn slip_angles(
    p: &Prepared,
    m: &Model,
    angles: &[Option<&[f64]>],
) -> Option<Vec<Option<Vec<f64>>>> {
    let body = m.get(Effect::SlipBody).map(|v| v[0]);
    let creep = m.get(Effect::SlipCreep).map(|v| v[0]);
    if body.is_none() && creep.is_none() {
        return None;
    }
    let n = p.rows();
    let robot = m.apply_geometry(&p.robot);
    let mut out: Vec<Option<Vec<f64>>> = angles.iter().map(|a| a.map(|s| s.to_vec())).collect();
    if let Some(tc) = creep {
        // Each contact follows its wheel with slip = creep_s * acceleration.
        for (i, a) in out.iter_mut().enumerate() {
            let Some(a) = a else { continue };
            if !robot.wheels[i].driven {
                continue;
            }
            let src = a.clone();
            let mut c = 0.0;
            let mut pos = src[0];
            for k in 0..n - 1 {
                let dt = (p.t[k + 1] - p.t[k]).max(fitkit::MIN_DT_S);
                let want = (src[k + 1] - src[k]) / dt;
                let e = (-dt / tc.max(fitkit::MIN_DT_S)).exp();
                pos += want * dt + (c - want) * tc * (1.0 - e);
                c = want + (c - want) * e;
                a[k + 1] = pos;
            }
        }
    }
    if let Some(mu) = body {
        let known: Vec<usize> = (0..out.len()).filter(|&i| out[i].is_some()).collect();
        if known.len() != robot.wheels.len() {
            return Some(out);
        }
        if !robot.wheels.iter().all(|w| w.driven) {
            body_bound_with_free_wheels(p, &robot, mu, &mut out);
            return Some(out);
        }
        let Ok(kin) = Kinematics::<f64>::new(&robot, &Corrections::None) else {
            return Some(out);
        };
        let m_w = known.len();
        let mut inc = vec![0.0; m_w];
        let mut dw = vec![0.0; m_w];
        // Body velocity from the wheels, over three rows (encoder quantisation).
        let vel = |k: usize, inc: &mut [f64], out: &[Option<Vec<f64>>]| -> Twist<f64> {
            let (k1, k2) = (k.saturating_sub(1), (k + 2).min(n - 1));
            let span = (p.t[k2] - p.t[k1]).max(fitkit::MIN_DT_S);
            for (j, &i) in known.iter().enumerate() {
                let a = out[i].as_ref().expect("known");
                inc[j] = (a[k2] - a[k1]) / span;
            }
            kin.forward(inc)
        };
        let mut v: Option<(f64, f64)> = None;
        let mut shift = vec![0.0; m_w];
        let src = out.clone();
        for k in 0..n - 1 {
            let dt = (p.t[k + 1] - p.t[k]).max(fitkit::MIN_DT_S);
            let want = vel(k, &mut inc, &src);
            let ((vx0, vy0), (vx1, vy1)) = follow(&mut v, &want, mu * p.driven_share[k], dt);
            // Body displacement lost (or gained) this row against what the wheels say.
            let diff = Twist::new(
                (0.5 * (vx0 + vx1) - want.vx) * dt,
                (0.5 * (vy0 + vy1) - want.vy) * dt,
                0.0,
            );
            kin.inverse_into(&diff, &mut dw);
            for (j, &i) in known.iter().enumerate() {
                shift[j] += dw[j];
                if let Some(a) = out[i].as_mut() {
                    a[k + 1] = src[i].as_ref().expect("known")[k + 1] + shift[j];
                }
            }
        }
    }
    Some(out)
}

/// One row of the body bound: the body's linear velocity `v` (the asked one at the first
/// row) moves towards what the wheels ask by at most `mu_share` g dt. Returns the
/// velocity at the row's start and end.
fn follow(
    v: &mut Option<(f64, f64)>,
    want: &Twist<f64>,
    mu_share: f64,
    dt: f64,
) -> ((f64, f64), (f64, f64)) {
    let a = (mu_share * crate::replay::G).max(1e-12) * dt;
    let (vx0, vy0) = *v.get_or_insert((want.vx, want.vy));
    let (dx, dy) = (want.vx - vx0, want.vy - vy0);
    let d = dx.hypot(dy);
    let f = if d > a { a / d } else { 1.0 };
    let end = (vx0 + dx * f, vy0 + dy * f);
    *v = Some(end);
    ((vx0, vy0), end)
}

/// The body bound on a robot with free wheels: the driven wheels say what the drive asks
/// of the body; its linear velocity follows at most `mu g` times the driven wheels'
/// share of the weight per second (the yaw rate as asked), and every wheel's angle is
/// then what that body motion makes of it. The free wheels' encoders, which roll with
/// the body, are compared with those angles by the ground stage, not used to drive it.
fn body_bound_with_free_wheels(
    p: &Prepared,
    robot: &calib_core::Robot,
    mu: f64,
    out: &mut [Option<Vec<f64>>],
) {
    let Some(drive) = DriveAsks::new(robot) else {
        return;
    };
    let idx: Vec<usize> = drive.driven.iter().map(|d| d.0).collect();
    let Ok(all) = Kinematics::<f64>::new(robot, &Corrections::None) else {
        return;
    };
    let n = p.rows();
    let src: Vec<Vec<f64>> = idx
        .iter()
        .map(|&i| out[i].clone().expect("every wheel has angles"))
        .collect();
    let mut rates = vec![0.0; idx.len()];
    // What the drive asks, over three rows (encoder quantisation).
    let asked = |k: usize, rates: &mut [f64]| -> Twist<f64> {
        let (k1, k2) = (k.saturating_sub(1), (k + 2).min(n - 1));
        let span = (p.t[k2] - p.t[k1]).max(fitkit::MIN_DT_S);
        for (r, a) in rates.iter_mut().zip(&src) {
            *r = (a[k2] - a[k1]) / span;
        }
        drive.twist(rates)
    };
    let (mut dw, mut dw_body) = (vec![0.0; robot.wheels.len()], vec![0.0; robot.wheels.len()]);
    let mut angle: Vec<f64> = out
        .iter()
        .map(|a| a.as_ref().map_or(0.0, |a| a[0]))
        .collect();
    let mut v: Option<(f64, f64)> = None;
    for k in 0..n - 1 {
        let dt = (p.t[k + 1] - p.t[k]).max(fitkit::MIN_DT_S);
        let want = asked(k, &mut rates);
        let ((vx0, vy0), (vx1, vy1)) = follow(&mut v, &want, mu * p.driven_share[k], dt);
        // The driven wheels keep their own increments less what the body did not follow;
        // the free wheels roll with the body.
        let body = Twist::new(0.5 * (vx0 + vx1) * dt, 0.5 * (vy0 + vy1) * dt, 0.0);
        let lag = Twist::new(body.vx - want.vx * dt, body.vy - want.vy * dt, 0.0);
        all.inverse_into(&lag, &mut dw);
        all.inverse_into(&Twist::new(body.vx, body.vy, want.omega * dt), &mut dw_body);
        for (i, a) in out.iter_mut().enumerate() {
            let Some(a) = a else { continue };
            angle[i] += match idx.iter().position(|&x| x == i) {
                Some(j) => src[j][k + 1] - src[j][k] + dw[i],
                None => dw_body[i],
            };
            a[k + 1] = angle[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::Robot;

    fn wlr() -> Robot {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/wlr.toml");
        formats::robot_file::load(&p).expect("robots/wlr.toml")
    }

    /// Contact speeds of the driven wheels for a body twist, as wheel rates (rad/s).
    fn rates_for(robot: &Robot, asks: &DriveAsks, t: &Twist<f64>) -> Vec<f64> {
        asks.driven
            .iter()
            .map(|&(i, _)| {
                let w = &robot.wheels[i];
                let row = w.rolling_row();
                (row[0] * t.vx + row[1] * t.vy + row[2] * t.omega)
                    / (w.radius_m * w.gamma_rad.cos())
            })
            .collect()
    }

    /// The wheeled-legged robot turns about its middle: front and rear axles both hold
    /// their wheels sideways, so what the driven front pair asks has no sideways velocity
    /// at the body origin. The front pair alone would put it at -omega x_front (0.175 m).
    #[test]
    fn a_legged_turn_has_no_sideways_velocity_at_the_middle() {
        let robot = wlr();
        let asks = DriveAsks::new(&robot).expect("the front pair resolves vx and omega");
        let t = Twist::new(0.3, 0.0, 1.2);
        let rates = rates_for(&robot, &asks, &t);
        let got = asks.twist(&rates);
        // Sliding rows weigh 1e-3 of a rolling row: they pull the turn rate by about
        // 1e-6 (x / y)^2 per axle, 2.4e-6 here; 1e-5 allows for that.
        assert!((got.vx - 0.3).abs() < 1e-5 * 0.3, "vx {}", got.vx);
        assert!((got.omega - 1.2).abs() < 1e-5 * 1.2, "omega {}", got.omega);
        assert!(got.vy.abs() < 1e-9, "vy {}", got.vy);
        // The front pair on its own (the old reading) puts the sideways velocity at its axle.
        let (front, _) = driven_kinematics(&robot).expect("front pair");
        let alone = front.forward(&rates);
        assert!(
            (alone.vy + 1.2 * 0.175).abs() < 1e-3 * 0.21,
            "vy alone {}",
            alone.vy
        );
    }

    /// With the rear axle moved to x = -0.1 m the body turns about the middle of the two
    /// axles (equal sliding weights): vy = -omega (0.175 - 0.1) / 2.
    #[test]
    fn an_asymmetric_body_turns_about_the_middle_of_its_axles() {
        let mut robot = wlr();
        for w in robot.wheels.iter_mut().filter(|w| !w.driven) {
            let (x, y): (f64, f64) = (-0.1, w.position().1);
            w.l_m = x.hypot(y);
            let alpha = y.atan2(x);
            // Keep the rolling direction along body x: beta = 90 deg - alpha (mod 2 pi).
            w.beta_rad += w.alpha_rad - alpha;
            w.alpha_rad = alpha;
        }
        let asks = DriveAsks::new(&robot).expect("front pair");
        let t = Twist::new(-0.2, 0.0, -0.8);
        let rates = rates_for(&robot, &asks, &t);
        let got = asks.twist(&rates);
        let want_vy = 0.8 * (0.175 - 0.1) / 2.0;
        assert!(
            (got.vy - want_vy).abs() < 1e-6,
            "vy {} want {want_vy}",
            got.vy
        );
        assert!((got.omega + 0.8).abs() < 1e-5 * 0.8, "omega {}", got.omega);
    }

    /// The cells' difference counts the cables between two points within the region:
    /// the multiples of the spacing in (min, max] clamped to [lo, hi], counted one by one.
    #[test]
    fn cable_cells_count_the_cables_between_two_points_in_the_region() {
        let spacing = 0.05;
        let count = |x0: f64, x1: f64, lo: f64, hi: f64| -> f64 {
            let (a, b) = (x0.min(x1).max(lo), x0.max(x1).min(hi));
            (-100..=100)
                .map(|k| k as f64 * spacing)
                .filter(|c| *c > a && *c <= b)
                .count() as f64
        };
        let xs = [
            -1.013, -0.26, -0.051, 0.0001, 0.049, 0.151, 0.333, 0.72, 1.207,
        ];
        let regions = [
            (f64::NEG_INFINITY, f64::INFINITY),
            (-0.27, 0.34),
            (0.16, 0.18),
        ];
        for &(lo, hi) in &regions {
            for &x0 in &xs {
                for &x1 in &xs {
                    let cells =
                        (cable_cell(x1, spacing, lo, hi) - cable_cell(x0, spacing, lo, hi)).abs();
                    assert_eq!(cells, count(x0, x1, lo, hi), "{x0} -> {x1} in [{lo}, {hi}]");
                }
            }
        }
        // Over the whole floor from -1.013 to 1.207 m: the cables at -1.00, -0.95, ..., 1.20 m.
        assert_eq!(
            cable_cell(1.207, spacing, f64::NEG_INFINITY, f64::INFINITY)
                - cable_cell(-1.013, spacing, f64::NEG_INFINITY, f64::INFINITY),
            45.0
        );
    }
}
