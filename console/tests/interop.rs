//! Files the tools people already use open as they are (issue 53 §3), each read by an
//! independent reader:
//! - `log pull --out X.mcap`, `diagnose --report`'s and `calibrate --report`'s paths.mcap
//!   decoded by Python's `mcap` + `mcap-ros2-support` (CDR from the files' own ros2msg
//!   schemas): every pose's x, y and yaw and every joint position equal what the board
//!   logged or the recording holds, within 1e-9;
//! - `--tum DIR` files read by evo (`evo_ape tum REF EST`): its RMSE equals the RMSE
//!   computed here from the same files within 1e-6 m, and `evaluate --tum`'s files give
//!   back `evaluate`'s own RMS.
//!
//! Needs python3 with mcap, mcap-ros2-support and evo (`bash scripts/setup.sh`); without
//! them the tests fail, naming setup.sh.

mod common;

use calib_core::motion::Direction;
use calib_core::protocol::{ProgramSpec, DEFAULT_LINK_TIMEOUT_MS};
use calibrate::{param_specs, robot_with};
use formats::recording::Recording;
use formats::robot_file;
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;
use wheelcal::link::Faults;
use wheelcal::mcap_out::TRIAL_TOPICS;
use wheelcal::tum;
use wheelcal::virtual_board::InProcessBoard;

const SETUP: &str = "run `bash scripts/setup.sh` (it installs the pinned Python packages)";

/// The messages of `path` as Python's mcap-ros2-support decodes them, by topic, and the
/// metadata records (name -> values).
fn python_decode(path: &Path) -> (BTreeMap<String, Vec<Value>>, BTreeMap<String, Value>) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/read_ros2_mcap.py");
    let o = Command::new("python3")
        .arg(&script)
        .arg(path)
        .output()
        .unwrap_or_else(|e| panic!("python3 cannot run ({e}): {SETUP}"));
    assert!(
        o.status.success(),
        "the Python MCAP reader failed on {} ({SETUP} if a package is missing):\n{}",
        path.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let (mut topics, mut meta) = (BTreeMap::<String, Vec<Value>>::new(), BTreeMap::new());
    for line in String::from_utf8(o.stdout).unwrap().lines() {
        let v: Value = serde_json::from_str(line).unwrap();
        if let Some(name) = v["metadata"].as_str() {
            meta.insert(name.to_string(), v["values"].clone());
        } else {
            let t = v["topic"].as_str().unwrap().to_string();
            topics.entry(t).or_default().push(v);
        }
    }
    (topics, meta)
}

/// evo's APE RMSE (m) of `est` against `reference` (`evo_ape tum`, its defaults: the
/// translation part, no alignment), read from its saved results at full precision.
fn evo_rmse(reference: &Path, est: &Path, scratch: &Path) -> f64 {
    let zip = scratch.join(format!(
        "evo-{}.zip",
        est.file_stem().unwrap().to_string_lossy()
    ));
    let _ = std::fs::remove_file(&zip);
    let o = Command::new("evo_ape")
        .arg("tum")
        .arg(reference)
        .arg(est)
        .args(["--no_warnings", "--save_results"])
        .arg(&zip)
        .output()
        .unwrap_or_else(|e| panic!("evo_ape cannot run ({e}): {SETUP}"));
    assert!(
        o.status.success(),
        "evo_ape failed ({SETUP}):\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    let o = Command::new("python3")
        .args([
            "-c",
            "import json, sys, zipfile; print(repr(json.load(zipfile.ZipFile(sys.argv[1]).open('stats.json'))['rmse']))",
        ])
        .arg(&zip)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    String::from_utf8(o.stdout).unwrap().trim().parse().unwrap()
}

fn read_tum(p: &Path) -> Vec<tum::Line> {
    tum::parse(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// Heading of a quaternion about z.
fn yaw(q: &Value) -> f64 {
    let f = |k: &str| q[k].as_f64().unwrap();
    assert!(
        f("x").abs() < 1e-15 && f("y").abs() < 1e-15,
        "a rotation about z: {q}"
    );
    2.0 * f("z").atan2(f("w"))
}

/// `a - b` wrapped into (-pi, pi].
fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::TAU);
    if d > std::f64::consts::PI {
        d - std::f64::consts::TAU
    } else {
        d
    }
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("a number: {v}"))
}

#[test]
fn a_pulled_trial_decodes_in_python_as_ros2_messages_with_the_boards_numbers() {
    let dir = common::scratch("interop-trial");
    let robot = robot_file::load(&common::robot("mobolab")).unwrap();
    let sim = sim::SimRobot::new(
        &robot,
        sim::Faults::none(robot.wheel_count()),
        sim::Surface::flat(),
        sim::SimConfig::default(),
    )
    .unwrap();
    let mut board = InProcessBoard::start(&robot, sim, Faults::none(), Faults::none(), 3).unwrap();
    let c = &mut board.client;
    c.timeout = Duration::from_secs(2);
    c.hello().unwrap();
    // A square turns through every heading: yaw is tested past +-pi.
    c.run_program(
        ProgramSpec::Umbmark {
            side_m: 0.3,
            dir: Direction::Ccw,
        },
        50,
        DEFAULT_LINK_TIMEOUT_MS,
    )
    .unwrap();
    wheelcal::board::wait_program(c, Duration::from_secs(120), |_| {}).unwrap();
    let info = c.trials().unwrap().trials.last().unwrap().clone();
    let out = dir.join("trial.mcap");
    let tum_dir = dir.join("tum");
    let pulled =
        wheelcal::board::trial_log::pull_trial_with(c, info.id, &out, Some(&tum_dir), |_, _| {})
            .unwrap();
    let data = c.pull_log(info.id, Vec::new(), |_, _| {}).unwrap();
    let recs = wheelcal::client::decode_records(&info, &data).unwrap();
    assert_eq!(pulled.records, recs.len());
    let k = recs.len();
    assert!(k > 100, "{k} records");

    let (topics, meta) = python_decode(&out);
    let mut want: Vec<&str> = TRIAL_TOPICS.to_vec();
    want.sort();
    assert_eq!(topics.keys().map(String::as_str).collect::<Vec<_>>(), want);
    for (t, schema) in TRIAL_TOPICS.iter().zip([
        "geometry_msgs/msg/PoseStamped",
        "tf2_msgs/msg/TFMessage",
        "sensor_msgs/msg/JointState",
        "sensor_msgs/msg/JointState",
    ]) {
        let m = &topics[*t];
        assert_eq!(m.len(), k, "{t}");
        assert_eq!(m[0]["schema"], schema, "{t}");
        assert_eq!(m[0]["schema_encoding"], "ros2msg");
        assert_eq!(m[0]["message_encoding"], "cdr");
    }
    let trial: Value =
        serde_json::from_str(meta["wheelcal.trial"]["trial"].as_str().unwrap()).unwrap();
    assert_eq!(trial["id"], info.id);

    let names: Vec<String> = robot.wheels.iter().map(|w| w.name.to_string()).collect();
    let rad = std::f64::consts::TAU / robot.drive.encoder_counts_per_rev;
    let tum_lines = read_tum(&tum_dir.join("odometry.txt"));
    assert_eq!(tum_lines.len(), k);
    let start_ns = info.start_ms * 1_000_000;
    let mut clock = wheelcal::mcap_out::TrialClock::new();
    let (mut worst_pos, mut worst_yaw, mut worst_joint, mut yaw_span) = (0f64, 0f64, 0f64, 0f64);
    for (i, r) in recs.iter().enumerate() {
        let t_ns = start_ns + clock.us(r.t_us) * 1000;
        let (x, y, th) = (r.pose.x as f64, r.pose.y as f64, r.pose.theta as f64);
        yaw_span = yaw_span.max(th.abs());
        let odo = &topics[TRIAL_TOPICS[0]][i];
        assert_eq!(odo["log_time"].as_u64().unwrap(), t_ns);
        let m = &odo["msg"];
        assert_eq!(m["header"]["frame_id"], "odom");
        let stamp = m["header"]["stamp"]["sec"].as_u64().unwrap() * 1_000_000_000
            + m["header"]["stamp"]["nanosec"].as_u64().unwrap();
        assert_eq!(stamp, t_ns);
        let p = &m["pose"]["position"];
        worst_pos = worst_pos
            .max((f(&p["x"]) - x).abs())
            .max((f(&p["y"]) - y).abs())
            .max(f(&p["z"]).abs());
        worst_yaw = worst_yaw.max(angle_diff(yaw(&m["pose"]["orientation"]), th).abs());
        let tf = &topics[TRIAL_TOPICS[1]][i]["msg"]["transforms"][0];
        assert_eq!(tf["child_frame_id"], "base_link");
        worst_pos = worst_pos
            .max((f(&tf["transform"]["translation"]["x"]) - x).abs())
            .max((f(&tf["transform"]["translation"]["y"]) - y).abs());
        worst_yaw = worst_yaw.max(angle_diff(yaw(&tf["transform"]["rotation"]), th).abs());
        let js = &topics[TRIAL_TOPICS[2]][i]["msg"];
        let got_names: Vec<&str> = js["name"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        assert_eq!(got_names, names);
        for (w, v) in js["position"].as_array().unwrap().iter().enumerate() {
            worst_joint = worst_joint.max((f(v) - r.counts[w] as f64 * rad).abs());
        }
        assert_eq!(js["velocity"].as_array().unwrap().len(), names.len());
        let cmd = &topics[TRIAL_TOPICS[3]][i]["msg"];
        for (w, v) in cmd["velocity"].as_array().unwrap().iter().enumerate() {
            assert!((f(v) - r.cmd[w] as f64).abs() <= 1e-9);
        }
        let l = tum_lines[i];
        assert!(
            (l[0] - t_ns as f64 * 1e-9).abs() < 1e-6,
            "{} vs {t_ns}",
            l[0]
        );
        worst_pos = worst_pos.max((l[1] - x).abs()).max((l[2] - y).abs());
        worst_yaw = worst_yaw.max(angle_diff(2.0 * l[6].atan2(l[7]), th).abs());
    }
    // The joint velocities are the positions' differences over the record period.
    let js = &topics[TRIAL_TOPICS[2]];
    let (a, b) = (&js[k / 2]["msg"], &js[k / 2 + 1]["msg"]);
    let dt = (b["header"]["stamp"]["nanosec"].as_i64().unwrap()
        - a["header"]["stamp"]["nanosec"].as_i64().unwrap())
    .rem_euclid(1_000_000_000) as f64
        * 1e-9;
    let v = (f(&b["position"][0]) - f(&a["position"][0])) / dt;
    assert!((f(&b["velocity"][0]) - v).abs() < 1e-6 * v.abs().max(1.0));
    println!(
        "{k} records: worst |pose - logged| {worst_pos:.1e} m, yaw {worst_yaw:.1e} rad (yaw up to {yaw_span:.2} rad), joint {worst_joint:.1e} rad"
    );
    assert!(yaw_span > 3.0, "the square turned through {yaw_span} rad");
    assert!(worst_pos <= 1e-9 && worst_yaw <= 1e-9 && worst_joint <= 1e-9);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A simulated square by a robot 1 %, 0.6 % and 3 % off mobolab's file, saved as CSV.
fn sim_recording(dir: &Path, seed: u64) -> PathBuf {
    let nominal = robot_file::load(&common::robot("mobolab")).unwrap();
    let specs = param_specs(&nominal, false);
    let actual = robot_with(&nominal, &specs, &[0.99, 1.006, 1.03]);
    let file = dir.join(format!("square{seed}.csv"));
    common::sim_square(&actual, Direction::Cw, seed)
        .save(&file)
        .unwrap();
    file
}

#[test]
fn diagnose_paths_decode_in_python_and_its_tum_files_give_evos_rmse() {
    let dir = common::scratch("interop-diagnose");
    let file = sim_recording(&dir, 3);
    let (report, tum_dir) = (dir.join("report"), dir.join("tum"));
    let o = common::wheelcal()
        .args(["--json", "diagnose", "--robot"])
        .arg(common::robot("mobolab"))
        .arg("--recording")
        .arg(&file)
        .arg("--report")
        .arg(&report)
        .arg("--tum")
        .arg(&tum_dir)
        .output()
        .unwrap();
    let rep = common::json_of(&o);
    let nominal = robot_file::load(&common::robot("mobolab")).unwrap();
    let rec = Recording::load(&file, &nominal).unwrap();
    let rows: Vec<(usize, f64, f64, f64)> = rec.pose_rows().collect();
    assert_eq!(rep["pose_samples"].as_u64().unwrap() as usize, rows.len());

    let (topics, _) = python_decode(&report.join("paths.mcap"));
    let names = ["measured", "nominal", "fitted"];
    let mut want: Vec<String> = names.iter().map(|n| format!("/paths/{n}")).collect();
    want.push("/tf".into());
    want.sort();
    assert_eq!(topics.keys().cloned().collect::<Vec<_>>(), want);
    assert_eq!(topics["/tf"].len(), 3 * rows.len());
    let mut worst = 0f64;
    for name in names {
        let msgs = &topics[&format!("/paths/{name}")];
        assert_eq!(msgs.len(), rows.len(), "{name}");
        assert_eq!(msgs[0]["schema"], "geometry_msgs/msg/PoseStamped");
        let lines = read_tum(&tum_dir.join(format!("{name}.txt")));
        assert_eq!(lines.len(), rows.len(), "{name}.txt");
        for (i, m) in msgs.iter().enumerate() {
            let p = &m["msg"]["pose"];
            let (x, y, th) = (
                f(&p["position"]["x"]),
                f(&p["position"]["y"]),
                yaw(&p["orientation"]),
            );
            // The TUM file holds the same poses.
            let l = lines[i];
            worst = worst
                .max((l[1] - x).abs())
                .max((l[2] - y).abs())
                .max(angle_diff(2.0 * l[6].atan2(l[7]), th).abs());
            assert!((l[0] - m["log_time"].as_u64().unwrap() as f64 * 1e-9).abs() < 1e-9);
            if name == "measured" {
                // The recording's own poses.
                let (_, rx, ry, rth) = rows[i];
                worst = worst
                    .max((x - rx).abs())
                    .max((y - ry).abs())
                    .max(angle_diff(th, rth).abs());
            }
        }
    }
    println!("worst |decoded - recording / TUM| {worst:.1e}");
    assert!(worst <= 1e-9, "{worst}");

    // evo's RMSE of the nominal and fitted paths against the measured one.
    let measured = tum_dir.join("measured.txt");
    let m = read_tum(&measured);
    for name in ["nominal", "fitted"] {
        let est = tum_dir.join(format!("{name}.txt"));
        let ours = tum::ape_rmse(&m, &read_tum(&est)).unwrap();
        let evo = evo_rmse(&measured, &est, &dir);
        println!(
            "{name}: evo_ape RMSE {evo:.9} m, ours {ours:.9} m, differ by {:.1e} m",
            (evo - ours).abs()
        );
        assert!((evo - ours).abs() <= 1e-6, "{name}: evo {evo} vs {ours}");
        assert!(ours > 0.0);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `calibrate --report`'s paths.mcap decoded by Python's mcap-ros2-support: per
/// recording `/paths/<recording>/measured|nominal|fitted` as `PoseStamped` (one per pose
/// row, the measured ones the recording's poses to 1e-9) and each pose as a transform on
/// `/tf`.
#[test]
fn calibrate_paths_decode_in_python_as_pose_stamped() {
    let dir = common::scratch("interop-calibrate");
    let files = [sim_recording(&dir, 3), sim_recording(&dir, 4)];
    let report = dir.join("report");
    let mut args: Vec<std::ffi::OsString> = Vec::new();
    for f in &files {
        args.push("--recording".into());
        args.push(f.clone().into_os_string());
    }
    args.push("--report".into());
    args.push(report.clone().into_os_string());
    let o = common::calibrate_mobolab(&args, &[], &dir.join("fitted.toml"));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (topics, _) = python_decode(&report.join("paths.mcap"));
    let nominal = robot_file::load(&common::robot("mobolab")).unwrap();
    let mut want = vec!["/tf".to_string()];
    let mut worst = 0f64;
    let mut total = 0;
    for (file, key) in files.iter().zip(["square3.csv", "square4.csv"]) {
        let rows: Vec<(usize, f64, f64, f64)> = Recording::load(file, &nominal)
            .unwrap()
            .pose_rows()
            .collect();
        total += 3 * rows.len();
        for k in ["measured", "nominal", "fitted"] {
            let topic = format!("/paths/{key}/{k}");
            let msgs = topics
                .get(&topic)
                .unwrap_or_else(|| panic!("{topic} in {:?}", topics.keys()));
            assert_eq!(msgs.len(), rows.len(), "{topic}");
            assert_eq!(msgs[0]["schema"], "geometry_msgs/msg/PoseStamped");
            if k == "measured" {
                for (m, &(_, x, y, th)) in msgs.iter().zip(&rows) {
                    let p = &m["msg"]["pose"];
                    worst = worst
                        .max((f(&p["position"]["x"]) - x).abs())
                        .max((f(&p["position"]["y"]) - y).abs())
                        .max(angle_diff(yaw(&p["orientation"]), th).abs());
                }
            }
            want.push(topic);
        }
    }
    want.sort();
    assert_eq!(topics.keys().cloned().collect::<Vec<_>>(), want);
    assert_eq!(topics["/tf"].len(), total);
    println!("worst |decoded - recording| {worst:.1e}");
    assert!(worst <= 1e-9, "{worst}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn evaluate_tum_files_give_evaluates_rms_and_evos() {
    let dir = common::scratch("interop-evaluate");
    let file = sim_recording(&dir, 5);
    let tum_dir = dir.join("tum");
    let o = common::wheelcal()
        .args(["--json", "evaluate", "--robot"])
        .arg(common::robot("mobolab"))
        .arg("--recording")
        .arg(&file)
        .arg("--tum")
        .arg(&tum_dir)
        .output()
        .unwrap();
    let ev = common::json_of(&o);
    let want = f(&ev["recordings"][0]["rmse_m"][0]);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&tum_dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "txt"))
        .collect();
    files.sort();
    let measured = files
        .iter()
        .find(|p| p.to_string_lossy().ends_with("__measured.txt"))
        .expect("a measured file")
        .clone();
    let est = files
        .iter()
        .find(|p| p.to_string_lossy().ends_with("__1_mobolab.txt"))
        .unwrap_or_else(|| panic!("the robot file's dead reckoning in {files:?}"))
        .clone();
    let ours = tum::ape_rmse(&read_tum(&measured), &read_tum(&est)).unwrap();
    let evo = evo_rmse(&measured, &est, &dir);
    println!(
        "evaluate's RMS {want:.9} m; from the TUM files {ours:.9} m ({:.1e} apart); evo_ape {evo:.9} m ({:.1e} from ours)",
        (ours - want).abs(),
        (evo - ours).abs()
    );
    assert!((evo - ours).abs() <= 1e-6, "evo {evo} vs {ours}");
    assert!(
        (ours - want).abs() <= 1e-6 * want.max(1e-3),
        "{ours} vs evaluate's {want}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// `evaluate --tum` writes every candidate evaluate judges, each the replay it judged: a
/// calibration as the board applies it (`--board`, through the firmware's odometry) and
/// a skid-steer robot (rover4, whose sides step by their turn-radius law). From each
/// TUM file and the measured one, the position RMS equals evaluate's to 1e-9 relative.
#[test]
fn evaluate_tum_writes_boards_and_skid_steer_robots_as_judged() {
    let dir = common::scratch("interop-evaluate-all");
    // A board: calibrate on one square, judged on another.
    let (train, test) = (sim_recording(&dir, 6), sim_recording(&dir, 7));
    let o = common::calibrate_mobolab(
        &["--recording".into(), train.into_os_string()],
        &[],
        &dir.join("fitted.toml"),
    );
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cal = dir.join("cal.json");
    std::fs::write(&cal, &o.stdout).unwrap();
    // A skid-steer robot's square, judged with its own file.
    let rover = robot_file::load(&common::robot("rover4")).unwrap();
    let rover_rec = dir.join("rover.csv");
    common::sim_square(&rover, Direction::Ccw, 8)
        .save(&rover_rec)
        .unwrap();
    for (robot, extra, rec, stem) in [
        (
            "mobolab",
            vec!["--board".into(), cal.into_os_string()],
            test,
            "__1_cal.txt",
        ),
        ("rover4", vec![], rover_rec, "__1_rover4.txt"),
    ] {
        let tum_dir = dir.join(format!("tum-{robot}"));
        let o = common::wheelcal()
            .args(["--json", "evaluate", "--robot"])
            .arg(common::robot(robot))
            .args(&extra)
            .arg("--recording")
            .arg(&rec)
            .arg("--tum")
            .arg(&tum_dir)
            .output()
            .unwrap();
        let ev = common::json_of(&o);
        let want = f(&ev["recordings"][0]["rmse_m"][0]);
        let names: Vec<String> = std::fs::read_dir(&tum_dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        let find = |end: &str| {
            tum_dir.join(
                names
                    .iter()
                    .find(|n| n.ends_with(end))
                    .unwrap_or_else(|| panic!("{robot}: no *{end} in {names:?}")),
            )
        };
        let ours =
            tum::ape_rmse(&read_tum(&find("__measured.txt")), &read_tum(&find(stem))).unwrap();
        println!("{robot}: evaluate's RMS {want:.9} m, from the TUM files {ours:.9} m");
        assert!(want > 1e-3, "{robot}: {want}");
        assert!(
            (ours - want).abs() <= 1e-9 * want,
            "{robot}: {ours} vs evaluate's {want}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}
