//! `wheelcal import ros2`: a ROS 2 bag to a formats.md recording folder (the work is in
//! the `ros2bag` crate; this only reads the flags and writes the files).

use crate::output::Output;
use anyhow::{bail, Context, Result};
use calib_core::robot::Robot;
use clap::{Args, Subcommand};
use formats::recording::Recording;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// Subcommands of `wheelcal import`.
#[derive(Debug, Subcommand)]
pub enum ImportCmd {
    /// A ROS 2 bag (rosbag2 folder or .mcap file, CDR messages) to a recording folder
    /// (recording.csv and a copy of the robot file).
    Ros2(Ros2Args),
}

/// Arguments of `wheelcal import ros2`.
#[derive(Debug, Args)]
pub struct Ros2Args {
    /// The bag: a rosbag2 folder (metadata.yaml beside .mcap files) or one .mcap file.
    pub bag: PathBuf,
    /// Robot description (formats.md §1); its encoder_counts_per_rev turns joint radians
    /// into counts.
    #[arg(long)]
    pub robot: PathBuf,
    /// Where to write recording.csv and robot.toml (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Replace an existing recording.csv / robot.toml in --out.
    #[arg(long)]
    pub force: bool,
    /// The bag's reading options.
    #[command(flatten)]
    pub bag_flags: BagFlags,
}

/// How to read a bag: shared by every command that takes one.
#[derive(Debug, Args, Clone)]
pub struct BagFlags {
    /// WHEEL=JOINT: the JointState joint of a robot-file wheel (repeatable); a wheel not
    /// named reads `<wheel>_wheel_joint`.
    #[arg(long = "joint", value_name = "WHEEL=JOINT")]
    pub joints: Vec<String>,
    /// The sensor_msgs/msg/JointState topic.
    #[arg(long, default_value = "/joint_states")]
    pub joint_topic: String,
    /// The pose topic: geometry_msgs/msg/PoseStamped, PoseWithCovarianceStamped,
    /// nav_msgs/msg/Odometry or tf2_msgs/msg/TFMessage (/tf); required to read a bag.
    #[arg(long)]
    pub pose_topic: Option<String>,
    /// The fixed frame of the poses (map, world); required with tf.
    #[arg(long)]
    pub pose_frame: Option<String>,
    /// The robot's body frame (base_link); required with tf.
    #[arg(long)]
    pub base_frame: Option<String>,
    /// The static tf topic.
    #[arg(long, default_value = "/tf_static")]
    pub tf_static_topic: String,
    /// geometry_msgs/msg/Twist or TwistStamped commands (default: /cmd_vel when present).
    #[arg(long)]
    pub cmd_topic: Option<String>,
    /// Seconds after which the last command counts as a stop (diff_drive_controller's
    /// cmd_vel_timeout).
    #[arg(long, default_value_t = 0.5)]
    pub cmd_timeout: f64,
    /// Stamp messages with the recorder's receive time instead of their header stamps.
    #[arg(long)]
    pub use_receive_time: bool,
    /// Do not interpolate between pose samples further apart than this, seconds.
    #[arg(long, default_value_t = 0.5)]
    pub max_pose_gap: f64,
    /// Import what precedes a damaged chunk instead of failing.
    #[arg(long)]
    pub keep_partial: bool,
}

impl BagFlags {
    /// The importer's options.
    pub fn options(&self) -> Result<ros2bag::ImportOptions> {
        let mut joints = Vec::new();
        for j in &self.joints {
            let Some((w, n)) = j.split_once('=') else {
                bail!("--joint {j}: expected WHEEL=JOINT, e.g. --joint left=left_wheel_joint");
            };
            joints.push((w.trim().to_string(), n.trim().to_string()));
        }
        for (v, f) in [
            (self.cmd_timeout, "--cmd-timeout"),
            (self.max_pose_gap, "--max-pose-gap"),
        ] {
            if !(v.is_finite() && v > 0.0) {
                bail!("{f} {v}: must be a positive number of seconds");
            }
        }
        let Some(pose_topic) = self.pose_topic.clone() else {
            bail!("reading a ROS 2 bag needs --pose-topic (e.g. /mocap/pose, /odom or /tf)");
        };
        Ok(ros2bag::ImportOptions {
            joints,
            joint_topic: self.joint_topic.clone(),
            pose_topic,
            pose_frame: self.pose_frame.clone(),
            base_frame: self.base_frame.clone(),
            tf_static_topic: self.tf_static_topic.clone(),
            cmd_topic: self.cmd_topic.clone(),
            cmd_timeout_s: self.cmd_timeout,
            use_receive_time: self.use_receive_time,
            max_pose_gap_s: self.max_pose_gap,
            keep_partial: self.keep_partial,
        })
    }
}

/// Whether `p` is a ROS 2 bag: an `.mcap` file or a folder with `metadata.yaml`.
pub fn is_bag(p: &Path) -> bool {
    (p.is_file() && p.extension().is_some_and(|e| e == "mcap"))
        || (p.is_dir() && p.join("metadata.yaml").is_file())
}

/// A recording from a formats.md CSV file or a ROS 2 bag (read with `flags`): for the
/// commands that take either (`calibrate`, `diagnose`). The import's notes go to stderr.
pub fn load_recording(p: &Path, robot: &Robot, flags: &BagFlags) -> Result<Recording> {
    if is_bag(p) {
        Ok(ros2bag::load_bag_recording(p, robot, &flags.options()?)?)
    } else {
        Ok(Recording::load(p, robot)?)
    }
}

/// What `import ros2` wrote (its `--json`).
#[derive(Debug, Serialize)]
pub struct ImportReport {
    /// The recording written.
    pub recording: PathBuf,
    /// Rows (joint samples).
    pub rows: usize,
    /// Rows with an interpolated pose.
    pub rows_with_pose: usize,
    /// Pose samples read.
    pub pose_samples: usize,
    /// Joint names, in the robot's wheel order.
    pub joints: Vec<String>,
    /// The frame the poses were in (the recording is in the robot's start frame).
    pub pose_frame: String,
    /// Unix time of the first row, s.
    pub t0_unix_s: f64,
    /// Time covered, s.
    pub duration_s: f64,
    /// Whether wheel commands were written.
    pub commands: bool,
    /// Largest distance of a joint position from a whole count.
    pub max_count_residual: f64,
    /// Remarks.
    pub notes: Vec<String>,
}

/// `wheelcal import ...`.
pub fn run(cmd: ImportCmd, out: Output) -> Result<()> {
    match cmd {
        ImportCmd::Ros2(a) => ros2(&a, out),
    }
}

fn ros2(a: &Ros2Args, out: Output) -> Result<()> {
    let robot = formats::robot_file::load(&a.robot)?;
    let opts = a.bag_flags.options()?;
    let rec_path = a.out.join("recording.csv");
    let robot_path = a.out.join("robot.toml");
    for p in [&rec_path, &robot_path] {
        if p.exists() && !a.force {
            bail!(
                "{} exists: give another --out, or --force to replace it",
                p.display()
            );
        }
    }
    let imp = ros2bag::import(&a.bag, &robot, &opts)?;
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("cannot create {}", a.out.display()))?;
    write_via_temp(&rec_path, |p| imp.recording.save(p))?;
    let robot_text =
        std::fs::read(&a.robot).with_context(|| format!("cannot read {}", a.robot.display()))?;
    if !same_file(&a.robot, &robot_path) {
        write_via_temp(&robot_path, |p| std::fs::write(p, &robot_text))?;
    }
    for n in &imp.notes {
        out.note(n);
    }
    let r = &imp.recording;
    let rep = ImportReport {
        recording: rec_path,
        rows: r.len(),
        rows_with_pose: imp.rows_with_pose,
        pose_samples: imp.pose_samples,
        joints: imp.joints.clone(),
        pose_frame: imp.pose_frame.clone(),
        t0_unix_s: imp.t0_ns as f64 * 1e-9,
        duration_s: r.t.last().copied().unwrap_or(0.0),
        commands: r.wheels.iter().any(|w| w.cmd.is_some()),
        max_count_residual: imp.max_count_residual,
        notes: imp.notes.clone(),
    };
    out.emit(&rep, || {
        format!(
            "{}: {} rows over {:.2} s ({} with a pose, from {} samples in frame {}, put in the robot's start frame); joints {}{}\n",
            rep.recording.display(),
            rep.rows,
            rep.duration_s,
            rep.rows_with_pose,
            rep.pose_samples,
            rep.pose_frame,
            rep.joints.join(", "),
            if rep.commands { "; wheel commands from cmd_vel" } else { "" }
        )
    })
}

/// Writes `path` through a temporary file beside it, renamed into place, so a failed
/// import never leaves half a recording.
fn write_via_temp(path: &Path, write: impl FnOnce(&Path) -> std::io::Result<()>) -> Result<()> {
    let tmp = path.with_extension("partial");
    write(&tmp).with_context(|| format!("cannot write {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
}
