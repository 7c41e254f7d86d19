//! ROS 2 bags written by an independent writer (the Python `rosbags` package, through
//! `tests/make_bag.py`) import to the recordings they were made from.
//!
//! Tolerances: encoder counts are integers and must come back exactly (radians x cpr / 2 pi
//! is within 1e-9 counts of the integer); poses and times to 1e-9 (a rigid map offset
//! applied and removed in f64 costs ~1e-15 m; stamps are whole nanoseconds, so t is off
//! by at most 0.5e-9 s); the calibrated geometry to 1e-4 (the figure: the same
//! data must give the same fit). Interpolated poses of the synthetic drive: linear
//! interpolation over the pose period h = 30 ms errs by at most |a| h^2 / 8 with
//! |a| = v |omega| <= 0.15 m/s^2, i.e. 1.7e-5 m, and |d omega/dt| h^2 / 8 <= 5.7e-6 rad.
//!
//! Needs python3 with rosbags: `bash scripts/setup.sh`. Missing, the tests FAIL (they do
//! not skip): the importer would otherwise go untested.

use calib_core::robot::Robot;
use formats::recording::Recording;
use ros2bag::{import, ImportOptions};
use std::path::{Path, PathBuf};
use std::process::Command;

/// The real runs kept in the repository (`data/real`).
fn real_dir() -> PathBuf {
    testdata::real_dir()
}

fn tmp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("ros2bag-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Runs make_bag.py; returns its JSON report.
fn make_bag(args: &[&str]) -> serde_json::Value {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/make_bag.py");
    let out = Command::new("python3").arg(&script).args(args).output();
    let out = match out {
        Ok(o) => o,
        Err(e) => panic!(
            "python3 could not be run ({e}): the ROS 2 bag tests write their bags with Python's \
             rosbags package; run `bash scripts/setup.sh`"
        ),
    };
    let err = String::from_utf8_lossy(&out.stderr);
    if err.contains("No module named 'rosbags'") || err.contains("No module named") {
        panic!(
            "python3 lacks the rosbags package the ROS 2 bag tests write their bags with: run \
             `bash scripts/setup.sh`\n{err}"
        );
    }
    assert!(out.status.success(), "make_bag.py failed: {err}");
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last().unwrap_or("")).expect("make_bag.py's JSON line")
}

fn real(folder: &str) -> (Robot, Recording, PathBuf) {
    let dir = real_dir().join(folder);
    let robot = formats::robot_file::load(&dir.join("robot.toml")).unwrap();
    let rec = Recording::load(&dir.join("recording.csv"), &robot).unwrap();
    (robot, rec, dir)
}

/// A bag of a real recording with poses of `pose` kind; returns the bag folder.
fn real_bag(folder: &str, pose: &str, extra: &[&str]) -> PathBuf {
    let dir = real_dir().join(folder);
    let out = tmp(&format!("{folder}-{pose}")).join("bag");
    let robot = dir.join("robot.toml");
    let csv = dir.join("recording.csv");
    let mut args = vec![
        "--robot",
        robot.to_str().unwrap(),
        "--csv",
        csv.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--pose",
        pose,
    ];
    args.extend_from_slice(extra);
    make_bag(&args);
    out
}

fn opts(pose_topic: &str) -> ImportOptions {
    ImportOptions {
        pose_topic: pose_topic.into(),
        ..ImportOptions::default()
    }
}

fn assert_same(a: &Recording, b: &Recording, what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: rows");
    for i in 0..a.len() {
        assert!((a.t[i] - b.t[i]).abs() <= 1e-9, "{what}: t row {i}");
        for (wa, wb) in a.wheels.iter().zip(&b.wheels) {
            assert_eq!(wa.name, wb.name);
            assert_eq!(
                wa.enc.as_ref().map(|e| e[i]),
                wb.enc.as_ref().map(|e| e[i]),
                "{what}: enc_{} row {i}",
                wa.name
            );
        }
        for (va, vb, c) in [
            (&a.x, &b.x, "x"),
            (&a.y, &b.y, "y"),
            (&a.theta, &b.theta, "theta"),
        ] {
            match (va[i], vb[i]) {
                (Some(p), Some(q)) => {
                    assert!((p - q).abs() <= 1e-9, "{what}: {c} row {i}: {p} vs {q}")
                }
                (p, q) => assert_eq!(p.is_some(), q.is_some(), "{what}: {c} row {i} blank"),
            }
        }
    }
}

#[test]
fn real_squares_import_exactly_and_calibrate_the_same() {
    let mut from_csv = Vec::new();
    let mut from_bag = Vec::new();
    let mut robot = None;
    for folder in ["diff-square-run-01", "diff-square-run-04"] {
        let (r, csv, _) = real(folder);
        let bag = real_bag(folder, "posestamped", &[]);
        let mut o = opts("/mocap/pose");
        o.pose_frame = Some("map".into());
        let imp = import(&bag, &r, &o).unwrap_or_else(|e| panic!("{folder}: {e}"));
        assert_same(&imp.recording, &csv, folder);
        // Motion capture has no jumps (part 3 of the issue must not flag a real square).
        let j = imp.pose_jumps.as_ref().unwrap();
        assert!(j.jumps.is_empty(), "{folder}: {:?}", j.jumps);
        from_csv.push((folder.to_string(), csv));
        from_bag.push((folder.to_string(), imp.recording));
        robot = Some(r);
    }
    let robot = robot.unwrap();
    let cal = |recs: &[(String, Recording)]| {
        calibrate::calibrate(&robot, recs, None, &Default::default()).unwrap()
    };
    let (a, b) = (cal(&from_csv), cal(&from_bag));
    assert_eq!(a.params.len(), b.params.len());
    for (p, q) in a.params.iter().zip(&b.params) {
        assert!(
            (p.value - q.value).abs() <= 1e-4,
            "{}: csv {} bag {}",
            p.spec.name,
            p.value,
            q.value
        );
    }
}

#[test]
fn tf_and_odometry_poses_give_the_posestamped_recording() {
    let folder = "diff-square-run-01";
    let (robot, _, _) = real(folder);
    let reference = import(
        &real_bag(folder, "posestamped", &[]),
        &robot,
        &opts("/mocap/pose"),
    )
    .unwrap()
    .recording;
    let odom = import(
        &real_bag(folder, "odometry", &[]),
        &robot,
        &opts("/mocap/odom"),
    )
    .unwrap();
    assert_same(&odom.recording, &reference, "odometry");
    let mut o = opts("/tf");
    o.pose_frame = Some("map".into());
    o.base_frame = Some("base_link".into());
    let tf = import(&real_bag(folder, "tf", &[]), &robot, &o).unwrap();
    assert_same(&tf.recording, &reference, "tf");
}

#[test]
fn synthetic_drive_interpolates_poses_and_converts_commands() {
    let (robot, _, dir) = real("diff-square-run-01");
    let out = tmp("synthetic");
    let bag = out.join("bag");
    let truth = out.join("truth.csv");
    make_bag(&[
        "--robot",
        dir.join("robot.toml").to_str().unwrap(),
        "--synthetic",
        "60",
        "--out",
        bag.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
        "--compress",
    ]);
    let mut o = opts("/mocap/pose");
    o.cmd_topic = Some("/cmd_vel".into());
    let rec = import(&bag, &robot, &o).unwrap().recording;
    let truth = Recording::load(&truth, &robot).unwrap();
    assert_eq!(rec.len(), truth.len());
    // Poses start at 7 ms: the joint rows before the first pose stay blank (no
    // extrapolation), and so do those after the last.
    let mut compared = 0;
    let (mut worst_p, mut worst_th) = (0.0f64, 0.0f64);
    // The start frame is the first pose's (7 ms in, where the truth's frame is the first
    // joint instant's): compare increments from the first row with a pose.
    let first = rec.pose_rows().next().unwrap();
    assert!(
        rec.t[first.0] > 0.006 && rec.t[first.0] <= 0.01 + 1e-9,
        "first pose row {}",
        rec.t[first.0]
    );
    assert_eq!(rec.x[0], None, "no extrapolation before the first pose");
    for i in 0..rec.len() {
        assert!((rec.t[i] - truth.t[i]).abs() <= 1e-9);
        for w in 0..2 {
            assert_eq!(
                rec.wheels[w].enc.as_ref().unwrap()[i],
                truth.wheels[w].enc.as_ref().unwrap()[i]
            );
            let (c, ct) = (
                rec.wheels[w].cmd.as_ref().unwrap()[i].unwrap(),
                truth.wheels[w].cmd.as_ref().unwrap()[i].unwrap(),
            );
            assert!((c - ct).abs() <= 1e-9, "cmd row {i}: {c} vs {ct}");
        }
        if let (Some(x), Some(y), Some(th)) = (rec.x[i], rec.y[i], rec.theta[i]) {
            // Truth relative to the truth at the start row, in that row's frame.
            let (x0, y0, t0) = (
                truth.x[first.0].unwrap(),
                truth.y[first.0].unwrap(),
                truth.theta[first.0].unwrap(),
            );
            let (dx, dy) = (truth.x[i].unwrap() - x0, truth.y[i].unwrap() - y0);
            let (c, s) = (t0.cos(), t0.sin());
            let (tx, ty, tt) = (
                c * dx + s * dy,
                -s * dx + c * dy,
                truth.theta[i].unwrap() - t0,
            );
            // The start frame itself is interpolated (3 ms after the first pose... no:
            // the first pose row is at 10 ms, between poses at 7 and 37 ms).
            worst_p = worst_p.max((x - tx).hypot(y - ty));
            worst_th = worst_th.max((th - tt).abs());
            compared += 1;
        }
    }
    assert!(
        compared > rec.len() * 9 / 10,
        "{compared} of {} rows have a pose",
        rec.len()
    );
    // Each of the two poses compared (the row's and the start row's) errs by at most
    // the interpolation bound: 2 x 1.7e-5 m (and the start heading's error moves far
    // points by up to 5.7e-6 rad x the ~18 m travelled: 1e-4 m), 2 x 5.7e-6 rad.
    assert!(
        worst_p <= 2.0 * 1.7e-5 + 18.0 * 5.7e-6,
        "worst position {worst_p}"
    );
    assert!(worst_th <= 2.0 * 5.7e-6, "worst heading {worst_th}");
    println!("synthetic: worst interpolated position {worst_p:.2e} m, heading {worst_th:.2e} rad");
}

fn err_of(bag: &Path, robot: &Robot, o: &ImportOptions) -> String {
    match import(bag, robot, o) {
        Ok(_) => panic!("{} imported, an error was expected", bag.display()),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bag_of_another_robot_names_the_joints_it_has() {
    let (diff, _, _) = real("diff-square-run-01");
    let bag = real_bag("omni3-square-run-01", "posestamped", &[]);
    let e = err_of(&bag, &diff, &opts("/mocap/pose"));
    assert!(e.contains("left_wheel_joint"), "{e}");
    for j in ["w1_wheel_joint", "w2_wheel_joint", "w3_wheel_joint"] {
        assert!(e.contains(j), "the bag's joints are listed: {e}");
    }
}

#[test]
fn bag_without_the_pose_topic_lists_its_topics() {
    let (robot, _, _) = real("diff-square-run-01");
    let bag = real_bag("diff-square-run-01", "none", &[]);
    let e = err_of(&bag, &robot, &opts("/mocap/pose"));
    assert!(e.contains("/mocap/pose"), "{e}");
    assert!(
        e.contains("/joint_states") && e.contains("sensor_msgs/msg/JointState"),
        "{e}"
    );
    // A topic of a type that carries no pose is refused, naming the types that do.
    let e = err_of(&bag, &robot, &opts("/joint_states"));
    assert!(
        e.contains("sensor_msgs/msg/JointState") && e.contains("geometry_msgs/msg/PoseStamped"),
        "{e}"
    );
}

#[test]
fn folder_without_metadata_is_refused() {
    let (robot, _, _) = real("diff-square-run-01");
    let bag = real_bag("diff-square-run-01", "posestamped", &[]);
    std::fs::remove_file(bag.join("metadata.yaml")).unwrap();
    let e = err_of(&bag, &robot, &opts("/mocap/pose"));
    assert!(e.contains("metadata.yaml"), "{e}");
    // The .mcap file itself still imports (it carries its own schemas and channels).
    let file = bag.join("bag.mcap");
    let imp = import(&file, &robot, &opts("/mocap/pose")).unwrap();
    assert_eq!(imp.recording.len(), 1388);
}

#[test]
fn corrupted_chunk_names_its_offset_and_keeps_what_came_before() {
    let (robot, _, dir) = real("diff-square-run-01");
    let out = tmp("corrupt");
    let robot_file = dir.join("robot.toml");
    let good = out.join("good");
    let bad = out.join("bad");
    let base = |o: &Path| {
        vec![
            "--robot".to_string(),
            robot_file.to_str().unwrap().to_string(),
            "--synthetic".into(),
            "120".into(),
            "--out".into(),
            o.to_str().unwrap().to_string(),
        ]
    };
    let mut a = base(&good);
    a.push("--compress".into());
    make_bag(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let mut a = base(&bad);
    a.extend(["--corrupt-chunk".into(), "2".into()]);
    let rep = make_bag(&a.iter().map(String::as_str).collect::<Vec<_>>());
    let offset = rep["corrupted_offset"].as_u64().unwrap();
    let offsets: Vec<u64> = rep["chunk_offsets"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert!(
        offsets.len() >= 4,
        "the bag has several chunks: {offsets:?}"
    );

    let mut o = opts("/mocap/pose");
    let e = err_of(&bad, &robot, &o);
    assert!(
        e.contains(&offset.to_string()),
        "the error names the chunk's offset {offset}: {e}"
    );
    o.keep_partial = true;
    let partial = import(&bad, &robot, &o).unwrap();
    assert!(
        partial
            .notes
            .iter()
            .any(|n| n.contains(&offset.to_string())),
        "{:?}",
        partial.notes
    );
    o.keep_partial = false;
    let full = import(&good, &robot, &o).unwrap().recording;
    let p = &partial.recording;
    // Every joint message the writer put in a chunk before the damaged one is kept, and
    // none after it: the writer reports how many those are.
    let before = rep["joint_messages_before"].as_u64().unwrap() as usize;
    assert!(
        before > 0 && before < full.len(),
        "{before} of {}",
        full.len()
    );
    assert_eq!(p.len(), before, "rows kept");
    let mut prefix = full.clone();
    for w in &mut prefix.wheels {
        if let Some(e) = &mut w.enc {
            e.truncate(p.len());
        }
        if let Some(c) = &mut w.cmd {
            c.truncate(p.len());
        }
    }
    prefix.t.truncate(p.len());
    prefix.x.truncate(p.len());
    prefix.y.truncate(p.len());
    prefix.theta.truncate(p.len());
    // The last kept rows may lack the pose after them (it was in the lost chunk).
    let mut q = p.clone();
    for i in 0..q.len() {
        if q.x[i].is_none() {
            prefix.x[i] = None;
            prefix.y[i] = None;
            prefix.theta[i] = None;
        }
    }
    q.notes.clear();
    assert_same(&q, &prefix, "partial vs prefix");
}

/// Part 3 of the issue: a SLAM-like pose stream (white noise 5 mm, 2.5 mrad per sample at
/// 33 Hz) with two loop-closure corrections. The wheels say how far the body moved between
/// two pose samples (their nominal-geometry error is ~0.1 mm per 30 ms step), so a step
/// departing from them by 6 robust scales is a jump: 0.15 m and (0.10 m, 0.05 rad) are
/// found at their times and sizes (each within 3 sigma of the step noise: 0.02 m,
/// 0.011 rad), the rows interpolated across them are blank, and the same stream without
/// the corrections has no jump (the threshold is > 10 sigma of the step noise: a false
/// one has probability < 1e-20 per step).
#[test]
fn slam_jumps_are_reported_at_their_times() {
    let (robot, _, dir) = real("diff-square-run-01");
    let out = tmp("slam");
    let robot_file = dir.join("robot.toml");
    let bag = |name: &str, jumps: &[&str]| {
        let b = out.join(name);
        let mut a = vec![
            "--robot",
            robot_file.to_str().unwrap(),
            "--synthetic",
            "30",
            "--pose-noise",
            "0.005",
        ];
        for j in jumps {
            a.extend(["--jump", j]);
        }
        let o = b.to_str().unwrap().to_string();
        a.extend(["--out", &o]);
        make_bag(&a);
        b
    };
    let with = import(
        &bag("jumps", &["10:0.15:0:0", "20:0:-0.1:0.05"]),
        &robot,
        &opts("/mocap/pose"),
    )
    .unwrap();
    let r = with.pose_jumps.as_ref().unwrap();
    println!("jumps: {:?}", r);
    assert_eq!(r.jumps.len(), 2, "{:?}", r.jumps);
    let t0 = with.t0_ns;
    for (j, (at, pos, head)) in r.jumps.iter().zip([(10.0, 0.15, 0.0), (20.0, 0.10, 0.05)]) {
        let (from, to) = ((j.from_ns - t0) as f64 * 1e-9, (j.to_ns - t0) as f64 * 1e-9);
        assert!(
            from < at && at <= to && to - from < 0.031,
            "jump at {at} s: {from}..{to}"
        );
        assert!(
            (j.position_m - pos).abs() <= 0.02,
            "{pos} m: {}",
            j.position_m
        );
        assert!(
            (j.heading_rad - head).abs() <= 0.011,
            "{head} rad: {}",
            j.heading_rad
        );
        let rec = &with.recording;
        for i in 0..rec.len() {
            if rec.t[i] > from + 1e-9 && rec.t[i] < to - 1e-9 {
                assert_eq!(rec.x[i], None, "row at {} s is across the jump", rec.t[i]);
            }
        }
    }
    assert!(
        with.notes.iter().any(|n| n.contains("pose jump")),
        "{:?}",
        with.notes
    );
    let without = import(&bag("clean", &[]), &robot, &opts("/mocap/pose")).unwrap();
    assert!(without.pose_jumps.unwrap().jumps.is_empty());
}
