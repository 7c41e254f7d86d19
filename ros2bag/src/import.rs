//! A bag to a formats.md recording: one row per wheel-joint sample (the joint stream is the
//! encoder stream), its time since the first joint sample, the encoder counts, the pose
//! interpolated at that instant and re-expressed in the robot's start frame, and the wheel
//! commands when the bag has them.

use crate::bag::Bag;
use crate::commands::{commands, wheel_commands};
use crate::error::ImportError;
use crate::joints::{joint_series, to_counts, JointSeries};
use crate::jumps::{find_jumps, JumpReport};
use crate::messages::types;
use crate::poses::{pose_series, PoseQuery, PoseSeries};
use crate::screen;
use crate::sync::{poses_at, to_start_frame};
use calib_core::robot::{Robot, RobotKind};
use formats::recording::{Recording, Row};
use std::path::Path;

/// How to read the bag.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportOptions {
    /// (wheel, joint) pairs; a wheel not named here reads the joint `<wheel>_wheel_joint`.
    pub joints: Vec<(String, String)>,
    /// The JointState topic.
    pub joint_topic: String,
    /// The pose topic (PoseStamped, PoseWithCovarianceStamped, Odometry or tf).
    pub pose_topic: String,
    /// The fixed frame of the poses (required for tf, checked otherwise).
    pub pose_frame: Option<String>,
    /// The robot's body frame (required for tf, checked against Odometry's child frame).
    pub base_frame: Option<String>,
    /// The static tf topic.
    pub tf_static_topic: String,
    /// The command topic (Twist or TwistStamped); `None`: `/cmd_vel` when the bag has it.
    pub cmd_topic: Option<String>,
    /// A command older than this is taken as a stop (the controller's timeout), s.
    pub cmd_timeout_s: f64,
    /// Use the recorder's receive times instead of the header stamps.
    pub use_receive_time: bool,
    /// Pose samples further apart than this are not interpolated between, s.
    pub max_pose_gap_s: f64,
    /// Import what was read before a damaged chunk instead of failing.
    pub keep_partial: bool,
}

impl Default for ImportOptions {
    fn default() -> Self {
        ImportOptions {
            joints: Vec::new(),
            joint_topic: "/joint_states".into(),
            pose_topic: String::new(),
            pose_frame: None,
            base_frame: None,
            tf_static_topic: "/tf_static".into(),
            cmd_topic: None,
            cmd_timeout_s: 0.5,
            use_receive_time: false,
            max_pose_gap_s: 0.5,
            keep_partial: false,
        }
    }
}

/// A bag imported.
#[derive(Debug, Clone, PartialEq)]
pub struct Imported {
    /// The recording (formats.md §2).
    pub recording: Recording,
    /// The joint names read, in the robot's wheel order.
    pub joints: Vec<String>,
    /// The pose topic's frame.
    pub pose_frame: String,
    /// Stamp of the first row (t = 0), ns since the epoch.
    pub t0_ns: i64,
    /// Pose samples read.
    pub pose_samples: usize,
    /// Rows with a pose.
    pub rows_with_pose: usize,
    /// Largest distance of a joint position from a whole encoder count, counts.
    pub max_count_residual: f64,
    /// The pose stream's jumps against the wheel odometry (SLAM loop closures), with the
    /// scatter of its steps; the rows interpolated across a jump are left blank.
    pub pose_jumps: Option<JumpReport>,
    /// What the reader should know (damage kept, dropped samples, rounding, tilt, jumps).
    pub notes: Vec<String>,
}

/// The joint names for the robot's wheels, in its wheel order.
fn joint_names(robot: &Robot, o: &ImportOptions) -> Result<Vec<String>, String> {
    for (w, _) in &o.joints {
        if !robot.wheels.iter().any(|x| x.name.as_str() == w) {
            return Err(format!(
                "--joint {w}=...: the robot has no wheel {w} (its wheels: {})",
                robot
                    .wheels
                    .iter()
                    .map(|x| x.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    Ok(robot
        .wheels
        .iter()
        .map(|w| {
            o.joints
                .iter()
                .find(|(n, _)| n == w.name.as_str())
                .map(|(_, j)| j.clone())
                .unwrap_or_else(|| format!("{}_wheel_joint", w.name))
        })
        .collect())
}

/// Imports the bag (rosbag2 folder or `.mcap` file) at `path` for `robot`.
///
/// The phases: the robot and options checked (`Import::new`), the bag opened and its
/// damage handled (`Import::open`), the joint and pose series read and screened
/// (`Import::series`), the poses at the joints' instants (`Import::poses_at_joints`)
/// with the rows across a pose jump left blank (`Import::blank_jumps`), the wheel
/// commands (`Import::wheel_commands`), then one row per joint sample (`Import::rows`).
pub fn import(path: &Path, robot: &Robot, o: &ImportOptions) -> Result<Imported, ImportError> {
    let mut im = Import::new(path, robot, o)?;
    let bag = im.open()?;
    let (js, ps) = im.series(&bag)?;
    let mut poses = im.poses_at_joints(&js, &ps)?;
    let pose_jumps = im.blank_jumps(&js, &ps, &mut poses);
    let rows_with_pose = poses.iter().flatten().count();
    to_start_frame(&mut poses);
    let cmds = im.wheel_commands(&bag, &js)?;
    let (recording, max_count_residual) = im.rows(&js, &poses, cmds.as_deref());
    Ok(Imported {
        recording,
        joints: im.joints,
        pose_frame: ps.frame,
        t0_ns: js.stamps_ns[0],
        pose_samples: ps.stamps_ns.len(),
        rows_with_pose,
        max_count_residual,
        pose_jumps,
        notes: im.notes,
    })
}

/// The topic read for commands when none is given.
const AUTO_CMD_TOPIC: &str = "/cmd_vel";

/// A pose in the floor plane: x and y (m), heading (rad).
type PlanePose = (f64, f64, f64);

/// Per joint sample, each wheel's commanded rate (rad/s); `None` before the first command.
type WheelCommands = Vec<Option<Vec<f64>>>;

/// One import: what it reads (the bag's path, the robot, the options, the joints of its
/// wheels and the encoder's counts per turn) and the notes its phases gather for the
/// reader.
struct Import<'a> {
    path: &'a Path,
    robot: &'a Robot,
    o: &'a ImportOptions,
    /// Encoder counts per wheel revolution.
    cpr: f64,
    /// The joint of each wheel, in the robot's wheel order.
    joints: Vec<String>,
    /// The command topic asked for, or [`AUTO_CMD_TOPIC`].
    cmd_topic: String,
    notes: Vec<String>,
}

impl<'a> Import<'a> {
    /// Refuses what cannot be imported before the bag is opened: a wheeled-legged robot
    /// (no leg angles read), a robot without encoder counts (the joints are written as
    /// counts), no pose topic, a `--joint` naming no wheel.
    fn new(path: &'a Path, robot: &'a Robot, o: &'a ImportOptions) -> Result<Self, ImportError> {
        if robot.kind == RobotKind::WheeledLegged {
            return Err(ImportError::new(
                path,
                "wheeled-legged robots need leg angles, which the importer does not read yet",
            ));
        }
        let cpr = robot.drive.encoder_counts_per_rev;
        if cpr <= 0.0 {
            return Err(ImportError::new(
                path,
                "the robot file has encoder_counts_per_rev = 0 (no encoder): the wheel joints are written as counts, so the robot file must say how many make a turn",
            ));
        }
        if o.pose_topic.is_empty() {
            return Err(ImportError::new(path, "no pose topic given (--pose-topic)"));
        }
        let joints = joint_names(robot, o).map_err(|e| ImportError::new(path, e))?;
        Ok(Import {
            path,
            robot,
            o,
            cpr,
            joints,
            cmd_topic: o
                .cmd_topic
                .clone()
                .unwrap_or_else(|| AUTO_CMD_TOPIC.to_string()),
            notes: Vec::new(),
        })
    }

    /// The bag's messages on the topics wanted. A damaged bag is an error (saying what
    /// was lost), or with `--keep-partial` what came before the damage, said.
    fn open(&mut self) -> Result<Bag, ImportError> {
        let o = self.o;
        let wanted = [
            o.joint_topic.as_str(),
            o.pose_topic.as_str(),
            o.tf_static_topic.as_str(),
            self.cmd_topic.as_str(),
        ];
        let bag = Bag::open(self.path, &wanted)?;
        if let Some(d) = &bag.damage {
            let t0 = bag.messages.values().flatten().map(|m| m.log_time_ns).min();
            let lost = match t0.and_then(|t0| d.lost_span_s(t0)) {
                Some((a, b)) => {
                    format!(
                        "; lost: the messages logged {a:.3} s to {b:.3} s after the bag's first"
                    )
                }
                None => "; what was lost after it cannot be told".into(),
            };
            if !o.keep_partial {
                return Err(ImportError::new(
                    self.path,
                    format!("{d}{lost}; import what came before with --keep-partial"),
                ));
            }
            self.notes.push(format!(
                "damaged bag, the messages before the damage are kept: {d}{lost}"
            ));
        }
        Ok(bag)
    }

    /// The wheel joints and the poses as series, every converted sample screened
    /// (`crate::screen`): refused samples are an error, or with `--keep-partial` dropped
    /// and said; samples with a repeated or earlier stamp dropped and said; a tilted body
    /// said.
    fn series(&mut self, bag: &Bag) -> Result<(JointSeries, PoseSeries), ImportError> {
        let (o, joints) = (self.o, &self.joints);
        let mut js = joint_series(bag, &o.joint_topic, joints, o.use_receive_time)?;
        if js.dropped > 0 {
            self.notes.push(format!(
                "{}: {} joint samples with a repeated or earlier stamp dropped",
                o.joint_topic, js.dropped
            ));
        }
        let mut ps = pose_series(
            bag,
            &PoseQuery {
                topic: &o.pose_topic,
                pose_frame: o.pose_frame.as_deref(),
                base_frame: o.base_frame.as_deref(),
                tf_static_topic: &o.tf_static_topic,
                use_receive_time: o.use_receive_time,
            },
        )?;
        if ps.dropped > 0 {
            self.notes.push(format!(
                "{}: {} pose samples with a repeated or earlier stamp dropped",
                o.pose_topic, ps.dropped
            ));
        }
        // Every converted sample checked (crate::screen): refused ones are an error, or with
        // --keep-partial dropped and said.
        let t0 = js.stamps_ns.first().copied().unwrap_or(0);
        let refused = [
            (
                o.joint_topic.as_str(),
                screen::joints(&mut js, joints, self.cpr),
            ),
            (o.pose_topic.as_str(), screen::poses(&mut ps)),
        ];
        for (topic, r) in &refused {
            if r.is_empty() {
                continue;
            }
            let said = screen::describe(topic, r, t0);
            if !o.keep_partial {
                return Err(ImportError::new(
                    self.path,
                    format!("{said}; import without them with --keep-partial"),
                ));
            }
            self.notes.push(format!("{said}: dropped"));
        }
        if js.stamps_ns.is_empty() || ps.stamps_ns.is_empty() {
            return Err(ImportError::new(
                self.path,
                "no valid wheel-joint or pose sample is left once the refused ones are dropped",
            ));
        }
        if ps.max_tilt_rad > 5f64.to_radians() {
            self.notes.push(format!(
                "{}: the body tilts up to {:.1} deg; the recording keeps the floor-plane projection",
                o.pose_topic,
                ps.max_tilt_rad.to_degrees()
            ));
        }
        Ok((js, ps))
    }

    /// The pose interpolated at each joint sample (none across a gap over
    /// `--max-pose-gap`); an error, naming both streams' spans, when no joint sample
    /// falls within the poses (often one clock that is not wall time).
    fn poses_at_joints(
        &self,
        js: &JointSeries,
        ps: &PoseSeries,
    ) -> Result<Vec<Option<PlanePose>>, ImportError> {
        let o = self.o;
        let max_gap = (o.max_pose_gap_s * 1e9) as i64;
        let poses = poses_at(ps, &js.stamps_ns, max_gap);
        if poses.iter().flatten().next().is_none() {
            let span = |s: &[i64]| {
                format!(
                    "{:.3}..{:.3} s",
                    s.first().copied().unwrap_or(0) as f64 * 1e-9,
                    s.last().copied().unwrap_or(0) as f64 * 1e-9
                )
            };
            return Err(ImportError::new(
                self.path,
                format!(
                    "no wheel-joint sample falls within the poses: joints {} over {}, poses {} over {} (Unix seconds){}",
                    o.joint_topic,
                    span(&js.stamps_ns),
                    o.pose_topic,
                    span(&ps.stamps_ns),
                    if o.use_receive_time { "" } else { "; if one clock is not wall time, try --use-receive-time" }
                ),
            ));
        }
        Ok(poses)
    }

    /// The pose stream's jumps against the wheel odometry ([`find_jumps`]): a jump is no
    /// motion, so the rows between the two pose samples around it (which would be
    /// interpolated across it) stay blank, and the jumps are said.
    fn blank_jumps(
        &mut self,
        js: &JointSeries,
        ps: &PoseSeries,
        poses: &mut [Option<PlanePose>],
    ) -> Option<JumpReport> {
        let pose_jumps = find_jumps(self.robot, js, ps);
        if let Some(r) = pose_jumps.as_ref().filter(|r| !r.jumps.is_empty()) {
            for j in &r.jumps {
                for (k, &t) in js.stamps_ns.iter().enumerate() {
                    if t > j.from_ns && t < j.to_ns {
                        poses[k] = None;
                    }
                }
            }
            let t0 = js.stamps_ns[0];
            let list: Vec<String> = r
                .jumps
                .iter()
                .map(|j| {
                    format!(
                        "t = {:.3}..{:.3} s: {:.3} m, {:+.2} deg",
                        (j.from_ns - t0) as f64 * 1e-9,
                        (j.to_ns - t0) as f64 * 1e-9,
                        j.position_m,
                        j.heading_rad.to_degrees()
                    )
                })
                .collect();
            self.notes.push(format!(
                "{}: {} pose jump(s) against the wheel odometry (a SLAM loop closure or relocalisation; the pose steps scatter {:.1} mm, {:.2} deg otherwise), the rows across them left blank: {}",
                self.o.pose_topic,
                r.jumps.len(),
                r.step_sigma_m * 1e3,
                r.step_sigma_rad.to_degrees(),
                list.join("; ")
            ));
        }
        pose_jumps
    }

    /// Each wheel's commanded rate at the joint samples, from the command topic asked
    /// for, or from [`AUTO_CMD_TOPIC`] when the bag has Twist messages there (said);
    /// `None` without commands.
    fn wheel_commands(
        &mut self,
        bag: &Bag,
        js: &JointSeries,
    ) -> Result<Option<WheelCommands>, ImportError> {
        let o = self.o;
        if !(o.cmd_topic.is_some()
            || bag
                .topic(AUTO_CMD_TOPIC)
                .is_some_and(|t| types::TWIST_TYPES.contains(&t.msg_type.as_str())))
        {
            return Ok(None);
        }
        let c = commands(bag, &self.cmd_topic, o.use_receive_time)?;
        if o.cmd_topic.is_none() {
            self.notes.push(format!(
                "commands from {AUTO_CMD_TOPIC} ({} messages)",
                c.stamps_ns.len()
            ));
        }
        Ok(Some(
            wheel_commands(
                self.robot,
                &c,
                &js.stamps_ns,
                (o.cmd_timeout_s * 1e9) as i64,
            )
            .map_err(|e| ImportError::new(self.path, e))?,
        ))
    }

    /// The recording: one row per joint sample, its time since the first, the joints as
    /// encoder counts, the pose and the commands. Returns it with the largest distance
    /// of a joint position from a whole count (said when over 0.01 count: the joints are
    /// then not counts, or the robot file's counts per turn are not the driver's).
    fn rows(
        &mut self,
        js: &JointSeries,
        poses: &[Option<PlanePose>],
        cmds: Option<&[Option<Vec<f64>>]>,
    ) -> (Recording, f64) {
        let cpr = self.cpr;
        let mut rec = Recording::new(self.robot, cmds.is_some(), true);
        let t0 = js.stamps_ns[0];
        let mut max_res = 0.0f64;
        let mut counts = vec![0i64; self.joints.len()];
        for (k, &t) in js.stamps_ns.iter().enumerate() {
            for (c, &rad) in counts.iter_mut().zip(&js.positions[k]) {
                let (n, res) = to_counts(rad, cpr);
                *c = n;
                max_res = max_res.max(res);
            }
            let cmd = cmds.and_then(|c| c[k].as_deref());
            rec.push_row(Row {
                t: (t - t0) as f64 * 1e-9,
                cmd,
                enc: Some(&counts),
                pose: poses[k],
                legs: None,
            });
        }
        if max_res > 0.01 {
            self.notes.push(format!(
                "joint positions are up to {max_res:.3} counts from whole counts of {cpr} per revolution: either the joints are not encoder counts (a simulator) or encoder_counts_per_rev differs from the one the robot's driver uses"
            ));
        }
        (rec, max_res)
    }
}

/// The recording of a bag, for commands that take a bag where they take a recording
/// (`calibrate`, `diagnose`): notes go to stderr.
pub fn load_bag_recording(
    path: &Path,
    robot: &Robot,
    o: &ImportOptions,
) -> Result<Recording, ImportError> {
    let imp = import(path, robot, o)?;
    for n in &imp.notes {
        eprintln!("note: {}: {n}", path.display());
    }
    Ok(imp.recording)
}
