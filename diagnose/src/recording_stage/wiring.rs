//! `encoder_sign` and `wheels_swapped`: each encoder column's travel against what the
//! measured body motion asks of every wheel. A column that matches its own wheel with
//! the opposite sign counts backwards; one that matches another wheel's demand far
//! better than its own holds that wheel's counts.

use super::artefact::{Artefact, Event};
use super::segments::Segments;
use calib_core::robot::Robot;
use formats::recording::Recording;
use std::collections::BTreeMap;

/// A column is matched to a wheel only when their travels correlate at least this much
/// (uncentred, over the segments): on the controls every column correlates above 0.9
/// with its own wheel (docs/diagnose.md), and a column unrelated to a wheel near 0.
pub const WIRING_MIN_CORR: f64 = 0.5;
/// A permutation of the columns is taken only when its unexplained share (sum of 1 -
/// corr^2 over the columns) is below this fraction of the columns as written: the same
/// motion seen through the other wheel must fit several times better, not marginally
/// (a robot driving straight asks the same of both sides and tells nothing).
pub const WIRING_RATIO: f64 = 0.25;
/// Columns up to this many are permuted (720 orders); more are checked for signs only.
const MAX_PERMUTED: usize = 6;

fn permutations(n: usize) -> Vec<Vec<usize>> {
    fn go(cur: &mut Vec<usize>, used: &mut Vec<bool>, out: &mut Vec<Vec<usize>>) {
        if cur.len() == used.len() {
            out.push(cur.clone());
            return;
        }
        for i in 0..used.len() {
            if !used[i] {
                used[i] = true;
                cur.push(i);
                go(cur, used, out);
                cur.pop();
                used[i] = false;
            }
        }
    }
    let mut out = vec![];
    go(&mut vec![], &mut vec![false; n], &mut out);
    out
}

/// The correlation of every column with every wheel's demand.
pub(super) fn correlations(segs: &Segments, nw: usize) -> Vec<Vec<f64>> {
    (0..nw)
        .map(|i| {
            (0..nw)
                .map(|j| {
                    let (ab, aa, bb, n) = Segments::dot(&segs.enc, i, &segs.asked, j);
                    if n >= 8 && aa > 0.0 && bb > 0.0 {
                        ab / (aa * bb).sqrt()
                    } else {
                        f64::NAN
                    }
                })
                .collect()
        })
        .collect()
}

/// The share of each judged column's motion its assigned wheel leaves unexplained
/// (1 - r^2, 1 where the correlation is unknown), summed: column `cols[a]` read as wheel
/// `cols[p[a]]`.
fn order_cost(c: &[Vec<f64>], cols: &[usize], p: &[usize]) -> f64 {
    p.iter()
        .enumerate()
        .map(|(a, &b)| {
            let r = c[cols[a]][cols[b]];
            if r.is_finite() {
                1.0 - r * r
            } else {
                1.0
            }
        })
        .sum()
}

/// The statistics the wiring thresholds bound: the smallest correlation of a column
/// with its own wheel, and the smallest unexplained share of any other order of the
/// columns over that of the columns as written.
pub(super) fn wiring_stats(robot: &Robot, segs: &Segments) -> (f64, f64) {
    let nw = robot.wheels.len();
    let c = correlations(segs, nw);
    let cols: Vec<usize> = (0..nw).filter(|&i| c[i][i].is_finite()).collect();
    let own = cols.iter().map(|&i| c[i][i]).fold(f64::INFINITY, f64::min);
    let cost = |p: &[usize]| order_cost(&c, &cols, p);
    let m = cols.len();
    let base = cost(&(0..m).collect::<Vec<_>>());
    let ratio = if (1..=MAX_PERMUTED).contains(&m) {
        permutations(m)
            .iter()
            .filter(|p| p.iter().enumerate().any(|(a, &b)| a != b))
            .map(|p| cost(p) / base)
            .fold(f64::INFINITY, f64::min)
    } else {
        f64::INFINITY
    };
    (own, ratio)
}

/// Finds swapped columns and reversed encoders, and puts them right in `rec`.
pub(super) fn wiring(robot: &Robot, rec: &mut Recording, segs: &Segments) -> Vec<Artefact> {
    let nw = robot.wheels.len();
    let c = correlations(segs, nw);
    // Columns that can be judged: an encoder, and a finite correlation with its wheel.
    let cols: Vec<usize> = (0..nw).filter(|&i| c[i][i].is_finite()).collect();
    let m = cols.len();
    if m == 0 {
        return vec![];
    }
    let cost = |p: &[usize]| order_cost(&c, &cols, p);
    let identity: Vec<usize> = (0..m).collect();
    let mut best = identity.clone();
    if m <= MAX_PERMUTED {
        let base = cost(&identity);
        let mut best_cost = base;
        for p in permutations(m) {
            let moved_ok = p
                .iter()
                .enumerate()
                .all(|(a, &b)| a == b || c[cols[a]][cols[b]].abs() >= WIRING_MIN_CORR);
            let k = cost(&p);
            if moved_ok && k < best_cost && k < WIRING_RATIO * base {
                best_cost = k;
                best = p;
            }
        }
    }
    // Column cols[a] holds wheel cols[best[a]]'s counts, with sign s.
    let mut swapped = Artefact::new("wheels_swapped");
    let mut sign = Artefact::new("encoder_sign");
    let mut src: Vec<(usize, usize, f64)> = vec![];
    for (a, &b) in best.iter().enumerate() {
        let (i, j) = (cols[a], cols[b]);
        let r = c[i][j];
        let s = if r <= -WIRING_MIN_CORR { -1.0 } else { 1.0 };
        if i != j {
            swapped
                .parameters
                .insert(format!("source_{}", robot.wheels[i].name), j as f64 + 1.0);
            swapped.notes.push(format!(
                "column enc_{} holds {}'s counts (correlation {r:.3}; with its own wheel {:.3})",
                robot.wheels[i].name, robot.wheels[j].name, c[i][i]
            ));
        }
        if s < 0.0 {
            sign.parameters
                .insert(format!("sign_{}", robot.wheels[j].name), -1.0);
            sign.notes.push(format!(
                "{} counts backwards (correlation {r:.3} with what the body motion asks of it)",
                robot.wheels[j].name
            ));
        }
        if i != j || s < 0.0 {
            src.push((i, j, s));
        }
    }
    if src.is_empty() {
        return vec![];
    }
    // Put the columns right: wheel j gets s times column i.
    let old: Vec<Option<Vec<Option<i64>>>> = rec.wheels.iter().map(|w| w.enc.clone()).collect();
    for &(i, j, s) in &src {
        rec.wheels[j].enc = old[i].as_ref().map(|e| {
            e.iter()
                .map(|v| v.map(|v| if s < 0.0 { v.saturating_neg() } else { v }))
                .collect()
        });
    }
    let t0 = rec.t.first().copied().unwrap_or(0.0);
    let mut out = vec![];
    for mut a in [swapped, sign] {
        if !a.parameters.is_empty() {
            a.removed = true;
            a.events.push(Event {
                at_s: t0,
                size: BTreeMap::new(),
            });
            a.notes
                .push("from the start of the recording; put right before the physics".into());
            out.push(a);
        }
    }
    out
}
