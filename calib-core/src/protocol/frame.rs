//! Framing: COBS(seq | postcard body | CRC-32) with a resynchronising decoder.

#[allow(unused_imports)]
use super::*;

/// Why a frame was not accepted.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FrameError {
    /// Not valid COBS (a code byte points past the frame's end).
    Cobs,
    /// Shorter than a sequence number and a CRC.
    TooShort,
    /// Longer than [`MAX_WIRE`] (or the caller's buffer when encoding).
    TooLong,
    /// Checksum mismatch: damaged in transit.
    Crc,
}

impl fmt::Display for FrameError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FrameError::Cobs => "bad COBS encoding",
            FrameError::TooShort => "frame too short",
            FrameError::TooLong => "frame too long",
            FrameError::Crc => "CRC mismatch",
        })
    }
}

impl core::error::Error for FrameError {}

/// An intact frame: its sequence number and postcard body.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Sequence number (responses echo the request's).
    pub seq: u16,
    /// The postcard-encoded message.
    pub body: &'a [u8],
}

impl<'a> Frame<'a> {
    /// Decodes the body as `T`.
    pub fn decode<T: Deserialize<'a>>(&self) -> Result<T, postcard::Error> {
        postcard::from_bytes(self.body)
    }
}

/// Most bytes COBS adds to `n` bytes (one per 254, plus the first code byte).
const fn cobs_overhead(n: usize) -> usize {
    n / 254 + 1
}

/// Encodes `msg` as a complete frame (delimiter included) into `out`, returning the wire
/// bytes. `out` of [`MAX_WIRE`] bytes fits any message of this protocol.
///
/// No scratch buffer: postcard writes `seq | body` at an offset inside `out`, the CRC-32
/// is computed over it in one pass and appended, and the `cobs` crate's encoder state
/// machine stuffs the bytes towards the start of `out` (its output index never overtakes
/// its input index when the input starts at least the COBS overhead in).
pub fn encode<'o, T: Serialize + ?Sized>(
    seq: u16,
    msg: &T,
    out: &'o mut [u8],
) -> Result<&'o [u8], FrameError> {
    let cap = out.len().min(MAX_WIRE);
    let raw_max = MAX_PAYLOAD.min(cap.saturating_sub(cobs_overhead(cap) + 1));
    let off = cobs_overhead(raw_max);
    if raw_max < SEQ_LEN + CRC_LEN {
        return Err(FrameError::TooLong);
    }
    let raw = &mut out[off..off + raw_max];
    raw[..SEQ_LEN].copy_from_slice(&seq.to_le_bytes());
    let body_len = postcard::to_slice(msg, &mut raw[SEQ_LEN..raw_max - CRC_LEN])
        .map_err(|_| FrameError::TooLong)?
        .len();
    let crc_at = SEQ_LEN + body_len;
    let crc = CRC32.checksum(&raw[..crc_at]);
    raw[crc_at..crc_at + CRC_LEN].copy_from_slice(&crc.to_le_bytes());
    let n = cobs_encode_in_place(out, off, crc_at + CRC_LEN);
    out[n] = 0;
    Ok(&out[..=n])
}

/// COBS-encodes `buf[off..off + len]` into `buf[0..]` with the `cobs` crate's
/// [`cobs::EncoderState`] (the state machine postcard's COBS flavour drives); returns the
/// encoded length. Position 0 holds the first code byte, as in the crate's encoders.
fn cobs_encode_in_place(buf: &mut [u8], off: usize, len: usize) -> usize {
    use cobs::PushResult::*;
    let mut state = cobs::EncoderState::default();
    let mut w = 1;
    for i in off..off + len {
        match state.push(buf[i]) {
            AddSingle(b) => {
                buf[w] = b;
                w += 1;
            }
            ModifyFromStartAndSkip((at, code)) => {
                buf[at] = code;
                w += 1; // the next code byte's place, filled later
            }
            ModifyFromStartAndPushAndSkip((at, code, b)) => {
                buf[at] = code;
                buf[w] = b;
                w += 2;
            }
        }
    }
    let (at, code) = state.finalize();
    buf[at] = code;
    w
}

/// Frames an already serialised body (fuzzers and tests send arbitrary bodies this way).
pub fn encode_body<'o>(seq: u16, body: &[u8], out: &'o mut [u8]) -> Result<&'o [u8], FrameError> {
    encode(seq, &RawBody(body), out)
}

/// Serialises as its bytes verbatim (postcard's tuple of u8 adds no length prefix).
struct RawBody<'a>(&'a [u8]);

impl Serialize for RawBody<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeTuple;
        let mut t = s.serialize_tuple(self.0.len())?;
        for b in self.0 {
            t.serialize_element(b)?;
        }
        t.end()
    }
}

/// Decodes COBS in place with the `cobs` crate (the one postcard uses); returns the
/// decoded length. An empty frame decodes to nothing (the caller reports it too short).
fn cobs_decode_in_place(buf: &mut [u8]) -> Result<usize, FrameError> {
    if buf.is_empty() {
        return Ok(0);
    }
    cobs::decode_in_place(buf).map_err(|_| FrameError::Cobs)
}

/// Splits a byte stream into frames: bounded memory ([`MAX_WIRE`] bytes), never panics,
/// resynchronises at the next 0x00 after garbage or an oversized frame.
#[derive(Debug, Clone)]
pub struct FrameDecoder {
    buf: [u8; MAX_WIRE],
    len: usize,
    overflow: bool,
}

impl Default for FrameDecoder {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameDecoder {
    /// An empty decoder; usable in `const` context.
    pub const fn new() -> Self {
        FrameDecoder {
            buf: [0; MAX_WIRE],
            len: 0,
            overflow: false,
        }
    }

    /// Forgets a partial frame.
    pub fn reset(&mut self) {
        self.len = 0;
        self.overflow = false;
    }

    /// Feeds one byte; at a delimiter returns the frame that ended (or why it was bad).
    /// Empty frames (repeated delimiters) are skipped silently.
    pub fn push(&mut self, byte: u8) -> Option<Result<Frame<'_>, FrameError>> {
        if byte != 0 {
            if self.len < self.buf.len() {
                self.buf[self.len] = byte;
                self.len += 1;
            } else {
                self.overflow = true;
            }
            return None;
        }
        let (len, overflow) = (self.len, self.overflow);
        self.reset();
        if overflow {
            return Some(Err(FrameError::TooLong));
        }
        if len == 0 {
            return None;
        }
        Some(parse_raw(&mut self.buf[..len]))
    }
}

/// Checks a COBS-decoded frame and splits it.
fn parse_raw(enc: &mut [u8]) -> Result<Frame<'_>, FrameError> {
    let n = cobs_decode_in_place(enc)?;
    if n < SEQ_LEN + CRC_LEN {
        return Err(FrameError::TooShort);
    }
    if n > MAX_PAYLOAD {
        return Err(FrameError::TooLong);
    }
    let raw = &enc[..n];
    let (data, crc) = raw.split_at(n - CRC_LEN);
    let want = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
    if CRC32.checksum(data) != want {
        return Err(FrameError::Crc);
    }
    Ok(Frame {
        seq: u16::from_le_bytes([data[0], data[1]]),
        body: &data[SEQ_LEN..],
    })
}

/// Decodes one complete wire frame (with or without its trailing delimiter), in place.
pub fn decode_frame(wire: &mut [u8]) -> Result<Frame<'_>, FrameError> {
    let end = wire.iter().position(|&b| b == 0).unwrap_or(wire.len());
    if end == 0 {
        return Err(FrameError::TooShort);
    }
    if end > MAX_WIRE {
        return Err(FrameError::TooLong);
    }
    parse_raw(&mut wire[..end])
}
