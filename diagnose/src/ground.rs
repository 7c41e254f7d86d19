//! Ground stage: wheel angles -> body motion, with the fitted geometry and the ground
//! effects (traction limit, side slip, floor bumps) applied to each sample's body
//! displacement before it is integrated as an exact arc.
//!
//! The nominal model is what the firmware's odometry does: least-squares forward
//! kinematics of all wheels, integrated per sample.

pub mod variants;

use crate::effects::{Effect, Model};
use crate::replay::{Prepared, G};
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::odometry::Pose;
use calib_core::robot::Robot;
use fitkit::geometry::geometry_at;

/// Exact-arc integration (as calib-core's `integrate_arc`) that carries the heading's
/// cosine and sine from sample to sample instead of calling sin/cos twice per sample:
/// the arc coefficients sin(d)/d and (1 - cos d)/d also give cos d and sin d.
struct Heading {
    c: f64,
    s: f64,
    count: u32,
}

impl Heading {
    fn new() -> Self {
        Heading {
            c: 1.0,
            s: 0.0,
            count: 0,
        }
    }

    fn advance(&mut self, pose: &mut Pose<f64>, d: &Twist<f64>) {
        let w = d.omega;
        let (a, b) = if w.abs() < 0.05 {
            // Series to w^4: truncation below 1e-11 relative at |w| = 0.05.
            let w2 = w * w;
            (
                1.0 - w2 / 6.0 * (1.0 - w2 / 20.0),
                w / 2.0 * (1.0 - w2 / 12.0 * (1.0 - w2 / 30.0)),
            )
        } else {
            (w.sin() / w, (1.0 - w.cos()) / w)
        };
        let lx = a * d.vx - b * d.vy;
        let ly = b * d.vx + a * d.vy;
        pose.x += self.c * lx - self.s * ly;
        pose.y += self.s * lx + self.c * ly;
        pose.theta += w;
        // cos w = 1 - w b, sin w = w a.
        let (cw, sw) = (1.0 - w * b, w * a);
        let (c, s) = (self.c * cw - self.s * sw, self.s * cw + self.c * sw);
        self.count += 1;
        if self.count & 255 == 0 {
            let (sn, cn) = pose.theta.sin_cos();
            (self.c, self.s) = (cn, sn);
        } else {
            (self.c, self.s) = (c, s);
        }
    }
}

/// (effective radius r cos(gamma), rolling direction, position, driven) of a wheel.
type ContactWheel = (f64, (f64, f64), (f64, f64), bool);

/// Predicted poses, starting at the origin with heading 0.
///
/// A fit compares the model with the measured poses only, so its paths hold the pose
/// rows alone ([`Rows::Poses`]); the windows and the localisation read a path at every
/// row ([`Rows::All`]).
#[derive(Debug, Clone, Default)]
pub struct Path {
    /// Predicted x, m: at each pose row (`Prepared::poses.row`), or at every row when
    /// `per_row`.
    pub x: Vec<f64>,
    /// Predicted y, m, at the same rows as `x`.
    pub y: Vec<f64>,
    /// Predicted heading, rad (not wrapped), at the same rows as `x`.
    pub theta: Vec<f64>,
    /// Whether `x`, `y`, `theta` and `step` are per row.
    pub per_row: bool,
    /// Body displacement over each interval (row k to k+1), body frame (per-row paths
    /// only).
    pub step: Vec<Twist<f64>>,
    /// Undriven wheels with encoders: (wheel index, predicted angle per row). They roll
    /// with the body, so the model predicts what their encoders must read.
    pub free: Vec<(usize, Vec<f64>)>,
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
                Kinematics::new(&d, &Corrections::None)
                    .ok()
                    .map(|k| (k, idx))
            })
        } else {
            None
        };
    }
}

/// Which rows a path holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Rows {
    /// The pose rows only (what a fit compares).
    Poses,
    /// Every row, with the steps between them.
    All,
}

/// Integrates the model over the recording. `angles[i]` is wheel i's angle per row (from
/// its encoder or from the actuator model); `None` for a wheel nobody measured or
/// commanded (it is left out of the least squares).
///
/// Floor-fixed effects (cables across world x) need the robot's world pose: they take
/// the measured pose, interpolated between samples, not the model's own dead-reckoned
/// pose, whose drift is exactly what is being diagnosed.
pub fn simulate(
    p: &Prepared,
    angles: &[Option<&[f64]>],
    model: &Model,
    rows: Rows,
    out: &mut Path,
) {
    out.reset(rows == Rows::All);
    let (ground, cache) = GroundModel::new(p, angles, model);
    let mut walk = Walk::start(p, &ground, cache, out);
    // Steps between the ground rows (every pose row, at most 1 / GROUND_RATE_HZ apart);
    // the rows between are interpolated (counts are cumulative, so the coarser
    // step loses no odometry, and the stage runs at a fraction of the cost).
    let gr = &p.ground_rows;
    for s_idx in 0..gr.len().saturating_sub(1) {
        let (k, k_next) = (gr[s_idx], gr[s_idx + 1]);
        let dt = p.t[k_next] - p.t[k];
        let d = walk.step(p, angles, model, &ground, s_idx, dt);
        walk.record(p, &ground, (k, k_next), dt, &d, out);
    }
}

impl Path {
    /// Empties the path for a new walk that holds every row (`per_row`) or the pose rows.
    fn reset(&mut self, per_row: bool) {
        self.per_row = per_row;
        self.x.clear();
        self.y.clear();
        self.theta.clear();
        self.step.clear();
        self.free.clear();
    }
}

/// What the model makes of the wheels for the whole walk: which wheels vote, where they
/// touch the ground, and the ground effects that act on them.
struct GroundModel {
    /// The wheels with an angle series (the others do not vote in the least squares).
    known: Vec<usize>,
    /// The known wheels' contacts.
    wheels: Vec<ContactWheel>,
    /// Traction limit of each known wheel, if the model has one.
    mu: Option<Vec<f64>>,
    /// Whether the model has side slip.
    side: bool,
    /// Cables across world x: (spacing, loss, lowest x, highest x).
    bumps: Option<(f64, f64, f64, f64)>,
    /// Whether each wheel's travel is worked out at its contact (traction or cables).
    per_wheel: bool,
    /// (index, rolling row / effective radius) of the free wheels the recording measured.
    free: Vec<(usize, [f64; 3])>,
}

impl GroundModel {
    /// The model's wheels on this recording, and the kinematics of the known wheels.
    fn new(p: &Prepared, angles: &[Option<&[f64]>], model: &Model) -> (Self, KinCache) {
        let (scales, eb) = model.geometry(&p.robot);
        let free = free_wheels(p, &scales, eb);
        // Wheels without any angle series must not vote in the least squares. A single
        // wheel's mounting error moves that wheel.
        let mut robot = model.apply_mounting(&p.robot);
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
        let mu = traction_limits(p, model, &known);
        // Mechanism variants live in `variants`.
        let side = model.get(Effect::LateralSlip).is_some()
            || model.get(Effect::LateralSaturating).is_some();
        let bumps = variants::cables(model);
        let per_wheel = mu.is_some() || bumps.is_some();
        // Effective radii and body-frame rolling directions and positions of the known wheels.
        let wheels: Vec<ContactWheel> = robot
            .wheels
            .iter()
            .zip(&scales_known)
            .map(|(w, s)| {
                let row = w.rolling_row();
                (
                    w.radius_m * s * w.gamma_rad.cos(),
                    (row[0], row[1]),
                    w.position(),
                    w.driven,
                )
            })
            .collect();
        let cache = KinCache::new(&robot, scales_known, eb);
        let ground = GroundModel {
            known,
            wheels,
            mu,
            side,
            bumps,
            per_wheel,
            free,
        };
        (ground, cache)
    }
}

/// (index, rolling row / effective radius) of the free wheels the recording measured.
fn free_wheels(p: &Prepared, scales: &[f64], eb: f64) -> Vec<(usize, [f64; 3])> {
    p.robot
        .wheels
        .iter()
        .enumerate()
        .filter(|(i, w)| !w.driven && p.wheels[*i].enc_rad.is_some())
        .map(|(i, w)| {
            let row = w.rolling_row();
            let r = w.radius_m * scales[i] * w.gamma_rad.cos();
            let l = eb;
            (i, [row[0] / r, row[1] / r, row[2] * l / r])
        })
        .collect()
}

/// Traction limits of the known wheels: one mu for every wheel, or each driven wheel
/// its own (`SlipPerWheel`, in the robot's order of driven wheels).
fn traction_limits(p: &Prepared, model: &Model, known: &[usize]) -> Option<Vec<f64>> {
    match (
        model.get(Effect::LongitudinalSlip),
        model.get(Effect::SlipPerWheel),
    ) {
        (Some(v), _) => Some(vec![v[0]; known.len()]),
        (None, Some(v)) => {
            let mut driven = 0;
            let of_wheel: Vec<f64> = p
                .robot
                .wheels
                .iter()
                .map(|w| {
                    if !w.driven {
                        return f64::INFINITY;
                    }
                    driven += 1;
                    v.get(driven - 1).copied().unwrap_or(f64::INFINITY)
                })
                .collect();
            Some(known.iter().map(|&i| of_wheel[i]).collect())
        }
        _ => None,
    }
}

/// World x of a body-frame point at row `k`, on the measured pose.
fn world_x(p: &Prepared, k: usize, (bx, by): (f64, f64)) -> f64 {
    let x = p.pose_at_row[k].0;
    let (c, s) = p.heading_cs_at_row[k];
    x + c * bx - s * by
}

/// World x component of a body-frame direction at row `k`, on the measured pose.
fn world_dir(p: &Prepared, k: usize, (dx, dy): (f64, f64)) -> f64 {
    let (c, s) = p.heading_cs_at_row[k];
    c * dx - s * dy
}

/// The walk's state from ground row to ground row: the dead-reckoned pose, the wheels'
/// contacts, and scratch buffers reused every step (this loop is the diagnosis' hot
/// path).
struct Walk {
    /// Forward kinematics at the current leg angles.
    cache: KinCache,
    /// The dead-reckoned pose.
    pose: Pose<f64>,
    /// Its heading's cosine and sine.
    heading: Heading,
    /// The next pose row to record (pose-row paths).
    next_pose: usize,
    /// Each known wheel's angle increment over the step.
    inc: Vec<f64>,
    /// Each known wheel's contact speed under a traction limit.
    contact: Option<Vec<f64>>,
    /// Travel each known wheel still owes to cables it rolled onto.
    owed: Vec<f64>,
    /// Each known wheel's travel at its contact over the step.
    disp: Vec<f64>,
    /// The same read over three samples (what a traction limit reacts to).
    smooth: Vec<f64>,
    /// The contact travel as a wheel angle.
    ang: Vec<f64>,
    /// The driven wheels' angles.
    sub: Vec<f64>,
    /// Each driven wheel's cable cell at the step's start (its end's at the step before).
    cells: Vec<f64>,
    /// Each free wheel's predicted angle.
    free_angle: Vec<f64>,
}

impl Walk {
    /// The walk at the first row: the path's first point where it holds one, its
    /// storage reserved.
    fn start(p: &Prepared, g: &GroundModel, cache: KinCache, out: &mut Path) -> Self {
        for (i, _) in &g.free {
            let mut v = Vec::with_capacity(p.rows());
            v.push(0.0);
            out.free.push((*i, v));
        }
        // Per row: the ground rows' steps, the rows between interpolated. Else the pose rows
        // (every pose row is a ground row).
        let per_row = out.per_row;
        let n = p.rows();
        let pose_rows = &p.poses.row;
        let mut next_pose = 0;
        let kept = if per_row { n } else { pose_rows.len() };
        out.x.reserve(kept);
        out.y.reserve(kept);
        out.theta.reserve(kept);
        if per_row {
            out.step.reserve(n);
        }
        if per_row || pose_rows.first() == Some(&0) {
            out.x.push(0.0);
            out.y.push(0.0);
            out.theta.push(0.0);
            next_pose = 1;
        }
        let m = g.known.len();
        let cells: Vec<f64> = match (g.bumps, p.ground_rows.first()) {
            (Some((spacing, _, lo, hi)), Some(&k0)) => g
                .wheels
                .iter()
                .map(|w| variants::cable_cell(world_x(p, k0, w.2), spacing.max(1e-6), lo, hi))
                .collect(),
            _ => Vec::new(),
        };
        Walk {
            cache,
            pose: Pose::new(0.0, 0.0, 0.0),
            heading: Heading::new(),
            next_pose,
            inc: vec![0.0; m],
            contact: None,
            owed: vec![0.0f64; m],
            disp: vec![0.0; m],
            smooth: vec![0.0; m],
            ang: vec![0.0; m],
            sub: vec![0.0; m],
            cells,
            free_angle: vec![0.0; g.free.len()],
        }
    }

    /// One step from ground row `s_idx` to the next (`dt` apart): the body displacement
    /// the wheels make, side slip added, integrated into the pose; cables crossed owe
    /// travel to the next steps. Returns the displacement.
    fn step(
        &mut self,
        p: &Prepared,
        angles: &[Option<&[f64]>],
        model: &Model,
        g: &GroundModel,
        s_idx: usize,
        dt: f64,
    ) -> Twist<f64> {
        let gr = &p.ground_rows;
        let (k, k_next) = (gr[s_idx], gr[s_idx + 1]);
        self.cache.update(p.leg_angles(k), g.mu.is_some());
        for (j, &i) in g.known.iter().enumerate() {
            let a = angles[i].expect("known wheels have angles");
            self.inc[j] = a[k_next] - a[k];
        }
        let mut d = if g.per_wheel {
            self.contact_travel(p, angles, g, s_idx, dt);
            self.body_twist(g)
        } else {
            match &self.cache.all {
                Some(kin) => kin.forward(&self.inc),
                None => Twist::zero(),
            }
        };
        if g.side {
            // v_y = -k v_x omega (or its saturating form), as a displacement.
            d.vy += variants::side_slip(model, &d, dt);
        }
        self.heading.advance(&mut self.pose, &d);
        if let Some(cables) = g.bumps {
            self.cross_cables(p, g, cables, k_next);
        }
        d
    }

    /// Each wheel's travel at its contact over the step (into `disp`, as an angle into
    /// `ang`): cables take their toll, traction bounds how fast the contact speed
    /// changes.
    fn contact_travel(
        &mut self,
        p: &Prepared,
        angles: &[Option<&[f64]>],
        g: &GroundModel,
        s_idx: usize,
        dt: f64,
    ) {
        let (wheels, inc, m) = (&g.wheels, &self.inc, g.known.len());
        let k = p.ground_rows[s_idx];
        let disp = &mut self.disp[..m];
        for j in 0..m {
            disp[j] = wheels[j].0 * inc[j];
        }
        let smooth_disp = &mut self.smooth[..m];
        smooth_disp.copy_from_slice(disp);
        if g.mu.is_some() {
            // The traction limit reacts to speed changes, and encoder quantisation
            // makes per-sample speeds jitter by a count per sample: read the speed
            // over three samples instead.
            let gr = &p.ground_rows;
            let (k1, k2) = (
                gr[s_idx.saturating_sub(1)],
                gr[(s_idx + 2).min(gr.len() - 1)],
            );
            let span = p.t[k2] - p.t[k1];
            for (j, &i) in g.known.iter().enumerate() {
                let a = angles[i].expect("known wheels have angles");
                if span > 0.0 {
                    smooth_disp[j] = wheels[j].0 * (a[k2] - a[k1]) / span * dt;
                }
            }
        }
        let owed = &mut self.owed;
        for j in 0..m {
            if owed[j] > 0.0 && disp[j] != 0.0 && wheels[j].3 {
                let take = owed[j].min(disp[j].abs());
                disp[j] -= take.copysign(disp[j]);
                owed[j] -= take;
            }
        }
        if let Some(mu) = &g.mu {
            let c = self
                .contact
                .get_or_insert_with(|| disp.iter().map(|d| d / dt).collect());
            for j in 0..m {
                if !wheels[j].3 {
                    continue;
                }
                let a = (mu[j] * G * p.driven_share[k]).max(1e-12);
                let want = (smooth_disp[j] - (wheels[j].0 * inc[j] - disp[j])) / dt;
                let gap = want - c[j];
                let t_reach = gap.abs() / a;
                if t_reach >= dt {
                    let e = c[j] + gap.signum() * a * dt;
                    disp[j] = 0.5 * (c[j] + e) * dt;
                    c[j] = e;
                } else {
                    disp[j] = 0.5 * (c[j] + want) * t_reach + want * (dt - t_reach);
                    c[j] = want;
                }
            }
        }
        let ang = &mut self.ang[..m];
        for j in 0..m {
            ang[j] = disp[j] / wheels[j].0;
        }
    }

    /// The body's least-squares twist from the wheels' contact travel (`ang`).
    fn body_twist(&mut self, g: &GroundModel) -> Twist<f64> {
        let ang = &self.ang[..g.known.len()];
        match (&self.cache.driven, g.mu.is_some()) {
            (Some((kin, idx)), true) => {
                // Undriven wheels roll with the body, so the body follows the
                // (traction-limited) driven wheels; its sideways motion, which the
                // driven pair alone barely constrains, stays what all wheels say.
                let sub = &mut self.sub[..idx.len()];
                for (o, &j) in sub.iter_mut().zip(idx) {
                    *o = ang[j];
                }
                let mut t = kin.forward(sub);
                if let Some(all) = &self.cache.all {
                    t.vy = all.forward(&self.inc).vy;
                }
                t
            }
            _ => match &self.cache.all {
                Some(kin) => kin.forward(ang),
                None => Twist::zero(),
            },
        }
    }

    /// Cables at world x = k * spacing: a driven wheel rolling onto one by row `k_next`
    /// owes `loss` of travel along its rolling direction's share of the crossing.
    fn cross_cables(
        &mut self,
        p: &Prepared,
        g: &GroundModel,
        (spacing, loss, lo, hi): (f64, f64, f64, f64),
        k_next: usize,
    ) {
        let spacing = spacing.max(1e-6);
        for j in 0..g.known.len() {
            let w = &g.wheels[j];
            if !w.3 {
                continue;
            }
            let cell = variants::cable_cell(world_x(p, k_next, w.2), spacing, lo, hi);
            let crossed = (cell - self.cells[j]).abs();
            self.cells[j] = cell;
            if crossed > 0.0 {
                self.owed[j] += crossed * loss * world_dir(p, k_next, w.1).abs();
            }
        }
    }

    /// Records the step from row `k` to `k_next` (`dt` apart, body displacement `d`):
    /// the pose at a pose row, or every row between, linear in time, and the free
    /// wheels' angles.
    fn record(
        &mut self,
        p: &Prepared,
        g: &GroundModel,
        (k, k_next): (usize, usize),
        dt: f64,
        d: &Twist<f64>,
        out: &mut Path,
    ) {
        let (pose, per_row) = (&self.pose, out.per_row);
        if !per_row && p.poses.row.get(self.next_pose) == Some(&k_next) {
            out.x.push(pose.x);
            out.y.push(pose.y);
            out.theta.push(pose.theta);
            self.next_pose += 1;
        }
        // Rows k+1 ..= k_next: linear in time between the step's ends (one row when the
        // recording is not faster than the ground rate).
        let (x0, y0, th0) = (
            out.x.last().copied().unwrap_or(0.0),
            out.y.last().copied().unwrap_or(0.0),
            out.theta.last().copied().unwrap_or(0.0),
        );
        for r in (k + 1..=k_next).filter(|_| per_row) {
            let f = if dt > 0.0 {
                (p.t[r] - p.t[k]) / dt
            } else {
                1.0
            };
            let share = if dt > 0.0 {
                (p.t[r] - p.t[r - 1]) / dt
            } else {
                1.0
            };
            out.x.push(x0 + f * (pose.x - x0));
            out.y.push(y0 + f * (pose.y - y0));
            out.theta.push(th0 + f * (pose.theta - th0));
            out.step.push(d.scale(share));
        }
        for ((_, row), (a, (_, series))) in g
            .free
            .iter()
            .zip(self.free_angle.iter_mut().zip(out.free.iter_mut()))
        {
            let a0 = *a;
            *a += row[0] * d.vx + row[1] * d.vy + row[2] * d.omega;
            for r in k + 1..=k_next {
                let f = if dt > 0.0 {
                    (p.t[r] - p.t[k]) / dt
                } else {
                    1.0
                };
                series.push(a0 + f * (*a - a0));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::odometry::integrate_arc;

    #[test]
    fn carried_heading_matches_integrate_arc() {
        let mut a = Pose::new(0.0, 0.0, 0.0);
        let mut b = a;
        let mut h = Heading::new();
        for k in 0..5000 {
            let d = Twist::new(
                0.002,
                0.0005 * (k as f64 * 0.01).sin(),
                0.03 * (k as f64 * 0.003).cos() + 0.06 * ((k % 97) as f64 / 97.0),
            );
            a = integrate_arc(a, &d);
            h.advance(&mut b, &d);
        }
        assert!(
            (a.x - b.x).abs() < 1e-10 && (a.y - b.y).abs() < 1e-10,
            "{a:?} {b:?}"
        );
        assert!((a.theta - b.theta).abs() < 1e-12);
    }
}
