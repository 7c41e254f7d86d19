//! The serial protocol between a board and the host: messages, framing and the trial-log
//! record layout, shared by the firmware, the virtual board and the console.
//!
//! # Framing
//! One frame on the wire is `COBS(seq u16 LE | postcard body | CRC-32/ISO-HDLC LE) 0x00`.
//! The CRC covers the sequence number and the body; COBS removes every zero byte so 0x00
//! only ever delimits frames, and a receiver that starts mid-stream or sees garbage
//! resynchronises at the next delimiter ([`FrameDecoder`]). A frame's unencoded content
//! (`seq | body | crc`) is at most [`MAX_PAYLOAD`] bytes, on the wire at most
//! [`MAX_WIRE`]. Responses echo the request's sequence number; unsolicited telemetry
//! frames carry the board's own counter and are told apart by their variant.
//!
//! # Handshake
//! [`Request::Hello`] and [`Response::Hello`] are variant 0 and their fields are frozen
//! across versions, so a host and a board of different versions can always tell each other
//! their [`PROTOCOL_VERSION`] and [`SCHEMA_FINGERPRINT`] and say so instead of misreading
//! the rest. After a Hello that did not match, the board rejects every other request with
//! [`Rejection::ProtocolMismatch`].
//!
//! # Using it from a host
//! - Send [`Request::Hello`] first; stop with the board's versions if `compatible` is false.
//! - Give every new request a new sequence number (wrapping). A board answers a repeated
//!   (sequence number, body) pair from its cache without acting again, so resending after
//!   a lost answer is safe; [`Response::Nack`] means the board saw a damaged frame: resend.
//! - Frames whose sequence number does not match the request outstanding are stale or
//!   telemetry ([`Response::Telemetry`]); skip them.
//! - Logs: [`Request::ListTrials`], then [`Request::ReadLog`] from offset 0 with
//!   `max_len` = [`MAX_LOG_CHUNK`], each next offset = offset + data length, until the
//!   offset reaches `total` of a finished trial. Decode the bytes with [`decode_blocks`]
//!   (compressed blocks of [`Record`]s, a key frame each; `record_size` in the trial's
//!   header is the size of one decoded record). A chunk may be shorter than asked (the
//!   ring's end); that is not the end of the trial.
//! - Saves ([`Request::SaveCorrections`], [`Request::SaveParams`]) answer only after the
//!   flash write: allow a few seconds (a sector erase takes up to 2 s).
//!
//! # Why not postcard-rpc
//! postcard-rpc (typed endpoints over a COBS serial transport) was considered. Its server
//! side is built around async dispatch tasks and its host client around tokio, while the
//! board's request handler here is a plain synchronous function `bytes in -> bytes out`
//! that must run identically on the UART, on a host pseudo-terminal and inside unit tests
//! without any executor. The messages do derive postcard-schema's `Schema` (the fingerprint
//! below is made from it) and COBS is the `cobs` crate's (as in postcard), so a move to
//! postcard-rpc later would keep the types.
//!
//! # Schema fingerprint
//! [`SCHEMA_FINGERPRINT`] is derived from the types: every message type derives
//! postcard-schema's `Schema`, and the fingerprint folds the schema hashes of
//! [`Request`], [`Response`] and the log [`Record`] with the [`WIRE_RULES`] the types cannot
//! express. A golden test (`tests::schema_golden`) also pins the bytes of one sample of
//! every variant, so an encoding change that leaves the types alone is caught too.

use crate::control::PiGains;
use crate::correction::{CorrectionError, Corrections};
use crate::kinematics::Twist;
use crate::motion::{Direction, OmniPath, ProfileLimits, Segment, MAX_SEGMENTS};
use crate::odometry::Pose;
pub use crate::omni_cal::IdleWheels;
use crate::robot::{DriveType, Robot, RobotError, RobotKind, MAX_WHEELS};
use core::fmt;
use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

mod frame;
mod log;
mod messages;
mod params;
#[cfg(test)]
mod tests;

pub use crate::num::Num;
pub use frame::*;
pub use log::*;
pub use messages::*;
pub use params::*;

/// Bumped on any incompatible change of the messages or framing.
pub const PROTOCOL_VERSION: u16 = 9;

/// Shortest non-zero host-link timeout a program accepts: the console's requests while it
/// waits for a program come every 50 ms, its heartbeat at the latest every 200 ms.
pub const MIN_LINK_TIMEOUT_MS: u16 = 250;

/// The host-link timeout the console asks for by default (ms).
pub const DEFAULT_LINK_TIMEOUT_MS: u16 = 500;

/// The encoding rules the message types cannot express (framing, the packed log record,
/// the log's block codec), hashed into [`SCHEMA_FINGERPRINT`] with the types.
pub const WIRE_RULES: &str = "wheelcal frame=cobs(seq:u16le|postcard(body)|crc32-iso-hdlc:u32le) 0x00, \
payload<=1024; log record=fields in declaration order, fixed-width little-endian, arrays cut to the \
trial's wheel count; log data=blocks of a key record then zigzag-varint deltas";

/// The fingerprint exchanged in the handshake, derived from the types: the postcard-schema
/// hashes (field and variant names, order and data-model types) of [`Request`],
/// [`Response`] and [`Record`] and the hash of [`WIRE_RULES`], folded by CRC-32. Changing
/// any message type changes it, without anyone editing a constant.
pub const SCHEMA_FINGERPRINT: u32 = schema_fingerprint::<Request, Response<'static>, Record>();

/// The fingerprint of a request type, a response type and a log record type.
const fn schema_fingerprint<Req, Resp, Rec>() -> u32
where
    Req: postcard_schema::Schema,
    Resp: postcard_schema::Schema,
    Rec: postcard_schema::Schema,
{
    use postcard_schema::key::Key;
    let keys = [
        Key::for_path::<Req>("wheelcal/request").to_bytes(),
        Key::for_path::<Resp>("wheelcal/response").to_bytes(),
        Key::for_path::<Rec>("wheelcal/log-record").to_bytes(),
        Key::for_path::<()>(WIRE_RULES).to_bytes(),
    ];
    let mut all = [0u8; 32];
    let mut i = 0;
    while i < all.len() {
        all[i] = keys[i / 8][i % 8];
        i += 1;
    }
    CRC32.checksum(&all)
}

/// Largest unencoded frame (seq + body + crc).
pub const MAX_PAYLOAD: usize = 1024;
/// Largest frame on the wire: COBS adds one byte per 254 plus one, and the delimiter.
pub const MAX_WIRE: usize = MAX_PAYLOAD + MAX_PAYLOAD / 254 + 2;
/// Largest log chunk: leaves room for the chunk's header inside [`MAX_PAYLOAD`].
pub const MAX_LOG_CHUNK: usize = 992;
/// Most trials a board keeps and lists.
pub const MAX_TRIALS: usize = 8;
/// Length of the firmware version text.
pub const FIRMWARE_LEN: usize = 24;

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
const SEQ_LEN: usize = 2;
const CRC_LEN: usize = 4;
