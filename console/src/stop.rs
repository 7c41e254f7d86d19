//! Stopping a robot from the host, whatever the console is doing.
//!
//! - **Ctrl-C.** One SIGINT/SIGTERM handler for the process. Inside a [`Guard`] (a drive,
//!   a program being waited for, a log pull, a procedure, `status --follow`, a command in
//!   `wheelcal console`) it only raises a flag: the loop that moves the robot sees it
//!   within one poll, sends Stop and returns [`Interrupted`]. Outside any guard nothing can
//!   be moving, and the process exits at once with status 130.
//! - **E-stop from another terminal.** A serial port is opened exclusively, so a second
//!   `wheelcal estop` cannot open it while another wheelcal holds it. The holder writes
//!   the E-stop frame for it (from a thread of its own, under the same write lock as its
//!   own frames), reached by one of two ways that depend on no file and no `TMPDIR`:
//!   1. **The relay socket**: a Linux abstract-namespace Unix socket named after the
//!      canonical device ([`relay_name`]). `wheelcal estop` connects there first, and
//!      trusts the answering process only if SO_PEERCRED names a process that really has
//!      the device open (its `/proc/PID/fd` links resolve to it): anybody can take an
//!      abstract name, so one held by another process is an impostor and is not asked.
//!   2. **The port itself**: when no genuine relay answers (the name taken, the holder's
//!      relay not started), `wheelcal estop` looks for the process that has the device
//!      open in `/proc/*/fd`. A wheelcal is sent [`RELAY_SIGNAL`] (SIGUSR1; every
//!      wheelcal installs its handler first thing in `main`, and a thread of a process
//!      holding a port answers it), on which it writes the E-stop frame and confirms on
//!      an abstract socket named after its own process id, which `wheelcal estop`
//!      listens on and whose caller it checks by SO_PEERCRED again. A wheelcal with the
//!      device open that holds no port (a virtual board keeps its terminal's other end
//!      open) answers so. Any other holder is named (pid and program) in the error: it
//!      cannot relay.
//!
//!   Either way a holder stopped by Ctrl-Z or SIGSTOP is sent SIGCONT so that it can
//!   write. Nobody holding the port: `wheelcal estop` opens it and sends the E-stop
//!   itself.

use anyhow::{Context, Result};
use calib_core::protocol::{encode, Request, MAX_WIRE};
use nix::sys::signal::{kill, SigSet, Signal};
use std::io::{BufRead, BufReader, Read, Write};
use std::os::linux::net::SocketAddrExt;
use std::os::unix::net::{SocketAddr, UnixListener, UnixStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicI32;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::OnceLock;
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

/// The abstract socket name (no file: nothing to squat in the file system, no `TMPDIR`)
/// on which the holder of `port` relays E-stops: one per device, whichever name (a link
/// or the device it points at) each process used.
pub fn relay_name(port: &str) -> String {
    let real = std::fs::canonicalize(port).unwrap_or_else(|_| PathBuf::from(port));
    format!("wheelcal-estop{}", real.display())
}

/// The abstract name on which `wheelcal estop` hears the confirmation of the holder with
/// process id `holder` after signalling it.
fn ack_name(holder: i32) -> String {
    format!("wheelcal-estop-ack{holder}")
}

fn abstract_addr(name: &str) -> std::io::Result<SocketAddr> {
    SocketAddr::from_abstract_name(name.as_bytes())
}

/// The signal on which a wheelcal that holds a port writes an E-stop frame to it and
/// confirms on the abstract socket named after its process id.
pub const RELAY_SIGNAL: Signal = Signal::SIGUSR1;

static SIGNAL_THREAD: Once = Once::new();
static NEXT_HOLD: AtomicUsize = AtomicUsize::new(1);
/// The write end of the pipe the signal handler wakes the relay thread through (-1:
/// none); never closed, so the handler never writes to a reused descriptor.
static WAKE_FD: AtomicI32 = AtomicI32::new(-1);
static WAKE_RX: OnceLock<UnixStream> = OnceLock::new();

/// The port the signal relay writes to: the current hold's number, a writer, the lock
/// shared with the console's own frames.
type Held = (usize, Box<dyn serialport::SerialPort>, Arc<Mutex<()>>);
static HELD: Mutex<Option<Held>> = Mutex::new(None);

/// [`RELAY_SIGNAL`]'s handler: one byte into the relay's pipe (write(2) is
/// async-signal-safe; the descriptor is non-blocking, so a full pipe loses nothing that
/// matters: the relay thread has requests waiting anyway).
#[allow(unsafe_code)]
extern "C" fn on_relay_signal(_: nix::libc::c_int) {
    let fd = WAKE_FD.load(Ordering::SeqCst);
    if fd >= 0 {
        let byte = 1u8;
        // SAFETY: `fd` is the write end of a pipe this process made and never closes;
        // write(2) of one byte from a local is async-signal-safe.
        unsafe {
            nix::libc::write(fd, (&byte as *const u8).cast(), 1);
        }
    }
}

/// Installs [`RELAY_SIGNAL`]'s handler (call first thing in `main`, before any thread
/// starts). Blocking the signal alone would not do: the serial port library waits in
/// `ppoll` with an empty signal mask, and the signal's default action (ending the
/// process) would then kill a console that is only being asked to relay. Until a port is held (or a virtual board serves, which keeps
/// its terminal's other end open) nobody reads the pipe and the signal does nothing.
pub fn install_relay_signal() {
    use nix::sys::signal::{SaFlags, SigAction, SigHandler};
    use std::os::fd::IntoRawFd;
    if WAKE_RX.get().is_some() {
        return;
    }
    let Ok((rx, tx)) = UnixStream::pair() else {
        return;
    };
    if tx.set_nonblocking(true).is_err() || WAKE_RX.set(rx).is_err() {
        return;
    }
    WAKE_FD.store(tx.into_raw_fd(), Ordering::SeqCst);
    let action = SigAction::new(
        SigHandler::Handler(on_relay_signal),
        SaFlags::SA_RESTART,
        SigSet::empty(),
    );
    install_handler(&action);
    // Blocked in this (the main) thread and so in every thread started after it; the
    // relay thread unblocks it. The signal then wakes that thread, and interrupts the
    // console's own system calls only inside the serial library's `ppoll` (which opens
    // the mask, and whose interruption reads as a timeout).
    let mut set = SigSet::empty();
    set.add(RELAY_SIGNAL);
    let _ = set.thread_block();
}

#[allow(unsafe_code)]
fn install_handler(action: &nix::sys::signal::SigAction) {
    // SAFETY: the handler only loads an atomic and calls write(2), both
    // async-signal-safe.
    let _ = unsafe { nix::sys::signal::sigaction(RELAY_SIGNAL, action) };
}

/// Starts the thread that answers [`RELAY_SIGNAL`] (once per process; needs
/// [`install_relay_signal`]): it writes the E-stop to the port held at that moment, or
/// answers that this process holds none (a virtual board has its terminal open too).
pub fn serve_relay_signal() {
    let Some(rx) = WAKE_RX.get() else {
        return;
    };
    SIGNAL_THREAD.call_once(|| {
        // Signals that came before anybody listened asked for nothing held now.
        let mut stale = [0u8; 64];
        if rx.set_nonblocking(true).is_ok() {
            while matches!((&*rx).read(&mut stale), Ok(n) if n > 0) {}
        }
        if rx.set_nonblocking(false).is_ok() {
            std::thread::spawn(move || signal_relay(rx));
        }
    });
}

/// The frame a relay writes: a delimiter first ends whatever partial frame the line
/// holds; the sequence number is one the console never waits for, so the board's answer
/// is skipped as stale.
fn estop_frame() -> Vec<u8> {
    let mut frame = vec![0u8];
    let mut wire = [0u8; MAX_WIRE];
    if let Ok(f) = encode(0xE5E5, &Request::EStop, &mut wire) {
        frame.extend_from_slice(f);
    }
    frame
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

/// The relays of a port's holder; ends them when dropped (the abstract name goes with
/// the listener).
pub struct Relay {
    hold: usize,
    stop: Option<Arc<AtomicBool>>,
}

impl Drop for Relay {
    fn drop(&mut self) {
        if let Some(stop) = &self.stop {
            stop.store(true, Ordering::SeqCst);
        }
        let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
        if held.as_ref().is_some_and(|h| h.0 == self.hold) {
            *held = None;
        }
    }
}

/// Wraps an opened port for the console and starts relaying E-stops to it: on the relay
/// socket when its name is free, and on [`RELAY_SIGNAL`] always (once `main` installed
/// its handler).
/// Without a relay the console still works: only the second terminal's E-stop needs it.
pub fn hold(port_name: &str, port: Box<dyn serialport::SerialPort>) -> (LockedPort, Option<Relay>) {
    let lock = Arc::new(Mutex::new(()));
    let hold = NEXT_HOLD.fetch_add(1, Ordering::SeqCst);
    let mut relay = None;
    if WAKE_RX.get().is_some() {
        if let Ok(writer) = port.try_clone() {
            *HELD.lock().unwrap_or_else(|p| p.into_inner()) = Some((hold, writer, lock.clone()));
            serve_relay_signal();
            relay = Some(Relay { hold, stop: None });
        }
    }
    // A name another process took leaves the signal relay: `wheelcal estop` finds this
    // process from the port and signals it.
    if let Ok(writer) = port.try_clone() {
        if let Ok(stop) = start_socket_relay(&relay_name(port_name), writer, lock.clone()) {
            relay = Some(Relay {
                hold,
                stop: Some(stop),
            });
        }
    }
    (LockedPort { port, lock }, relay)
}

/// Writes the E-stop frame under the console's write lock; whether it went out, and the
/// microseconds that took.
fn write_estop(writer: &mut dyn serialport::SerialPort, lock: &Mutex<()>) -> (bool, u128) {
    let frame = estop_frame();
    let t0 = Instant::now();
    let ok = {
        let _held = lock.lock().unwrap_or_else(|p| p.into_inner());
        writer
            .write_all(&frame)
            .and_then(|_| writer.flush())
            .is_ok()
    };
    (ok, t0.elapsed().as_micros())
}

/// The thread that answers [`RELAY_SIGNAL`] for the process's life (woken through the
/// handler's pipe): writes the E-stop to the port held at that moment and confirms.
fn signal_relay(rx: &'static UnixStream) {
    let mut set = SigSet::empty();
    set.add(RELAY_SIGNAL);
    let _ = set.thread_unblock();
    let mut wake = [0u8; 64];
    loop {
        match (&*rx).read(&mut wake) {
            Ok(n) if n > 0 => {}
            Ok(_) => return, // the write end is never closed: not reached
            Err(_) => {
                std::thread::sleep(Duration::from_millis(5));
                continue;
            }
        }
        let answer = {
            let mut held = HELD.lock().unwrap_or_else(|p| p.into_inner());
            match held.as_mut() {
                Some((_, writer, lock)) => {
                    let (ok, us) = write_estop(writer.as_mut(), lock);
                    format!("{} {us}", if ok { "ok" } else { "failed" })
                }
                None => "idle".to_string(), // no port held here (a virtual board)
            }
        };
        let me = std::process::id() as i32;
        if let Ok(mut conn) =
            abstract_addr(&ack_name(me)).and_then(|a| UnixStream::connect_addr(&a))
        {
            let _ = conn.set_write_timeout(Some(Duration::from_millis(200)));
            let _ = writeln!(conn, "{answer}");
        }
    }
}

fn start_socket_relay(
    name: &str,
    mut writer: Box<dyn serialport::SerialPort>,
    lock: Arc<Mutex<()>>,
) -> Result<Arc<AtomicBool>> {
    let listener = abstract_addr(name)
        .and_then(|a| UnixListener::bind_addr(&a))
        .with_context(|| format!("cannot listen on the abstract socket {name}"))?;
    listener.set_nonblocking(true)?;
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    std::thread::spawn(move || {
        while !stop2.load(Ordering::SeqCst) {
            match listener.accept() {
                Ok((mut conn, _)) => {
                    let mut line = String::new();
                    let _ = conn.set_nonblocking(false);
                    let _ = conn.set_read_timeout(Some(Duration::from_millis(200)));
                    let _ = BufReader::new(&conn).read_line(&mut line);
                    if line.trim() == "estop" {
                        let (ok, us) = write_estop(writer.as_mut(), &lock);
                        let _ = writeln!(conn, "{} {us}", if ok { "ok" } else { "failed" });
                    }
                }
                Err(_) => std::thread::sleep(Duration::from_millis(5)),
            }
        }
    });
    Ok(stop)
}

/// How the E-stop request reached the holder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Via {
    /// Its relay socket.
    Socket,
    /// [`RELAY_SIGNAL`], the holder found from the port.
    Signal,
}

/// How an E-stop reached a port another wheelcal holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Relayed {
    /// From asking to the holder's confirmation that the frame is on the port.
    pub elapsed: Duration,
    /// The holder was stopped (Ctrl-Z, SIGSTOP): its process id, sent SIGCONT so that
    /// its relay could write.
    pub woke_pid: Option<i32>,
    /// The holder's process id.
    pub holder_pid: Option<i32>,
    /// The way the request went.
    pub via: Via,
    /// Whether the answering process was seen to hold the port (false: its
    /// `/proc/PID/fd` could not be read, as for another user's process).
    pub verified: bool,
}

/// How long a holder may take to confirm before it is taken for stopped and woken.
pub const WAKE_AFTER: Duration = Duration::from_millis(100);

/// How long a woken or signalled holder may take to confirm before `estop` fails.
pub const CONFIRM_WITHIN: Duration = Duration::from_secs(1);

/// What [`relay_estop`] found.
#[derive(Debug, Clone, PartialEq)]
pub enum RelayOutcome {
    /// Nobody (that this user can see) holds the port: open it yourself.
    NotHeld,
    /// The holder wrote the E-stop to the port.
    Relayed(Relayed),
    /// The holder (this process id) died while asked: the port is free, open it yourself.
    HolderGone(i32),
    /// A program that is not a wheelcal has the port open: it cannot relay. Try the port
    /// (it may not have locked it); if that fails, name this process.
    HeldByOther {
        /// Its process id.
        pid: i32,
        /// Its program (`/proc/PID/comm`).
        name: String,
    },
}

/// [`relay_estop`]'s finding and who answered on the relay name without holding the port.
#[derive(Debug, Clone, PartialEq)]
pub struct EstopRoute {
    /// What happened.
    pub outcome: RelayOutcome,
    /// A process that answered on [`relay_name`] but does not hold the port: not asked.
    pub impostor_pid: Option<i32>,
}

/// Asks the process holding `port` to send an E-stop: on its relay socket when the
/// process answering there holds the port, else by [`RELAY_SIGNAL`] to the wheelcal
/// found holding the device in `/proc`. A holder that does not confirm within
/// [`WAKE_AFTER`] is taken for suspended (Ctrl-Z, SIGSTOP: all its threads stand) and
/// sent SIGCONT. A holder that is gone leaves the port to the caller.
pub fn relay_estop(port: &str) -> Result<EstopRoute> {
    let t0 = Instant::now();
    let Ok(device) = std::fs::canonicalize(port) else {
        return Ok(EstopRoute {
            outcome: RelayOutcome::NotHeld,
            impostor_pid: None,
        });
    };
    let mut impostor_pid = None;
    let mut unverified = None;
    if let Ok(conn) = abstract_addr(&relay_name(port)).and_then(|a| UnixStream::connect_addr(&a)) {
        let pid = holder_pid(&conn);
        match pid.map(|p| holds(p, &device)) {
            Some(Some(true)) => {
                return Ok(EstopRoute {
                    outcome: ask_relay(conn, port, pid, true, t0)?,
                    impostor_pid: None,
                });
            }
            Some(Some(false)) => impostor_pid = pid,
            // Another user's process: cannot be checked; asked if nobody visible holds
            // the port.
            _ => unverified = Some((conn, pid)),
        }
    }
    let me = std::process::id() as i32;
    let found: Vec<i32> = holders(&device).into_iter().filter(|&p| p != me).collect();
    let (wheelcals, others): (Vec<i32>, Vec<i32>) = found.iter().partition(|&&p| is_wheelcal(p));
    let mut outcome = RelayOutcome::NotHeld;
    if !wheelcals.is_empty() {
        outcome = signal_holders(port, &wheelcals, t0)?;
    }
    if outcome == RelayOutcome::NotHeld {
        if let Some(&pid) = others.first() {
            outcome = RelayOutcome::HeldByOther {
                pid,
                name: process_name(pid),
            };
        } else if let Some((conn, pid)) = unverified {
            outcome = ask_relay(conn, port, pid, false, t0)?;
        }
    }
    Ok(EstopRoute {
        outcome,
        impostor_pid,
    })
}

/// The E-stop request on a relay socket, the holder woken if it does not answer.
fn ask_relay(
    mut conn: UnixStream,
    port: &str,
    pid: Option<i32>,
    verified: bool,
    t0: Instant,
) -> Result<RelayOutcome> {
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
        conn.set_read_timeout(Some(CONFIRM_WITHIN))?;
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
            holder_pid: pid,
            via: Via::Socket,
            verified,
        })),
        None if pid.is_some_and(|p| !alive(p)) => Ok(RelayOutcome::HolderGone(pid.unwrap_or(0))),
        _ => anyhow::bail!(
            "the wheelcal holding {port} could not write the E-stop to the port ({})",
            answer.trim()
        ),
    }
}

/// The E-stop request by [`RELAY_SIGNAL`] to the wheelcals `pids` that have `port` open,
/// each one's confirmation heard on [`ack_name`] from that process only. One holds the
/// port as a console and writes the frame; any other (a virtual board keeps its
/// terminal's other end open) answers that it holds none. [`RelayOutcome::NotHeld`] if
/// none holds it.
fn signal_holders(port: &str, pids: &[i32], t0: Instant) -> Result<RelayOutcome> {
    struct Asked {
        pid: i32,
        ack: Option<UnixListener>,
        woke: bool,
        done: bool,
    }
    let mut asked = Vec::new();
    let mut refused = None;
    for &pid in pids {
        let ack = abstract_addr(&ack_name(pid))
            .and_then(|a| UnixListener::bind_addr(&a))
            .and_then(|l| l.set_nonblocking(true).map(|_| l))
            .ok();
        match kill(nix::unistd::Pid::from_raw(pid), RELAY_SIGNAL) {
            Ok(()) => {}
            Err(nix::errno::Errno::ESRCH) => continue,
            Err(e) => {
                refused = Some((pid, e));
                continue;
            }
        }
        let woke = process_state(pid) == Some('T') && wake(pid);
        asked.push(Asked {
            pid,
            ack,
            woke,
            done: false,
        });
    }
    let mut gone = None;
    let deadline = t0 + WAKE_AFTER + CONFIRM_WITHIN;
    let mut late_wake = false;
    while asked.iter().any(|a| !a.done) {
        for a in asked.iter_mut().filter(|a| !a.done) {
            // Looked at before the accept: a holder that writes the E-stop and then ends
            // (it sees the latched board) leaves its confirmation queued.
            let was_alive = alive(a.pid);
            let conn = a.ack.as_ref().and_then(|l| l.accept().ok());
            let Some((conn, _)) = conn else {
                if !was_alive {
                    a.done = true;
                    gone = Some(a.pid);
                }
                continue;
            };
            if holder_pid(&conn) != Some(a.pid) {
                continue; // not the holder: not its confirmation
            }
            let _ = conn.set_nonblocking(false);
            let _ = conn.set_read_timeout(Some(Duration::from_millis(200)));
            let mut answer = String::new();
            let _ = BufReader::new(&conn).read_line(&mut answer);
            a.done = true;
            match answer.split_whitespace().next() {
                Some("ok") => {
                    return Ok(RelayOutcome::Relayed(Relayed {
                        elapsed: t0.elapsed(),
                        woke_pid: a.woke.then_some(a.pid),
                        holder_pid: Some(a.pid),
                        via: Via::Signal,
                        verified: true,
                    }))
                }
                Some("idle") => {}
                _ => anyhow::bail!(
                    "the wheelcal holding {port} (process {}) could not write the E-stop to \
                     the port ({})",
                    a.pid,
                    answer.trim()
                ),
            }
        }
        if !late_wake && t0.elapsed() > WAKE_AFTER {
            // Stopped after the first look: wake it now.
            late_wake = true;
            for a in asked.iter_mut().filter(|a| !a.done) {
                if process_state(a.pid) == Some('T') && wake(a.pid) {
                    a.woke = true;
                }
            }
        }
        if Instant::now() > deadline {
            let silent: Vec<String> = asked
                .iter()
                .filter(|a| !a.done)
                .map(|a| match a.ack {
                    Some(_) => format!("process {} did not confirm", a.pid),
                    None => format!(
                        "process {}'s confirmation cannot be heard (the name {} is taken)",
                        a.pid,
                        ack_name(a.pid)
                    ),
                })
                .collect();
            anyhow::bail!(
                "signalled the wheelcal holding {port} to send the E-stop, but {} within {} ms: \
                 check that the robot stopped; stop it by hand if not",
                silent.join(", "),
                (WAKE_AFTER + CONFIRM_WITHIN).as_millis()
            );
        }
        std::thread::sleep(Duration::from_millis(2));
    }
    if let Some((pid, e)) = refused {
        anyhow::bail!(
            "the wheelcal holding {port} (process {pid}, {}) cannot be signalled to relay \
             the E-stop ({e}; another user's process?): stop the robot by hand",
            process_name(pid)
        );
    }
    Ok(match gone {
        Some(pid) => RelayOutcome::HolderGone(pid),
        None => RelayOutcome::NotHeld,
    })
}

/// The process at the other end of a Unix socket (SO_PEERCRED).
fn holder_pid(conn: &UnixStream) -> Option<i32> {
    use nix::sys::socket::{getsockopt, sockopt::PeerCredentials};
    getsockopt(conn, PeerCredentials).ok().map(|c| c.pid())
}

/// Whether process `pid` has `device` open; `None` when its descriptors cannot be read
/// (another user's process).
fn holds(pid: i32, device: &Path) -> Option<bool> {
    let fds = std::fs::read_dir(format!("/proc/{pid}/fd")).ok()?;
    Some(
        fds.flatten()
            .any(|fd| std::fs::read_link(fd.path()).is_ok_and(|l| l == device)),
    )
}

/// The processes (that this user can see) with `device` open.
fn holders(device: &Path) -> Vec<i32> {
    let Ok(procs) = std::fs::read_dir("/proc") else {
        return Vec::new();
    };
    procs
        .flatten()
        .filter_map(|p| p.file_name().to_str()?.parse::<i32>().ok())
        .filter(|&pid| holds(pid, device) == Some(true))
        .collect()
}

/// A process's program name (`/proc/PID/comm`), "?" if unreadable.
fn process_name(pid: i32) -> String {
    std::fs::read_to_string(format!("/proc/{pid}/comm"))
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "?".into())
}

/// Whether process `pid` runs wheelcal: its program is this one, or is named `wheelcal`.
fn is_wheelcal(pid: i32) -> bool {
    let exe = std::fs::read_link(format!("/proc/{pid}/exe")).ok();
    let this = std::env::current_exe().ok();
    (exe.is_some() && exe == this)
        || exe
            .as_ref()
            .and_then(|e| e.file_name())
            .is_some_and(|n| n == "wheelcal")
        || process_name(pid) == "wheelcal"
}

/// The state letter of `/proc/PID/stat` (`T`: stopped, `Z`: zombie).
fn process_state(pid: i32) -> Option<char> {
    let s = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    s.rsplit_once(')')?.1.trim_start().chars().next()
}

/// Sends SIGCONT; false when the process does not exist.
fn wake(pid: i32) -> bool {
    kill(nix::unistd::Pid::from_raw(pid), Signal::SIGCONT).is_ok()
}

/// Whether a process exists (signal 0) and is not a zombie.
fn alive(pid: i32) -> bool {
    let exists = kill(nix::unistd::Pid::from_raw(pid), None).is_ok();
    exists && process_state(pid) != Some('Z')
}
