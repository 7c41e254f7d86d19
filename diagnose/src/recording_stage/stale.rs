//! `stale_samples`: rows repeating the previous row's encoder values while the wheels
//! turn, then catching up (a stale buffer), and pose samples repeating the previous pose
//! sample while the robot moves (a tracker that did not update).

use super::artefact::{Artefact, Event, MAX_EVENTS};
use super::odometry::robust_sd;
use formats::recording::Recording;
use std::collections::BTreeMap;

/// Longest run of stale encoder rows looked for (rows): a buffer a few rows late.
pub const MAX_STALE_RUN: usize = 3;
/// A wheel turning at least this many counts per row (at the rate of the row before a
/// still run, and at the rate of the catch-up row) cannot stand still between: honest rows
/// of a turning wheel differ by the whole counts of its travel, at least `floor(v)` for v
/// counts per row, so only a stale row shows none.
pub const STALE_MIN_COUNTS: i64 = 2;
/// A pose sample equal to the one before is stale when the next fresh sample lies
/// further than this many pose-noise sigmas (of a difference of two samples) from it.
/// On the controls (docs/diagnose.md) no fresh sample ever equals the one before.
pub const STALE_POSE_Z: f64 = 5.0;

/// Finds stale encoder rows (repaired by interpolating their counts between the rows
/// around the run) and stale pose samples (blanked).
pub(super) fn stale(rec: &mut Recording) -> Option<Artefact> {
    let mut a = Artefact::new("stale_samples");
    let enc_rows = stale_encoders(rec, &mut a.events);
    let pose_rows = stale_poses(rec, &mut a.events);
    if enc_rows == 0 && pose_rows == 0 {
        return None;
    }
    a.events.sort_by(|x, y| x.at_s.total_cmp(&y.at_s));
    a.events.truncate(MAX_EVENTS);
    a.parameters
        .insert("stale_encoder_rows".into(), enc_rows as f64);
    a.parameters
        .insert("stale_pose_samples".into(), pose_rows as f64);
    a.removed = true;
    a.notes.push(
        "stale encoder rows interpolated between the rows around them; stale pose samples blanked"
            .into(),
    );
    Some(a)
}

fn push(events: &mut Vec<Event>, at_s: f64, key: &str, v: f64) {
    if events.len() < 2 * MAX_EVENTS {
        let mut size = BTreeMap::new();
        size.insert(key.to_string(), v);
        events.push(Event { at_s, size });
    }
}

#[allow(clippy::needless_range_loop)] // rows of several columns indexed alike
fn stale_encoders(rec: &mut Recording, events: &mut Vec<Event>) -> usize {
    let n = rec.len();
    let cols: Vec<usize> = (0..rec.wheels.len())
        .filter(|&i| rec.wheels[i].enc.as_ref().is_some_and(|e| e.len() == n))
        .collect();
    if cols.is_empty() || n < 4 {
        return 0;
    }
    let get = |rec: &Recording, i: usize, k: usize| -> Option<i64> {
        rec.wheels[i]
            .enc
            .as_ref()
            .and_then(|e| e.get(k).copied().flatten())
    };
    // Row k repeats row k - 1 on every encoder (all present).
    let same = |rec: &Recording, k: usize| {
        cols.iter()
            .all(|&i| match (get(rec, i, k - 1), get(rec, i, k)) {
                (Some(a), Some(b)) => a == b,
                _ => false,
            })
    };
    let mut found = 0usize;
    let mut k = 2;
    while k + 1 < n {
        if !same(rec, k) {
            k += 1;
            continue;
        }
        let mut l = 1;
        while k + l < n && l <= MAX_STALE_RUN && same(rec, k + l) {
            l += 1;
        }
        let c = k + l;
        if l > MAX_STALE_RUN || c >= n {
            k = c;
            continue;
        }
        // Some wheel turns, at the rate of the row before and at the rate of the
        // catch-up, at least 2 counts per row over the still rows' time, the same way
        // (rates, not counts: rows need not be regular); and the catch-up carries the
        // still rows' travel: its rate over the run and itself is at least
        // (l + 3/4) / (l + 1) of the mean rate of the rows either side (a quarter row
        // for the rate changing between rows). A wheel that really paused (a robot
        // stopping between the legs of a square) restarts slower than that (the real
        // squares: 11, 0, 15, 42 counts; 11, 0, 15, 8).
        let span = rec.t[c - 1] - rec.t[k - 1];
        let (db, dc) = (rec.t[k - 1] - rec.t[k - 2], rec.t[c] - rec.t[k - 1]);
        // (less a part in a million: times written in decimals do not divide exactly)
        let need = (STALE_MIN_COUNTS * l as i64) as f64 * (1.0 - 1e-6);
        let share = (l as f64 + 0.75) / (l as f64 + 1.0);
        let fast = db > 0.0
            && dc > 0.0
            && cols.iter().any(|&i| {
                match (
                    get(rec, i, k - 2),
                    get(rec, i, k - 1),
                    get(rec, i, c - 1),
                    get(rec, i, c),
                ) {
                    (Some(a), Some(b), Some(x), Some(y)) => {
                        let (before, catch) = (b - a, y - x);
                        let rb = before.abs() as f64 / db;
                        let rc = catch.abs() as f64 / dc;
                        // The neighbours' rates over two rows each (a stale row just
                        // before this run does not inflate them), the same way.
                        let rate = |p: usize, q: usize| -> f64 {
                            match (get(rec, i, p), get(rec, i, q)) {
                                (Some(u), Some(v)) if rec.t[q] > rec.t[p] => {
                                    let d = v - u;
                                    if d.signum() == catch.signum() {
                                        d.abs() as f64 / (rec.t[q] - rec.t[p])
                                    } else {
                                        0.0
                                    }
                                }
                                _ => f64::NAN,
                            }
                        };
                        let rb2 = if k >= 3 { rate(k - 3, k - 1) } else { f64::NAN };
                        let rb2 = if rb2.is_finite() { rb2 } else { rb };
                        let ra2 = if c + 2 < n { rate(c, c + 2) } else { f64::NAN };
                        let ra2 = if ra2.is_finite() { ra2 } else { rb2 };
                        // One count for the catch-up's own rounding.
                        let expected = share * 0.5 * (rb2 + ra2) * dc - 1.0;
                        before.signum() == catch.signum()
                            && before.abs() >= STALE_MIN_COUNTS
                            && rb * span >= need
                            && rc * span >= need
                            && catch.abs() as f64 >= expected
                    }
                    _ => false,
                }
            });
        if fast {
            let (t0, t1) = (rec.t[k - 1], rec.t[c]);
            for &i in &cols {
                let (Some(e0), Some(e1)) = (get(rec, i, k - 1), get(rec, i, c)) else {
                    continue;
                };
                if let Some(e) = rec.wheels[i].enc.as_mut() {
                    for m in k..c {
                        let f = (rec.t[m] - t0) / (t1 - t0);
                        let v = e0 as f64 + (e1 as f64 - e0 as f64) * f;
                        if v.is_finite() {
                            e[m] = Some(v.round() as i64);
                        }
                    }
                }
            }
            for m in k..c {
                push(events, rec.t[m], "encoder_rows", l as f64);
            }
            found += l;
        }
        k = c;
    }
    found
}

fn stale_poses(rec: &mut Recording, events: &mut Vec<Event>) -> usize {
    let rows: Vec<(usize, f64, f64, f64)> = rec.pose_rows().collect();
    let m = rows.len();
    if m < 8 {
        return 0;
    }
    // Pose noise from second differences (sd sqrt 6 sigma for white noise); the stale
    // samples themselves are few and do not move the median.
    let d2 = |c: fn(&(usize, f64, f64, f64)) -> f64| -> Vec<f64> {
        rows.windows(3)
            .map(|w| c(&w[2]) - 2.0 * c(&w[1]) + c(&w[0]))
            .collect()
    };
    let sx = robust_sd(&d2(|r| r.1)) / 6f64.sqrt();
    let sy = robust_sd(&d2(|r| r.2)) / 6f64.sqrt();
    // At least the quantisation's noise: poses written at whole millimetres repeat
    // honestly whenever the robot moves less than a millimetre between samples.
    let xs: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let ys: Vec<f64> = rows.iter().map(|r| r.2).collect();
    let q = super::odometry::quantum(&xs).max(super::odometry::quantum(&ys));
    let sigma = (0.5 * (sx * sx + sy * sy))
        .sqrt()
        .max(super::odometry::quantum_sd(q) * 6f64.sqrt());
    if !sigma.is_finite() {
        return 0;
    }
    let mut found = 0usize;
    let mut j = 1;
    while j + 1 < m {
        let eq = |a: &(usize, f64, f64, f64), b: &(usize, f64, f64, f64)| {
            a.1 == b.1 && a.2 == b.2 && a.3 == b.3
        };
        if !eq(&rows[j], &rows[j - 1]) {
            j += 1;
            continue;
        }
        let mut l = 1;
        while j + l < m && eq(&rows[j + l], &rows[j - 1]) {
            l += 1;
        }
        let f = j + l;
        if f < m {
            let moved = (rows[f].1 - rows[j - 1].1).hypot(rows[f].2 - rows[j - 1].2);
            if moved > STALE_POSE_Z * sigma * std::f64::consts::SQRT_2 {
                for r in &rows[j..f] {
                    rec.x[r.0] = None;
                    rec.y[r.0] = None;
                    rec.theta[r.0] = None;
                    push(events, rec.t[r.0], "pose_samples", l as f64);
                }
                found += l;
            }
        }
        j = f + 1;
    }
    found
}
