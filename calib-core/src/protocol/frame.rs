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

/// Encodes `msg` as a complete frame (delimiter included) into `out`, returning the wire
/// bytes. `out` of [`MAX_WIRE`] bytes fits any message of this protocol.
///
/// One pass, no scratch copy: postcard serialises `seq` and the body through its CRC
/// flavour (which appends the CRC-32) into its COBS flavour (which stuffs the bytes as
/// they come and adds the delimiter) into `out`.
pub fn encode<'o, T: Serialize + ?Sized>(
    seq: u16,
    msg: &T,
    out: &'o mut [u8],
) -> Result<&'o [u8], FrameError> {
    let cap = out.len().min(MAX_WIRE);
    let wire =
        postcard::ser_flavors::Cobs::try_new(postcard::ser_flavors::Slice::new(&mut out[..cap]))
            .map_err(|_| FrameError::TooLong)?;
    let crc = postcard::ser_flavors::crc::CrcModifier::new(wire, CRC32.digest());
    let limited = Limit {
        inner: crc,
        left: MAX_PAYLOAD - CRC_LEN,
    };
    // A `[u8; 2]` is a postcard tuple: the two bytes verbatim, no length prefix.
    let n = postcard::serialize_with_flavor(&(seq.to_le_bytes(), msg), limited)
        .map_err(|_| FrameError::TooLong)?
        .len();
    Ok(&out[..n])
}

/// Refuses more than `left` bytes: the frame's unencoded size limit ([`MAX_PAYLOAD`]),
/// which the wire buffer's size alone cannot express (COBS overhead depends on content).
struct Limit<F> {
    inner: F,
    left: usize,
}

impl<F: postcard::ser_flavors::Flavor> postcard::ser_flavors::Flavor for Limit<F> {
    type Output = F::Output;

    // Not inlined: the CRC and COBS steps then exist once, not in every serialiser.
    #[inline(never)]
    fn try_push(&mut self, data: u8) -> postcard::Result<()> {
        self.left = self
            .left
            .checked_sub(1)
            .ok_or(postcard::Error::SerializeBufferFull)?;
        self.inner.try_push(data)
    }

    fn finalize(self) -> postcard::Result<F::Output> {
        self.inner.finalize()
    }
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
