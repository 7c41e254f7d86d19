//! Every converted sample is checked before it becomes a row: a corrupted message that
//! still decodes must not become a count of 0, a count of 2^63 - 1, a heading of NaN or a
//! recording half a billion seconds long (issue 52 §7).
//!
//! What is refused, and why each bound:
//! - a joint position that is not finite, or whose count would not be exact in f64
//!   (|rad x cpr / 2 pi| > 2^53): no encoder reaches it;
//! - a pose whose position or heading is not finite (a zero quaternion normalises to NaN);
//! - a sample whose stamp stands more than [`MAX_GAP_NS`] from the rest of its stream:
//!   the recording format refuses a step in `t` over an hour (docs/formats.md §2), so a
//!   lone stamp that far away (2^31 - 1 s) is damage, not a pause.

use crate::joints::JointSeries;
use crate::poses::PoseSeries;

/// The largest step between two samples of one stream that is still one recording.
pub const MAX_GAP_NS: i64 = 3_600_000_000_000;

/// The largest count magnitude a joint position may give (exact integers in f64).
const MAX_COUNTS: f64 = 9_007_199_254_740_992.0;

/// A sample refused: its stamp and why.
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    /// Its stamp, ns.
    pub stamp_ns: i64,
    /// What is wrong with it.
    pub why: String,
}

/// The indices of the samples outside the stream's largest run of stamps no more than
/// [`MAX_GAP_NS`] apart (stamps strictly increasing).
fn stamp_outliers(stamps: &[i64]) -> Vec<usize> {
    if stamps.is_empty() {
        return Vec::new();
    }
    let mut best = (0, 0); // [start, end) of the longest run
    let mut start = 0;
    for i in 1..=stamps.len() {
        if i == stamps.len() || stamps[i].saturating_sub(stamps[i - 1]) > MAX_GAP_NS {
            if i - start > best.1 - best.0 {
                best = (start, i);
            }
            start = i;
        }
    }
    (0..stamps.len())
        .filter(|&i| i < best.0 || i >= best.1)
        .collect()
}

fn keep<T: Clone>(v: &mut Vec<T>, bad: &[bool]) {
    let mut i = 0;
    v.retain(|_| {
        i += 1;
        !bad[i - 1]
    });
}

/// Removes the joint samples that cannot be counts; returns what was removed.
pub fn joints(js: &mut JointSeries, names: &[String], counts_per_rev: f64) -> Vec<Refused> {
    let mut bad = vec![false; js.stamps_ns.len()];
    let mut out = Vec::new();
    for (i, p) in js.positions.iter().enumerate() {
        for (v, name) in p.iter().zip(names) {
            let counts = v * counts_per_rev / std::f64::consts::TAU;
            if !counts.is_finite() || counts.abs() > MAX_COUNTS {
                bad[i] = true;
                out.push(Refused {
                    stamp_ns: js.stamps_ns[i],
                    why: format!("joint {name} at position {v} rad"),
                });
                break;
            }
        }
    }
    for i in stamp_outliers(&js.stamps_ns) {
        if !bad[i] {
            bad[i] = true;
            out.push(Refused {
                stamp_ns: js.stamps_ns[i],
                why: "a stamp over an hour from the rest of the stream".into(),
            });
        }
    }
    keep(&mut js.stamps_ns, &bad);
    keep(&mut js.positions, &bad);
    out
}

/// Removes the pose samples that are not poses; returns what was removed.
pub fn poses(ps: &mut PoseSeries) -> Vec<Refused> {
    let mut bad = vec![false; ps.stamps_ns.len()];
    let mut out = Vec::new();
    for (i, b) in bad.iter_mut().enumerate() {
        let (x, y, yaw) = (ps.x[i], ps.y[i], ps.yaw[i]);
        if !(x.is_finite() && y.is_finite() && yaw.is_finite()) {
            *b = true;
            out.push(Refused {
                stamp_ns: ps.stamps_ns[i],
                why: format!(
                    "pose ({x}, {y}) heading {yaw} (a non-finite value, or a zero quaternion)"
                ),
            });
        }
    }
    for i in stamp_outliers(&ps.stamps_ns) {
        if !bad[i] {
            bad[i] = true;
            out.push(Refused {
                stamp_ns: ps.stamps_ns[i],
                why: "a stamp over an hour from the rest of the stream".into(),
            });
        }
    }
    keep(&mut ps.stamps_ns, &bad);
    keep(&mut ps.x, &bad);
    keep(&mut ps.y, &bad);
    keep(&mut ps.yaw, &bad);
    out
}

/// One line for a note or an error: how many, the first few with their times after
/// `t0_ns`.
pub fn describe(topic: &str, refused: &[Refused], t0_ns: i64) -> String {
    let first: Vec<String> = refused
        .iter()
        .take(3)
        .map(|r| {
            format!(
                "{} at {:.3} s",
                r.why,
                r.stamp_ns.saturating_sub(t0_ns) as f64 * 1e-9
            )
        })
        .collect();
    format!(
        "{topic}: {} sample(s) refused ({}{})",
        refused.len(),
        first.join("; "),
        if refused.len() > 3 { "; ..." } else { "" }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nan_inf_and_far_stamps_are_refused_and_the_rest_kept() {
        let s = 1_000_000_000i64;
        let mut js = JointSeries {
            stamps_ns: vec![0, s, 2 * s, 3 * s, (1i64 << 31) * s],
            positions: vec![
                vec![0.0, 0.0],
                vec![f64::NAN, 0.1],
                vec![0.2, f64::INFINITY],
                vec![0.3, 0.3],
                vec![0.4, 0.4],
            ],
            dropped: 0,
        };
        let names = ["l".to_string(), "r".to_string()];
        let r = joints(&mut js, &names, 1920.0);
        assert_eq!(r.len(), 3, "{r:?}");
        assert_eq!(js.stamps_ns, vec![0, 3 * s]);
        assert!(r[0].why.contains("joint l") && r[1].why.contains("joint r"));
        assert!(r[2].why.contains("hour"));
    }

    #[test]
    fn a_nan_heading_is_refused_and_the_rest_kept() {
        let mut ps = PoseSeries {
            stamps_ns: vec![0, 1, 2, 3],
            x: vec![0.0; 4],
            y: vec![0.0; 4],
            yaw: vec![3.0, f64::NAN, 3.1, 3.2],
            ..PoseSeries::default()
        };
        let r = poses(&mut ps);
        assert_eq!(r.len(), 1);
        assert_eq!(ps.yaw, vec![3.0, 3.1, 3.2]);
    }
}
