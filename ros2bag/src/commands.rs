//! Wheel commands from the body twist commands (`cmd_vel`: `geometry_msgs/msg/Twist` or
//! `TwistStamped`), through the robot file's nominal kinematics (formats.md §1's rolling
//! constraints: the rates the controller asks of each wheel).
//!
//! A command holds until the next one (the controller keeps the last command) but no
//! longer than the timeout after it: `diff_drive_controller` stops the robot when no
//! command came for `cmd_vel_timeout` (0.5 s by default), so the recording says 0 there.
//! A `Twist` has no header and is stamped with its receive time.

use crate::bag::Bag;
use crate::error::ImportError;
use crate::messages::{decode, types, Twist, TwistStamped};
use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist as BodyTwist};
use calib_core::robot::Robot;

/// The body twist commands over time.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Commands {
    /// Stamps, ns since the epoch, sorted.
    pub stamps_ns: Vec<i64>,
    /// (vx m/s, vy m/s, omega rad/s) in the body frame.
    pub twists: Vec<(f64, f64, f64)>,
}

/// Reads the twist commands on `topic`.
pub fn commands(bag: &Bag, topic: &str, use_receive_time: bool) -> Result<Commands, ImportError> {
    let Some(t) = bag.topic(topic) else {
        return Err(ImportError::new(
            &bag.path,
            format!(
                "no command topic {topic}; the bag holds:\n{}",
                bag.describe_topics()
            ),
        ));
    };
    let stamped = match t.msg_type.as_str() {
        types::TWIST => false,
        types::TWIST_STAMPED => true,
        other => {
            return Err(ImportError::new(
                &bag.path,
                format!(
                    "{topic} is {other}; commands must be {} or {}",
                    types::TWIST,
                    types::TWIST_STAMPED
                ),
            ))
        }
    };
    let mut rows = Vec::new();
    for (k, m) in bag
        .messages
        .get(topic)
        .map(Vec::as_slice)
        .unwrap_or(&[])
        .iter()
        .enumerate()
    {
        let err = |e: String| {
            ImportError::new(
                &bag.path,
                format!("{topic}: message {k} cannot be decoded: {e}"),
            )
        };
        let (stamp, tw) = if stamped {
            let s: TwistStamped = decode(&m.data).map_err(err)?;
            let st = if use_receive_time {
                m.log_time_ns as i64
            } else {
                s.header.stamp.ns()
            };
            (st, s.twist)
        } else {
            let s: Twist = decode(&m.data).map_err(err)?;
            (m.log_time_ns as i64, s)
        };
        rows.push((stamp, (tw.linear.x, tw.linear.y, tw.angular.z)));
    }
    rows.sort_by_key(|r| r.0);
    Ok(Commands {
        stamps_ns: rows.iter().map(|r| r.0).collect(),
        twists: rows.iter().map(|r| r.1).collect(),
    })
}

/// Each wheel's commanded rate (rad/s) at the sorted instants `t_ns`: the last command
/// at or before the instant through the nominal inverse kinematics, 0 once it is older
/// than `timeout_ns`, `None` before the first command.
pub fn wheel_commands(
    robot: &Robot,
    c: &Commands,
    t_ns: &[i64],
    timeout_ns: i64,
) -> Result<Vec<Option<Vec<f64>>>, String> {
    let k = Kinematics::<f64>::new(robot, &Corrections::None)
        .map_err(|_| "the robot's wheels cannot resolve a body twist".to_string())?;
    let mut out = Vec::with_capacity(t_ns.len());
    let mut i = 0; // commands with stamp <= t
    for &t in t_ns {
        while i < c.stamps_ns.len() && c.stamps_ns[i] <= t {
            i += 1;
        }
        if i == 0 {
            out.push(None);
            continue;
        }
        let (vx, vy, w) = if t - c.stamps_ns[i - 1] > timeout_ns {
            (0.0, 0.0, 0.0)
        } else {
            c.twists[i - 1]
        };
        out.push(Some(k.inverse(&BodyTwist::new(vx, vy, w)).to_vec()));
    }
    Ok(out)
}
