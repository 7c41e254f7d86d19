//! The `recording` stage: artefacts of how a run was logged, not physics, with their own
//! catalogue ids. Found and fitted before the physics is judged, reported under their own
//! heading, and removed from the recording the physics stages see:
//!
//! - `sample_glitch`: missing samples (a gap of whole row intervals in `t`) and duplicated
//!   samples (a row repeating the previous one's encoders and pose while the robot moves
//!   on both sides): gaps as intervals with their count, duplicates with their times.
//!   Duplicated rows are dropped; gaps only reported
//!   (encoders are cumulative, so a gap loses no travel).
//! - `counts_per_rev_error` (`counts_ratio_<wheel>`: true over configured counts per
//!   wheel revolution, snapped to p/q; `counts_ratio_raw_<wheel>` the raw estimate with
//!   its sigma): each wheel's encoder travel against the travel the measured body motion
//!   asks of it through the nominal kinematics, over quarter-second segments. A ratio at
//!   least [`COUNTS_FAR`] from 1 (no tyre or mounting error explains it) that exactly one
//!   simple fraction (q <= 4: a resolution, quadrature mode or gear ratio written wrong)
//!   matches within the tyre band and three sigmas is removed; one far from 1 that no
//!   single fraction matches is reported as unexplained and left in. Nearer 1 it is tyre
//!   size or geometry, physics.
//! - `time_offset` (`time_offset_s`, poses later than encoders when positive) and
//!   `clock_rate` (`clock_ratio`, the pose clock over the encoder clock): fitted with the
//!   geometry by [`calibrate`](mod@calibrate); reported when beyond four sigmas and a material
//!   size (a quarter row interval; 0.05 %), then the poses are moved onto the encoder
//!   clock.

mod artefact;
mod encoder_scale;
mod odometry;
mod pose_jump;
mod segments;
mod stale;
mod time;
mod wiring;

pub use artefact::{Artefact, Event, Gap, MAX_EVENTS};
pub use encoder_scale::{POSES_AGREE, SCALE_MIN, SCALE_SIGMAS};
pub use pose_jump::{JUMP_WINDOW, JUMP_Z};
pub use stale::{MAX_STALE_RUN, STALE_MIN_COUNTS, STALE_POSE_Z};
pub use time::JITTER_FRACTION;
pub use wiring::{WIRING_MIN_CORR, WIRING_RATIO};

use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::Robot;
use calibrate::{calibrate, CalOptions, Nuisance};
use fitkit::series::unwrap_angles;
use formats::recording::Recording;

/// Recording-stage catalogue ids (`formats::catalogue::RECORDING_IDS`).
pub const RECORDING_IDS: [&str; 11] = formats::catalogue::RECORDING_IDS;

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
    pub geometry: Option<calibrate::Calibration>,
}

/// Runs the recording stage on `rec` of `robot`.
pub fn analyse(robot: &Robot, rec: Recording) -> RecordingStage {
    let mut artefacts = Vec::new();
    let mut cur = rec;
    // Time first (the reader re-timed rows going back; jitter widens what a gap is),
    // then the rows, the wiring, the counts, the poses, and the clocks last.
    artefacts.extend(time::time_backwards(&cur));
    let jitter = time::time_jitter(&cur);
    let step_sd = time::step_stats(&cur).map_or(0.0, |s| s.1);
    if let Some(a) = sample_glitches(&mut cur, step_sd) {
        artefacts.push(a);
    }
    artefacts.extend(jitter);
    artefacts.extend(stale::stale(&mut cur));
    if let Some(segs) = segments::segments(robot, &cur) {
        artefacts.extend(wiring::wiring(robot, &mut cur, &segs));
    }
    artefacts.extend(counts_per_rev(robot, &mut cur));
    if let Some(segs) = segments::segments(robot, &cur) {
        artefacts.extend(encoder_scale::encoder_scale(robot, &mut cur, &segs));
    }
    artefacts.extend(pose_jump::pose_jumps(robot, &mut cur));
    let (clock_artefacts, geometry) = clocks(robot, &mut cur, CLOCK_FIT_MAX_ROWS);
    artefacts.extend(clock_artefacts);
    RecordingStage {
        artefacts,
        corrected: cur,
        geometry,
    }
}

/// The statistics the logger-fault checks compare with their thresholds, on a
/// recording as given (no fault removed): what `logger_faults`' controls measure to state
/// each threshold's false-alarm margin (docs/diagnose.md).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Statistics {
    /// Smallest correlation of an encoder column with its own wheel's demand (a sign
    /// flip needs <= -[`WIRING_MIN_CORR`]).
    pub own_correlation_min: f64,
    /// Smallest unexplained share of another order of the columns over the columns as
    /// written (a swap needs < [`WIRING_RATIO`]).
    pub permuted_ratio_min: f64,
    /// Largest |encoder over commanded travel - 1| on a stepper robot (NaN otherwise;
    /// [`SCALE_MIN`]).
    pub scale_off_max: f64,
    /// ... and in its own sigmas ([`SCALE_SIGMAS`]).
    pub scale_off_sigmas_max: f64,
    /// Largest pose innovation in its robust sigmas ([`JUMP_Z`]).
    pub innovation_z_max: f64,
    /// The written times' jitter over the row interval ([`JITTER_FRACTION`]).
    pub jitter_fraction: f64,
}

/// [`Statistics`] of `rec` of `robot`.
pub fn statistics(robot: &Robot, rec: &Recording) -> Statistics {
    let (own, ratio, mut off, mut off_s) = match segments::segments(robot, rec) {
        Some(segs) => {
            let (own, ratio) = wiring::wiring_stats(robot, &segs);
            let (mut off, mut off_s) = (f64::NAN, f64::NAN);
            for (k, sigma, _) in encoder_scale::stepper_scales(robot, &segs)
                .into_iter()
                .flatten()
            {
                off = (k - 1.0).abs().max(if off.is_nan() { 0.0 } else { off });
                let z = (k - 1.0).abs() / sigma;
                off_s = z.max(if off_s.is_nan() { 0.0 } else { off_s });
            }
            (own, ratio, off, off_s)
        }
        None => (f64::NAN, f64::NAN, f64::NAN, f64::NAN),
    };
    if !off.is_finite() {
        off = f64::NAN;
        off_s = f64::NAN;
    }
    let jitter_fraction =
        time::step_stats(rec).map_or(f64::NAN, |(med, sd)| sd / std::f64::consts::SQRT_2 / med);
    Statistics {
        own_correlation_min: own,
        permuted_ratio_min: ratio,
        scale_off_max: off,
        scale_off_sigmas_max: off_s,
        innovation_z_max: pose_jump::largest_innovation_z(robot, rec),
        jitter_fraction,
    }
}

/// The gaps in `t` (a step of at least 1.5 median row intervals) and the samples missing
/// in all, in memory proportional to the number of rows whatever the steps' size.
pub fn gaps(t: &[f64]) -> (Vec<Gap>, f64) {
    if t.len() < 2 {
        return (vec![], 0.0);
    }
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    d.sort_by(|a, b| a.total_cmp(b));
    let dt = d[d.len() / 2];
    if !(dt > 0.0 && dt.is_finite()) {
        return (vec![], 0.0);
    }
    gaps_at(t, dt)
}

fn gaps_at(t: &[f64], dt: f64) -> (Vec<Gap>, f64) {
    gaps_beyond(t, dt, 1.5 * dt)
}

/// Gaps: steps of at least `least` (s), counted in intervals of `dt`.
fn gaps_beyond(t: &[f64], dt: f64, least: f64) -> (Vec<Gap>, f64) {
    let mut out = Vec::new();
    let mut total = 0.0;
    for w in t.windows(2) {
        let steps = (w[1] - w[0]) / dt;
        if w[1] - w[0] >= least && steps >= 1.5 {
            // A step beyond f64 (1e308 s over a millisecond) counts as the largest.
            let missing = (steps.round() - 1.0).min(f64::MAX);
            total += missing;
            out.push(Gap {
                after_s: w[0],
                before_s: w[1],
                missing,
            });
        }
    }
    (out, total)
}

/// Missing rows (gaps of >= 1.5 median intervals, plus 4 sd of the written steps when
/// the times jitter) and duplicated rows (dropped).
fn sample_glitches(rec: &mut Recording, step_sd: f64) -> Option<Artefact> {
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
    // Jittered steps reach past 1.5 intervals without a row missing.
    let margin = if step_sd.is_finite() && step_sd > 0.0 {
        4.0 * step_sd
    } else {
        0.0
    };
    let (gaps, missing) = gaps_beyond(&rec.t, dt, 1.5 * dt + margin);
    a.gaps = gaps;
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
    if a.gaps.is_empty() && a.duplicated_at_s.is_empty() {
        return None;
    }
    a.parameters.insert("missing_samples".into(), missing);
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

/// A wheel's counts ratio is examined only this far from 1 (at or above 1.3, at or below
/// 1 / 1.3). Nearer 1 it is tyre size or geometry, for the physics stages: a tyre is within
/// [`calibrate::RADIUS_RANGE`] (5 %) of nominal, and the nominal kinematics this
/// estimate uses also fold wheel mounting errors into it (the real omni3 square shows a
/// wheel 17 % large under nominal geometry, from its wheel angles); 1.05 x 1.17 = 1.23
/// stays below the bound.
pub const COUNTS_FAR: f64 = 1.3;
/// Largest denominator q of a counts ratio p/q taken as a configuration error (a gear
/// ratio or resolution written wrong: 3, 3/2, 5/3, 5/2, 3/4, ...). Powers of two down to
/// 1/16 (quadrature modes and missed gear stages combined) count too.
pub const COUNTS_MAX_DEN: u32 = 4;
/// Largest numerator p of a counts ratio p/q.
pub const COUNTS_MAX_NUM: u32 = 16;
/// Sigmas of the estimate's own scatter added to the tyre band when a raw ratio is
/// matched to a fraction.
pub const COUNTS_SIGMAS: f64 = 3.0;
/// Travel is compared over segments of about this length (s): long enough that pose
/// noise is small against the travel (1 mm against ~5 cm), short enough that a wheel
/// rarely reverses inside one.
const COUNTS_SEGMENT_S: f64 = 0.25;

/// The fractions a counts ratio may snap to: p/q in lowest terms with q <= 4 and
/// p <= 16, and the powers of two 1/8 and 1/16; 1 excluded. Ascending.
pub fn counts_fractions() -> Vec<(u32, u32)> {
    fn gcd(a: u32, b: u32) -> u32 {
        if b == 0 {
            a
        } else {
            gcd(b, a % b)
        }
    }
    let mut out: Vec<(u32, u32)> = vec![(1, 8), (1, 16)];
    for q in 1..=COUNTS_MAX_DEN {
        for p in 1..=COUNTS_MAX_NUM {
            if p != q && gcd(p, q) == 1 {
                out.push((p, q));
            }
        }
    }
    out.sort_by(|a, b| (a.0 as f64 / a.1 as f64).total_cmp(&(b.0 as f64 / b.1 as f64)));
    out
}

/// One wheel's raw counts ratio: measured over asked-of-it travel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawRatio {
    /// Encoder travel over the travel the measured body motion asks of the wheel
    /// (nominal kinematics), segment by segment.
    pub ratio: f64,
    /// One sigma, from the scatter of the segments about the ratio (their lag-1
    /// autocorrelation counted).
    pub sigma: f64,
    /// Segments used.
    pub segments: usize,
}

/// What a raw ratio far from 1 is taken for.
#[derive(Debug, Clone, PartialEq)]
pub enum CountsMatch {
    /// Within the tyre band of 1: physics, left to the later stages.
    NearOne,
    /// Exactly one fraction p/q lies within the tyre band and [`COUNTS_SIGMAS`] of the raw
    /// ratio.
    Fraction(u32, u32),
    /// Far from 1, and no fraction or several lie within the band: not identified.
    Unexplained(Vec<(u32, u32)>),
}

/// Classifies a raw ratio: near 1 (physics), one simple fraction (a counts error), or
/// unexplained. The band around a fraction f is |ln(raw / f)| <= ln(1 + RADIUS_RANGE) +
/// COUNTS_SIGMAS sigma / raw: the raw ratio is the counts ratio times the wheel's own
/// radius error (a tyre within RADIUS_RANGE), measured with scatter sigma.
pub fn match_counts_ratio(raw: &RawRatio) -> CountsMatch {
    let r = raw.ratio;
    if !(r.is_finite() && r > 0.0) || r.ln().abs() < COUNTS_FAR.ln() {
        return CountsMatch::NearOne;
    }
    let band = calibrate::RADIUS_RANGE.ln_1p() + COUNTS_SIGMAS * raw.sigma / r;
    let near: Vec<(u32, u32)> = counts_fractions()
        .into_iter()
        .filter(|(p, q)| (r * *q as f64 / *p as f64).ln().abs() <= band)
        .collect();
    match near.as_slice() {
        [(p, q)] => CountsMatch::Fraction(*p, *q),
        _ => CountsMatch::Unexplained(near),
    }
}

/// Per wheel, the raw counts ratio from the measured body motion; `None` for a wheel
/// without an encoder or without enough motion to tell (less than a revolution in all or
/// fewer than 8 segments).
pub fn raw_counts_ratios(robot: &Robot, rec: &Recording) -> Vec<Option<RawRatio>> {
    let nw = robot.wheels.len();
    let none = vec![None; nw];
    let Some(rpc) = robot.drive.rad_per_count() else {
        return none;
    };
    let Ok(kin) = Kinematics::<f64>::new(robot, &Corrections::None) else {
        return none;
    };
    // Median pose interval: steps across a longer gap are skipped (a chord over a gap is
    // not the wheel's travel).
    let Some((rows, th, dt_med)) = segments::pose_track(rec) else {
        return none;
    };
    // Per wheel, (measured, asked) travel per segment, rad.
    let mut segs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); nw];
    let mut acc = vec![(0.0, 0.0); nw];
    let mut ok = vec![true; nw];
    let mut seg_t = 0.0;
    fn flush(acc: &mut [(f64, f64)], ok: &mut [bool], segs: &mut [Vec<(f64, f64)>]) {
        for ((a, o), s) in acc.iter_mut().zip(ok.iter_mut()).zip(segs.iter_mut()) {
            if *o && (a.0 != 0.0 || a.1 != 0.0) {
                s.push(*a);
            }
            *a = (0.0, 0.0);
            *o = true;
        }
    }
    for j in 1..rows.len() {
        let (k0, k1) = (rows[j - 1].0, rows[j].0);
        let dt = rec.t[k1] - rec.t[k0];
        if !(dt > 0.0 && dt <= 2.5 * dt_med) {
            flush(&mut acc, &mut ok, &mut segs);
            seg_t = 0.0;
            continue;
        }
        let (dx, dy) = (rows[j].1 - rows[j - 1].1, rows[j].2 - rows[j - 1].2);
        let mid = 0.5 * (th[j] + th[j - 1]);
        let (c, s) = (mid.cos(), mid.sin());
        let tw = Twist::new(c * dx + s * dy, -s * dx + c * dy, th[j] - th[j - 1]);
        for i in 0..nw {
            let e = rec.wheels.get(i).and_then(|w| w.enc.as_ref());
            match e.and_then(|e| Some((*e.get(k0)?, *e.get(k1)?))) {
                Some((Some(a), Some(b))) => {
                    acc[i].0 += (b as f64 - a as f64) * rpc;
                    acc[i].1 += kin.wheel_rate(i, &tw);
                }
                _ => ok[i] = false,
            }
        }
        seg_t += dt;
        if seg_t >= COUNTS_SEGMENT_S {
            flush(&mut acc, &mut ok, &mut segs);
            seg_t = 0.0;
        }
    }
    segs.iter()
        .map(|s| {
            // Magnitudes: a time offset between poses and encoders moves a reversal from
            // one segment to the next, not the travel.
            let pp: f64 = s.iter().map(|x| x.1 * x.1).sum();
            let travel: f64 = s.iter().map(|x| x.1.abs()).sum();
            let dot: f64 = s.iter().map(|x| x.0 * x.1).sum();
            // A wheel turning against the asked direction is a wiring question, not a
            // resolution.
            if s.len() < 8 || travel < std::f64::consts::TAU || dot.is_nan() || dot <= 0.0 {
                return None;
            }
            let ratio = s.iter().map(|x| x.0.abs() * x.1.abs()).sum::<f64>() / pp;
            let e: Vec<f64> = s.iter().map(|x| x.0.abs() - ratio * x.1.abs()).collect();
            let w: Vec<f64> = s.iter().zip(&e).map(|(x, e)| x.1.abs() * e).collect();
            let ss: f64 = w.iter().map(|v| v * v).sum();
            let rho = fitkit::noise::lag1_autocorrelation([w.as_slice()], 0.9);
            let sigma = ss.sqrt() / pp * fitkit::noise::ar1_inflation(rho).sqrt();
            (ratio.is_finite() && sigma.is_finite()).then_some(RawRatio {
                ratio,
                sigma,
                segments: s.len(),
            })
        })
        .collect()
}

/// Per-wheel counts ratio from the measured body motion; rescales the counts of wheels
/// off by a simple fraction no tyre explains, and reports (without removing) wheels far
/// from 1 that no single simple fraction explains.
fn counts_per_rev(robot: &Robot, rec: &mut Recording) -> Vec<Artefact> {
    let raw = raw_counts_ratios(robot, rec);
    let mut found = Artefact::new("counts_per_rev_error");
    let mut odd = Artefact::new("counts_per_rev_error");
    let mut scale = vec![1.0; raw.len()];
    for (i, r) in raw.iter().enumerate() {
        let Some(r) = r else { continue };
        let name = &robot.wheels[i].name;
        let (key, raw_key) = (
            format!("counts_ratio_{name}"),
            format!("counts_ratio_raw_{name}"),
        );
        match match_counts_ratio(r) {
            CountsMatch::NearOne => {}
            CountsMatch::Fraction(p, q) => {
                let f = p as f64 / q as f64;
                found.parameters.insert(key, f);
                found.parameters.insert(raw_key.clone(), r.ratio);
                found.uncertainties.insert(raw_key, r.sigma);
                found.notes.push(format!(
                    "{name}: {p}/{q} ({} segments; raw within {:.1} % of it)",
                    r.segments,
                    (r.ratio / f - 1.0) * 100.0
                ));
                scale[i] = f;
            }
            CountsMatch::Unexplained(near) => {
                odd.parameters.insert(raw_key.clone(), r.ratio);
                odd.uncertainties.insert(raw_key, r.sigma);
                let why = if near.is_empty() {
                    "no simple fraction p/q (q <= 4) within the tyre band".to_string()
                } else {
                    let s: Vec<String> = near.iter().map(|(p, q)| format!("{p}/{q}")).collect();
                    format!(
                        "{} all within the tyre band: cannot tell which",
                        s.join(", ")
                    )
                };
                odd.notes.push(format!(
                    "{name}: unexplained, travel {:.3} of what the body motion asks, {why}; not removed",
                    r.ratio
                ));
            }
        }
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
    let mut out = Vec::new();
    if !found.parameters.is_empty() {
        found.removed = true;
        out.push(found);
    }
    if !odd.parameters.is_empty() {
        out.push(odd);
    }
    out
}

/// Most rows the clock fit takes: 40 minutes at diagnose's 100 rows/s. A longer
/// recording is fitted on its rows merged to this many (`Recording::decimated`): on a
/// two-hour recording at 100 rows/s the fit's series, Jacobian and solver held 250 MB of
/// the 290 MB heap peak, and its residuals are correlated over hundreds of rows, so the
/// extra rows sharpen nothing (BENCHMARKS.md, the very large recording).
pub const CLOCK_FIT_MAX_ROWS: usize = 240_000;

/// Time offset and clock ratio of the poses against the encoders, fitted on at most
/// `max_rows` rows ([`CLOCK_FIT_MAX_ROWS`] in [`analyse`]); the artefacts found are
/// removed from `rec` (all its rows), and the fit is returned for its geometry evidence.
pub fn clocks(
    robot: &Robot,
    rec: &mut Recording,
    max_rows: usize,
) -> (Vec<Artefact>, Option<calibrate::Calibration>) {
    let span = match (rec.t.first(), rec.t.last()) {
        (Some(a), Some(b)) => b - a,
        _ => 0.0,
    };
    let thinned = (rec.len() > max_rows && span > 0.0)
        .then(|| rec.clone().decimated(max_rows as f64 / span).0);
    // Borrowed otherwise: a copy of a long recording would be the stage's largest
    // allocation.
    let recs = [("recording".to_string(), thinned.as_ref().unwrap_or(rec))];
    let opts = CalOptions {
        free_start: true,
        ..Default::default()
    };
    let fitted = calibrate(robot, &recs, None, &opts);
    drop(thinned);
    let Ok(cal) = fitted else {
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
