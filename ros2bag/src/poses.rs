//! The measured body pose over time, from `geometry_msgs/msg/PoseStamped`,
//! `PoseWithCovarianceStamped`, `nav_msgs/msg/Odometry` or the tf tree
//! (`tf2_msgs/msg/TFMessage`, see [`crate::tf`]), projected on the floor plane: x, y and
//! the heading (yaw, unwrapped along the stream).

use crate::bag::Bag;
use crate::error::ImportError;
use crate::messages::{
    decode, types, unit, Odometry, Pose, PoseStamped, PoseWithCovarianceStamped,
};
use nalgebra::{Isometry3, Translation3};
use std::collections::BTreeSet;

/// Where the pose comes from.
#[derive(Debug, Clone, Copy)]
pub struct PoseQuery<'a> {
    /// The topic (for tf: the dynamic tf topic, usually `/tf`).
    pub topic: &'a str,
    /// The fixed frame the pose is in (`map`, `world`, `odom`); checked against the
    /// messages' frame, required for tf.
    pub pose_frame: Option<&'a str>,
    /// The robot's body frame (`base_link`); checked against Odometry's child frame,
    /// required for tf.
    pub base_frame: Option<&'a str>,
    /// The static tf topic (`/tf_static`).
    pub tf_static_topic: &'a str,
    /// Use the recorder's receive time instead of the header stamps.
    pub use_receive_time: bool,
}

/// The body pose on the floor plane over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PoseSeries {
    /// Stamps, ns since the epoch, strictly increasing.
    pub stamps_ns: Vec<i64>,
    /// x in the pose frame, m.
    pub x: Vec<f64>,
    /// y in the pose frame, m.
    pub y: Vec<f64>,
    /// Heading in the pose frame, rad, unwrapped (continuous).
    pub yaw: Vec<f64>,
    /// The frame the poses are in.
    pub frame: String,
    /// Largest roll or pitch seen, rad (the projection on the floor ignores them).
    pub max_tilt_rad: f64,
    /// Samples dropped because their stamp repeated or went back.
    pub dropped: usize,
}

/// A ROS pose as an isometry (the quaternion normalised).
pub fn isometry(p: &Pose) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(p.position.x, p.position.y, p.position.z),
        unit(&p.orientation),
    )
}

/// x, y, yaw and tilt (the larger of |roll|, |pitch|) of an isometry.
pub fn planar(iso: &Isometry3<f64>) -> (f64, f64, f64, f64) {
    let q = iso.rotation.quaternion();
    let (w, x, y, z) = (q.w, q.i, q.j, q.k);
    let yaw = (2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z));
    let (roll, pitch, _) = iso.rotation.euler_angles();
    (
        iso.translation.x,
        iso.translation.y,
        yaw,
        roll.abs().max(pitch.abs()),
    )
}

/// Reads the pose stream `q` asks for.
pub fn pose_series(bag: &Bag, q: &PoseQuery<'_>) -> Result<PoseSeries, ImportError> {
    let Some(t) = bag.topic(q.topic) else {
        let poses: Vec<String> = bag
            .topics_of(&types::POSE_TYPES)
            .iter()
            .map(|t| format!("{} ({})", t.name, t.msg_type))
            .collect();
        return Err(ImportError::new(
            &bag.path,
            format!(
                "no pose topic {}{}; the bag holds:\n{}",
                q.topic,
                if poses.is_empty() {
                    " and no topic of a pose type".to_string()
                } else {
                    format!(" (topics with poses: {})", poses.join(", "))
                },
                bag.describe_topics()
            ),
        ));
    };
    let msgs = bag.messages.get(q.topic).map(Vec::as_slice).unwrap_or(&[]);
    let decode_err = |k: usize, e: String| {
        ImportError::new(
            &bag.path,
            format!("{}: message {k} cannot be decoded: {e}", q.topic),
        )
    };
    let mut frames: BTreeSet<String> = BTreeSet::new();
    let mut children: BTreeSet<String> = BTreeSet::new();
    // (stamp, frame, child, pose)
    let mut samples: Vec<(i64, Isometry3<f64>)> = Vec::with_capacity(msgs.len());
    let mut wrong_frame = 0usize;
    let stamp = |h: i64, log: u64| if q.use_receive_time { log as i64 } else { h };
    match t.msg_type.as_str() {
        types::POSE_STAMPED | types::POSE_COV_STAMPED | types::ODOMETRY => {
            for (k, m) in msgs.iter().enumerate() {
                let (h, child, pose) = match t.msg_type.as_str() {
                    types::POSE_STAMPED => {
                        let p: PoseStamped = decode(&m.data).map_err(|e| decode_err(k, e))?;
                        (p.header, None, p.pose)
                    }
                    types::POSE_COV_STAMPED => {
                        let p: PoseWithCovarianceStamped =
                            decode(&m.data).map_err(|e| decode_err(k, e))?;
                        (p.header, None, p.pose.pose)
                    }
                    _ => {
                        let o: Odometry = decode(&m.data).map_err(|e| decode_err(k, e))?;
                        (o.header, Some(o.child_frame_id), o.pose.pose)
                    }
                };
                let frame_ok = q.pose_frame.is_none_or(|f| f == h.frame_id);
                let child_ok = match (&child, q.base_frame) {
                    (Some(c), Some(b)) => c == b,
                    _ => true,
                };
                frames.insert(h.frame_id.clone());
                if let Some(c) = child {
                    children.insert(c);
                }
                if !(frame_ok && child_ok) {
                    wrong_frame += 1;
                    continue;
                }
                samples.push((stamp(h.stamp.ns(), m.log_time_ns), isometry(&pose)));
            }
            if samples.is_empty() && wrong_frame > 0 {
                return Err(ImportError::new(
                    &bag.path,
                    format!(
                        "{}: no pose in frame {}{}; its messages are in frame(s) {}{}",
                        q.topic,
                        q.pose_frame.unwrap_or("(any)"),
                        q.base_frame.map(|b| format!(" of {b}")).unwrap_or_default(),
                        frames.iter().cloned().collect::<Vec<_>>().join(", "),
                        if children.is_empty() {
                            String::new()
                        } else {
                            format!(
                                " for child frame(s) {}",
                                children.iter().cloned().collect::<Vec<_>>().join(", ")
                            )
                        }
                    ),
                ));
            }
            if frames.len() > 1 && q.pose_frame.is_none() {
                return Err(ImportError::new(
                    &bag.path,
                    format!(
                        "{}: poses in several frames ({}): choose one with --pose-frame",
                        q.topic,
                        frames.iter().cloned().collect::<Vec<_>>().join(", ")
                    ),
                ));
            }
        }
        types::TF => {
            let (Some(pf), Some(bf)) = (q.pose_frame, q.base_frame) else {
                return Err(ImportError::new(
                    &bag.path,
                    format!(
                        "{} is tf ({}): say which transform is the pose with --pose-frame (e.g. map) and --base-frame (e.g. base_link)",
                        q.topic,
                        types::TF
                    ),
                ));
            };
            samples = crate::tf::chain(bag, q.topic, q.tf_static_topic, pf, bf, q.use_receive_time)?;
            frames.insert(pf.to_string());
        }
        other => {
            return Err(ImportError::new(
                &bag.path,
                format!(
                    "{} is {other}, which carries no pose; a pose topic must be one of {}; the bag holds:\n{}",
                    q.topic,
                    types::POSE_TYPES.join(", "),
                    bag.describe_topics()
                ),
            ))
        }
    }
    if samples.is_empty() {
        return Err(ImportError::new(
            &bag.path,
            format!("{}: no pose message was read", q.topic),
        ));
    }
    samples.sort_by_key(|s| s.0);
    let mut out = PoseSeries {
        frame: frames.into_iter().next().unwrap_or_default(),
        ..PoseSeries::default()
    };
    for (t, iso) in samples {
        if out.stamps_ns.last().is_some_and(|&l| t <= l) {
            out.dropped += 1;
            continue;
        }
        let (x, y, yaw, tilt) = planar(&iso);
        // Unwrapped against the last finite heading: a NaN one (refused later, by
        // crate::screen) must not poison every heading after it.
        let yaw = match out.yaw.iter().rev().find(|v| v.is_finite()) {
            Some(&prev) if yaw.is_finite() => prev + wrap(yaw - prev),
            _ => yaw,
        };
        out.stamps_ns.push(t);
        out.x.push(x);
        out.y.push(y);
        out.yaw.push(yaw);
        out.max_tilt_rad = out.max_tilt_rad.max(tilt);
    }
    Ok(out)
}

/// An angle in (-pi, pi].
pub fn wrap(a: f64) -> f64 {
    let tau = std::f64::consts::TAU;
    let r = a - tau * (a / tau).round();
    if r <= -std::f64::consts::PI {
        r + tau
    } else {
        r
    }
}
