//! The ROS 2 message types the importer reads, as serde structs decoded from CDR by the
//! `cdr-encoding` crate. Field order is the wire order of the `.msg` definitions
//! (builtin_interfaces, std_msgs, sensor_msgs, geometry_msgs, nav_msgs, tf2_msgs).

use serde::de::DeserializeOwned;
use serde::Deserialize;

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Time {
    /// Seconds (Unix time for wall-clock stamps).
    pub sec: i32,
    /// Nanoseconds within the second.
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the epoch.
    pub fn ns(&self) -> i64 {
        self.sec as i64 * 1_000_000_000 + self.nanosec as i64
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct Header {
    /// When the data was measured.
    pub stamp: Time,
    /// The frame the data is expressed in.
    pub frame_id: String,
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct JointState {
    /// Stamp and frame.
    pub header: Header,
    /// Joint names.
    pub name: Vec<String>,
    /// Positions (rad for revolute joints), same order as `name`.
    pub position: Vec<f64>,
    /// Velocities (rad/s); may be empty.
    pub velocity: Vec<f64>,
    /// Efforts; may be empty.
    pub effort: Vec<f64>,
}

/// `geometry_msgs/msg/Vector3` (and `Point`, same layout).
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Pose {
    /// Position (a `Point`).
    pub position: Vector3,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct PoseStamped {
    /// Stamp and the frame the pose is in.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// A 6 x 6 covariance (`float64[36]`, row-major), read as six rows because serde's
/// fixed-size arrays stop at 32.
pub type Covariance = [[f64; 6]; 6];

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `geometry_msgs/msg/PoseWithCovarianceStamped` (AMCL, SLAM toolboxes).
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct PoseWithCovarianceStamped {
    /// Stamp and the frame the pose is in.
    pub header: Header,
    /// The pose and covariance.
    pub pose: PoseWithCovariance,
}

/// `geometry_msgs/msg/Twist`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Twist {
    /// Linear velocity, m/s, body frame.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/TwistStamped`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct TwistStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The twist.
    pub twist: Twist,
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Its covariance.
    pub covariance: Covariance,
}

/// `nav_msgs/msg/Odometry`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct Odometry {
    /// Stamp and the frame the pose is in.
    pub header: Header,
    /// The frame whose pose this is.
    pub child_frame_id: String,
    /// The pose of `child_frame_id` in `header.frame_id`.
    pub pose: PoseWithCovariance,
    /// The twist, in `child_frame_id`.
    pub twist: TwistWithCovariance,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, Deserialize, PartialEq)]
pub struct Transform {
    /// Translation.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct TransformStamped {
    /// Stamp and the parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child frame's pose in the parent frame.
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, Deserialize, PartialEq)]
pub struct TFMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// Type names.
pub mod types {
    /// `sensor_msgs/msg/JointState`.
    pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
    /// `geometry_msgs/msg/PoseStamped`.
    pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
    /// `geometry_msgs/msg/PoseWithCovarianceStamped`.
    pub const POSE_COV_STAMPED: &str = "geometry_msgs/msg/PoseWithCovarianceStamped";
    /// `nav_msgs/msg/Odometry`.
    pub const ODOMETRY: &str = "nav_msgs/msg/Odometry";
    /// `tf2_msgs/msg/TFMessage`.
    pub const TF: &str = "tf2_msgs/msg/TFMessage";
    /// `geometry_msgs/msg/Twist`.
    pub const TWIST: &str = "geometry_msgs/msg/Twist";
    /// `geometry_msgs/msg/TwistStamped`.
    pub const TWIST_STAMPED: &str = "geometry_msgs/msg/TwistStamped";
    /// The types a pose can come from.
    pub const POSE_TYPES: [&str; 4] = [POSE_STAMPED, POSE_COV_STAMPED, ODOMETRY, TF];
    /// The types a command can come from.
    pub const TWIST_TYPES: [&str; 2] = [TWIST, TWIST_STAMPED];
}

/// Decodes one serialised message: the 4-byte encapsulation header says plain CDR, big
/// (0x0000) or little (0x0001) endian, as ROS 2's rmw layers write; `cdr-encoding` reads
/// the body, alignment counted from after the header.
pub fn decode<T: DeserializeOwned>(data: &[u8]) -> Result<T, String> {
    if data.len() < 4 {
        return Err(format!("{} bytes: shorter than the CDR header", data.len()));
    }
    let body = &data[4..];
    let r = match (data[0], data[1]) {
        (0, 0) => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        (0, 1) => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        (a, b) => {
            return Err(format!(
                "encapsulation 0x{a:02x}{b:02x} is not plain CDR (only 0x0000 and 0x0001 are read)"
            ))
        }
    };
    r.map(|(v, _)| v).map_err(|e| e.to_string())
}

/// A ROS quaternion as nalgebra's, normalised (poses and transforms both need it).
pub fn unit(q: &Quaternion) -> nalgebra::UnitQuaternion<f64> {
    nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z))
}
