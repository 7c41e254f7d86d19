//! Stopping a robot from the host, whatever the console is doing.
//!
//! - **Ctrl-C.** One SIGINT/SIGTERM handler for the process. Inside a [`Guard`] (a drive,
//!   a program being waited for, a log pull, a procedure, `status --follow`, a command in
//!   `wheelcal console`) it only raises a flag: the loop that moves the robot sees it
//!   within one poll, sends Stop and returns [`Interrupted`]. Outside any guard nothing can
//!   be moving, and the process exits at once with status 130.
//! - **E-stop from another terminal.** A serial port is opened exclusively, so a second
//!   `wheelcal estop` cannot open it while another wheelcal holds it. The holder therefore
//!   listens on a Unix socket named after the port ([`socket_path`]) and, on request,
//!   writes an E-stop frame straight onto the port from its listener thread (under the
//!   same write lock as its own frames), then answers with the time that took. `wheelcal
//!   estop` tries that socket first and opens the port itself only when nobody holds it.

use anyhow::{Context, Result};
use calib_core::protocol::{encode, Request, MAX_WIRE};
use std::io::{BufRead, BufReader, Read, Write};
use std::os::unix::net::{UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Once};
use std::time::{Duration, Instant};

static REQUESTED: AtomicBool = AtomicBool::new(false);
static GUARDS: AtomicUsize = AtomicUsize::new(0);
static INSTALL: Once = Once::new();

/// Installs the process's SIGINT/SIGTERM handler (idempotent).
pub fn install() {
    INSTALL.call_once(|| {
        let _ = ctrlc::set_handler(|| {
            if GUARDS.load(Ordering::SeqCst) == 0 {
                std::process::exit(130);
            }
            REQUESTED.store(true, Ordering::SeqCst);
        });
    });
}

/// Whether Ctrl-C (or SIGTERM) arrived inside the current guard.
pub fn requested() -> bool {
    REQUESTED.load(Ordering::SeqCst)
}

/// While alive, Ctrl-C raises [`requested`] instead of ending the process.
pub struct Guard(());

impl Guard {
    /// Starts a section in which the caller polls [`requested`] and stops the robot.
    pub fn new() -> Guard {
        install();
        if GUARDS.fetch_add(1, Ordering::SeqCst) == 0 {
            REQUESTED.store(false, Ordering::SeqCst);
        }
        Guard(())
    }
}

impl Default for Guard {
    fn default() -> Self {
        Self::new()
    }
}

impl Drop for Guard {
    fn drop(&mut self) {
        if GUARDS.fetch_sub(1, Ordering::SeqCst) == 1 {
            REQUESTED.store(false, Ordering::SeqCst);
        }
    }
}

/// The error a guarded loop returns after Ctrl-C, once it has sent Stop and watched the
/// robot come to rest (a program's Stop ramps down at the acceleration limit: "the motors
/// are off" at the moment Stop was sent would be false for a good half second).
#[derive(Debug)]
pub struct Interrupted {
    /// How long after Stop the board reported every wheel at rest; `None`: it had not
    /// within [`REST_TIMEOUT`] (or could not be asked).
    pub came_to_rest_after: Option<Duration>,
}

/// How long to watch for standstill after Ctrl-C before saying it was not confirmed.
pub const REST_TIMEOUT: Duration = Duration::from_secs(3);

/// A wheel commanded and measured slower than this (rad/s) is at rest: below one encoder
/// count per 8 ms rate window of a 1920-count wheel (0.41 rad/s), so the estimate reads 0.
pub const REST_RATE: f32 = 0.05;

impl std::fmt::Display for Interrupted {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.came_to_rest_after {
            Some(t) => write!(
                f,
                "interrupted (Ctrl-C): sent Stop; the robot came to rest {} ms later",
                t.as_millis()
            ),
            None => write!(
                f,
                "interrupted (Ctrl-C): sent Stop, but standstill was not confirmed within {} s: \
                 check the robot (`wheelcal estop` cuts the motors)",
                REST_TIMEOUT.as_secs()
            ),
        }
    }
}

impl std::error::Error for Interrupted {}

/// The socket a port's holder listens on: one per port, whichever name (a link or the
/// device it points at) each process used.
pub fn socket_path(port: &str) -> PathBuf {
    let real = std::fs::canonicalize(port).unwrap_or_else(|_| PathBuf::from(port));
    let name: String = real
        .to_string_lossy()
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() { c } else { '_' })
        .collect();
    std::env::temp_dir().join(format!("wheelcal-estop{name}.sock"))
}

/// A serial port whose writes hold a lock shared with the E-stop relay, so a relayed
/// frame never lands in the middle of one of the console's own frames.
pub struct LockedPort {
    port: Box<dyn serialport::SerialPort>,
    lock: Arc<Mutex<()>>,
}

impl Read for LockedPort {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        self.port.read(buf)
    }
}

impl Write for LockedPort {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let _held = self.lock.lock().unwrap_or_else(|p| p.into_inner());
        self.port.write(buf)
    }
    fn flush(&mut self) -> std::io::Result<()> {
        self.port.flush()
    }
}

/// The listener of a port's holder; removes its socket when dropped.
pub struct Relay {
    path: PathBuf,
    stop: Arc<AtomicBool>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Wraps an opened port for the console and starts relaying E-stops to it. Without a
/// relay (the socket cannot be made) the console still works: only the second terminal's
/// E-stop needs it, and `wheelcal estop` then says the port is busy.
pub fn hold(port_name: &str, port: Box<dyn serialport::SerialPort>) -> (LockedPort, Option<Relay>) {
    let lock = Arc::new(Mutex::new(()));
    let relay = match port.try_clone() {
        Ok(writer) => match start_relay(&socket_path(port_name), writer, lock.clone()) {
            Ok(r) => Some(r),
            Err(e) => {
                eprintln!("note: {e:#}: `wheelcal estop` from another terminal cannot reach this port while this command holds it");
                None
            }
        },
        Err(_) => None,
    };
    (LockedPort { port, lock }, relay)
}

fn start_relay(
    path: &Path,
    mut writer: Box<dyn serialport::SerialPort>,
    lock: Arc<Mutex<()>>,
) -> Result<Relay> {
    // A socket left by a holder that died is stale: nobody answers on it. Anything else
    // at that path is somebody's file: never deleted (no relay then).
    crate::output::check_stale_socket(path)?;
    if path.exists() && UnixStream::connect(path).is_err() {
        let _ = std::fs::remove_file(path);
    }
    let listener =
        UnixListener::bind(path).with_context(|| format!("cannot listen on {}", path.display()))?;
    listener.set_nonblocking(true)?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    // A delimiter first ends whatever partial frame the line holds; the sequence number
    // is one the console never waits for, so the board's answer is skipped as stale.
    let mut frame = vec![0u8];
    let mut wire = [0u8; MAX_WIRE];
    frame.extend_from_slice(encode(0xE5E5, &Request::EStop, &mut wire)?);
    std::thread::spawn(move || {
        while !stop2.load(Ordering::SeqCst) {
            match listener.accept() {
                Ok((mut conn, _)) => {
                    let mut line = String::new();
                    let _ = conn.set_read_timeout(Some(Duration::from_millis(200)));
                    let _ = BufReader::new(&conn).read_line(&mut line);
                    if line.trim() == "estop" {
                        let t0 = Instant::now();
                        let ok = {
                            let _held = lock.lock().unwrap_or_else(|p| p.into_inner());
                            writer
                                .write_all(&frame)
                                .and_then(|_| writer.flush())
                                .is_ok()
                        };
                        let us = t0.elapsed().as_micros();
                        let _ = writeln!(conn, "{} {us}", if ok { "ok" } else { "failed" });
                    }
                }
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            }
        }
    });
    Ok(Relay {
        path: path.to_path_buf(),
        stop,
    })
}

/// How an E-stop reached a port another wheelcal holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relayed {
    /// From asking to the holder's confirmation that the frame is on the port.
    pub elapsed: Duration,
    /// The holder was stopped (Ctrl-Z, SIGSTOP) and did not answer within
    /// [`WAKE_AFTER`]: its process id, sent SIGCONT so that its relay could write.
    pub woke_pid: Option<i32>,
}

/// How long a holder may take to confirm before it is taken for stopped and woken.
pub const WAKE_AFTER: Duration = Duration::from_millis(100);

/// What [`relay_estop`] found.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RelayOutcome {
    /// Nobody holds the port: open it yourself.
    NotHeld,
    /// The holder wrote the E-stop to the port.
    Relayed(Relayed),
    /// The holder (this process id) died while asked: the port is free, open it yourself.
    HolderGone(i32),
}

/// Asks the process holding `port` to send an E-stop. A holder that does not confirm
/// within [`WAKE_AFTER`] is taken for suspended (Ctrl-Z, SIGSTOP: all its threads stand,
/// the relay's too) and sent SIGCONT, its process id read from the socket's peer
/// credentials; its relay then writes the frame. A holder that is gone leaves the port to
/// the caller.
pub fn relay_estop(port: &str) -> Result<RelayOutcome> {
    let path = socket_path(port);
    let t0 = Instant::now();
    let Ok(mut conn) = UnixStream::connect(&path) else {
        return Ok(RelayOutcome::NotHeld);
    };
    let pid = holder_pid(&conn);
    writeln!(conn, "estop")?;
    let mut reader = BufReader::new(conn.try_clone()?);
    let mut answer = String::new();
    conn.set_read_timeout(Some(WAKE_AFTER))?;
    let mut woke_pid = None;
    if reader.read_line(&mut answer).is_err() {
        // No answer in time: a suspended holder cannot relay. Wake it.
        let Some(pid) = pid else {
            anyhow::bail!(
                "the wheelcal holding {port} did not confirm the E-stop within {} ms, and its \
                 process id could not be read to wake it",
                WAKE_AFTER.as_millis()
            );
        };
        if !wake(pid) {
            return Ok(RelayOutcome::HolderGone(pid));
        }
        woke_pid = Some(pid);
        conn.set_read_timeout(Some(Duration::from_secs(1)))?;
        answer.clear();
        if reader.read_line(&mut answer).is_err() || answer.is_empty() {
            if !alive(pid) {
                return Ok(RelayOutcome::HolderGone(pid));
            }
            anyhow::bail!(
                "the wheelcal holding {port} (process {pid}) did not confirm the E-stop even \
                 after being woken: stop the robot by hand"
            );
        }
    }
    match answer.split_whitespace().next() {
        Some("ok") => Ok(RelayOutcome::Relayed(Relayed {
            elapsed: t0.elapsed(),
            woke_pid,
        })),
        None if pid.is_some_and(|p| !alive(p)) => Ok(RelayOutcome::HolderGone(pid.unwrap_or(0))),
        _ => anyhow::bail!(
            "the wheelcal holding {port} could not write the E-stop to the port ({})",
            answer.trim()
        ),
    }
}

/// The process at the other end of a Unix socket (SO_PEERCRED).
fn holder_pid(conn: &UnixStream) -> Option<i32> {
    use nix::sys::socket::{getsockopt, sockopt::PeerCredentials};
    getsockopt(conn, PeerCredentials).ok().map(|c| c.pid())
}

/// Sends SIGCONT; false when the process does not exist.
fn wake(pid: i32) -> bool {
    use nix::sys::signal::{kill, Signal};
    kill(nix::unistd::Pid::from_raw(pid), Signal::SIGCONT).is_ok()
}

/// Whether a process exists (signal 0) and is not a zombie.
fn alive(pid: i32) -> bool {
    let exists = nix::sys::signal::kill(nix::unistd::Pid::from_raw(pid), None).is_ok();
    let zombie = std::fs::read_to_string(format!("/proc/{pid}/stat"))
        .ok()
        .and_then(|s| {
            s.rsplit_once(')')
                .map(|(_, r)| r.trim_start().starts_with('Z'))
        })
        .unwrap_or(false);
    exists && !zombie
}
