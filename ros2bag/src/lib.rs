//! Imports ROS 2 bags (rosbag2 folders or single `.mcap` files, CDR messages) as
//! formats.md recordings, so a ROS user calibrates from the bag the robot already records.
//!
//! One module per concept: [`bag`] reads the MCAP files (the `mcap` crate), [`messages`]
//! decodes the few message types needed (the `cdr-encoding` crate), [`joints`] turns
//! `sensor_msgs/msg/JointState` into encoder counts, [`poses`] and [`tf`] give the body
//! pose from `PoseStamped`, `Odometry` or the tf tree, [`sync`] matches poses to the joint
//! stream by time (interpolated, never extrapolated), [`commands`] turns `cmd_vel` into
//! wheel commands, [`jumps`] finds the pose stream's jumps (SLAM loop closures) against
//! the wheels and [`mod@import`] puts them together.

pub mod bag;
pub mod commands;
pub mod error;
pub mod import;
pub mod joints;
pub mod jumps;
pub mod messages;
pub mod poses;
pub mod records;
pub mod screen;
pub mod sync;
pub mod tf;

pub use error::ImportError;
pub use import::{import, load_bag_recording, ImportOptions, Imported};
