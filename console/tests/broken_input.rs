//! Issue 23 §3 and §4 through the `wheelcal` binary: any input ends in bounded memory and
//! time, and a recording with a non-finite or physically absurd value is a data error that
//! names file:line:col instead of a confident answer.
//!
//! The bounds (formats::recording): poses within 500 m of the origin, a body that moves at
//! most 30 m/s between pose samples, wheel surface speeds (commanded or from the encoders)
//! at most 30 m/s, headings within 10^4 rad, leg angles within one turn, and no jump in `t`
//! over an hour. The fixtures are a simulated UMBmark square of mobolab (r = 0.05 m,
//! 1920 counts per wheel turn, 200 rows/s, ~0.3 m/s), so a clean file is far inside each
//! bound and every broken value below is far outside it.

mod common;

use common::{robot, scratch, wheelcal};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

/// A simulated UMBmark square of `robot_name` in `dir/rec` (recording.csv, robot.toml).
fn simulated(dir: &Path, robot_name: &str) -> PathBuf {
    let out = dir.join(format!("rec-{robot_name}"));
    let mut c = wheelcal();
    c.args(["sim", "record", "--seed", "3", "--robot"])
        .arg(robot(robot_name))
        .arg("--out")
        .arg(&out);
    if robot_name == "wlr" {
        c.args(["--duration", "20"]);
    } else {
        c.args(["--umbmark-side", "1"]);
    }
    let o = c.output().expect("runs");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// The recording's header and data rows as cells (data row i is line i + 2).
fn table(dir: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(dir.join("recording.csv")).unwrap();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_string).collect())
        .collect();
    (header, rows)
}

/// Writes `rows` under `header` as `dir/name`.
fn write(dir: &Path, name: &str, header: &[String], rows: &[Vec<String>]) -> PathBuf {
    let mut s = header.join(",");
    s.push('\n');
    for r in rows {
        s.push_str(&r.join(","));
        s.push('\n');
    }
    let p = dir.join(name);
    std::fs::write(&p, s).unwrap();
    p
}

fn col(header: &[String], name: &str) -> usize {
    header.iter().position(|h| h == name).expect(name)
}

/// Runs `cmd`, killing it after `limit` (an input that grows memory without bound never
/// ends by itself); returns the output and the time it took.
fn run_bounded(mut cmd: Command, limit: Duration) -> (Output, Duration) {
    let t0 = Instant::now();
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawns");
    // Read both pipes on threads so a chatty child never blocks.
    let mut so = child.stdout.take().unwrap();
    let mut se = child.stderr.take().unwrap();
    let ho = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = so.read_to_end(&mut v);
        v
    });
    let he = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = se.read_to_end(&mut v);
        v
    });
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd:?} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let took = t0.elapsed();
    let out = Output {
        status,
        stdout: ho.join().unwrap(),
        stderr: he.join().unwrap(),
    };
    (out, took)
}

/// `wheelcal diagnose` on `recording` of `robot_file`: exit code, stdout, stderr.
fn diagnose(robot_file: &Path, recording: &Path) -> (Option<i32>, String, String) {
    let mut c = wheelcal();
    c.arg("diagnose")
        .arg("--robot")
        .arg(robot_file)
        .arg("--recording")
        .arg(recording);
    let (o, _) = run_bounded(c, Duration::from_secs(60));
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Asserts a data error at `file:line:col` whose message contains every one of `words`.
fn assert_data_error(
    got: (Option<i32>, String, String),
    file: &Path,
    line: usize,
    col: Option<usize>,
    words: &[&str],
) {
    let (code, out, err) = got;
    assert_eq!(code, Some(1), "stdout:\n{out}\nstderr:\n{err}");
    let at = match col {
        Some(c) => format!("{}:{line}:{c}:", file.display()),
        None => format!("{}:{line}:", file.display()),
    };
    assert!(err.contains(&at), "expected {at} in:\n{err}");
    for w in words {
        assert!(err.contains(w), "expected {w:?} in:\n{err}");
    }
    for bad in ["inf mm", "NaN", "panicked"] {
        assert!(
            !err.contains(bad) && !out.contains(bad),
            "{bad} in:\n{out}\n{err}"
        );
    }
}

/// A 1e300 cell in any numeric column (or a time cell) is refused at its cell: it made
/// diagnose print "inf mm" and 300-digit sigmas, and calibrate "1.00000 ± 0.00000".
#[test]
fn a_huge_cell_is_a_data_error_at_its_cell() {
    let dir = scratch("huge-cell");
    let rec = simulated(&dir, "mobolab");
    let (h, rows) = table(&rec);
    let robot_file = rec.join("robot.toml");
    // A pose row (every 10th row has one at 200 rows/s with a 20 Hz camera).
    let k = (1000..)
        .find(|&k| !rows[k][col(&h, "x")].is_empty())
        .unwrap();
    for (name, value) in [
        ("x", "1e300"),
        ("y", "-1e300"),
        ("theta", "1e300"),
        ("cmd_left", "1e300"),
    ] {
        let mut r = rows.clone();
        r[k][col(&h, name)] = value.into();
        let f = write(&dir, &format!("{name}.csv"), &h, &r);
        assert_data_error(
            diagnose(&robot_file, &f),
            &f,
            k + 2,
            Some(col(&h, name) + 1),
            &[name],
        );
    }
    // The last row's time: a jump no recording holds.
    let mut r = rows.clone();
    let last = r.len() - 1;
    r[last][0] = "1e300".into();
    let f = write(&dir, "t.csv", &h, &r);
    assert_data_error(diagnose(&robot_file, &f), &f, last + 2, Some(1), &["t"]);
}

/// A logger writing t = 0 and then Unix time, or t jumping to 1e6 s: diagnose listed
/// every missing sample (24 GB, killed; or "199,993,999 missing samples", exit 0).
#[test]
fn a_jump_in_time_no_run_holds_is_a_data_error() {
    let dir = scratch("t-jump");
    let rec = simulated(&dir, "mobolab");
    let (h, rows) = table(&rec);
    let robot_file = rec.join("robot.toml");
    for (name, from, offset) in [("unix", 1usize, 1.7e9), ("million", 2000, 1e6)] {
        let mut r = rows.clone();
        for row in r.iter_mut().skip(from) {
            let t: f64 = row[0].parse().unwrap();
            row[0] = format!("{}", t + offset);
        }
        let f = write(&dir, &format!("{name}.csv"), &h, &r);
        assert_data_error(diagnose(&robot_file, &f), &f, from + 2, Some(1), &["jumps"]);
    }
}

/// A gap a run can hold (2 s of rows lost) is reported as one interval with its count,
/// not one entry per missing sample: counted at the file's own rate with `--max-rate 0`,
/// and at the merged rate (about 100 rows/s, formats.md §2) by default.
#[test]
fn a_gap_is_reported_as_an_interval_with_its_count() {
    let dir = scratch("gap");
    let rec = simulated(&dir, "mobolab");
    let (h, mut rows) = table(&rec);
    // Rows 2000..2400 lost: 400 samples at 200 rows/s.
    rows.drain(2000..2400);
    let f = write(&dir, "gap.csv", &h, &rows);
    // (--max-rate, samples missing at the rows' rate, the last row before the gap)
    for (max_rate, missing, after_s) in [("0", 400.0, 9.995), ("100", 200.0, 9.99)] {
        let o = wheelcal()
            .args(["--json", "diagnose", "--max-rate", max_rate, "--robot"])
            .arg(rec.join("robot.toml"))
            .arg("--recording")
            .arg(&f)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
        let glitch = v["recording_artefacts"]
            .as_array()
            .expect("recording_artefacts")
            .iter()
            .find(|a| a["id"] == "sample_glitch")
            .unwrap_or_else(|| panic!("no sample_glitch in {}", v["recording_artefacts"]));
        assert_eq!(glitch["parameters"]["missing_samples"], missing, "{glitch}");
        let gaps = glitch["gaps"].as_array().expect("gaps");
        assert_eq!(gaps.len(), 1, "{glitch}");
        assert_eq!(gaps[0]["missing"].as_f64(), Some(missing), "{glitch}");
        // From the last row kept before to the first after (t = 12 s).
        let (a, b) = (
            gaps[0]["after_s"].as_f64().unwrap(),
            gaps[0]["before_s"].as_f64().unwrap(),
        );
        assert!(
            (a - after_s).abs() < 1e-9 && (b - 12.0).abs() < 1e-9,
            "{glitch}"
        );
    }
}

/// Poses in millimetres (a 1 m square written as 1000): an RMSE of 1,105 m before.
#[test]
fn poses_in_millimetres_are_named() {
    let dir = scratch("mm");
    let rec = simulated(&dir, "mobolab");
    let (h, mut rows) = table(&rec);
    let first_pose_row = 0; // the simulator measures the pose in the first row
    for row in rows.iter_mut() {
        for name in ["x", "y"] {
            let c = col(&h, name);
            if !row[c].is_empty() {
                let v: f64 = row[c].parse().unwrap();
                row[c] = format!("{}", v * 1000.0);
            }
        }
    }
    assert!(!rows[first_pose_row][col(&h, "x")].is_empty());
    let f = write(&dir, "mm.csv", &h, &rows);
    let (code, _, err) = diagnose(&rec.join("robot.toml"), &f);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains(&format!("{}:", f.display())), "{err}");
    assert!(err.contains("millimetres"), "{err}");
}

/// A commanded wheel rate no motor reaches (5000 rad/s on a 5 cm wheel: 250 m/s).
#[test]
fn a_wheel_faster_than_a_motor_is_a_data_error() {
    let dir = scratch("fast-wheel");
    let rec = simulated(&dir, "mobolab");
    let (h, mut rows) = table(&rec);
    rows[1234][col(&h, "cmd_right")] = "5000".into();
    let f = write(&dir, "fast.csv", &h, &rows);
    assert_data_error(
        diagnose(&rec.join("robot.toml"), &f),
        &f,
        1236,
        Some(col(&h, "cmd_right") + 1),
        &["m/s"],
    );
}

/// One encoder sample off by 1e17 counts: calibrate pinned its factors at the bounds and a
/// clean recording went from 21.7 to 1385.6 mm.
#[test]
fn an_encoder_glitch_is_a_data_error_at_its_cell() {
    let dir = scratch("enc-glitch");
    let rec = simulated(&dir, "mobolab");
    let (h, mut rows) = table(&rec);
    let c = col(&h, "enc_left");
    let v: i64 = rows[3000][c].parse().unwrap();
    rows[3000][c] = format!("{}", v + 100_000_000_000_000_000);
    let f = write(&dir, "glitch.csv", &h, &rows);
    assert_data_error(
        diagnose(&rec.join("robot.toml"), &f),
        &f,
        3002,
        Some(c + 1),
        &["enc_left", "m/s"],
    );
}

/// Encoders that never move while the poses do: calibrate answered "± inf".
#[test]
fn encoders_that_never_move_while_the_poses_do_are_refused() {
    let dir = scratch("enc-still");
    let rec = simulated(&dir, "mobolab");
    let (h, mut rows) = table(&rec);
    for row in rows.iter_mut() {
        row[col(&h, "enc_left")] = "17".into();
        row[col(&h, "enc_right")] = "-4".into();
    }
    let f = write(&dir, "still.csv", &h, &rows);
    let (code, _, err) = diagnose(&rec.join("robot.toml"), &f);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains(&format!("{}:", f.display())), "{err}");
    assert!(err.contains("never"), "{err}");
    assert!(err.contains("enc_left"), "{err}");
}

/// Leg angles in degrees on the wheeled-legged robot (90 for a vertical leg).
#[test]
fn leg_angles_in_degrees_are_named() {
    let dir = scratch("legs-deg");
    let rec = simulated(&dir, "wlr");
    let (h, mut rows) = table(&rec);
    for row in rows.iter_mut() {
        for name in ["leg_front", "leg_rear"] {
            let c = col(&h, name);
            let v: f64 = row[c].parse().unwrap();
            row[c] = format!("{}", v.to_degrees());
        }
    }
    let f = write(&dir, "deg.csv", &h, &rows);
    assert_data_error(
        diagnose(&rec.join("robot.toml"), &f),
        &f,
        2,
        Some(col(&h, "leg_front") + 1),
        &["degrees"],
    );
}

/// Reads are capped by the bytes actually read: `/dev/zero` and `/dev/full` report a size
/// of 0 and never end (20 GB in 2 s for `--flash /dev/full`).
#[test]
fn endless_files_fail_fast_naming_the_file() {
    let dir = scratch("endless");
    let rec = simulated(&dir, "mobolab");
    let robot_file = rec.join("robot.toml");
    let recording = rec.join("recording.csv");
    let runs = dir.join("runs.csv");
    std::fs::write(
        &runs,
        "test,path,length_m,x_err_m,y_err_m\numbmark,cw,1,0.01,0.02\numbmark,ccw,1,0.01,-0.02\n",
    )
    .unwrap();
    let omni_runs = dir.join("omni-runs.csv");
    let mut o = String::from("test,path,length_m,x_err_m,y_err_m\n");
    for k in 0..3 {
        let e = 0.001 * k as f64;
        o.push_str(&format!(
            "omni,4W-1,0.5,{},0.01\nomni,4W-2,0.5,0.012,{}\n",
            0.003 + e,
            0.004 - e
        ));
    }
    std::fs::write(&omni_runs, o).unwrap();
    for dev in ["/dev/zero", "/dev/full"] {
        let cases: Vec<Vec<String>> = vec![
            vec![
                "diagnose".into(),
                "--robot".into(),
                dev.into(),
                "--recording".into(),
                recording.display().to_string(),
            ],
            vec![
                "diagnose".into(),
                "--robot".into(),
                robot_file.display().to_string(),
                "--recording".into(),
                dev.into(),
            ],
            vec![
                "umbmark".into(),
                "compute".into(),
                "--robot".into(),
                robot_file.display().to_string(),
                "--runs".into(),
                dev.into(),
            ],
            vec![
                "omni".into(),
                "compute".into(),
                "--robot".into(),
                robot("omni4").display().to_string(),
                "--runs".into(),
                omni_runs.display().to_string(),
                "--previous".into(),
                dev.into(),
            ],
            vec![
                "factors".into(),
                "export".into(),
                "--ros2".into(),
                dir.join("r.yaml").display().to_string(),
                "--from".into(),
                dev.into(),
            ],
            vec![
                "sim-board".into(),
                "--robot".into(),
                robot_file.display().to_string(),
                "--link".into(),
                dir.join("b").display().to_string(),
                "--flash".into(),
                dev.into(),
            ],
        ];
        for args in cases {
            let mut c = wheelcal();
            c.args(&args);
            let (o, took) = run_bounded(c, Duration::from_secs(30));
            let err = String::from_utf8_lossy(&o.stderr);
            assert_eq!(o.status.code(), Some(1), "{args:?}: {err}");
            assert!(err.contains(dev), "{args:?}: {err}");
            assert!(took < Duration::from_secs(10), "{args:?}: {took:?}");
        }
    }
}

/// A long diagnose says it is working on stderr within 2 s, also when stderr is a pipe
/// (the 505 MB recording printed nothing for 600 s).
#[test]
fn diagnose_shows_progress_within_two_seconds() {
    let dir = scratch("progress");
    let out = dir.join("long");
    let o = wheelcal()
        .args([
            "sim",
            "record",
            "--seed",
            "5",
            "--duration",
            "3000",
            "--robot",
        ])
        .arg(robot("mobolab"))
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let t0 = Instant::now();
    let mut child = wheelcal()
        .arg("diagnose")
        .arg("--robot")
        .arg(out.join("robot.toml"))
        .arg("--recording")
        .arg(out.join("recording.csv"))
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut se = child.stderr.take().unwrap();
    let mut first = [0u8; 1];
    let got = se.read(&mut first);
    let took = t0.elapsed();
    let still_running = child.try_wait().unwrap().is_none();
    let _ = child.kill();
    let _ = child.wait();
    assert!(matches!(got, Ok(1)), "no progress on stderr");
    assert!(
        still_running,
        "diagnose ended before its first progress line"
    );
    assert!(
        took < Duration::from_millis(2500),
        "first progress after {took:?}"
    );
}

/// The real runs kept in the repository (`data/real`).
fn real_dir() -> PathBuf {
    testdata::real_dir()
}

/// Issue 23 §4: a bare CSV of another robot (no robot.toml beside it to compare) mixed in
/// with this robot's recordings was fitted as this robot's. Its travel per encoder count
/// differs: another robot's CSV (here square 04 with counts of a 1.3x finer encoder) is
/// refused, naming the file; the robot's own squares 01 and 04 still calibrate, and a
/// recording given twice is read once, with a warning. `evaluate` refuses the same set.
#[test]
fn another_robots_bare_csv_is_refused_by_name() {
    let real = real_dir();
    let dir = scratch("mixed-robots");
    let (header, rows) = table(&real.join("diff-square-run-04"));
    let (l, r) = (col(&header, "enc_left"), col(&header, "enc_right"));
    let scaled: Vec<Vec<String>> = rows
        .into_iter()
        .map(|mut row| {
            for c in [l, r] {
                if let Ok(v) = row[c].parse::<f64>() {
                    row[c] = format!("{}", (v * 1.3).round() as i64);
                }
            }
            row
        })
        .collect();
    // A bare CSV: no robot.toml beside it.
    let bare = write(&dir, "other.csv", &header, &scaled);
    let robot_file = real.join("diff-square-run-01/robot.toml");
    let run01 = real.join("diff-square-run-01");
    let run04 = real.join("diff-square-run-04");
    let calibrate = |recs: &[&Path]| {
        let mut c = wheelcal();
        c.args(["calibrate", "--no-cross-validation", "--robot"])
            .arg(&robot_file);
        for r in recs {
            c.arg("--recording").arg(r);
        }
        let o = c.output().expect("runs");
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (code, err) = calibrate(&[&run01, &run04, &bare]);
    assert_eq!(code, Some(1), "{err}");
    assert!(
        err.contains(&bare.display().to_string()) && err.contains("another robot"),
        "{err}"
    );
    assert!(
        !err.contains("diff-square-run-01 ("),
        "named this robot's run: {err}"
    );
    let (code, err) = calibrate(&[&run01, &run04, &run04]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("is given twice"), "{err}");
    // `evaluate` gathers recordings the same way and refuses the same set.
    let o = wheelcal()
        .args(["evaluate", "--robot"])
        .arg(&robot_file)
        .args(["--recording".as_ref(), run01.as_os_str()])
        .args(["--recording".as_ref(), run04.as_os_str()])
        .args(["--recording".as_ref(), bare.as_os_str()])
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(o.stdout.is_empty());
    assert!(
        err.contains(&bare.display().to_string()) && err.contains("another robot"),
        "{err}"
    );
}

/// Issue 23 §5: `calibrate` never printed the "ignored unknown column" note the file
/// format asks for. A real square with an extra `battery_v` column calibrates as before,
/// and the note names the file and the column.
#[test]
fn calibrate_notes_an_ignored_column() {
    let real = real_dir();
    let dir = scratch("unknown-column");
    let (mut header, rows) = table(&real.join("diff-square-run-01"));
    header.push("battery_v".into());
    let rows: Vec<Vec<String>> = rows
        .into_iter()
        .map(|mut r| {
            r.push("12.6".into());
            r
        })
        .collect();
    let extra = write(&dir, "extra.csv", &header, &rows);
    let o = wheelcal()
        .args(["calibrate", "--no-cross-validation", "--robot"])
        .arg(real.join("diff-square-run-01/robot.toml"))
        .arg("--recording")
        .arg(&extra)
        .output()
        .expect("runs");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains(&format!(
            "{}: ignored unknown column 'battery_v' (column {})",
            extra.display(),
            header.len()
        )),
        "{err}"
    );
}
