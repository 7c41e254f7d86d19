//! `time_backwards` (the file's time went back; the reader re-timed the rows) and
//! `time_jitter` (the written row intervals vary by more than a logger's clock allows).

use super::artefact::{Artefact, Event, MAX_EVENTS};
use super::odometry::robust_sd;
use formats::recording::Recording;
use std::collections::BTreeMap;

/// `time_jitter` is reported when the written times' jitter (the robust standard
/// deviation of the steps over sqrt 2: white timestamp noise of sd s gives steps of sd
/// s sqrt 2) exceeds this fraction of the median row interval. Every simulated control
/// has 0; at 5 % of the interval a command's travel per row is off by 5 % of one row's
/// travel, below what the actuator stage resolves (docs/diagnose.md, recording stage).
pub const JITTER_FRACTION: f64 = 0.05;

/// The rows whose written time went back, as the reader found and re-timed them.
pub(super) fn time_backwards(rec: &Recording) -> Option<Artefact> {
    let f = &rec.time_faults;
    if f.count == 0 {
        return None;
    }
    let mut a = Artefact::new("time_backwards");
    let mut largest: f64 = 0.0;
    let mut steps = 0usize;
    for b in &f.back {
        largest = largest.max(b.back_s);
        steps += usize::from(b.clock_step);
        if a.events.len() < MAX_EVENTS {
            let mut size = BTreeMap::new();
            size.insert("back_s".to_string(), b.back_s);
            size.insert("line".to_string(), b.line as f64);
            size.insert("clock_step".to_string(), f64::from(u8::from(b.clock_step)));
            a.events.push(Event {
                at_s: b.written_s,
                size,
            });
        }
    }
    a.parameters.insert("times_back".into(), f.count as f64);
    a.parameters.insert("clock_steps".into(), steps as f64);
    a.parameters.insert("largest_back_s".into(), largest);
    a.removed = true;
    a.notes.push(
        "re-timed as read: where later rows follow a step back, every later row moved on by the step (the clock stepped); a row written early alone placed halfway between its neighbours".into(),
    );
    Some(a)
}

/// The written steps' median and robust standard deviation: the reader's, over every
/// row of the file before merging, or else from `rec.t` when no row was merged.
pub(super) fn step_stats(rec: &Recording) -> Option<(f64, f64)> {
    let f = &rec.time_faults;
    if f.rows > 2 && f.step_median_s.is_finite() && f.step_sd_s.is_finite() {
        return Some((f.step_median_s, f.step_sd_s));
    }
    if rec.merged.is_some() || rec.len() < 3 {
        return None;
    }
    let mut d: Vec<f64> = rec.t.windows(2).map(|w| w[1] - w[0]).collect();
    let sd = robust_sd(&d);
    let med = super::odometry::median(&mut d);
    (med.is_finite() && sd.is_finite()).then_some((med, sd))
}

/// The written times' jitter, when above [`JITTER_FRACTION`] of the row interval.
pub(super) fn time_jitter(rec: &Recording) -> Option<Artefact> {
    let (med, sd) = step_stats(rec)?;
    let jitter = sd / std::f64::consts::SQRT_2;
    if !(med > 0.0 && jitter > JITTER_FRACTION * med) {
        return None;
    }
    let mut a = Artefact::new("time_jitter");
    a.parameters.insert("time_jitter_s".into(), jitter);
    a.parameters.insert("row_interval_s".into(), med);
    a.notes.push(format!(
        "the written row intervals vary by {:.1} % of the {:.1} ms interval (sd {:.2} ms over sqrt 2); the rows are used at their written times, and a step of less than 1.5 intervals plus 4 sd is not counted as missing rows",
        100.0 * jitter / med,
        med * 1e3,
        sd * 1e3
    ));
    Some(a)
}
