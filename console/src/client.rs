//! The host side of the board protocol (calib_core::protocol): requests with sequence
//! numbers, retries, the version handshake, and resumable log downloads.
//!
//! The client works over any `Read + Write` whose reads time out (a serial port, the
//! virtual board's pseudo-terminal, or an in-process pipe in tests). A request that gets
//! no answer, or a Nack for a damaged frame, is resent with the same sequence number;
//! the board caches its last answer, so a resent request is never acted on twice.

use calib_core::protocol::{
    self, encode, FrameDecoder, FrameError, Info, Params, ProgramSpec, Record, Rejection, Request,
    Response, Status, TrialInfo, Trials, MAX_LOG_CHUNK, MAX_WIRE, PROTOCOL_VERSION,
    SCHEMA_FINGERPRINT,
};
use calib_core::{Corrections, Twist};
use std::fmt;
use std::io::{self, Read, Write};
use std::time::{Duration, Instant};

/// Smallest log chunk asked for on a noisy link.
pub const MIN_CHUNK: usize = 48;

/// A board's answer, owned. Variants differ in size (an `Info` is large); replies are
/// short-lived values, so they are not boxed.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Reply {
    /// The handshake answer.
    Hello {
        /// The board's protocol version.
        protocol_version: u16,
        /// The board's schema fingerprint.
        schema: u32,
        /// Firmware version text.
        firmware: String,
        /// Whether the board found our version and schema equal to its own.
        compatible: bool,
    },
    /// Done (for requests with nothing to return).
    Ok,
    /// What the board reports about itself.
    Info(Info),
    /// The active corrections.
    Corrections(Corrections),
    /// The active parameters.
    Params(Params),
    /// The board's status, asked for (telemetry is kept apart).
    Status(Status),
    /// The stored trials.
    Trials(Trials),
    /// A piece of a trial's record bytes.
    LogChunk {
        /// Trial id.
        trial: u16,
        /// Where `data` starts in the trial's records, bytes.
        offset: u32,
        /// Size of the trial's records, bytes.
        total: u32,
        /// The bytes themselves.
        data: Vec<u8>,
    },
    /// The board refused the request; nothing changed there.
    Rejected(Rejection),
}

/// What went wrong talking to a board.
#[derive(Debug)]
pub enum ClientError {
    /// Nothing intact came back after every retry.
    NoAnswer {
        /// The port, as named to the client.
        port: String,
        /// Silent attempts allowed per request.
        tries: u32,
        /// Damaged frames seen on this connection so far.
        bad_frames: u32,
    },
    /// The board speaks another protocol version or schema.
    ProtocolMismatch {
        /// The board's protocol version.
        board_version: u16,
        /// The board's schema fingerprint.
        board_schema: u32,
        /// The board's firmware version text.
        firmware: String,
    },
    /// The board refused the request; nothing changed there.
    Rejected(Rejection),
    /// An answer of the wrong kind.
    Unexpected(String),
    /// Reading or writing the port failed (or a transfer was interrupted).
    Io(io::Error),
}

impl fmt::Display for ClientError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ClientError::NoAnswer {
                port,
                tries,
                bad_frames,
            } => {
                write!(f, "no answer from {port} after {tries} tries")?;
                if *bad_frames > 0 {
                    write!(
                        f,
                        " ({bad_frames} damaged frames: check the baud rate and cable)"
                    )
                } else {
                    write!(f, " (is the board powered and running wheelcal firmware, and the baud rate right?)")
                }
            }
            ClientError::ProtocolMismatch {
                board_version,
                board_schema,
                firmware,
            } => write!(
                f,
                "{} (board firmware {firmware}): update the firmware or wheelcal so they match",
                Rejection::ProtocolMismatch {
                    board_version: *board_version,
                    board_schema: *board_schema,
                }
            ),
            ClientError::Rejected(r) => write!(f, "the board refused: {r}"),
            ClientError::Unexpected(what) => write!(f, "unexpected answer from the board: {what}"),
            // The OS error is the `source()`: `{:#}` prints "serial I/O error: <it>".
            ClientError::Io(_) => write!(f, "serial I/O error"),
        }
    }
}

impl std::error::Error for ClientError {
    /// The OS error under a serial I/O failure, kept as a cause rather than text.
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            ClientError::Io(e) => Some(e),
            _ => None,
        }
    }
}

impl From<io::Error> for ClientError {
    fn from(e: io::Error) -> Self {
        ClientError::Io(e)
    }
}

/// Counters of what crossed the link.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct LinkStats {
    /// Bytes thrown away unread: stale answers and replies to noise found waiting.
    pub discarded: u64,
    /// Requests made (each counted once, however many times it was sent).
    pub requests: u32,
    /// Resends after silence or damage.
    pub retries: u32,
    /// Damaged frames received.
    pub bad_frames: u32,
    /// Bytes written to the link.
    pub bytes_sent: u64,
    /// Bytes read from the link (discarded ones included).
    pub bytes_received: u64,
}

/// Result of the handshake.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Hello {
    /// The board's firmware version text.
    pub firmware: String,
    /// The protocol version both sides speak.
    pub protocol_version: u16,
    /// The schema fingerprint both sides share.
    pub schema: u32,
}

/// Resends a request may take for damage (Nacks, damaged answers) before giving up.
const MAX_DAMAGE_RESENDS: u32 = 32;

/// A starting sequence number that differs between sessions: the board answers a repeated
/// (sequence number, body) pair from its cache without acting, so two console sessions
/// both starting at 1 would have the second one's first requests answered, not done.
fn fresh_seq() -> u16 {
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos())
        .unwrap_or(0);
    (t ^ std::process::id().rotate_left(16)) as u16
}

/// A connection to one board.
pub struct Client<L: Read + Write> {
    link: L,
    port: String,
    dec: FrameDecoder,
    seq: u16,
    /// Attempts per request (first try included).
    pub tries: u32,
    /// How long to wait for each attempt's answer.
    pub timeout: Duration,
    /// What crossed the link so far.
    pub stats: LinkStats,
    telemetry: std::collections::VecDeque<Status>,
    pending: std::collections::VecDeque<u8>,
}

impl<L: Read + Write> Client<L> {
    /// A client over `link`; `port` names it in messages. Call [`Client::hello`] next.
    pub fn new(link: L, port: &str) -> Self {
        Client {
            link,
            port: port.to_string(),
            dec: FrameDecoder::new(),
            seq: fresh_seq(),
            tries: 4,
            timeout: Duration::from_millis(500),
            stats: LinkStats::default(),
            telemetry: Default::default(),
            pending: Default::default(),
        }
    }

    /// The handshake: checks protocol version and schema fingerprint. What was waiting
    /// on the line (answers to an earlier session, replies to noise) is discarded first.
    pub fn hello(&mut self) -> Result<Hello, ClientError> {
        self.drain();
        match self.request(&Request::Hello {
            protocol_version: PROTOCOL_VERSION,
            schema: SCHEMA_FINGERPRINT,
        })? {
            Reply::Hello {
                protocol_version,
                schema,
                firmware,
                compatible,
            } => {
                if !compatible
                    || protocol_version != PROTOCOL_VERSION
                    || schema != SCHEMA_FINGERPRINT
                {
                    return Err(ClientError::ProtocolMismatch {
                        board_version: protocol_version,
                        board_schema: schema,
                        firmware,
                    });
                }
                Ok(Hello {
                    firmware,
                    protocol_version,
                    schema,
                })
            }
            other => Err(ClientError::Unexpected(format!("{other:?} to Hello"))),
        }
    }

    /// Sends a request and waits for its answer, retrying on silence or damage.
    pub fn request(&mut self, req: &Request) -> Result<Reply, ClientError> {
        self.seq = self.seq.wrapping_add(1);
        let seq = self.seq;
        // A delimiter first: whatever noise the line carried ends there as one damaged
        // frame, and this request decodes on its own.
        let mut wire = [0u8; MAX_WIRE + 1];
        let len = encode(seq, req, &mut wire[1..])
            .map_err(|e| ClientError::Unexpected(format!("request does not fit a frame: {e}")))?
            .len();
        let frame = &wire[..1 + len];
        self.stats.requests += 1;
        // Silent attempts (timeouts) are limited by `tries`. Damage (a Nack, a damaged
        // frame) asks for a resend at once, after throwing away whatever else is queued:
        // after a burst of line noise, the board's Nacks to the noise are still waiting,
        // and each would otherwise cost a try. Those resends have their own, larger budget.
        let mut silent = 0;
        let mut damaged = 0;
        let mut first = true;
        while silent < self.tries.max(1) && damaged <= MAX_DAMAGE_RESENDS {
            if !first {
                self.stats.retries += 1;
            }
            first = false;
            self.link.write_all(frame)?;
            self.link.flush()?;
            self.stats.bytes_sent += frame.len() as u64;
            let deadline = Instant::now() + self.timeout;
            loop {
                match self.read_frame(deadline)? {
                    None => {
                        silent += 1; // timed out: resend
                        break;
                    }
                    Some(Err(_)) => {
                        // Most likely our answer, damaged: ask again now rather than
                        // wait out the timeout (the board answers a repeat from cache).
                        self.stats.bad_frames += 1;
                        damaged += 1;
                        self.drain();
                        break;
                    }
                    Some(Ok((_, Incoming::Nack))) => {
                        // The board saw damage (ours, or noise before it): resend.
                        damaged += 1;
                        self.drain();
                        break;
                    }
                    Some(Ok((_, Incoming::Telemetry(s)))) => {
                        if self.telemetry.len() >= 256 {
                            self.telemetry.pop_front();
                        }
                        self.telemetry.push_back(s);
                    }
                    Some(Ok((s, Incoming::Reply(r)))) if s == seq => return Ok(r),
                    Some(Ok(_)) => {} // a late answer to an earlier request
                }
            }
        }
        Err(ClientError::NoAnswer {
            port: self.port.clone(),
            tries: self.tries,
            bad_frames: self.stats.bad_frames,
        })
    }

    /// Throws away what is waiting on the line: reads until it has been quiet for 20 ms
    /// (at most 1 s, so a board streaming telemetry cannot hold us here).
    pub fn drain(&mut self) {
        self.pending.clear();
        self.dec = FrameDecoder::new();
        let t0 = Instant::now();
        let mut quiet_since = Instant::now();
        let mut buf = [0u8; 1024];
        while quiet_since.elapsed() < Duration::from_millis(20)
            && t0.elapsed() < Duration::from_secs(1)
        {
            match self.link.read(&mut buf) {
                Ok(n) if n > 0 => {
                    self.stats.bytes_received += n as u64;
                    self.stats.discarded += n as u64;
                    quiet_since = Instant::now();
                }
                Ok(_) => std::thread::sleep(Duration::from_millis(1)),
                Err(_) => {}
            }
        }
    }

    /// Reads bytes until a frame completes or the deadline passes. Bytes read past the
    /// end of a frame stay in `pending` for the next call.
    fn read_frame(&mut self, deadline: Instant) -> Result<Option<FrameResult>, ClientError> {
        let mut buf = [0u8; 256];
        loop {
            while let Some(b) = self.pending.pop_front() {
                if let Some(result) = self.dec.push(b) {
                    return Ok(Some(result.and_then(|f| {
                        let seq = f.seq;
                        f.decode::<Response<'_>>()
                            .map(|r| (seq, Incoming::from(r)))
                            .map_err(|_| FrameError::Cobs)
                    })));
                }
            }
            if Instant::now() >= deadline {
                return Ok(None);
            }
            match self.link.read(&mut buf) {
                Ok(0) => std::thread::sleep(Duration::from_millis(1)),
                Ok(n) => {
                    self.stats.bytes_received += n as u64;
                    self.pending.extend(&buf[..n]);
                }
                Err(e)
                    if matches!(
                        e.kind(),
                        io::ErrorKind::TimedOut
                            | io::ErrorKind::WouldBlock
                            | io::ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(e.into()),
            }
        }
    }

    fn expect_ok(&mut self, req: Request) -> Result<(), ClientError> {
        match self.request(&req)? {
            Reply::Ok => Ok(()),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Asks for what the board reports about itself.
    pub fn info(&mut self) -> Result<Info, ClientError> {
        match self.request(&Request::GetInfo)? {
            Reply::Info(i) => Ok(i),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Asks for the active corrections.
    pub fn corrections(&mut self) -> Result<Corrections, ClientError> {
        match self.request(&Request::GetCorrections)? {
            Reply::Corrections(c) => Ok(c),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Makes `c` the active corrections (the board validates them; not saved yet).
    pub fn set_corrections(&mut self, c: Corrections) -> Result<(), ClientError> {
        self.expect_ok(Request::SetCorrections(c))
    }

    /// Saves the active corrections to flash.
    pub fn save_corrections(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::SaveCorrections)
    }

    /// Active corrections back to none (save to make it last).
    pub fn reset_corrections(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::ResetCorrections)
    }

    /// Makes `p` the active parameters (the board validates them; idle only; not
    /// persisted until saved).
    pub fn set_params(&mut self, p: Params) -> Result<(), ClientError> {
        self.expect_ok(Request::SetParams(p))
    }

    /// Saves the active parameters to flash.
    pub fn save_params(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::SaveParams)
    }

    /// Asks for the active parameters.
    pub fn params(&mut self) -> Result<Params, ClientError> {
        match self.request(&Request::GetParams)? {
            Reply::Params(p) => Ok(p),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Drives at `twist` (m/s, m/s, rad/s) until the next drive or `timeout_ms` (0: the
    /// board's configured timeout).
    pub fn drive(&mut self, twist: Twist<f32>, timeout_ms: u16) -> Result<(), ClientError> {
        self.expect_ok(Request::Drive { twist, timeout_ms })
    }

    /// Starts a motion program, logging a trial at `log_rate_hz` (0: no log); the board
    /// cuts it when no request arrives from this host for `link_timeout_ms` (0: off).
    pub fn run_program(
        &mut self,
        program: ProgramSpec,
        log_rate_hz: u16,
        link_timeout_ms: u16,
    ) -> Result<(), ClientError> {
        self.expect_ok(Request::RunProgram {
            program,
            log_rate_hz,
            link_timeout_ms,
        })
    }

    /// Controlled stop: the controllers ramp to zero.
    pub fn stop(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::Stop)
    }

    /// Immediate motor cut-off, latched until [`Client::clear_fault`].
    pub fn estop(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::EStop)
    }

    /// Clears a latched E-stop or fault.
    pub fn clear_fault(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::ClearFault)
    }

    /// Deletes every stored trial on the board.
    pub fn clear_logs(&mut self) -> Result<(), ClientError> {
        self.expect_ok(Request::ClearLogs)
    }

    /// Asks for a telemetry frame every `period_ms` (0: off).
    pub fn set_telemetry(&mut self, period_ms: u16) -> Result<(), ClientError> {
        self.expect_ok(Request::SetTelemetry { period_ms })
    }

    /// Asks for the board's status.
    pub fn status(&mut self) -> Result<Status, ClientError> {
        match self.request(&Request::GetStatus)? {
            Reply::Status(s) => Ok(s),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Waits up to `timeout` for the next unsolicited telemetry frame.
    pub fn next_telemetry(&mut self, timeout: Duration) -> Result<Option<Status>, ClientError> {
        if let Some(s) = self.telemetry.pop_front() {
            return Ok(Some(s));
        }
        let deadline = Instant::now() + timeout;
        while let Some(f) = self.read_frame(deadline)? {
            match f {
                Ok((_, Incoming::Telemetry(s))) => return Ok(Some(s)),
                Err(_) => self.stats.bad_frames += 1,
                _ => {}
            }
        }
        Ok(None)
    }

    /// Asks for the list of stored trials.
    pub fn trials(&mut self) -> Result<Trials, ClientError> {
        match self.request(&Request::ListTrials)? {
            Reply::Trials(t) => Ok(t),
            Reply::Rejected(r) => Err(ClientError::Rejected(r)),
            other => Err(ClientError::Unexpected(format!("{other:?}"))),
        }
    }

    /// Downloads a trial's record bytes from `offset` (resume by passing what you have),
    /// calling `progress(done, total)` after each chunk. On a noisy link the chunk size
    /// halves after a chunk fails every retry (down to [`MIN_CHUNK`]) and grows back after
    /// clean ones: big chunks are efficient, small ones get through noise.
    pub fn pull_log(
        &mut self,
        trial: u16,
        mut data: Vec<u8>,
        mut progress: impl FnMut(u64, u64),
    ) -> Result<Vec<u8>, ClientError> {
        let mut chunk = MAX_LOG_CHUNK;
        let mut clean = 0u32;
        loop {
            if crate::stop::requested() {
                return Err(ClientError::Io(io::Error::new(
                    io::ErrorKind::Interrupted,
                    "log transfer interrupted (Ctrl-C); nothing was written",
                )));
            }
            let offset = data.len() as u32;
            let reply = match self.request(&Request::ReadLog {
                trial,
                offset,
                max_len: chunk as u16,
            }) {
                Err(ClientError::NoAnswer { .. }) if chunk > MIN_CHUNK => {
                    chunk = (chunk / 2).max(MIN_CHUNK);
                    clean = 0;
                    continue;
                }
                other => other?,
            };
            match reply {
                Reply::LogChunk {
                    trial: t,
                    offset: o,
                    total,
                    data: bytes,
                } => {
                    if t != trial || o != offset {
                        return Err(ClientError::Unexpected(format!(
                            "chunk of trial {t} at {o}, asked trial {trial} at {offset}"
                        )));
                    }
                    data.extend_from_slice(&bytes);
                    progress(data.len() as u64, total as u64);
                    if bytes.is_empty() || data.len() as u32 >= total {
                        return Ok(data);
                    }
                    clean += 1;
                    if clean >= 8 && chunk < MAX_LOG_CHUNK {
                        chunk = (chunk * 2).min(MAX_LOG_CHUNK);
                        clean = 0;
                    }
                }
                Reply::Rejected(r) => return Err(ClientError::Rejected(r)),
                other => return Err(ClientError::Unexpected(format!("{other:?}"))),
            }
        }
    }
}

/// A complete frame: its sequence number and content, or why it was damaged.
type FrameResult = Result<(u16, Incoming), FrameError>;

/// A decoded incoming frame.
#[allow(clippy::large_enum_variant)]
enum Incoming {
    Reply(Reply),
    Telemetry(Status),
    Nack,
}

impl From<Response<'_>> for Incoming {
    fn from(r: Response<'_>) -> Self {
        Incoming::Reply(match r {
            Response::Hello {
                protocol_version,
                schema,
                firmware,
                compatible,
            } => Reply::Hello {
                protocol_version,
                schema,
                firmware: firmware.to_string(),
                compatible,
            },
            Response::Ok => Reply::Ok,
            Response::Info(i) => Reply::Info(i),
            Response::Corrections(c) => Reply::Corrections(c),
            Response::Params(p) => Reply::Params(p),
            Response::Status(s) => Reply::Status(s),
            Response::Telemetry(s) => return Incoming::Telemetry(s),
            Response::Trials(t) => Reply::Trials(t),
            Response::LogChunk(c) => Reply::LogChunk {
                trial: c.trial,
                offset: c.offset,
                total: c.total,
                data: c.data.0.to_vec(),
            },
            Response::Rejected(r) => Reply::Rejected(r),
            Response::Nack(_) => return Incoming::Nack,
        })
    }
}

/// Why a trial's log could not be decoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LogError {
    /// The trial says it has more wheels than any robot may.
    TooManyWheels {
        /// The trial's id.
        trial: u16,
        /// Its wheel count.
        wheels: u8,
    },
    /// Blocks were damaged or the data ends inside one.
    Damaged {
        /// The trial's id.
        trial: u16,
        /// Blocks whose check failed.
        bad_blocks: u32,
        /// Records in them.
        lost_records: u32,
        /// Bytes after the last whole block.
        trailing: u32,
    },
}

impl fmt::Display for LogError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LogError::TooManyWheels { trial, wheels } => {
                write!(f, "trial {trial}: {wheels} wheels is too many")
            }
            LogError::Damaged {
                trial,
                bad_blocks,
                lost_records,
                trailing,
            } => write!(
                f,
                "trial {trial}: {bad_blocks} damaged log blocks ({lost_records} records), {trailing} bytes cut short"
            ),
        }
    }
}

impl std::error::Error for LogError {}

/// Decodes a trial's log blocks; errors when a block is damaged or the data is cut short
/// (use [`decode_records_lossy`] to keep the intact blocks).
pub fn decode_records(info: &TrialInfo, data: &[u8]) -> Result<Vec<Record>, LogError> {
    let (recs, s) = decode_records_lossy(info, data)?;
    if s.bad_blocks > 0 || s.trailing > 0 {
        return Err(LogError::Damaged {
            trial: info.id,
            bad_blocks: s.bad_blocks,
            lost_records: s.lost_records,
            trailing: s.trailing,
        });
    }
    Ok(recs)
}

/// Decodes a trial's log blocks, skipping damaged ones (each costs only its own records).
pub fn decode_records_lossy(
    info: &TrialInfo,
    data: &[u8],
) -> Result<(Vec<Record>, protocol::BlockSummary), LogError> {
    let n = info.wheel_count as usize;
    if n > calib_core::robot::MAX_WHEELS {
        return Err(LogError::TooManyWheels {
            trial: info.id,
            wheels: info.wheel_count,
        });
    }
    let mut recs = Vec::with_capacity(info.records as usize);
    let s = protocol::decode_blocks(n, data, |r| recs.push(r));
    Ok((recs, s))
}
