//! `wheelcal import ros2` as a ROS user runs it (the README's walk-through): a bag written
//! by Python's rosbags from a real square imports to a folder whose recording.csv equals
//! the original to the printed precision (counts exact, t and poses to 1e-9) and whose
//! robot.toml is the robot file; an existing recording is not overwritten; a bad flag is
//! a clear error. Needs python3 with rosbags (`bash scripts/setup.sh`): FAILS without.

use formats::recording::Recording;
use std::path::{Path, PathBuf};
use std::process::Command;

/// The real runs kept in the repository (`data/real`).
fn real_dir() -> PathBuf {
    testdata::real_dir()
}

fn make_bag(robot: &Path, csv: &Path, out: &Path) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../ros2bag/tests/make_bag.py");
    let o = Command::new("python3")
        .arg(script)
        .args([
            "--robot",
            robot.to_str().unwrap(),
            "--csv",
            csv.to_str().unwrap(),
        ])
        .args(["--out", out.to_str().unwrap()])
        .output()
        .unwrap_or_else(|e| panic!("python3 cannot run ({e}): run `bash scripts/setup.sh`"));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.success(),
        "make_bag.py failed (python3 with rosbags is needed: run `bash scripts/setup.sh`): {err}"
    );
}

fn wheelcal(args: &[&str]) -> (bool, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_wheelcal"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.success(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn import_ros2_writes_the_recording_folder() {
    let run = real_dir().join("diff-square-run-04");
    let tmp = std::env::temp_dir().join(format!("wheelcal-import-ros2-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    let bag = tmp.join("square_bag");
    make_bag(&run.join("robot.toml"), &run.join("recording.csv"), &bag);
    let out = tmp.join("imported");
    let robot = run.join("robot.toml");
    let args = [
        "import",
        "ros2",
        bag.to_str().unwrap(),
        "--robot",
        robot.to_str().unwrap(),
        "--joint",
        "left=left_wheel_joint",
        "--joint",
        "right=right_wheel_joint",
        "--pose-topic",
        "/mocap/pose",
        "--pose-frame",
        "map",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    let (ok, stdout, stderr) = wheelcal(&args);
    assert!(ok, "{stderr}");
    let rep: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    let r = formats::robot_file::load(&robot).unwrap();
    let csv = Recording::load(&run.join("recording.csv"), &r).unwrap();
    assert_eq!(rep["rows"].as_u64().unwrap() as usize, csv.len());
    assert_eq!(rep["pose_frame"], "map");
    let got = Recording::load(&out.join("recording.csv"), &r).unwrap();
    assert_eq!(got.len(), csv.len());
    for i in 0..csv.len() {
        assert!((got.t[i] - csv.t[i]).abs() <= 1e-9);
        for w in 0..2 {
            assert_eq!(
                got.wheels[w].enc.as_ref().unwrap()[i],
                csv.wheels[w].enc.as_ref().unwrap()[i]
            );
        }
        assert!((got.x[i].unwrap() - csv.x[i].unwrap()).abs() <= 1e-9);
        assert!((got.y[i].unwrap() - csv.y[i].unwrap()).abs() <= 1e-9);
        assert!((got.theta[i].unwrap() - csv.theta[i].unwrap()).abs() <= 1e-9);
    }
    assert_eq!(
        std::fs::read(out.join("robot.toml")).unwrap(),
        std::fs::read(&robot).unwrap()
    );
    // Run again: the recording is there, nothing is replaced without --force.
    let before = std::fs::read(out.join("recording.csv")).unwrap();
    let (ok, _, stderr) = wheelcal(&args);
    assert!(
        !ok && stderr.contains("exists") && stderr.contains("--force"),
        "{stderr}"
    );
    assert_eq!(std::fs::read(out.join("recording.csv")).unwrap(), before);
    // A --joint without '=' is refused with the expected form.
    let mut bad = args.to_vec();
    bad[6] = "left";
    let (ok, _, stderr) = wheelcal(&bad);
    assert!(!ok && stderr.contains("WHEEL=JOINT"), "{stderr}");
}

/// `calibrate` and `diagnose` read a bag directly with the import's flags: the geometry
/// fitted from two real squares given as bags equals the one from their CSV recordings
/// (to 1e-9: the same rows), and diagnose gives the same verdict and RMSE.
#[test]
fn calibrate_and_diagnose_take_a_bag_directly() {
    let real = real_dir();
    let tmp = std::env::temp_dir().join(format!("wheelcal-bag-direct-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&tmp);
    std::fs::create_dir_all(&tmp).unwrap();
    let robot = real.join("diff-square-run-01/robot.toml");
    let mut bags = Vec::new();
    for run in ["diff-square-run-01", "diff-square-run-04"] {
        let bag = tmp.join(run);
        make_bag(
            &real.join(run).join("robot.toml"),
            &real.join(run).join("recording.csv"),
            &bag,
        );
        bags.push(bag);
    }
    let robot_s = robot.to_str().unwrap();
    let geometry = |recs: &[&Path], bag_flags: &[&str]| -> serde_json::Value {
        let mut args = vec![
            "--json",
            "calibrate",
            "--robot",
            robot_s,
            "--no-cross-validation",
        ];
        for r in recs {
            args.extend(["--recording", r.to_str().unwrap()]);
        }
        args.extend(bag_flags);
        let (ok, out, err) = wheelcal(&args);
        assert!(ok, "{err}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("calibrate JSON");
        v["geometry"].clone()
    };
    let from_bags = geometry(
        &[bags[0].as_path(), bags[1].as_path()],
        &["--pose-topic", "/mocap/pose"],
    );
    let csv = [
        real.join("diff-square-run-01"),
        real.join("diff-square-run-04"),
    ];
    let from_csv = geometry(&[csv[0].as_path(), csv[1].as_path()], &[]);
    let values = |g: &serde_json::Value| -> Vec<f64> {
        let mut v = Vec::new();
        collect_numbers(g, &mut v);
        v
    };
    let (a, b) = (values(&from_bags), values(&from_csv));
    assert!(
        !a.is_empty() && a.len() == b.len(),
        "{from_bags} vs {from_csv}"
    );
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (x - y).abs() <= 1e-9 * y.abs().max(1.0),
            "{from_bags} vs {from_csv}"
        );
    }
    // diagnose, one bag: the same verdict and RMSEs as its CSV.
    let diag = |rec: &Path, flags: &[&str]| -> serde_json::Value {
        let mut args = vec!["--json", "diagnose", "--robot", robot_s, "--recording"];
        args.push(rec.to_str().unwrap());
        args.extend(flags);
        let (ok, out, err) = wheelcal(&args);
        assert!(ok, "{err}");
        serde_json::from_str(&out).expect("diagnose JSON")
    };
    let d_bag = diag(&bags[0], &["--pose-topic", "/mocap/pose"]);
    let d_csv = diag(&csv[0], &[]);
    assert_eq!(d_bag["verdict"], d_csv["verdict"]);
    for k in ["rmse_nominal_m", "rmse_final_m"] {
        let (x, y) = (d_bag[k].as_f64().unwrap(), d_csv[k].as_f64().unwrap());
        assert!((x - y).abs() <= 1e-9, "{k}: {x} vs {y}");
    }
    // A bag without --pose-topic is a clear error, not a guess.
    let (ok, _, err) = wheelcal(&[
        "diagnose",
        "--robot",
        robot_s,
        "--recording",
        bags[0].to_str().unwrap(),
    ]);
    assert!(!ok && err.contains("pose-topic"), "{err}");
    let _ = std::fs::remove_dir_all(&tmp);
}

fn collect_numbers(v: &serde_json::Value, out: &mut Vec<f64>) {
    match v {
        serde_json::Value::Number(n) => out.extend(n.as_f64()),
        serde_json::Value::Array(a) => a.iter().for_each(|x| collect_numbers(x, out)),
        serde_json::Value::Object(o) => o.values().for_each(|x| collect_numbers(x, out)),
        _ => {}
    }
}
