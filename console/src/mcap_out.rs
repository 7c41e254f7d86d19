//! MCAP output in ROS 2's standard messages, which Foxglove, Rerun and PlotJuggler open
//! as they are: a pulled trial ([`write_trial`]), the diagnose report's measured, nominal
//! and fitted paths ([`write_report_paths`]) and calibrate's per recording (any poses:
//! [`write_pose_paths`]).
//!
//! Every message is CDR (little endian, ROS 2's encapsulation header `00 01 00 00`), each
//! channel's schema the `.msg` definition with its dependencies (MCAP's `ros2msg`
//! encoding), as `ros2 bag record -s mcap` writes them:
//! - poses as `geometry_msgs/msg/PoseStamped` and the same pose as a transform on `/tf`
//!   (`tf2_msgs/msg/TFMessage`), so a 3D panel follows the robot without set-up;
//! - wheel states as `sensor_msgs/msg/JointState`: positions in rad from the encoder
//!   counts (counts x 2 pi / `encoder_counts_per_rev`), velocities in rad/s.
//!
//! Why ROS 2's messages and not Foxglove's protobuf schemas: only ROS 2 has a joint-state
//! message (Foxglove's schema set has none), so one family holds poses, transforms and
//! wheels, and the files are single-file ROS 2 bags in MCAP storage.
//!

use anyhow::{bail, Context, Result};
use calib_core::protocol::{Record, TrialInfo};
use calib_core::robot::Robot;
use mcap::records::MessageHeader;
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;

/// ROS 2 message types as CDR-serialisable structs (field order is the wire order of the
/// `.msg` definitions) and their `ros2msg` schemas.
pub mod ros2 {
    use serde::Serialize;

    /// `builtin_interfaces/msg/Time`.
    #[derive(Debug, Clone, Copy, Serialize, PartialEq)]
    pub struct Time {
        /// Seconds.
        pub sec: i32,
        /// Nanoseconds within the second.
        pub nanosec: u32,
    }

    impl Time {
        /// The stamp of `ns` nanoseconds (saturating at `i32::MAX` seconds).
        pub fn from_ns(ns: u64) -> Time {
            let sec = (ns / 1_000_000_000).min(i32::MAX as u64) as i32;
            Time {
                sec,
                nanosec: (ns % 1_000_000_000) as u32,
            }
        }
    }

    /// `std_msgs/msg/Header`.
    #[derive(Debug, Clone, Serialize, PartialEq)]
    pub struct Header {
        /// Stamp.
        pub stamp: Time,
        /// Frame the data is in.
        pub frame_id: String,
    }

    /// `geometry_msgs/msg/Point` and `Vector3` (same layout).
    #[derive(Debug, Clone, Copy, Serialize, PartialEq)]
    pub struct Vector3 {
        /// x.
        pub x: f64,
        /// y.
        pub y: f64,
        /// z.
        pub z: f64,
    }

    /// `geometry_msgs/msg/Quaternion`.
    #[derive(Debug, Clone, Copy, Serialize, PartialEq)]
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

    impl Quaternion {
        /// A rotation by `yaw` rad about z.
        pub fn yaw(yaw: f64) -> Quaternion {
            let h = 0.5 * yaw;
            Quaternion {
                x: 0.0,
                y: 0.0,
                z: h.sin(),
                w: h.cos(),
            }
        }
    }

    /// `geometry_msgs/msg/Pose`.
    #[derive(Debug, Clone, Copy, Serialize, PartialEq)]
    pub struct Pose {
        /// Position, m.
        pub position: Vector3,
        /// Orientation.
        pub orientation: Quaternion,
    }

    impl Pose {
        /// A planar pose: (x m, y m) at z = 0, heading `yaw` rad.
        pub fn planar(x: f64, y: f64, yaw: f64) -> Pose {
            Pose {
                position: Vector3 { x, y, z: 0.0 },
                orientation: Quaternion::yaw(yaw),
            }
        }
    }

    /// `geometry_msgs/msg/PoseStamped`.
    #[derive(Debug, Clone, Serialize, PartialEq)]
    pub struct PoseStamped {
        /// Stamp and frame.
        pub header: Header,
        /// The pose.
        pub pose: Pose,
    }

    /// `geometry_msgs/msg/Transform`.
    #[derive(Debug, Clone, Copy, Serialize, PartialEq)]
    pub struct Transform {
        /// Translation, m.
        pub translation: Vector3,
        /// Rotation.
        pub rotation: Quaternion,
    }

    /// `geometry_msgs/msg/TransformStamped`.
    #[derive(Debug, Clone, Serialize, PartialEq)]
    pub struct TransformStamped {
        /// Stamp and parent frame.
        pub header: Header,
        /// The child frame.
        pub child_frame_id: String,
        /// The child frame's pose in the parent.
        pub transform: Transform,
    }

    /// `tf2_msgs/msg/TFMessage`.
    #[derive(Debug, Clone, Serialize, PartialEq)]
    pub struct TfMessage {
        /// The transforms.
        pub transforms: Vec<TransformStamped>,
    }

    impl TfMessage {
        /// One transform: `child` at `pose` in `header.frame_id`.
        pub fn one(header: Header, child: &str, pose: &Pose) -> TfMessage {
            TfMessage {
                transforms: vec![TransformStamped {
                    header,
                    child_frame_id: child.into(),
                    transform: Transform {
                        translation: pose.position,
                        rotation: pose.orientation,
                    },
                }],
            }
        }
    }

    /// `sensor_msgs/msg/JointState`.
    #[derive(Debug, Clone, Serialize, PartialEq)]
    pub struct JointState {
        /// Stamp and frame.
        pub header: Header,
        /// Joint names (the robot file's wheel names).
        pub name: Vec<String>,
        /// Positions, rad (empty when unknown).
        pub position: Vec<f64>,
        /// Velocities, rad/s (empty when unknown).
        pub velocity: Vec<f64>,
        /// Efforts (always empty here).
        pub effort: Vec<f64>,
    }

    const SEP: &str =
        "================================================================================\n";

    fn with_deps(top: &str, deps: &[(&str, &str)]) -> String {
        let mut s = top.to_string();
        for (name, def) in deps {
            s.push('\n');
            s.push_str(SEP);
            s.push_str("MSG: ");
            s.push_str(name);
            s.push('\n');
            s.push_str(def);
        }
        s
    }

    const HEADER: (&str, &str) = (
        "std_msgs/Header",
        "builtin_interfaces/Time stamp\nstring frame_id\n",
    );
    const TIME: (&str, &str) = ("builtin_interfaces/Time", "int32 sec\nuint32 nanosec\n");
    const POSE: (&str, &str) = (
        "geometry_msgs/Pose",
        "Point position\nQuaternion orientation\n",
    );
    const POINT: (&str, &str) = ("geometry_msgs/Point", "float64 x\nfloat64 y\nfloat64 z\n");
    const VECTOR3: (&str, &str) = ("geometry_msgs/Vector3", "float64 x\nfloat64 y\nfloat64 z\n");
    const QUATERNION: (&str, &str) = (
        "geometry_msgs/Quaternion",
        "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n",
    );
    const TRANSFORM_STAMPED: (&str, &str) = (
        "geometry_msgs/TransformStamped",
        "std_msgs/Header header\nstring child_frame_id\nTransform transform\n",
    );
    const TRANSFORM: (&str, &str) = (
        "geometry_msgs/Transform",
        "Vector3 translation\nQuaternion rotation\n",
    );

    /// Schema name of [`PoseStamped`].
    pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
    /// Schema name of [`TfMessage`].
    pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
    /// Schema name of [`JointState`].
    pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";

    /// The `ros2msg` schema text of a type named by [`POSE_STAMPED`], [`TF_MESSAGE`] or
    /// [`JOINT_STATE`] (`None` for another name).
    pub fn schema(name: &str) -> Option<String> {
        Some(match name {
            POSE_STAMPED => with_deps(
                "std_msgs/Header header\nPose pose\n",
                &[HEADER, TIME, POSE, POINT, QUATERNION],
            ),
            TF_MESSAGE => with_deps(
                "geometry_msgs/TransformStamped[] transforms\n",
                &[TRANSFORM_STAMPED, HEADER, TIME, TRANSFORM, VECTOR3, QUATERNION],
            ),
            JOINT_STATE => with_deps(
                "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
                &[HEADER, TIME],
            ),
            _ => return None,
        })
    }

    /// `msg` as a serialised ROS 2 message: the encapsulation header of little-endian
    /// plain CDR, then the body.
    pub fn cdr<T: Serialize>(msg: &T) -> Result<Vec<u8>, String> {
        let mut out = vec![0u8, 1, 0, 0];
        cdr_encoding::to_writer::<T, byteorder::LittleEndian, _>(&mut out, msg)
            .map_err(|e| e.to_string())?;
        Ok(out)
    }
}

/// Topics of a trial's channels, in the order they are written: the board's odometry
/// (`PoseStamped` in frame `odom`), the same pose as the transform `odom` -> `base_link`,
/// the wheels' measured state (`JointState`: positions from the encoder counts,
/// velocities from their differences) and the commanded wheel rates (`JointState`,
/// velocities only).
pub const TRIAL_TOPICS: [&str; 4] = [
    "/wheelcal/odometry",
    "/tf",
    "/joint_states",
    "/wheelcal/wheel_commands",
];

/// The odometry frame of a pulled trial (the trial's start pose is its origin).
pub const ODOM_FRAME: &str = "odom";
/// The robot's frame.
pub const BASE_FRAME: &str = "base_link";
/// The frame of diagnose's paths (the recording's measurement frame).
pub const WORLD_FRAME: &str = "world";

struct Out<W: Write + Seek> {
    w: mcap::Writer<W>,
    seq: BTreeMap<u16, u32>,
    schemas: BTreeMap<String, u16>,
}

impl<W: Write + Seek> Out<W> {
    fn new(w: W) -> Result<Self> {
        Ok(Out {
            w: mcap::Writer::new(w).context("cannot start the MCAP file")?,
            seq: BTreeMap::new(),
            schemas: BTreeMap::new(),
        })
    }
    /// A CDR channel of the ROS 2 type `ty` ([`ros2::schema`]).
    fn ros2_channel(&mut self, topic: &str, ty: &str) -> Result<u16> {
        let s = match self.schemas.get(ty) {
            Some(&s) => s,
            None => {
                let text = ros2::schema(ty).with_context(|| format!("no schema for {ty}"))?;
                let s = self.w.add_schema(ty, "ros2msg", text.as_bytes())?;
                self.schemas.insert(ty.to_string(), s);
                s
            }
        };
        Ok(self.w.add_channel(s, topic, "cdr", &BTreeMap::new())?)
    }
    fn put_bytes(&mut self, channel: u16, t_ns: u64, data: &[u8]) -> Result<()> {
        let seq = self.seq.entry(channel).or_insert(0);
        *seq = seq.wrapping_add(1);
        self.w.write_to_known_channel(
            &MessageHeader {
                channel_id: channel,
                sequence: *seq,
                log_time: t_ns,
                publish_time: t_ns,
            },
            data,
        )?;
        Ok(())
    }
    fn put_cdr<T: Serialize>(&mut self, channel: u16, t_ns: u64, msg: &T) -> Result<()> {
        let data = ros2::cdr(msg).map_err(|e| anyhow::anyhow!("CDR: {e}"))?;
        self.put_bytes(channel, t_ns, &data)
    }
    fn finish(mut self) -> Result<()> {
        self.w.finish().context("cannot finish the MCAP file")?;
        Ok(())
    }
}

fn create(out: &Path) -> Result<std::io::BufWriter<std::fs::File>> {
    let f =
        std::fs::File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    Ok(std::io::BufWriter::new(f))
}

/// One record's time since the trial's start, µs, unwrapping the board's u32 clock.
pub struct TrialClock {
    wraps: u64,
    last: u32,
}

impl TrialClock {
    /// A clock at the trial's start.
    pub fn new() -> Self {
        TrialClock { wraps: 0, last: 0 }
    }
    /// Microseconds since the trial's start of the next record's `t_us`.
    pub fn us(&mut self, t_us: u32) -> u64 {
        if t_us < self.last {
            self.wraps += 1; // the u32 microsecond clock wraps after 71 minutes
        }
        self.last = t_us;
        self.wraps * (1u64 << 32) + t_us as u64
    }
}

impl Default for TrialClock {
    fn default() -> Self {
        Self::new()
    }
}

/// Writes a trial's records as MCAP ([`TRIAL_TOPICS`]) stamped with the board's uptime
/// (trial start + record time), and the trial's header as an MCAP metadata record named
/// `wheelcal.trial` (`trial`: its JSON). `robot` is the board's robot: its wheel names
/// name the joints and its encoder resolution turns counts into radians (a robot without
/// encoders gets no positions).
pub fn write_trial(robot: &Robot, info: &TrialInfo, recs: &[Record], out: &Path) -> Result<()> {
    let n = info.wheel_count as usize;
    if n != robot.wheel_count() || n > calib_core::robot::MAX_WHEELS {
        bail!(
            "trial {} has {} wheels, the board's robot {}",
            info.id,
            n,
            robot.wheel_count()
        );
    }
    let names: Vec<String> = robot.wheels.iter().map(|w| w.name.to_string()).collect();
    let rad = robot.drive.rad_per_count();
    let mut o = Out::new(create(out)?)?;
    let odo = o.ros2_channel(TRIAL_TOPICS[0], ros2::POSE_STAMPED)?;
    let tf = o.ros2_channel(TRIAL_TOPICS[1], ros2::TF_MESSAGE)?;
    let joints = o.ros2_channel(TRIAL_TOPICS[2], ros2::JOINT_STATE)?;
    let cmds = o.ros2_channel(TRIAL_TOPICS[3], ros2::JOINT_STATE)?;
    let start_ns = info.start_ms.saturating_mul(1_000_000);
    let mut clock = TrialClock::new();
    let mut prev: Option<(u64, Vec<f64>)> = None;
    for r in recs {
        let us = clock.us(r.t_us);
        let t_ns = start_ns.saturating_add(us.saturating_mul(1000));
        let header = |frame: &str| ros2::Header {
            stamp: ros2::Time::from_ns(t_ns),
            frame_id: frame.into(),
        };
        let pose = ros2::Pose::planar(r.pose.x as f64, r.pose.y as f64, r.pose.theta as f64);
        o.put_cdr(
            odo,
            t_ns,
            &ros2::PoseStamped {
                header: header(ODOM_FRAME),
                pose,
            },
        )?;
        o.put_cdr(
            tf,
            t_ns,
            &ros2::TfMessage::one(header(ODOM_FRAME), BASE_FRAME, &pose),
        )?;
        let position: Vec<f64> = match rad {
            Some(k) => r.counts[..n].iter().map(|&c| c as f64 * k).collect(),
            None => Vec::new(),
        };
        // Velocity: the change of position since the previous record over its time; the
        // first record has none yet (zeros: the trial starts from standstill or not, the
        // counts cannot say).
        let velocity = match (&prev, position.is_empty()) {
            (_, true) => Vec::new(),
            (Some((t0, p0)), false) if us > *t0 => {
                let dt = (us - t0) as f64 * 1e-6;
                position.iter().zip(p0).map(|(a, b)| (a - b) / dt).collect()
            }
            _ => vec![0.0; n],
        };
        o.put_cdr(
            joints,
            t_ns,
            &ros2::JointState {
                header: header(BASE_FRAME),
                name: names.clone(),
                position: position.clone(),
                velocity,
                effort: Vec::new(),
            },
        )?;
        o.put_cdr(
            cmds,
            t_ns,
            &ros2::JointState {
                header: header(BASE_FRAME),
                name: names.clone(),
                position: Vec::new(),
                velocity: r.cmd[..n].iter().map(|&v| v as f64).collect(),
                effort: Vec::new(),
            },
        )?;
        prev = Some((us, position));
    }
    let mut meta = BTreeMap::new();
    meta.insert("trial".to_string(), serde_json::to_string(info)?);
    meta.insert("robot".to_string(), robot.name.to_string());
    o.w.write_metadata(&mcap::records::Metadata {
        name: "wheelcal.trial".into(),
        metadata: meta,
    })?;
    o.finish()
}

/// One path of planar poses: its name (topic `/paths/<name>`, child frame `<name>`),
/// sample times (s) and poses `(x m, y m, yaw rad)`.
pub struct PoseSeries<'a> {
    /// The path's name (`measured`, `nominal`, `fitted`).
    pub name: &'a str,
    /// Sample times (s).
    pub t: &'a [f64],
    /// Poses (m, m, rad) in the frame [`WORLD_FRAME`].
    pub pose: &'a [(f64, f64, f64)],
}

/// A time in seconds as MCAP nanoseconds (negative and non-finite times at 0).
pub fn ns_of_s(t: f64) -> u64 {
    if t.is_finite() && t > 0.0 {
        (t * 1e9).round().min(u64::MAX as f64) as u64
    } else {
        0
    }
}

/// Writes paths of poses as MCAP: per path a `PoseStamped` channel `/paths/<name>` in
/// frame [`WORLD_FRAME`], and one `/tf` channel with each path's transform `world` ->
/// `<name>` at each of its samples.
pub fn write_pose_paths(paths: &[PoseSeries<'_>], out: &Path) -> Result<()> {
    let mut o = Out::new(create(out)?)?;
    let tf = o.ros2_channel("/tf", ros2::TF_MESSAGE)?;
    for p in paths {
        let ch = o.ros2_channel(&format!("/paths/{}", p.name), ros2::POSE_STAMPED)?;
        for (&t, &(x, y, yaw)) in p.t.iter().zip(p.pose) {
            let t_ns = ns_of_s(t);
            let header = ros2::Header {
                stamp: ros2::Time::from_ns(t_ns),
                frame_id: WORLD_FRAME.into(),
            };
            let pose = ros2::Pose::planar(x, y, yaw);
            o.put_cdr(
                ch,
                t_ns,
                &ros2::PoseStamped {
                    header: header.clone(),
                    pose,
                },
            )?;
            o.put_cdr(tf, t_ns, &ros2::TfMessage::one(header, p.name, &pose))?;
        }
    }
    o.finish()
}

/// The diagnose report's three paths as planar poses `(x m, y m, yaw rad)`, named
/// `measured`, `nominal` and `fitted`, one pose per report pose sample.
pub type ReportPoses = [(&'static str, Vec<(f64, f64, f64)>); 3];

/// The diagnose report's measured, nominal and fitted paths as planar poses: positions
/// from the report's plot series, headings from the recording's measured headings
/// (`measured`: the recording's pose rows (x, y, theta) in order, as given to diagnose)
/// less the report's heading errors. `None` when the report's measured samples cannot be
/// matched to the recording's rows (then the headings are unknown).
pub fn report_poses(rep: &diagnose::Report, measured: &[(f64, f64, f64)]) -> Option<ReportPoses> {
    let p = &rep.plot;
    let k = p.measured.len();
    if p.nominal.len() != k
        || p.fitted.len() != k
        || p.heading_nominal.len() != k
        || p.heading_fitted.len() != k
    {
        return None;
    }
    // The report's samples are the recording's pose rows, some perhaps dropped by the
    // recording stage (duplicates): walk both in order, matching positions exactly.
    let mut yaw = Vec::with_capacity(k);
    let mut rows = measured.iter();
    for &(x, y) in &p.measured {
        let th = rows.find(|r| r.0 == x && r.1 == y)?.2;
        yaw.push(th);
    }
    let with = |xy: &[(f64, f64)], err: Option<&[f64]>| -> Vec<(f64, f64, f64)> {
        xy.iter()
            .enumerate()
            .map(|(i, &(x, y))| (x, y, yaw[i] - err.map_or(0.0, |e| e[i])))
            .collect()
    };
    Some([
        ("measured", with(&p.measured, None)),
        ("nominal", with(&p.nominal, Some(&p.heading_nominal))),
        ("fitted", with(&p.fitted, Some(&p.heading_fitted))),
    ])
}

/// The diagnose report's measured, nominal and fitted paths as MCAP (beside its HTML):
/// [`write_pose_paths`] of [`report_poses`]; the times are the report's pose times.
pub fn write_report_paths(rep: &diagnose::Report, poses: &ReportPoses, out: &Path) -> Result<()> {
    let t = &rep.plot.pose_t;
    let paths: Vec<PoseSeries<'_>> = poses
        .iter()
        .map(|(name, pose)| PoseSeries { name, t, pose })
        .collect();
    write_pose_paths(&paths, out)
}
