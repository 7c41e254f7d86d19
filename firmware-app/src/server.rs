//! The request handler's byte side: frames in, frames out.
//!
//! `decode frame -> validate -> act -> respond`, synchronous, so the UART task, the host's
//! pseudo-terminal and in-process tests run it the same way. A damaged frame is answered
//! with a Nack (its sequence number cannot be trusted) and changes nothing; an intact frame
//! whose body is not a request is rejected as undecodable.
//!
//! Retries: when the host resends a request with the same sequence number and body (its
//! answer was lost), the cached answer is sent again instead of acting twice, so a
//! repeated RunProgram does not restart the program.

use crate::app::{App, Handled, PersistItem};
use crate::hal::ByteStream;
use calib_core::protocol::{encode, FrameDecoder, Rejection, Request, Response, MAX_WIRE};

/// Room for a telemetry status frame (~110 bytes with eight wheels).
const TELEMETRY_WIRE: usize = 192;

/// What the caller has to do after a byte.
#[derive(Debug)]
pub enum Step<'s> {
    /// Nothing yet.
    Idle,
    /// Send these bytes.
    Send(&'s [u8]),
    /// Write `item` to flash, then send [`Server::reply`]`(seq, app.persisted(ok))`.
    Persist {
        /// Sequence number of the request, for the reply.
        seq: u16,
        /// What to write.
        item: PersistItem,
    },
}

/// Framing state of one link.
pub struct Server {
    dec: FrameDecoder,
    out: [u8; MAX_WIRE],
    out_len: usize,
    /// Sequence number and body hash of the request whose answer is in `out`.
    last: Option<(u16, u32)>,
    tele: [u8; TELEMETRY_WIRE],
    tele_seq: u16,
}

impl Default for Server {
    fn default() -> Self {
        Self::new()
    }
}

/// FNV-1a: cheap identity of a request body for retry detection.
fn fnv(b: &[u8]) -> u32 {
    b.iter().fold(0x811c_9dc5u32, |h, &x| {
        (h ^ x as u32).wrapping_mul(0x0100_0193)
    })
}

impl Server {
    /// A server with no partial frame and nothing cached; usable in `const` context.
    pub const fn new() -> Self {
        Server {
            dec: FrameDecoder::new(),
            out: [0; MAX_WIRE],
            out_len: 0,
            last: None,
            tele: [0; TELEMETRY_WIRE],
            tele_seq: 0,
        }
    }

    /// Encodes a response for `seq` into the output buffer and remembers it.
    pub fn reply(&mut self, seq: u16, r: &Response<'_>) -> &[u8] {
        self.out_len = match encode(seq, r, &mut self.out) {
            Ok(w) => w.len(),
            // Every message fits (a calib-core test checks the largest ones); should one
            // not, say so rather than send nothing.
            Err(e) => encode(seq, &Response::Nack(e), &mut self.out).map_or(0, |w| w.len()),
        };
        &self.out[..self.out_len]
    }

    /// The first `len` bytes of the last answer (what [`Step::Send`] pointed to), for glue
    /// that cannot hold that borrow across its lock.
    pub fn last_frame(&self, len: usize) -> &[u8] {
        &self.out[..len.min(self.out_len)]
    }

    /// The first `len` bytes of the last telemetry frame.
    pub fn last_telemetry(&self, len: usize) -> &[u8] {
        &self.tele[..len.min(TELEMETRY_WIRE)]
    }

    /// Feeds one received byte.
    pub fn push(&mut self, byte: u8, app: &mut App<'_>, now_us: u64) -> Step<'_> {
        let (seq, key, req) = match self.dec.push(byte) {
            None => return Step::Idle,
            Some(Err(e)) => {
                app.note_bad_frame();
                self.last = None;
                return Step::Send(self.reply(0, &Response::Nack(e)));
            }
            Some(Ok(f)) => (f.seq, fnv(f.body), f.decode::<Request>()),
        };
        if self.last == Some((seq, key)) && self.out_len > 0 {
            return Step::Send(&self.out[..self.out_len]);
        }
        let Ok(req) = req else {
            self.last = Some((seq, key));
            return Step::Send(self.reply(seq, &Response::Rejected(Rejection::Undecodable)));
        };
        match app.handle(req, now_us) {
            Handled::Reply(r) => {
                self.last = Some((seq, key));
                let n = match encode(seq, &r, &mut self.out) {
                    Ok(w) => w.len(),
                    Err(e) => encode(seq, &Response::Nack(e), &mut self.out).map_or(0, |w| w.len()),
                };
                self.out_len = n;
                Step::Send(&self.out[..n])
            }
            Handled::Persist(item) => {
                // The answer is cached when `reply` sends it.
                self.last = Some((seq, key));
                self.out_len = 0;
                Step::Persist { seq, item }
            }
        }
    }

    /// A telemetry frame when one is due.
    pub fn telemetry(&mut self, app: &mut App<'_>) -> Option<&[u8]> {
        let s = app.telemetry_due()?;
        self.tele_seq = self.tele_seq.wrapping_add(1);
        encode(self.tele_seq, &Response::Telemetry(s), &mut self.tele).ok()
    }

    /// Serves a non-blocking stream: reads what is there, answers, sends telemetry.
    /// `persist` writes an item to flash synchronously (the host runs the async store with
    /// a `block_on`) and returns whether it worked.
    pub fn poll<S: ByteStream>(
        &mut self,
        app: &mut App<'_>,
        stream: &mut S,
        now_us: u64,
        mut persist: impl FnMut(&PersistItem) -> bool,
    ) {
        let mut buf = [0u8; 64];
        loop {
            let n = stream.read(&mut buf);
            if n == 0 {
                break;
            }
            for &b in &buf[..n.min(buf.len())] {
                match self.push(b, app, now_us) {
                    Step::Idle => {}
                    Step::Send(w) => stream.write(w),
                    Step::Persist { seq, item } => {
                        let ok = persist(&item);
                        let r = app.persisted(ok);
                        stream.write(self.reply(seq, &r));
                    }
                }
            }
        }
        if let Some(t) = self.telemetry(app) {
            stream.write(t);
        }
    }
}
