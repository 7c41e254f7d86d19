//! Issue 52.1: the second terminal's `wheelcal estop` must reach the console that holds
//! the port whatever sits in the file system or the abstract socket namespace: a regular
//! file where the old relay's socket was, the two terminals with different `TMPDIR`s, the
//! relay's name taken by an impostor that answers "ok" without doing anything. Real
//! processes against a real-time `wheelcal sim-board`; the robot must stand within
//! 0.6 s of the moment `wheelcal estop` was started.

mod common;

use common::{pose_of, scratch, wait_exit, wait_until_held, wheelcal, Board};
use serde_json::Value;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Where the relay of wheelcal up to issue 52 listened: `$TMPDIR/wheelcal-estop<dev>.sock`.
fn old_socket_path(tmpdir: &Path, link: &Path) -> PathBuf {
    let real = std::fs::canonicalize(link).unwrap();
    let name: String = real
        .to_string_lossy()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    tmpdir.join(format!("wheelcal-estop{name}.sock"))
}

fn last_trial(board: &Board) -> Value {
    let o = board.run(&["--json", "log", "list"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: Value = serde_json::from_slice(&o.stdout).expect("log list JSON");
    v["trials"]
        .as_array()
        .and_then(|t| t.last())
        .cloned()
        .expect("a trial")
}

/// A console driving a 4 m square (link failsafe off: only the E-stop can stop it), with
/// `TMPDIR` = `tmpdir`.
fn holder(board: &Board, tmpdir: &Path) -> Child {
    let run = wheelcal()
        .env("TMPDIR", tmpdir)
        .arg("--port")
        .arg(&board.link)
        .args([
            "--json",
            "run",
            "umbmark",
            "--dir",
            "cw",
            "--side",
            "4",
            "--no-link-failsafe",
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("run starts");
    wait_until_held(&board.link, run.id());
    run
}

/// 1.5 s into the holder's square (suspended by SIGSTOP 0.3 s before if `suspend`),
/// `wheelcal --json estop` with `TMPDIR` = `tmpdir`;
/// asserts that it succeeded, that the board latched the E-stop and ended the trial for
/// it within 0.6 s of the estop's start, and that the robot stands. Returns the estop's
/// JSON.
fn estop_stops_the_square(board: &Board, mut run: Child, tmpdir: &Path, suspend: bool) -> Value {
    if suspend {
        std::thread::sleep(Duration::from_millis(1200));
        common::signal(&run, "-STOP");
        std::thread::sleep(Duration::from_millis(300));
    } else {
        std::thread::sleep(Duration::from_millis(1500));
    }
    let t_estop = Instant::now();
    let o = wheelcal()
        .env("TMPDIR", tmpdir)
        .arg("--port")
        .arg(&board.link)
        .args(["--json", "estop"])
        .stdin(Stdio::null())
        .output()
        .unwrap();
    let took = t_estop.elapsed();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    if !o.status.success() {
        let _ = run.kill();
        let _ = run.wait();
        panic!("estop failed after {} ms: {err}", took.as_millis());
    }
    let v: Value = serde_json::from_slice(&o.stdout).expect("estop JSON");
    assert_eq!(v["estop"], true, "{v}");
    // The holder sees the latched board and ends; then the board can be asked.
    wait_exit(
        &mut run,
        Duration::from_secs(5),
        "the console never ended after the E-stop",
    );
    let t_query = Instant::now();
    let s = board.status();
    let since_query = t_query.elapsed().as_secs_f64() / 2.0;
    assert_eq!(s["estop"], true, "{s}");
    let trial = last_trial(board);
    assert_eq!(trial["end"], "estop", "{trial}");
    // When the board cut the program, on the test's clock (the board runs in real time).
    let uptime_s = s["uptime_ms"].as_f64().unwrap() / 1e3;
    let start_s = trial["start_s"].as_f64().unwrap();
    let length_s = trial["records"].as_f64().unwrap() / trial["rate_hz"].as_f64().unwrap();
    let query_after_estop = (t_query - t_estop).as_secs_f64() + since_query;
    let cut_after_estop = query_after_estop - (uptime_s - start_s - length_s);
    println!(
        "estop ran {} ms; program cut {:.0} ms after it started ({v})",
        took.as_millis(),
        cut_after_estop * 1e3
    );
    // -50 ms: the trial log's record period and the status round trip.
    assert!(
        (-0.05..=0.6).contains(&cut_after_estop),
        "the robot stood {cut_after_estop:.3} s after `wheelcal estop` started"
    );
    let a = pose_of(&s);
    std::thread::sleep(Duration::from_millis(300));
    let b = pose_of(&board.status());
    assert!(
        (a.0 - b.0).hypot(a.1 - b.1) < 1e-4,
        "moving: {a:?} -> {b:?}"
    );
    // Cut on the first 4 m leg, 1.5 s in at most 0.3 m/s.
    assert!(a.0.hypot(a.1) < 0.6, "drove to {a:?}");
    v
}

/// (a) A regular file where the old relay's socket was (for both processes' `TMPDIR`):
/// the old holder could not listen and `wheelcal estop` failed with "Unable to acquire
/// exclusive lock" while the square ran on.
#[test]
fn estop_stops_the_robot_with_a_file_at_the_old_socket_path() {
    let dir = scratch("estop-file");
    let tmp = dir.join("tmp");
    std::fs::create_dir_all(&tmp).unwrap();
    let board = Board::start_at("mobolab", &dir, "1");
    let squatted = old_socket_path(&tmp, &board.link);
    std::fs::write(&squatted, b"somebody's file\n").unwrap();
    let run = holder(&board, &tmp);
    estop_stops_the_square(&board, run, &tmp, false);
    assert_eq!(std::fs::read(&squatted).unwrap(), b"somebody's file\n");
}

/// (b) The holder and `wheelcal estop` with different `TMPDIR`s (tmux, sudo, a service).
#[test]
fn estop_stops_the_robot_across_different_tmpdirs() {
    let dir = scratch("estop-tmpdirs");
    let (tmp_a, tmp_b) = (dir.join("a"), dir.join("b"));
    std::fs::create_dir_all(&tmp_a).unwrap();
    std::fs::create_dir_all(&tmp_b).unwrap();
    let board = Board::start_at("mobolab", &dir, "1");
    let run = holder(&board, &tmp_a);
    estop_stops_the_square(&board, run, &tmp_b, false);
}

/// The abstract socket name the relay listens on for `link` (as the console names it).
fn relay_name(link: &Path) -> String {
    let real = std::fs::canonicalize(link).unwrap();
    format!("wheelcal-estop{}", real.display())
}

/// A process (this test) that took the relay's abstract name and answers every E-stop
/// request with "ok" without doing anything, until dropped.
struct Impostor {
    asked: Arc<AtomicUsize>,
    done: Arc<AtomicBool>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Impostor {
    fn squat(link: &Path) -> Impostor {
        use std::os::linux::net::SocketAddrExt;
        use std::os::unix::net::{SocketAddr, UnixListener};
        let addr = SocketAddr::from_abstract_name(relay_name(link).as_bytes()).unwrap();
        let impostor = UnixListener::bind_addr(&addr).expect("the name is free");
        impostor.set_nonblocking(true).unwrap();
        let asked = Arc::new(AtomicUsize::new(0));
        let done = Arc::new(AtomicBool::new(false));
        let (asked2, done2) = (asked.clone(), done.clone());
        let thread = std::thread::spawn(move || {
            while !done2.load(Ordering::SeqCst) {
                let Ok((mut conn, _)) = impostor.accept() else {
                    std::thread::sleep(Duration::from_millis(2));
                    continue;
                };
                let _ = conn.set_nonblocking(false);
                let _ = conn.set_read_timeout(Some(Duration::from_millis(200)));
                let mut line = String::new();
                let _ = BufReader::new(&conn).read_line(&mut line);
                if line.trim() == "estop" {
                    asked2.fetch_add(1, Ordering::SeqCst);
                    let _ = writeln!(conn, "ok 1");
                }
            }
        });
        Impostor {
            asked,
            done,
            thread: Some(thread),
        }
    }

    /// How many E-stop requests it was sent.
    fn asked(&self) -> usize {
        self.asked.load(Ordering::SeqCst)
    }
}

impl Drop for Impostor {
    // The name is free again when the test ends: the next test's board may get the same
    // terminal.
    fn drop(&mut self) {
        self.done.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// (c) Another process took the relay's abstract name before the console opened the port
/// and answers every request with "ok" without doing anything: `wheelcal estop` must see
/// that the answering process does not hold the port, and reach the holder anyway.
#[test]
fn estop_stops_the_robot_when_an_impostor_holds_the_relay_name() {
    let dir = scratch("estop-impostor");
    let board = Board::start_at("mobolab", &dir, "1");
    let impostor = Impostor::squat(&board.link);
    let run = holder(&board, &std::env::temp_dir());
    let v = estop_stops_the_square(&board, run, &std::env::temp_dir(), false);
    let me = std::process::id() as u64;
    assert_eq!(v["impostor_pid"].as_u64(), Some(me), "{v}");
    assert_eq!(v["relayed_via"], "signal", "{v}");
    assert_eq!(
        impostor.asked(),
        0,
        "the impostor was trusted with the request"
    );
}

/// (c) with the holder suspended (Ctrl-Z, SIGSTOP) as well: found from the port, woken
/// with SIGCONT, and its relay writes the E-stop.
#[test]
fn estop_wakes_a_suspended_holder_when_an_impostor_holds_the_relay_name() {
    let dir = scratch("estop-impostor-stopped");
    let board = Board::start_at("mobolab", &dir, "1");
    let impostor = Impostor::squat(&board.link);
    let run = holder(&board, &std::env::temp_dir());
    let pid = run.id() as u64;
    let v = estop_stops_the_square(&board, run, &std::env::temp_dir(), true);
    assert_eq!(v["woke_pid"].as_u64(), Some(pid), "{v}");
    assert_eq!(v["relayed_via"], "signal", "{v}");
    assert_eq!(
        impostor.asked(),
        0,
        "the impostor was trusted with the request"
    );
}

/// A port held by a program that is not a wheelcal cannot be relayed to: `wheelcal
/// estop` fails and names the process (pid and name) that holds it.
#[test]
fn estop_names_a_holder_that_is_not_a_wheelcal() {
    let dir = scratch("estop-other");
    let board = Board::start("mobolab", &dir);
    let held = serialport::new(board.link.to_str().unwrap(), 115_200)
        .timeout(Duration::from_millis(20))
        .open()
        .expect("the test opens the port exclusively");
    let o = board.run(&["estop"]);
    drop(held);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let me = std::process::id().to_string();
    let comm = std::fs::read_to_string("/proc/self/comm").unwrap();
    assert!(
        err.contains(&me) && err.contains(comm.trim()),
        "the holder (process {me}, {}) not named: {err}",
        comm.trim()
    );
}
