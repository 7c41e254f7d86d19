//! Issue 23 §5's smaller defects through the `wheelcal` binary, each as it was found:
//! `status --follow | head -1` never ended, `run` named trials for eviction that stayed,
//! damaged flash read "none saved", `factors export --from` refused calibrate's result,
//! `log pull --out x.json` wrote CSV, errors on /dev/full named nothing, and the runs-file
//! check named y_err_m for the radial error.

mod common;

use common::{robot, scratch, wheelcal, Board};
use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

fn wait(child: &mut Child, limit: Duration) -> Option<std::process::ExitStatus> {
    let t0 = Instant::now();
    while t0.elapsed() < limit {
        if let Some(s) = child.try_wait().unwrap() {
            return Some(s);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    None
}

/// `status --follow | head -1`: the reader goes after one line; wheelcal must end (it
/// wrote into a broken pipe forever, holding the port) and the port must be free.
#[test]
fn status_follow_ends_when_its_reader_goes() {
    let dir = scratch("follow");
    let board = Board::start("mobolab", &dir);
    for json in [false, true] {
        let mut c = wheelcal();
        c.arg("--port").arg(&board.link);
        if json {
            c.arg("--json");
        }
        let mut child = c
            .args(["status", "--follow", "--period-ms", "50"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        assert!(first.contains("pose") || first.contains("x_m"), "{first}");
        // The reader is gone (dropped above): wheelcal sees EPIPE at its next line.
        let status = wait(&mut child, Duration::from_secs(5));
        if status.is_none() {
            let _ = child.kill();
            panic!("json={json}: still running 5 s after its reader went");
        }
        // The port is free again.
        let (o, _, err) = board.run_text(&["info"]);
        assert!(o.status.success(), "json={json}: {err}");
    }
}

/// Trials named in `run`'s eviction note ("will evict trial(s) 1, 2 ...").
fn named(stderr: &str) -> BTreeSet<u16> {
    stderr
        .lines()
        .find(|l| l.contains("will evict trial(s)"))
        .map(|l| {
            let ids = l
                .split("trial(s) ")
                .nth(1)
                .unwrap()
                .split(" from")
                .next()
                .unwrap();
            ids.split(", ").map(|s| s.trim().parse().unwrap()).collect()
        })
        .unwrap_or_default()
}

fn stored(board: &Board) -> BTreeSet<u16> {
    let (o, out, err) = board.run_text(&["--json", "log", "list"]);
    assert!(o.status.success(), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    v["trials"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t["trial"].as_u64().unwrap() as u16)
        .collect()
}

/// `run` named trials 1-4 for eviction and none went (32 bytes a record assumed; the log
/// stores ~5). The note must name exactly the trials the run pushes out. After `log
/// clear`, `log list` must not say trials "were evicted".
#[test]
fn the_eviction_note_names_exactly_the_trials_that_go() {
    let dir = scratch("evict");
    let board = Board::start("mobolab", &dir);
    let mut evicted_any = false;
    // 1000 records/s on a 4 m square: ~360 kB a trial in a 5 MiB log.
    for run in 0..18 {
        let before = stored(&board);
        let (o, _, err) = board.run_text(&[
            "run",
            "umbmark",
            "--dir",
            "cw",
            "--side",
            "4",
            "--log-rate",
            "1000",
        ]);
        assert!(o.status.success(), "{err}");
        let after = stored(&board);
        let gone: BTreeSet<u16> = before.difference(&after).copied().collect();
        assert_eq!(named(&err), gone, "run {run}: note vs evicted\n{err}");
        evicted_any |= !gone.is_empty();
    }
    assert!(evicted_any, "the log never filled: no case tested");
    let (o, _, err) = board.run_text(&["log", "clear"]);
    assert!(o.status.success(), "{err}");
    let (o, out, err) = board.run_text(&["log", "list"]);
    assert!(o.status.success(), "{err}");
    assert!(!out.contains("evicted"), "{out}");
}

fn start_board(dir: &Path, flash: &Path) -> Board {
    let link = dir.join("board");
    // The last board was killed: its link is stale (and its pseudo-terminal number may
    // be in use again).
    let _ = std::fs::remove_file(&link);
    let child = wheelcal()
        .args(["sim-board", "--speed", "max", "--robot"])
        .arg(robot("mobolab"))
        .arg("--link")
        .arg(&link)
        .arg("--flash")
        .arg(flash)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    while !link.exists() {
        assert!(t0.elapsed() < Duration::from_secs(20), "no link");
        std::thread::sleep(Duration::from_millis(20));
    }
    Board { child, link }
}

/// A saved calibration whose flash file is damaged (truncated, bits flipped, random
/// bytes, twice the size) was mostly reported "none saved": the user must hear it was
/// lost (`corrupted`), never "none saved".
#[test]
fn damaged_flash_files_read_as_corrupted() {
    let dir = scratch("flash");
    let flash = dir.join("flash.img");
    {
        let board = start_board(&dir, &flash);
        for args in [
            &[
                "factors", "set", "--c-l", "1.01", "--c-r", "0.99", "--e-b", "1.02",
            ][..],
            &["factors", "save"],
        ] {
            let (o, _, err) = board.run_text(args);
            assert!(o.status.success(), "{args:?}: {err}");
        }
    }
    let good = std::fs::read(&flash).unwrap();
    assert_eq!(good.len(), 16384);
    // The saved image boots with the factors.
    {
        let board = start_board(&dir, &flash);
        assert_eq!(info(&board)["corrections_at_boot"], "loaded");
    }
    let written: Vec<usize> = (0..good.len()).filter(|&i| good[i] != 0xFF).collect();
    let mut seed = 0x9e37_79b9_7f4a_7c15u64;
    let mut rnd = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    let mut flipped = good.clone();
    for &i in &written {
        flipped[i] ^= 1 << (rnd() % 8);
    }
    let random: Vec<u8> = (0..good.len()).map(|_| rnd() as u8).collect();
    // Whether the saved factors may survive the damage (`loaded` with exactly the saved
    // factors is then the truth; otherwise the loss must be reported; never "none
    // saved"). A file cut or grown after the saved item holds it whole, but an image of
    // the wrong size is no flash of this board and is never loaded (issue 52 item 10).
    let cut_in_data = written[written.len() / 2];
    let cases: [(&str, Vec<u8>, bool); 5] = [
        ("truncated in the data", good[..cut_in_data].to_vec(), false),
        (
            "truncated after the data",
            good[..good.len() / 2].to_vec(),
            false,
        ),
        ("flipped bits", flipped, false),
        ("random bytes", random, false),
        ("double size", [good.clone(), good.clone()].concat(), false),
    ];
    for (what, bytes, may_survive) in cases {
        std::fs::write(&flash, &bytes).unwrap();
        let board = start_board(&dir, &flash);
        let v = info(&board);
        let state = v["corrections_at_boot"].as_str().unwrap().to_string();
        if may_survive && state == "loaded" {
            let (o, out, err) = board.run_text(&["--json", "factors", "get"]);
            assert!(o.status.success(), "{err}");
            let f: serde_json::Value = serde_json::from_str(&out).unwrap();
            assert_eq!(
                (&f["c_l"], &f["c_r"], &f["e_b"]),
                (&1.01.into(), &0.99.into(), &1.02.into()),
                "{what}: {f}"
            );
        } else {
            assert_eq!(state, "corrupted", "{what}: {v}");
        }
        drop(board);
        // A damaged file of another size is never rewritten.
        if bytes.len() != good.len() {
            assert_eq!(std::fs::read(&flash).unwrap(), bytes, "{what}");
        }
    }
}

fn info(board: &Board) -> serde_json::Value {
    let (o, out, err) = board.run_text(&["--json", "info"]);
    assert!(o.status.success(), "{err}");
    serde_json::from_str(&out).unwrap()
}

/// A simulated square of mobolab with its robot file.
fn recording(dir: &Path) -> PathBuf {
    let out = dir.join("rec");
    let o = wheelcal()
        .args([
            "sim",
            "record",
            "--seed",
            "4",
            "--umbmark-side",
            "1",
            "--robot",
        ])
        .arg(robot("mobolab"))
        .args(["--effect", "wheel_diameter_mismatch=ed:1.004"])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

/// `factors export --from calibration.json` failed (calibrate nests `factors`), and the
/// ROS 2 YAML calibrate writes said "from UMBmark factors".
#[test]
fn calibrate_results_export_to_ros2_and_say_where_they_came_from() {
    let dir = scratch("export");
    let rec = recording(&dir);
    let report = dir.join("report");
    let o = wheelcal()
        .args(["--json", "calibrate", "--no-cross-validation", "--robot"])
        .arg(rec.join("robot.toml"))
        .arg("--recording")
        .arg(&rec)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let cal: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let yaml = std::fs::read_to_string(report.join("ros2.yaml")).unwrap();
    assert!(!yaml.contains("UMBmark"), "{yaml}");
    assert!(yaml.contains("calibrate"), "{yaml}");
    let out = dir.join("ros2.yaml");
    let o = wheelcal()
        .args(["--json", "factors", "export", "--ros2"])
        .arg(&out)
        .arg("--from")
        .arg(report.join("calibration.json"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    for k in ["c_l", "c_r", "e_b"] {
        let (a, b) = (v[k].as_f64().unwrap(), cal["factors"][k].as_f64().unwrap());
        assert!((a - b).abs() < 1e-12, "{k}: {a} vs {b}");
    }
    let yaml = std::fs::read_to_string(&out).unwrap();
    assert!(
        yaml.contains("calibration.json") && !yaml.contains("UMBmark"),
        "{yaml}"
    );
}

/// `log pull --out x.json` silently wrote CSV; `--out /dev/full` and stdout on
/// /dev/full gave errors that named no file.
#[test]
fn output_names_are_checked_and_failed_writes_name_their_file() {
    let dir = scratch("pull");
    let board = Board::start("mobolab", &dir);
    let (o, _, err) = board.run_text(&["run", "umbmark", "--dir", "cw", "--side", "0.5"]);
    assert!(o.status.success(), "{err}");
    let json = dir.join("x.json");
    let (o, _, err) = board.run_text(&[
        "log",
        "pull",
        "--trial",
        "1",
        "--out",
        &json.display().to_string(),
    ]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("x.json") && err.contains(".csv") && err.contains(".mcap"),
        "{err}"
    );
    assert!(!json.exists());
    let (o, _, err) = board.run_text(&["log", "pull", "--trial", "1", "--out", "/dev/full"]);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("/dev/full"), "{err}");
    // Standard output on /dev/full.
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let o = wheelcal()
        .arg("--port")
        .arg(&board.link)
        .args(["--json", "info"])
        .stdout(full)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(err.contains("standard output"), "{err}");
}

/// The runs-file magnitude check is on the radial end error: it named y_err_m alone.
#[test]
fn the_runs_check_names_the_radial_error() {
    let dir = scratch("radial");
    let runs = dir.join("runs.csv");
    // 3 m and 3.5 m: 4.6 m radial on a 4 m UMBmark path (1 m side).
    std::fs::write(
        &runs,
        "test,path,length_m,x_err_m,y_err_m\numbmark,cw,1,3,3.5\numbmark,ccw,1,0.01,0.02\n",
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_wheelcal"))
        .args(["umbmark", "compute", "--robot"])
        .arg(robot("mobolab"))
        .arg("--runs")
        .arg(&runs)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("runs.csv:2:") && err.contains("radial"),
        "{err}"
    );
    assert!(!err.contains("column 'y_err_m'"), "{err}");
}

/// The board going away under a command said "serial I/O error: Broken pipe" without
/// naming the port.
#[test]
fn a_port_that_breaks_is_named() {
    let dir = scratch("broken-port");
    let mut board = Board::start_at("mobolab", &dir, "1");
    let mut child = wheelcal()
        .arg("--port")
        .arg(&board.link)
        .args(["status", "--follow"])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(1500));
    let _ = board.child.kill();
    let _ = board.child.wait();
    let Some(status) = wait(&mut child, Duration::from_secs(10)) else {
        let _ = child.kill();
        panic!("status --follow still running 10 s after its board went");
    };
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(status.code(), Some(1), "{err}");
    assert!(err.contains(&board.link.display().to_string()), "{err}");
}

/// UMBmark on a skid-steer robot: its closed form assumes errors of a few per cent, and
/// such a robot's E_b is 1.5-2; the refusal says to use `calibrate` instead.
#[test]
fn umbmark_refuses_a_skid_steer_robot_and_names_calibrate() {
    let dir = scratch("skid-umbmark");
    let runs = dir.join("runs.csv");
    std::fs::write(
        &runs,
        "test,path,length_m,x_err_m,y_err_m\numbmark,cw,1,0.01,0.02\numbmark,cw,1,0.01,0.02\numbmark,ccw,1,0.01,0.02\numbmark,ccw,1,0.01,0.02\n",
    )
    .unwrap();
    let o = Command::new(env!("CARGO_BIN_EXE_wheelcal"))
        .args(["umbmark", "compute", "--robot"])
        .arg(robot("rover4"))
        .arg("--runs")
        .arg(&runs)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("skid_steer") && err.contains("wheelcal calibrate"),
        "{err}"
    );
}
