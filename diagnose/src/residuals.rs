//! Residuals of a model against the recording, in both stages, with the nuisance
//! parameters solved in closed form for every evaluation (variable projection):
//! - ground: the start pose (x0, y0, theta0) that best lays the predicted path onto the
//!   measured poses, because the first pose sample is as noisy as the others;
//! - actuator: each encoder's offset (encoders start anywhere, and backlash leaves the
//!   wheel anywhere inside its play).
//!
//! The noise of each stage is estimated from the data (robust spread of residual
//! increments), so residuals can be weighed against each other and against the noise.

use crate::actuator::{simulate_wheel, ActuatorParams};
use crate::effects::{Effect, Model, Stage};
use crate::ground::{simulate, Path, Rows};
use crate::replay::Prepared;
use fitkit::noise::lag1_autocorrelation;
use std::cell::RefCell;
use std::rc::Rc;

/// What a worker thread needs to rebuild an equivalent evaluator.
#[derive(Debug, Clone, Copy)]
pub struct ForkSpec {
    /// The parent's noise levels.
    pub noise: Noise,
    /// The parent's reading of the commands (linear between rows, or held).
    pub linear_commands: bool,
}

/// Simulated angle series per wheel (`None` for wheels without commands), shared.
type WheelAngles = Rc<Vec<Option<Vec<f64>>>>;
/// Per actuator-compared wheel: (wheel index, error per compared row), as [`Eval::act`].
type WheelResiduals = Vec<(usize, Vec<f64>)>;
/// The ground residuals of one path, on one fold, weighed by one noise.
type GroundResiduals = (Rc<Path>, Fold, Noise, Eval);

/// Which samples take part: all, or alternate time blocks (for held-out validation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fold {
    /// Every sample.
    All,
    /// Samples in the even-numbered of the recording's ten equal time blocks.
    Even,
    /// Samples in the odd-numbered time blocks.
    Odd,
}

impl Fold {
    fn contains(self, block: u8) -> bool {
        match self {
            Fold::All => true,
            Fold::Even => block == 0,
            Fold::Odd => block == 1,
        }
    }

    /// The complementary fold (the held-out samples of a fit on `self`); `All` for `All`.
    pub fn other(self) -> Fold {
        match self {
            Fold::All => Fold::All,
            Fold::Even => Fold::Odd,
            Fold::Odd => Fold::Even,
        }
    }
}

/// Noise levels (one standard deviation) estimated from the nominal residuals.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Noise {
    /// Position noise of the measured poses, per axis, m.
    pub pose_sigma_m: f64,
    /// Heading noise of the measured poses, rad.
    pub heading_sigma_rad: f64,
    /// Wheel-surface noise of the actuator stage (encoder angle times radius).
    pub actuator_sigma_m: f64,
    /// Wheel-surface noise of free wheels' encoders against the body motion.
    pub free_wheel_sigma_m: f64,
}

/// The result of evaluating one model.
#[derive(Debug, Clone, Default)]
pub struct Eval {
    /// Position and heading error (measured - predicted) per pose sample.
    pub ex: Vec<f64>,
    /// y error (measured - predicted) per pose sample, m.
    pub ey: Vec<f64>,
    /// Heading error (measured - predicted) per pose sample, rad.
    pub eth: Vec<f64>,
    /// Fitted start pose.
    pub start: (f64, f64, f64),
    /// Per actuator-compared wheel: (wheel index, error in m per compared row).
    pub act: Vec<(usize, Vec<f64>)>,
    /// Per free (undriven) wheel with an encoder: (wheel index, encoder minus predicted
    /// rolling, m at the wheel surface, per compared row). Ground-stage evidence.
    pub free: Vec<(usize, Vec<f64>)>,
}

/// Sums of squares per stage over a fold.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageRss {
    /// Sum of ex^2 + ey^2 (m^2) and the number of pose samples.
    pub pos: f64,
    /// Sum of heading errors squared, rad^2.
    pub heading: f64,
    /// Number of pose samples in the fold.
    pub n_pose: usize,
    /// Sum of actuator errors squared (m^2) and their number.
    pub act: f64,
    /// Number of actuator errors in the fold.
    pub n_act: usize,
    /// Sum of free-wheel errors squared (m^2) and their number (ground stage).
    pub free: f64,
    /// Number of free-wheel errors in the fold.
    pub n_free: usize,
}

impl StageRss {
    /// Position RMSE over the pose samples, m (0 without samples).
    pub fn ground_rmse(&self) -> f64 {
        (self.pos / self.n_pose.max(1) as f64).sqrt()
    }

    /// Actuator RMSE at the wheel surface, m (0 without actuator errors).
    pub fn actuator_rmse(&self) -> f64 {
        (self.act / self.n_act.max(1) as f64).sqrt()
    }
}

/// Evaluates models against one prepared recording, caching each stage's simulation.
pub struct Evaluator<'a> {
    /// The recording the models are compared with.
    pub p: &'a Prepared,
    /// Noise levels that weight the residuals.
    pub noise: Noise,
    /// Rows compared in the actuator stage (decimated: the residual is an integrated
    /// angle, so neighbouring rows add little information but cost time).
    pub act_rows: Vec<usize>,
    pose_block: Vec<u8>,
    act_block: Vec<u8>,
    act_cache: RefCell<Option<(Vec<f64>, WheelAngles)>>,
    /// Actuator sum of squares (m^2) of the nominal model with the best lag shorter than
    /// a quarter row: timing below that is a logging convention (where in its cycle each
    /// column is sampled), the floor against which actuator mismatch is judged.
    pub act_floor_rss: std::cell::Cell<f64>,
    /// Commands read as linear between rows (decided on the nominal model).
    pub linear_commands: std::cell::Cell<bool>,
    /// Model runs so far (ground, actuator), for the report and the benchmark.
    pub runs: std::cell::Cell<(usize, usize)>,
    ground_cache: RefCell<Option<(Vec<f64>, Rc<Path>)>>,
    /// The ground residuals of the last path evaluated, on its fold and with the noise
    /// that weighs its start pose: a fit of an actuator effect leaves the path as it was
    /// (the same `Rc`).
    ground_res_cache: RefCell<Option<GroundResiduals>>,
    /// The actuator residuals of the last wheel angles evaluated, on its fold: a fit of
    /// a ground effect leaves the angles as they were (the same `Rc`).
    act_res_cache: RefCell<Option<(WheelAngles, Fold, WheelResiduals)>>,
}

/// Cap of the lag-1 autocorrelation used to discount the sample count: a residual that
/// still drifts after a fit counts as at least n / 200 independent samples.
const MAX_AUTOCORRELATION: f64 = 0.99;

/// Most rows per wheel compared in the actuator stage.
const MAX_ACT_ROWS: usize = 6000;
/// Number of alternating time blocks for held-out validation.
const BLOCKS: f64 = 10.0;

fn key(m: &Model, stage: Stage, with_actuator: bool) -> Vec<f64> {
    let mut effects: Vec<&(Effect, Vec<f64>)> = m
        .effects
        .iter()
        .filter(|(e, _)| e.stage() == stage || (with_actuator && e.stage() == Stage::Actuator))
        .collect();
    effects.sort_by(|a, b| a.0.code().total_cmp(&b.0.code()));
    let mut k = Vec::new();
    for (e, p) in effects {
        // The code, the parameter count and the values: no two models share a key.
        k.push(e.code());
        k.push(p.len() as f64);
        k.extend_from_slice(p);
    }
    k
}

impl<'a> Evaluator<'a> {
    /// An evaluator for `p`: decides whether commands are held or linear between rows
    /// (whichever fits the encoders better) and estimates the noise from the nominal
    /// model's residuals.
    pub fn new(p: &'a Prepared) -> Self {
        let mut ev = Self::with_noise(
            p,
            Noise {
                pose_sigma_m: 1.0,
                heading_sigma_rad: 1.0,
                actuator_sigma_m: 1.0,
                free_wheel_sigma_m: 1.0,
            },
        );
        let mut nominal = ev.evaluate(&Model::default(), Fold::All);
        // A log slower than the control loop samples commands that changed in between:
        // read them as linear between rows if that fits the encoders better.
        // A lag shifts the encoders the way holding a command does, so the two readings
        // are compared each with its best first-order lag (or dead band).
        if !nominal.act.is_empty() {
            // (best RSS with any lag, best RSS with a sub-quarter-row lag)
            let quarter_row = 0.25 * p.row_dt_s();
            // Merged rows carry interval means: held is the reading that keeps their
            // travel exact, so the linear one is not tried, and of the held reading only
            // the floor is needed (its best lag is compared with nothing).
            let compare = !p.commands_are_means;
            let best_with_lag = |ev: &Evaluator| -> (f64, f64) {
                let base = ev
                    .rss(&ev.evaluate(&Model::default(), Fold::All), Fold::All)
                    .act;
                let (mut best, mut floor) = (base, base);
                let rss_at = |u: f64| -> f64 {
                    let m = Model::default().with(Effect::MotorLag, vec![u.exp()]);
                    ev.rss(&ev.evaluate(&m, Fold::All), Fold::All).act
                };
                // Log grid from 0.1 ms to 0.3 s, then two zooms around the best point.
                let (lo, hi) = (1e-4f64.ln(), 0.3f64.ln());
                let step = (hi - lo) / 15.0;
                let mut best_u = lo;
                for i in 0..16 {
                    let u = lo + step * i as f64;
                    if !compare && u.exp() > quarter_row {
                        break;
                    }
                    let r = rss_at(u);
                    if r < best {
                        (best, best_u) = (r, u);
                    }
                    if u.exp() <= quarter_row {
                        floor = floor.min(r);
                    }
                }
                if !compare {
                    return (best, floor);
                }
                let mut half = step;
                for _ in 0..2 {
                    let centre = best_u;
                    for j in 1..8 {
                        let u = centre - half + 2.0 * half * j as f64 / 8.0;
                        let r = rss_at(u);
                        if r < best {
                            (best, best_u) = (r, u);
                        }
                    }
                    half /= 4.0;
                }
                // A dead band also changes how commands and counts line up: give each
                // reading its best dead band too.
                for i in 0..16 {
                    let d = 0.02 * (1000f64).powf(i as f64 / 15.0);
                    let m = Model::default().with(Effect::CoulombFriction, vec![d]);
                    best = best.min(ev.rss(&ev.evaluate(&m, Fold::All), Fold::All).act);
                }
                (best, floor)
            };
            // Each reading on its own evaluator and thread (the same numbers as one after
            // the other).
            let noise = ev.noise;
            let (held, linear) = std::thread::scope(|s| {
                let linear = compare.then(|| {
                    s.spawn(move || {
                        let other = Evaluator::with_noise(p, noise);
                        other.linear_commands.set(true);
                        (best_with_lag(&other), other.runs.get())
                    })
                });
                let held = best_with_lag(&ev);
                let linear =
                    linear.map(|h| h.join().unwrap_or_else(|e| std::panic::resume_unwind(e)));
                (held, linear)
            });
            let linear = linear.map(|(best, (g, a))| {
                let (g0, a0) = ev.runs.get();
                ev.runs.set((g0 + g, a0 + a));
                best
            });
            if let Some(linear) = linear.filter(|l| l.0 < held.0) {
                ev.linear_commands.set(true);
                *ev.act_cache.borrow_mut() = None;
                *ev.ground_cache.borrow_mut() = None;
                nominal = ev.evaluate(&Model::default(), Fold::All);
                ev.act_floor_rss.set(linear.1);
            } else {
                ev.act_floor_rss.set(held.1);
            }
        }
        ev.noise = estimate_noise(p, &nominal);
        ev
    }

    /// A worker's copy: same noise and command reading, empty caches.
    pub fn fork(&self) -> ForkSpec {
        ForkSpec {
            noise: self.noise,
            linear_commands: self.linear_commands.get(),
        }
    }

    /// An evaluator built from a [`ForkSpec`] (in a worker thread).
    pub fn from_fork(p: &'a Prepared, f: ForkSpec) -> Self {
        let ev = Self::with_noise(p, f.noise);
        ev.linear_commands.set(f.linear_commands);
        ev
    }

    /// An evaluator with given noise levels and empty caches.
    pub fn with_noise(p: &'a Prepared, noise: Noise) -> Self {
        let n = p.rows();
        let step = n.div_ceil(MAX_ACT_ROWS).max(1);
        let act_rows: Vec<usize> = (0..n).step_by(step).collect();
        let (t0, t1) = (
            p.t.first().copied().unwrap_or(0.0),
            p.t.last().copied().unwrap_or(0.0),
        );
        let block_len = ((t1 - t0) / BLOCKS).max(fitkit::MIN_DT_S);
        let block = |row: usize| (((p.t[row] - t0) / block_len).floor() as i64 % 2) as u8;
        let pose_block = p.poses.row.iter().map(|&r| block(r)).collect();
        let act_block = act_rows.iter().map(|&r| block(r)).collect();
        Evaluator {
            p,
            noise,
            act_rows,
            pose_block,
            act_block,
            act_cache: RefCell::new(None),
            runs: std::cell::Cell::new((0, 0)),
            linear_commands: std::cell::Cell::new(false),
            act_floor_rss: std::cell::Cell::new(0.0),
            ground_cache: RefCell::new(None),
            ground_res_cache: RefCell::new(None),
            act_res_cache: RefCell::new(None),
        }
    }

    /// Wheel-surface travel of one encoder count (largest over the compared wheels).
    pub fn actuator_quantum_m(&self) -> f64 {
        self.actuator_wheels()
            .iter()
            .map(|&i| self.p.wheels[i].rad_per_count * self.p.wheels[i].radius_m)
            .fold(0.0, f64::max)
    }

    /// Wheels compared in the actuator stage.
    pub fn actuator_wheels(&self) -> Vec<usize> {
        self.p
            .wheels
            .iter()
            .enumerate()
            .filter(|(_, w)| w.cmd.is_some() && w.enc_rad.is_some())
            .map(|(i, _)| i)
            .collect()
    }

    /// A stepper drive's electrical cycle (four full steps) in wheel radians: the steps
    /// a pulled-out rotor loses at once. `None` for other drives.
    pub fn stepper_cycle_rad(&self) -> Option<f64> {
        let d = &self.p.robot.drive;
        (d.kind == calib_core::robot::DriveType::Stepper && d.steps_per_rev > 0)
            .then(|| 4.0 * std::f64::consts::TAU / (d.steps_per_rev as f64 * d.gear_ratio))
    }

    /// True when the ground stage depends on the actuator model (a wheel without encoder
    /// is driven by its commands).
    pub fn ground_uses_actuator(&self) -> bool {
        self.p
            .wheels
            .iter()
            .any(|w| w.enc_rad.is_none() && w.cmd.is_some())
    }

    fn actuator_angles(&self, m: &Model) -> WheelAngles {
        let mut k = key(m, Stage::Actuator, false);
        k.push(if self.linear_commands.get() { 1.0 } else { 0.0 });
        if let Some((ck, v)) = &*self.act_cache.borrow() {
            if *ck == k {
                return Rc::clone(v);
            }
        }
        let (g, a) = self.runs.get();
        self.runs.set((g, a + 1));
        let mut params = ActuatorParams::from_model(m);
        params.linear = self.linear_commands.get();
        params.step_cycle_rad = self.stepper_cycle_rad();
        // Each wheel's own values, when the model has a per-wheel mechanism.
        let v: Vec<Option<Vec<f64>>> = self
            .p
            .wheels
            .iter()
            .enumerate()
            .map(|(i, w)| {
                w.cmd.as_ref().map(|c| {
                    let mut out = Vec::new();
                    simulate_wheel(&self.p.t, c, &params.for_wheel(m, i), &mut out);
                    out
                })
            })
            .collect();
        let v = Rc::new(v);
        *self.act_cache.borrow_mut() = Some((k, Rc::clone(&v)));
        v
    }

    /// The predicted path of a model (origin start) at the pose rows: what a fit compares.
    /// The last one is cached.
    pub fn path(&self, m: &Model) -> Rc<Path> {
        let uses_act = self.ground_uses_actuator();
        let mut k = key(m, Stage::Ground, uses_act);
        k.push(if self.linear_commands.get() { 1.0 } else { 0.0 });
        if let Some((ck, path)) = &*self.ground_cache.borrow() {
            if *ck == k {
                return Rc::clone(path);
            }
        }
        let path = Rc::new(self.simulate(m, Rows::Poses));
        *self.ground_cache.borrow_mut() = Some((k, Rc::clone(&path)));
        path
    }

    /// The predicted path of a model at every row, with the steps between rows (for the
    /// windows and the localisation; not cached).
    pub fn path_per_row(&self, m: &Model) -> Path {
        self.simulate(m, Rows::All)
    }

    fn simulate(&self, m: &Model, rows: Rows) -> Path {
        let uses_act = self.ground_uses_actuator();
        let act = if uses_act {
            self.actuator_angles(m)
        } else {
            Rc::new(vec![None; self.p.wheels.len()])
        };
        let angles: Vec<Option<&[f64]>> = self
            .p
            .wheels
            .iter()
            .zip(act.iter())
            .map(|(w, a)| w.enc_rad.as_deref().or(a.as_deref()))
            .collect();
        let (g, a) = self.runs.get();
        self.runs.set((g + 1, a));
        let mut path = Path::default();
        // Traction slip by the body-bound or creep mechanisms rewrites the wheel angles.
        let slipped = crate::ground::variants::slip_angles(self.p, m, &angles);
        let angles: Vec<Option<&[f64]>> = match &slipped {
            Some(v) => v.iter().map(|a| a.as_deref()).collect(),
            None => angles,
        };
        simulate(self.p, &angles, m, rows, &mut path);
        path
    }

    /// Residuals of a model with the nuisance parameters fitted on `fit`.
    pub fn evaluate(&self, m: &Model, fit: Fold) -> Eval {
        let path = self.path(m);
        let cached = match &*self.ground_res_cache.borrow() {
            Some((p, f, n, e)) if Rc::ptr_eq(p, &path) && *f == fit && *n == self.noise => {
                Some(e.clone())
            }
            _ => None,
        };
        let mut ev = cached.unwrap_or_else(|| {
            let mut ev = Eval::default();
            self.ground_residuals(&path, fit, &mut ev);
            for (i, pred) in &path.free {
                let Some(enc) = &self.p.wheels[*i].enc_rad else {
                    continue;
                };
                ev.free.push((
                    *i,
                    self.wheel_residual(enc, pred, self.p.wheels[*i].radius_m, fit),
                ));
            }
            *self.ground_res_cache.borrow_mut() =
                Some((Rc::clone(&path), fit, self.noise, ev.clone()));
            ev
        });
        let wheels = self.actuator_wheels();
        if !wheels.is_empty() {
            let sim = self.actuator_angles(m);
            if let Some((s, f, act)) = &*self.act_res_cache.borrow() {
                if Rc::ptr_eq(s, &sim) && *f == fit {
                    ev.act = act.clone();
                    return ev;
                }
            }
            for i in wheels {
                let (Some(enc), Some(model)) = (&self.p.wheels[i].enc_rad, &sim[i]) else {
                    continue;
                };
                ev.act.push((
                    i,
                    self.wheel_residual(enc, model, self.p.wheels[i].radius_m, fit),
                ));
            }
            *self.act_res_cache.borrow_mut() = Some((sim, fit, ev.act.clone()));
        }
        ev
    }

    /// A wheel's residual (measured minus modelled angle, as ground travel) on the
    /// actuator rows, less its mean over the rows of the fitting fold: the encoder's
    /// zero is a nuisance, not evidence.
    fn wheel_residual(&self, enc: &[f64], model: &[f64], radius_m: f64, fit: Fold) -> Vec<f64> {
        let mut e: Vec<f64> = self
            .act_rows
            .iter()
            .map(|&k| (enc[k] - model[k]) * radius_m)
            .collect();
        let (mut s, mut c) = (0.0, 0usize);
        for (j, v) in e.iter().enumerate() {
            if fit.contains(self.act_block[j]) {
                s += v;
                c += 1;
            }
        }
        let off = if c > 0 { s / c as f64 } else { 0.0 };
        e.iter_mut().for_each(|v| *v -= off);
        e
    }

    fn ground_residuals(&self, path: &Path, fit: Fold, ev: &mut Eval) {
        let ps = &self.p.poses;
        let n = ps.len();
        let (px, py, pth) = if path.per_row {
            (
                &ps.row.iter().map(|&r| path.x[r]).collect::<Vec<f64>>(),
                &ps.row.iter().map(|&r| path.y[r]).collect::<Vec<f64>>(),
                &ps.row.iter().map(|&r| path.theta[r]).collect::<Vec<f64>>(),
            )
        } else {
            (&path.x, &path.y, &path.theta)
        };
        let use_k = |k: usize| fit.contains(self.pose_block[k]);
        let wp = 1.0 / self.noise.pose_sigma_m.powi(2);
        let wt = 1.0 / self.noise.heading_sigma_rad.powi(2);
        // Centroids over the fit samples.
        let (mut cpx, mut cpy, mut cmx, mut cmy, mut dth, mut cnt) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
        for k in (0..n).filter(|&k| use_k(k)) {
            cpx += px[k];
            cpy += py[k];
            cmx += ps.x[k];
            cmy += ps.y[k];
            dth += ps.theta[k] - pth[k];
            cnt += 1.0;
        }
        let th0 = if cnt > 0.0 {
            cpx /= cnt;
            cpy /= cnt;
            cmx /= cnt;
            cmy /= cnt;
            dth /= cnt;
            let (mut sdot, mut scross) = (0.0, 0.0);
            for k in (0..n).filter(|&k| use_k(k)) {
                let (ax, ay) = (px[k] - cpx, py[k] - cpy);
                let (bx, by) = (ps.x[k] - cmx, ps.y[k] - cmy);
                sdot += ax * bx + ay * by;
                scross += ax * by - ay * bx;
            }
            // Minimise -2 wp (sdot cos + scross sin) + wt sum (th0 - dth_k)^2 by Newton
            // from the heading offset; a handful of steps converge.
            let mut th = dth;
            for _ in 0..8 {
                let (s, c) = th.sin_cos();
                let g = 2.0 * wp * (sdot * s - scross * c) + 2.0 * wt * cnt * (th - dth);
                let h = 2.0 * wp * (sdot * c + scross * s) + 2.0 * wt * cnt;
                if h <= 0.0 || !h.is_finite() {
                    break;
                }
                let step = (g / h).clamp(-0.5, 0.5);
                th -= step;
                if step.abs() < 1e-12 {
                    break;
                }
            }
            th
        } else {
            0.0
        };
        let (s, c) = th0.sin_cos();
        let (x0, y0) = (cmx - (c * cpx - s * cpy), cmy - (s * cpx + c * cpy));
        ev.start = (x0, y0, th0);
        ev.ex.clear();
        ev.ey.clear();
        ev.eth.clear();
        for k in 0..n {
            let wx = x0 + c * px[k] - s * py[k];
            let wy = y0 + s * px[k] + c * py[k];
            ev.ex.push(ps.x[k] - wx);
            ev.ey.push(ps.y[k] - wy);
            ev.eth.push(ps.theta[k] - (pth[k] + th0));
        }
    }

    /// Sums of squares over a fold.
    pub fn rss(&self, ev: &Eval, fold: Fold) -> StageRss {
        let mut r = StageRss::default();
        for k in 0..ev.ex.len() {
            if fold.contains(self.pose_block[k]) {
                r.pos += ev.ex[k].powi(2) + ev.ey[k].powi(2);
                r.heading += ev.eth[k].powi(2);
                r.n_pose += 1;
            }
        }
        for (_, e) in &ev.act {
            for (j, v) in e.iter().enumerate() {
                if fold.contains(self.act_block[j]) {
                    r.act += v * v;
                    r.n_act += 1;
                }
            }
        }
        for (_, e) in &ev.free {
            for (j, v) in e.iter().enumerate() {
                if fold.contains(self.act_block[j]) {
                    r.free += v * v;
                    r.n_free += 1;
                }
            }
        }
        r
    }

    /// Noise-weighted residual vector over a fold (what the optimiser minimises).
    pub fn weighted(&self, ev: &Eval, fold: Fold, out: &mut Vec<f64>) {
        out.clear();
        let (sp, st, sa) = (
            self.noise.pose_sigma_m,
            self.noise.heading_sigma_rad,
            self.noise.actuator_sigma_m,
        );
        for k in 0..ev.ex.len() {
            if fold.contains(self.pose_block[k]) {
                out.push(ev.ex[k] / sp);
                out.push(ev.ey[k] / sp);
                out.push(ev.eth[k] / st);
            }
        }
        for (_, e) in &ev.act {
            for (j, v) in e.iter().enumerate() {
                if fold.contains(self.act_block[j]) {
                    out.push(v / sa);
                }
            }
        }
        let sf = self.noise.free_wheel_sigma_m;
        for (_, e) in &ev.free {
            for (j, v) in e.iter().enumerate() {
                if fold.contains(self.act_block[j]) {
                    out.push(v / sf);
                }
            }
        }
    }

    /// Chi-square of one stage over a fold (noise-weighted sum of squares).
    pub fn chi2(&self, rss: &StageRss, stage: Stage) -> f64 {
        match stage {
            Stage::Ground => {
                rss.pos / self.noise.pose_sigma_m.powi(2)
                    + rss.heading / self.noise.heading_sigma_rad.powi(2)
                    + rss.free / self.noise.free_wheel_sigma_m.powi(2)
            }
            Stage::Actuator => rss.act / self.noise.actuator_sigma_m.powi(2),
        }
    }

    /// Lag-1 autocorrelation of a stage's residuals: near 0 for white noise, near 1 for
    /// drift a model has not explained. Used to discount the sample count.
    pub fn autocorrelation(&self, ev: &Eval, stage: Stage) -> f64 {
        let series: Vec<&[f64]> = match stage {
            Stage::Ground => {
                let mut v: Vec<&[f64]> = vec![&ev.ex, &ev.ey, &ev.eth];
                v.extend(ev.free.iter().map(|(_, e)| e.as_slice()));
                v
            }
            Stage::Actuator => ev.act.iter().map(|(_, e)| e.as_slice()).collect(),
        };
        lag1_autocorrelation(series, MAX_AUTOCORRELATION)
    }
}

/// Robust standard deviation: 1.4826 * median absolute deviation from the median.
pub fn robust_sigma(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let med = v[v.len() / 2];
    let mut dev: Vec<f64> = v.iter().map(|x| (x - med).abs()).collect();
    dev.sort_by(|a, b| a.total_cmp(b));
    1.4826 * dev[dev.len() / 2]
}

/// Noise from the increments of the nominal residual between consecutive samples: white
/// measurement noise of sigma gives increments of sigma * sqrt(2), while model drift
/// changes little from one sample to the next.
fn estimate_noise(p: &Prepared, nominal: &Eval) -> Noise {
    let diffs = |v: &[f64]| -> Vec<f64> { v.windows(2).map(|w| w[1] - w[0]).collect() };
    let mut pos = diffs(&nominal.ex);
    pos.extend(diffs(&nominal.ey));
    let pose_sigma_m = (robust_sigma(&mut pos) / 2f64.sqrt()).max(1e-5);
    let heading_sigma_rad = (robust_sigma(&mut diffs(&nominal.eth)) / 2f64.sqrt()).max(1e-5);
    let mut act = Vec::new();
    let mut quant: f64 = 1e-7;
    for (i, e) in &nominal.act {
        act.extend(diffs(e));
        let w = &p.wheels[*i];
        quant = quant.max(w.rad_per_count * w.radius_m / 12f64.sqrt());
    }
    let actuator_sigma_m = (robust_sigma(&mut act) / 2f64.sqrt()).max(quant);
    let mut free = Vec::new();
    let mut free_quant: f64 = 1e-7;
    for (i, e) in &nominal.free {
        free.extend(diffs(e));
        let w = &p.wheels[*i];
        free_quant = free_quant.max(w.rad_per_count * w.radius_m / 12f64.sqrt());
    }
    let free_wheel_sigma_m = (robust_sigma(&mut free) / 2f64.sqrt()).max(free_quant);
    Noise {
        pose_sigma_m,
        heading_sigma_rad,
        actuator_sigma_m,
        free_wheel_sigma_m,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::{presets, Drive};
    use sim::{record, Motion, RandomMotion, RecordConfig, Surface};

    /// Every field of two evaluations, to the bit.
    fn same(a: &Eval, b: &Eval, what: &str) {
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a.ex), bits(&b.ex), "{what}: ex");
        assert_eq!(bits(&a.ey), bits(&b.ey), "{what}: ey");
        assert_eq!(bits(&a.eth), bits(&b.eth), "{what}: eth");
        let s = |e: &Eval| [e.start.0, e.start.1, e.start.2].map(f64::to_bits);
        assert_eq!(s(a), s(b), "{what}: start");
        for (x, y) in [(&a.act, &b.act), (&a.free, &b.free)] {
            assert_eq!(x.len(), y.len(), "{what}: wheels");
            for ((i, u), (j, v)) in x.iter().zip(y) {
                assert_eq!((i, bits(u)), (j, bits(v)), "{what}: wheel {i}");
            }
        }
    }

    /// The residual caches (the ground residuals of the last path, the actuator residuals
    /// of the last wheel angles) give what a fresh evaluator gives, bit for bit, when the
    /// model changes in the other stage, when the fold changes and when the noise that
    /// weighs the start pose changes; and the cached ground residuals are not the stale
    /// ones (a 1 % wheel scale moves them by millimetres over a 20 s drive).
    #[test]
    fn cached_residuals_are_a_fresh_evaluators_to_the_bit() {
        let robot = presets::diff_drive("dc_diff", 0.05, 0.40, Drive::default());
        let cfg = RecordConfig {
            row_rate_hz: 50.0,
            ..RecordConfig::default()
        };
        let motion = Motion::Random(RandomMotion {
            duration_s: 20.0,
            v_max_m_s: 0.3,
            a_max_m_s2: 0.5,
            ..RandomMotion::default()
        });
        let rec = record(&robot, &[], Surface::flat(), &motion, &cfg)
            .unwrap()
            .recording;
        let p = Prepared::new(&robot, &rec);
        let mut ev = Evaluator::new(&p);
        assert!(!ev.actuator_wheels().is_empty(), "commands and encoders");
        let ground = |ed: f64| Model::default().with(Effect::WheelDiameterMismatch, vec![ed]);
        let lag = |tau: f64| Model::default().with(Effect::MotorLag, vec![tau]);
        let both = ground(1.01).with(Effect::MotorLag, vec![0.05]);
        let steps = [
            (ground(1.01), Fold::All),
            // The same path, another actuator model: ground residuals from the cache.
            (both.clone(), Fold::All),
            // The same angles, another path: actuator residuals from the cache.
            (
                both.with(Effect::WheelDiameterMismatch, vec![0.99]),
                Fold::All,
            ),
            (lag(0.05), Fold::Even),
            // Another fold on the same path and angles.
            (lag(0.05), Fold::Odd),
            (lag(0.08), Fold::Odd),
            (ground(1.01), Fold::Odd),
        ];
        let mut last_ex = Vec::new();
        for (k, (m, fold)) in steps.iter().enumerate() {
            let got = ev.evaluate(m, *fold);
            let fresh = Evaluator::from_fork(&p, ev.fork()).evaluate(m, *fold);
            same(&got, &fresh, &format!("step {k}"));
            if k == 2 {
                // ed 1.01 -> 0.99 over 20 s at up to 0.3 m/s: the residuals moved.
                let moved = got
                    .ex
                    .iter()
                    .zip(&last_ex)
                    .map(|(a, b): (&f64, &f64)| (a - b).abs())
                    .fold(0.0, f64::max);
                assert!(moved > 1e-3, "ground residuals moved by {moved} m only");
            }
            last_ex = got.ex.clone();
        }
        // The noise weighs the start pose's heading against its position: a change of
        // noise is a change of the ground residuals, on the same path and fold.
        ev.noise.heading_sigma_rad *= 100.0;
        let got = ev.evaluate(&ground(1.01), Fold::Odd);
        let fresh = Evaluator::from_fork(&p, ev.fork()).evaluate(&ground(1.01), Fold::Odd);
        same(&got, &fresh, "noise changed");
    }
}
