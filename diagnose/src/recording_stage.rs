//! The `recording` stage: artefacts of how a run was logged, not physics, with their own
//! catalogue ids. Found and fitted before the physics is judged, reported under their own
//! heading, and removed from the recording the physics stages see:
//!
//! - `sample_glitch`: missing samples (a gap of whole row intervals in `t`) and duplicated
//!   samples (a row repeating the previous one's encoders and pose while the robot moves
//!   on both sides), with their times. Duplicated rows are dropped; gaps only reported
//!   (encoders are cumulative, so a gap loses no travel).
//! - `counts_per_rev_error` (`counts_ratio_<wheel>`: true over configured counts per
//!   wheel revolution): each wheel's encoder travel against the travel the measured body
//!   motion asks of it. Only powers of two (within 10 %: a quadrature mode, a missed
//!   gear stage) count; a few per cent is tyre size, physics.
//! - `time_offset` (`time_offset_s`, poses later than encoders when positive) and
//!   `clock_rate` (`clock_ratio`, the pose clock over the encoder clock): fitted with the
//!   geometry by [`crate::calibrate`]; reported when beyond four sigmas and a material
//!   size (a quarter row interval; 0.05 %), then the poses are moved onto the encoder
//!   clock.

use crate::calibrate::{calibrate, CalOptions, Nuisance};
use crate::replay::unwrap_angles;
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::Robot;
use formats::recording::Recording;
use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// Recording-stage catalogue ids.
pub const RECORDING_IDS: [&str; 4] = [
    "time_offset",
    "clock_rate",
    "sample_glitch",
    "counts_per_rev_error",
];

/// One artefact found in the recording.
#[derive(Debug, Clone, Serialize)]
pub struct Artefact {
    /// One of [`RECORDING_IDS`].
    pub id: &'static str,
    /// Fitted values or counts by name (`time_offset_s`, `clock_ratio`,
    /// `counts_ratio_<wheel>`, `missing_samples`, `duplicated_samples`).
    pub parameters: BTreeMap<String, f64>,
    /// Uncertainty per fitted parameter: one sigma for the clocks; for a counts ratio,
    /// how far the raw estimate lies from the power of two it was snapped to.
    pub uncertainties: BTreeMap<String, f64>,
    /// Times of the missing samples (s).
    pub missing_at_s: Vec<f64>,
    /// Times of the duplicated rows (s).
    pub duplicated_at_s: Vec<f64>,
    /// Whether the physics stages saw the recording with this artefact removed.
    pub removed: bool,
}

impl Artefact {
    fn new(id: &'static str) -> Self {
        Artefact {
            id,
            parameters: BTreeMap::new(),
            uncertainties: BTreeMap::new(),
            missing_at_s: vec![],
            duplicated_at_s: vec![],
            removed: false,
        }
    }
}

impl fmt::Display for Artefact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.id)?;
        for (k, v) in &self.parameters {
            match self.uncertainties.get(k) {
                Some(s) => write!(f, " {k} = {v:.5} ± {s:.2e}")?,
                None => write!(f, " {k} = {v:.5}")?,
            }
        }
        let times = |v: &[f64]| {
            let mut s: Vec<String> = v.iter().take(8).map(|t| format!("{t:.3}")).collect();
            if v.len() > 8 {
                s.push(format!("... ({} in all)", v.len()));
            }
            s.join(", ")
        };
        if !self.missing_at_s.is_empty() {
            write!(f, " missing samples at {} s", times(&self.missing_at_s))?;
        }
        if !self.duplicated_at_s.is_empty() {
            write!(
                f,
                " duplicated samples at {} s",
                times(&self.duplicated_at_s)
            )?;
        }
        if self.removed {
            write!(f, " (removed before the physics)")?;
        }
        Ok(())
    }
}

/// What the recording stage found, and the recording with it removed.
#[derive(Debug, Clone)]
pub struct RecordingStage {
    /// The artefacts found.
    pub artefacts: Vec<Artefact>,
    /// The recording with the artefacts marked `removed` taken out (what the physics
    /// stages see).
    pub corrected: Recording,
    /// The whole-geometry fit the clocks came from (its identifiability tells which
    /// geometry effects this recording cannot separate).
    pub geometry: Option<crate::calibrate::Calibration>,
}

/// Runs the recording stage on `rec` of `robot`.
pub fn analyse(robot: &Robot, rec: &Recording) -> RecordingStage {
    let mut artefacts = Vec::new();
    let mut cur = rec.clone();
    if let Some(a) = sample_glitches(&mut cur) {
        artefacts.push(a);
    }
    if let Some(a) = counts_per_rev(robot, &mut cur) {
        artefacts.push(a);
    }
    let (clock_artefacts, geometry) = clocks(robot, &mut cur);
    artefacts.extend(clock_artefacts);
    RecordingStage {
        artefacts,
        corrected: cur,
        geometry,
    }
}

/// Missing rows (gaps of >= 1.5 median intervals) and duplicated rows (dropped).
fn sample_glitches(rec: &mut Recording) -> Option<Artefact> {
    let n = rec.len();
    if n < 4 {
        return None;
    }
    let mut d: Vec<f64> = rec.t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    let dt = d[d.len() / 2];
    if dt <= 0.0 {
        return None;
    }
    let mut a = Artefact::new("sample_glitch");
    for k in 1..n {
        let gap = (rec.t[k] - rec.t[k - 1]) / dt;
        if gap >= 1.5 {
            // One time per missing row.
            for j in 1..gap.round() as usize {
                a.missing_at_s.push(rec.t[k - 1] + j as f64 * dt);
            }
        }
    }
    let enc = |k: usize| -> Vec<Option<i64>> {
        rec.wheels
            .iter()
            .map(|w| w.enc.as_ref().and_then(|e| e[k]))
            .collect()
    };
    let pose = |k: usize| (rec.x[k], rec.y[k], rec.theta[k]);
    let has_enc = rec.wheels.iter().any(|w| w.enc.is_some());
    let mut dup = vec![false; n];
    if has_enc {
        for (k, d) in dup.iter_mut().enumerate().take(n - 1).skip(2) {
            let (e0, e1, e2, e3) = (enc(k - 2), enc(k - 1), enc(k), enc(k + 1));
            let moving = |a: &[Option<i64>], b: &[Option<i64>]| {
                a.iter()
                    .zip(b)
                    .any(|(x, y)| matches!((x, y), (Some(x), Some(y)) if x != y))
            };
            let same_pose = match (pose(k - 1), pose(k)) {
                ((Some(a), Some(b), Some(c)), (Some(x), Some(y), Some(z))) => {
                    a == x && b == y && c == z
                }
                ((None, ..), (None, ..)) => true,
                _ => false,
            };
            // A wheel turning at least 2 counts per row on both sides cannot stand still
            // for one row: a still row there is a stale sample, not slow motion (at high
            // row rates slow wheels leave many honest rows unchanged).
            let fast =
                |a: &[Option<i64>], b: &[Option<i64>], c: &[Option<i64>], d: &[Option<i64>]| {
                    (0..a.len()).any(|i| match (a[i], b[i], c[i], d[i]) {
                        (Some(a), Some(b), Some(c), Some(d)) => {
                            (b - a).abs() >= 2 && (d - c).abs() >= 2
                        }
                        _ => false,
                    })
                };
            if e2 == e1
                && same_pose
                && moving(&e0, &e1)
                && moving(&e2, &e3)
                && fast(&e0, &e1, &e2, &e3)
            {
                *d = true;
                a.duplicated_at_s.push(rec.t[k]);
            }
        }
    }
    if a.missing_at_s.is_empty() && a.duplicated_at_s.is_empty() {
        return None;
    }
    a.parameters
        .insert("missing_samples".into(), a.missing_at_s.len() as f64);
    a.parameters
        .insert("duplicated_samples".into(), a.duplicated_at_s.len() as f64);
    if dup.iter().any(|&x| x) {
        drop_rows(rec, &dup);
        a.removed = true;
    }
    Some(a)
}

fn drop_rows(rec: &mut Recording, drop: &[bool]) {
    fn keep<T: Clone>(v: &[T], drop: &[bool]) -> Vec<T> {
        v.iter()
            .zip(drop)
            .filter(|(_, d)| !**d)
            .map(|(x, _)| x.clone())
            .collect()
    }
    rec.t = keep(&rec.t, drop);
    rec.x = keep(&rec.x, drop);
    rec.y = keep(&rec.y, drop);
    rec.theta = keep(&rec.theta, drop);
    for w in rec.wheels.iter_mut() {
        if let Some(e) = &w.enc {
            w.enc = Some(keep(e, drop));
        }
        if let Some(c) = &w.cmd {
            w.cmd = Some(keep(c, drop));
        }
    }
    if let Some(l) = &rec.leg_front {
        rec.leg_front = Some(keep(l, drop));
    }
    if let Some(l) = &rec.leg_rear {
        rec.leg_rear = Some(keep(l, drop));
    }
}

/// Per-wheel counts ratio from the measured body motion; rescales the counts of wheels
/// off by a factor no tyre explains.
fn counts_per_rev(robot: &Robot, rec: &mut Recording) -> Option<Artefact> {
    let rpc = robot.drive.rad_per_count()?;
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let rows: Vec<(usize, f64, f64, f64)> = rec.pose_rows().collect();
    if rows.len() < 20 {
        return None;
    }
    let mut th: Vec<f64> = rows.iter().map(|r| r.3).collect();
    unwrap_angles(&mut th);
    let nw = robot.wheels.len();
    let (mut num, mut den) = (vec![0.0; nw], vec![0.0; nw]);
    for j in 1..rows.len() {
        let (k0, k1) = (rows[j - 1].0, rows[j].0);
        let (dx, dy) = (rows[j].1 - rows[j - 1].1, rows[j].2 - rows[j - 1].2);
        let mid = 0.5 * (th[j] + th[j - 1]);
        let (c, s) = (mid.cos(), mid.sin());
        let tw = Twist::new(c * dx + s * dy, -s * dx + c * dy, th[j] - th[j - 1]);
        for i in 0..nw {
            let Some(e) = rec.wheels.get(i).and_then(|w| w.enc.as_ref()) else {
                continue;
            };
            let (Some(a), Some(b)) = (e[k0], e[k1]) else {
                continue;
            };
            let meas = (b - a) as f64 * rpc;
            let pred = kin.wheel_rate(i, &tw);
            num[i] += pred * meas;
            den[i] += pred * pred;
        }
    }
    let mut a = Artefact::new("counts_per_rev_error");
    let mut scale = vec![1.0; nw];
    for i in 0..nw {
        // Need real motion of this wheel (root-sum-square travel over half a radian).
        if den[i] <= 0.0 || den[i].sqrt() < 0.5 {
            continue;
        }
        let ratio = num[i] / den[i];
        if !(ratio.is_finite() && ratio > 0.0) {
            continue;
        }
        // Only a power of two other than 1, within 10 %: what a quadrature mode or a
        // missed gear stage makes. Anything else this estimate sees (it uses the nominal
        // geometry) may be geometry the later stages fit.
        let p2 = 2f64.powf(ratio.log2().round());
        if p2 == 1.0 || (ratio / p2 - 1.0).abs() > 0.1 {
            continue;
        }
        let snapped = p2;
        a.parameters
            .insert(format!("counts_ratio_{}", robot.wheels[i].name), snapped);
        a.uncertainties.insert(
            format!("counts_ratio_{}", robot.wheels[i].name),
            (ratio - snapped).abs(),
        );
        scale[i] = snapped;
    }
    if a.parameters.is_empty() {
        return None;
    }
    for (w, s) in rec.wheels.iter_mut().zip(&scale) {
        if *s != 1.0 {
            if let Some(e) = &mut w.enc {
                for c in e.iter_mut().flatten() {
                    *c = (*c as f64 / s).round() as i64;
                }
            }
        }
    }
    a.removed = true;
    Some(a)
}

/// Time offset and clock ratio of the poses against the encoders.
fn clocks(
    robot: &Robot,
    rec: &mut Recording,
) -> (Vec<Artefact>, Option<crate::calibrate::Calibration>) {
    let recs = [("recording".to_string(), rec.clone())];
    let Ok(cal) = calibrate(robot, &recs, None, &CalOptions::default()) else {
        return (vec![], None);
    };
    let p = &cal.per_recording[0];
    let nu = p.nuisance;
    let mut d: Vec<f64> = rec.t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    let dt = d.get(d.len() / 2).copied().unwrap_or(0.0);
    let mut out = vec![];
    let mut applied = Nuisance {
        time_offset_s: 0.0,
        clock_ratio: 1.0,
        ..nu
    };
    if nu.time_offset_s.abs() > 4.0 * p.time_offset_sigma_s && nu.time_offset_s.abs() > 0.25 * dt {
        let mut a = Artefact::new("time_offset");
        a.parameters
            .insert("time_offset_s".into(), nu.time_offset_s);
        a.uncertainties
            .insert("time_offset_s".into(), p.time_offset_sigma_s);
        a.removed = true;
        applied.time_offset_s = nu.time_offset_s;
        out.push(a);
    }
    if (nu.clock_ratio - 1.0).abs() > 4.0 * p.clock_ratio_sigma
        && (nu.clock_ratio - 1.0).abs() > 5e-4
    {
        let mut a = Artefact::new("clock_rate");
        a.parameters.insert("clock_ratio".into(), nu.clock_ratio);
        a.uncertainties
            .insert("clock_ratio".into(), p.clock_ratio_sigma);
        a.removed = true;
        applied.clock_ratio = nu.clock_ratio;
        out.push(a);
    }
    if !out.is_empty() {
        *rec = on_encoder_clock(rec, &applied);
    }
    (out, Some(cal))
}

/// The recording with its pose columns moved onto the encoders' clock: the pose written
/// at row k becomes the measured pose at the time that shows the robot at row k's encoder
/// time, t' = t0 + offset + ratio (t_k - t0), interpolated between measured samples.
/// Rows whose t' falls outside the measured poses lose their pose.
pub fn on_encoder_clock(rec: &Recording, nu: &Nuisance) -> Recording {
    let mut out = rec.clone();
    let rows: Vec<(usize, f64, f64, f64)> = rec.pose_rows().collect();
    if rows.len() < 2 || rec.t.is_empty() {
        return out;
    }
    let ts: Vec<f64> = rows.iter().map(|r| rec.t[r.0]).collect();
    let mut th: Vec<f64> = rows.iter().map(|r| r.3).collect();
    unwrap_angles(&mut th);
    let t0 = rec.t[0];
    for &(k, ..) in &rows {
        let tq = t0 + nu.time_offset_s + nu.clock_ratio * (rec.t[k] - t0);
        let j = ts.partition_point(|&v| v <= tq);
        if j == 0 || j >= ts.len() {
            // Outside the measured span (or exactly at its end).
            if (tq - ts[ts.len() - 1]).abs() < 1e-12 {
                continue;
            }
            out.x[k] = None;
            out.y[k] = None;
            out.theta[k] = None;
            continue;
        }
        let f = (tq - ts[j - 1]) / (ts[j] - ts[j - 1]);
        let l = |a: f64, b: f64| a + (b - a) * f;
        out.x[k] = Some(l(rows[j - 1].1, rows[j].1));
        out.y[k] = Some(l(rows[j - 1].2, rows[j].2));
        out.theta[k] = Some(l(th[j - 1], th[j]));
    }
    out
}
