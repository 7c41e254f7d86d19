//! Wheel positions from `sensor_msgs/msg/JointState` and their conversion to encoder
//! counts.
//!
//! Why counts and not a new angle column: formats.md §2 already carries wheel rotation as
//! cumulative counts with the counts per revolution in the robot file, and every reader
//! (diagnose, calibrate, the sim, other people's tools) reads it. ROS wheel joints are
//! almost always an encoder's counts scaled to radians by the hardware interface, so
//! `rad x cpr / 2 pi` gives back whole counts (the import reports how far from whole they
//! are: far from whole means the robot file's `encoder_counts_per_rev` is not the one the
//! robot's driver used). A joint that is not quantised (a simulator) loses at most half a
//! count, the resolution of the encoder the robot file names.

use crate::bag::Bag;
use crate::error::ImportError;
use crate::messages::{decode, types, JointState};
use std::collections::BTreeSet;

/// The wheel joints' positions over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct JointSeries {
    /// Stamp of each sample, ns since the epoch, strictly increasing.
    pub stamps_ns: Vec<i64>,
    /// Per sample, one position (rad) per requested joint, in the order asked.
    pub positions: Vec<Vec<f64>>,
    /// Samples dropped because their stamp repeated or went back.
    pub dropped: usize,
}

/// Reads `joints` from the JointState messages on `topic`. Messages that carry none of
/// them are skipped (another controller's joints); one carrying some but not all is an
/// error naming the missing ones.
pub fn joint_series(
    bag: &Bag,
    topic: &str,
    joints: &[String],
    use_receive_time: bool,
) -> Result<JointSeries, ImportError> {
    let Some(t) = bag.topic(topic) else {
        let js: Vec<String> = bag
            .topics_of(&[types::JOINT_STATE])
            .iter()
            .map(|t| t.name.clone())
            .collect();
        return Err(ImportError::new(
            &bag.path,
            format!(
                "no topic {topic} for the wheel joints{}; the bag holds:\n{}",
                if js.is_empty() {
                    String::new()
                } else {
                    format!(
                        " (JointState topics: {}; choose one with --joint-topic)",
                        js.join(", ")
                    )
                },
                bag.describe_topics()
            ),
        ));
    };
    if t.msg_type != types::JOINT_STATE {
        return Err(ImportError::new(
            &bag.path,
            format!(
                "{topic} is {}, not {}; the bag holds:\n{}",
                t.msg_type,
                types::JOINT_STATE,
                bag.describe_topics()
            ),
        ));
    }
    let msgs = bag.messages.get(topic).map(Vec::as_slice).unwrap_or(&[]);
    let mut seen: BTreeSet<String> = BTreeSet::new();
    let mut rows: Vec<(i64, Vec<f64>)> = Vec::with_capacity(msgs.len());
    let mut index = vec![usize::MAX; joints.len()];
    let mut zero_stamps = 0usize;
    for (k, m) in msgs.iter().enumerate() {
        let js: JointState = decode(&m.data).map_err(|e| {
            ImportError::new(
                &bag.path,
                format!("{topic}: message {k} cannot be decoded: {e}"),
            )
        })?;
        // Look the names up again only when the message's layout changes.
        let fits = index
            .iter()
            .zip(joints)
            .all(|(&i, j)| js.name.get(i).is_some_and(|n| n == j));
        if !fits {
            for (slot, j) in index.iter_mut().zip(joints) {
                *slot = js.name.iter().position(|n| n == j).unwrap_or(usize::MAX);
            }
        }
        let found = index.iter().filter(|&&i| i != usize::MAX).count();
        if found == 0 {
            seen.extend(js.name.iter().cloned());
            continue;
        }
        if found < joints.len() || js.position.len() < js.name.len() {
            let missing: Vec<&str> = joints
                .iter()
                .zip(&index)
                .filter(|(_, &i)| i == usize::MAX)
                .map(|(j, _)| j.as_str())
                .collect();
            return Err(ImportError::new(
                &bag.path,
                format!(
                    "{topic}: message {k} has joints {} but not {} (or fewer positions than names)",
                    js.name.join(", "),
                    missing.join(", ")
                ),
            ));
        }
        let stamp = if use_receive_time {
            m.log_time_ns as i64
        } else {
            if js.header.stamp.ns() == 0 {
                zero_stamps += 1;
            }
            js.header.stamp.ns()
        };
        rows.push((stamp, index.iter().map(|&i| js.position[i]).collect()));
    }
    if rows.is_empty() {
        let names: Vec<String> = seen.into_iter().collect();
        return Err(ImportError::new(
            &bag.path,
            format!(
                "{topic}: no message has the joints {} (map each wheel with --joint WHEEL=JOINT); the bag's JointState messages name: {}",
                joints.join(", "),
                if names.is_empty() { "(no joints)".into() } else { names.join(", ") }
            ),
        ));
    }
    if zero_stamps > rows.len() / 2 {
        return Err(ImportError::new(
            &bag.path,
            format!(
                "{topic}: {zero_stamps} of {} header stamps are zero (the publisher does not stamp them): import with --use-receive-time",
                rows.len()
            ),
        ));
    }
    // Stable sort by stamp (messages can arrive out of order); repeated stamps dropped.
    rows.sort_by_key(|r| r.0);
    let mut out = JointSeries::default();
    for (t, p) in rows {
        if out.stamps_ns.last().is_some_and(|&l| t <= l) {
            out.dropped += 1;
            continue;
        }
        out.stamps_ns.push(t);
        out.positions.push(p);
    }
    Ok(out)
}

/// Radians to counts: `rad x cpr / 2 pi` rounded, and how far it was from a whole count.
pub fn to_counts(rad: f64, counts_per_rev: f64) -> (i64, f64) {
    let c = rad * counts_per_rev / std::f64::consts::TAU;
    let r = c.round();
    (r as i64, (c - r).abs())
}
