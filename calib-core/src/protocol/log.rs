//! The trial list, log chunks and the fixed-size log record.

#[allow(unused_imports)]
use super::*;

/// The trial list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Trials {
    /// Trials still stored, oldest first.
    pub trials: Vec<TrialInfo, MAX_TRIALS>,
    /// Trials evicted since boot to make room for newer ones.
    pub evicted: u32,
}

/// A trial's header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct TrialInfo {
    /// Trial id (from 1, wrapping; never 0).
    pub id: u16,
    /// What was run.
    pub program: ProgramKind,
    /// Board uptime at the first record.
    pub start_ms: u64,
    /// Record rate (Hz): the control rate divided by the decimation.
    pub rate_hz: u16,
    /// Wheels per record.
    pub wheel_count: u8,
    /// Bytes per record ([`record_size`] of `wheel_count`).
    pub record_size: u16,
    /// Records stored (`bytes / record_size`).
    pub records: u32,
    /// Bytes stored.
    pub bytes: u32,
    /// Records not stored because the log was full: the trial is missing its end.
    pub dropped: u32,
    /// How the trial ended (`Running` while it records).
    pub end: TrialEnd,
    /// Corrections in force during the trial.
    pub corrections: Corrections,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
/// What a trial ran, kept in its header.
pub enum ProgramKind {
    /// Driving by twist commands rather than a program.
    Drive,
    /// UMBmark square.
    Umbmark {
        /// Side length (m).
        side_m: f32,
        /// Turning sense.
        dir: Direction,
    },
    /// One of [Redundant omni]'s straight omni paths.
    Omni {
        /// Which path.
        path: OmniPath,
        /// Commanded length (m).
        length_m: f32,
    },
    /// A segment list from the host.
    Custom {
        /// Number of segments.
        segments: u8,
    },
    /// A circle driven forward.
    Circle {
        /// Radius (m).
        radius_m: f32,
        /// Turning sense.
        dir: Direction,
        /// Times round.
        laps: u8,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
/// How a trial ended.
pub enum TrialEnd {
    /// Still recording.
    Running,
    /// The program ran to its end.
    Completed,
    /// Stopped by request (or by the start of another trial).
    Stopped,
    /// Cut by an emergency stop.
    EStop,
    /// Cut by a wheel fault (stall or counter jump).
    Fault,
    /// Cut because twist commands stopped arriving within the command timeout.
    CommandTimeout,
    /// Cut by the host-link failsafe: no request from the host within the program's
    /// link timeout.
    LinkLost,
}

/// Part of a trial's record bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct LogChunk<'a> {
    /// Trial id.
    pub trial: u16,
    /// Byte offset of `data` within the trial's records.
    pub offset: u32,
    /// The trial's length in bytes so far (grows while it runs).
    pub total: u32,
    #[serde(borrow)]
    /// The bytes.
    pub data: Bytes<'a>,
}

/// Borrowed bytes serialised as one postcard byte string (length + raw bytes), so a log
/// chunk is copied once, straight from the ring into the frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Bytes<'a>(pub &'a [u8]);

impl Serialize for Bytes<'_> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_bytes(self.0)
    }
}

impl postcard_schema::Schema for Bytes<'_> {
    const SCHEMA: &'static postcard_schema::schema::NamedType =
        &postcard_schema::schema::NamedType {
            name: "Bytes",
            ty: &postcard_schema::schema::DataModelType::ByteArray,
        };
}

impl<'de: 'a, 'a> Deserialize<'de> for Bytes<'a> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        <&'de [u8]>::deserialize(d).map(Bytes)
    }
}

// Log records
// ---------------------------------------------------------------------------------------

/// Bytes of one log record for `n` wheels.
pub const fn record_size(n: usize) -> usize {
    4 + 8 * n + 12
}

/// One decimated control tick, packed little-endian without padding or tags (the layout
/// is its `Schema` plus [`WIRE_RULES`]), so log transfer is almost all payload.
#[derive(Debug, Clone, Copy, PartialEq, Default, postcard_schema::Schema)]
pub struct Record {
    /// Microseconds since the trial's start (wraps after 71 minutes).
    pub t_us: u32,
    /// Encoder counts since the trial's start.
    pub counts: [i32; MAX_WHEELS],
    /// Commanded wheel rates, rad/s.
    pub cmd: [f32; MAX_WHEELS],
    /// Dead-reckoned pose (m, m, rad) in the trial's frame.
    pub pose: Pose<f32>,
}

impl Record {
    /// Writes the record for `n` wheels; returns the bytes written or `None` if `out` is
    /// too short.
    pub fn encode(&self, n: usize, out: &mut [u8]) -> Option<usize> {
        let n = n.min(MAX_WHEELS);
        let size = record_size(n);
        let out = out.get_mut(..size)?;
        let mut w = out.chunks_exact_mut(4);
        let mut put = |b: [u8; 4]| {
            if let Some(c) = w.next() {
                c.copy_from_slice(&b);
            }
        };
        put(self.t_us.to_le_bytes());
        self.counts[..n].iter().for_each(|c| put(c.to_le_bytes()));
        self.cmd[..n].iter().for_each(|c| put(c.to_le_bytes()));
        put(self.pose.x.to_le_bytes());
        put(self.pose.y.to_le_bytes());
        put(self.pose.theta.to_le_bytes());
        Some(size)
    }

    /// Reads a record for `n` wheels from the start of `b`.
    pub fn decode(n: usize, b: &[u8]) -> Option<Record> {
        if n > MAX_WHEELS {
            return None;
        }
        let b = b.get(..record_size(n))?;
        let mut words = b.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]);
        let mut next = || words.next().unwrap_or_default();
        let mut r = Record {
            t_us: u32::from_le_bytes(next()),
            ..Record::default()
        };
        for c in r.counts[..n].iter_mut() {
            *c = i32::from_le_bytes(next());
        }
        for c in r.cmd[..n].iter_mut() {
            *c = f32::from_le_bytes(next());
        }
        r.pose = Pose::new(
            f32::from_le_bytes(next()),
            f32::from_le_bytes(next()),
            f32::from_le_bytes(next()),
        );
        Some(r)
    }
}

// Compressed log blocks
// ---------------------------------------------------------------------------------------
//
// A trial's log bytes are a sequence of blocks `len u16 LE | records u8 | body`. A block's
// first record is a key frame (predicted from zero), the others are predicted from the
// two before (`2*prev - prev2`, wrapping, on the 32-bit words of the record: time,
// counts, command bits, pose bits), and each residual is written zigzag + varint as
// postcard writes integers. A steady drive leaves residuals of 0 or ±1, one byte each,
// and a record header byte omits whole groups whose residuals are all zero. Floats are
// predicted on their bit patterns, so the decoded records are bit-exact. Every block
// decodes on its own: a damaged or missing block costs only its own records.

/// Largest block (header included): one block is staged in RAM on the board.
pub const LOG_BLOCK_MAX: usize = 512;
/// Block header: length (u16 LE) of the body, then the record count (u8).
pub const LOG_BLOCK_HEADER: usize = 3;
/// Most bytes one encoded record can take: a header byte and a 5-byte varint per word.
pub const fn max_encoded_record(n: usize) -> usize {
    1 + 5 * (record_size(n) / 4)
}

const GROUP_T: u8 = 1;
const GROUP_COUNTS: u8 = 2;
const GROUP_CMD: u8 = 4;
const GROUP_POSE: u8 = 8;
/// Words per record for `n` wheels.
const fn words(n: usize) -> usize {
    record_size(n) / 4
}
const MAX_WORDS: usize = record_size(MAX_WHEELS) / 4;

fn to_words(r: &Record, n: usize, w: &mut [u32; MAX_WORDS]) {
    w[0] = r.t_us;
    for i in 0..n {
        w[1 + i] = r.counts[i] as u32;
        w[1 + n + i] = r.cmd[i].to_bits();
    }
    w[1 + 2 * n] = r.pose.x.to_bits();
    w[2 + 2 * n] = r.pose.y.to_bits();
    w[3 + 2 * n] = r.pose.theta.to_bits();
}

fn from_words(w: &[u32; MAX_WORDS], n: usize) -> Record {
    let mut r = Record {
        t_us: w[0],
        ..Record::default()
    };
    for i in 0..n {
        r.counts[i] = w[1 + i] as i32;
        r.cmd[i] = f32::from_bits(w[1 + n + i]);
    }
    r.pose = Pose::new(
        f32::from_bits(w[1 + 2 * n]),
        f32::from_bits(w[2 + 2 * n]),
        f32::from_bits(w[3 + 2 * n]),
    );
    r
}

/// Word ranges of the groups a header bit can omit, in order.
fn groups(n: usize) -> [(u8, core::ops::Range<usize>); 4] {
    [
        (GROUP_T, 0..1),
        (GROUP_COUNTS, 1..1 + n),
        (GROUP_CMD, 1 + n..1 + 2 * n),
        (GROUP_POSE, 1 + 2 * n..4 + 2 * n),
    ]
}

/// The prediction state shared by the encoder and the decoder.
#[derive(Debug, Clone)]
struct Predictor {
    prev: [u32; MAX_WORDS],
    prev2: [u32; MAX_WORDS],
    /// Records seen in this block (saturating at 2).
    seen: u8,
}

impl Predictor {
    const fn new() -> Self {
        Predictor {
            prev: [0; MAX_WORDS],
            prev2: [0; MAX_WORDS],
            seen: 0,
        }
    }
    fn predict(&self, k: usize) -> u32 {
        match self.seen {
            0 => 0,
            1 => self.prev[k],
            _ => self.prev[k].wrapping_mul(2).wrapping_sub(self.prev2[k]),
        }
    }
    fn push(&mut self, w: &[u32; MAX_WORDS]) {
        self.prev2 = self.prev;
        self.prev = *w;
        self.seen = self.seen.saturating_add(1).min(2);
    }
}

fn zigzag(v: i32) -> u32 {
    ((v << 1) ^ (v >> 31)) as u32
}

fn unzigzag(v: u32) -> i32 {
    ((v >> 1) as i32) ^ -((v & 1) as i32)
}

fn put_varint(mut v: u32, out: &mut [u8], at: &mut usize) {
    loop {
        let b = (v & 0x7f) as u8;
        v >>= 7;
        out[*at] = if v == 0 { b } else { b | 0x80 };
        *at += 1;
        if v == 0 {
            return;
        }
    }
}

fn get_varint(b: &[u8], at: &mut usize) -> Option<u32> {
    let mut v = 0u32;
    for i in 0..5 {
        let byte = *b.get(*at)?;
        *at += 1;
        if i == 4 && byte > 0x0f {
            return None; // more than 32 bits
        }
        v |= ((byte & 0x7f) as u32) << (7 * i);
        if byte & 0x80 == 0 {
            return Some(v);
        }
    }
    None
}

/// Builds log blocks one record at a time in a buffer of [`LOG_BLOCK_MAX`] bytes.
#[derive(Debug, Clone)]
pub struct BlockEncoder {
    n: usize,
    buf: [u8; LOG_BLOCK_MAX],
    len: usize,
    records: u8,
    pred: Predictor,
}

impl BlockEncoder {
    /// An encoder for records of `n` wheels (at most [`MAX_WHEELS`]).
    pub const fn new(n: usize) -> Self {
        BlockEncoder {
            n: if n > MAX_WHEELS { MAX_WHEELS } else { n },
            buf: [0; LOG_BLOCK_MAX],
            len: LOG_BLOCK_HEADER,
            records: 0,
            pred: Predictor::new(),
        }
    }

    /// Records in the block being built.
    pub fn records(&self) -> u8 {
        self.records
    }

    /// Whether `push` would first need the block taken out.
    pub fn is_full(&self) -> bool {
        self.records == u8::MAX || self.len + max_encoded_record(self.n) > LOG_BLOCK_MAX
    }

    /// Adds a record; false (record not added) when the block is full: take it first.
    pub fn push(&mut self, r: &Record) -> bool {
        if self.is_full() {
            return false;
        }
        let n = self.n;
        let mut w = [0u32; MAX_WORDS];
        to_words(r, n, &mut w);
        let mut res = [0u32; MAX_WORDS];
        for (k, x) in res[..words(n)].iter_mut().enumerate() {
            *x = zigzag(w[k].wrapping_sub(self.pred.predict(k)) as i32);
        }
        let head_at = self.len;
        let mut at = head_at + 1;
        let mut head = 0u8;
        for (bit, range) in groups(n) {
            if res[range.clone()].iter().all(|&x| x == 0) {
                head |= bit;
            } else {
                for &x in &res[range] {
                    put_varint(x, &mut self.buf, &mut at);
                }
            }
        }
        self.buf[head_at] = head;
        self.len = at;
        self.records += 1;
        self.pred.push(&w);
        true
    }

    /// The finished block (header included), if it holds any record; the next record
    /// starts a new block with a key frame.
    pub fn take(&mut self) -> Option<&[u8]> {
        if self.records == 0 {
            return None;
        }
        let body = (self.len - LOG_BLOCK_HEADER) as u16;
        self.buf[..2].copy_from_slice(&body.to_le_bytes());
        self.buf[2] = self.records;
        let len = self.len;
        self.len = LOG_BLOCK_HEADER;
        self.records = 0;
        self.pred = Predictor::new();
        Some(&self.buf[..len])
    }
}

/// What [`decode_blocks`] found.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BlockSummary {
    /// Records decoded from intact blocks.
    pub records: u32,
    /// Blocks skipped because their body did not decode to their record count.
    pub bad_blocks: u32,
    /// Records those blocks declared.
    pub lost_records: u32,
    /// Bytes at the end too short for a block (a truncated transfer).
    pub trailing: u32,
}

/// Decodes a trial's blocks for `n` wheels, calling `each` per record in order. A block
/// that does not decode exactly is skipped whole (its records are counted as lost); the
/// next block is found by its length, so one damaged block costs only itself.
pub fn decode_blocks(n: usize, data: &[u8], mut each: impl FnMut(Record)) -> BlockSummary {
    let mut s = BlockSummary::default();
    if n > MAX_WHEELS {
        s.trailing = data.len() as u32;
        return s;
    }
    let mut at = 0;
    while at < data.len() {
        let Some(h) = data.get(at..at + LOG_BLOCK_HEADER) else {
            s.trailing = (data.len() - at) as u32;
            break;
        };
        let body_len = u16::from_le_bytes([h[0], h[1]]) as usize;
        let count = h[2];
        let Some(body) = data.get(at + LOG_BLOCK_HEADER..at + LOG_BLOCK_HEADER + body_len) else {
            s.trailing = (data.len() - at) as u32;
            break;
        };
        at += LOG_BLOCK_HEADER + body_len;
        // Validate first, then emit: a bad block must not emit half its records.
        if decode_block(n, body, count, |_| {}) {
            decode_block(n, body, count, &mut each);
            s.records += count as u32;
        } else {
            s.bad_blocks += 1;
            s.lost_records += count as u32;
        }
    }
    s
}

fn decode_block(n: usize, body: &[u8], count: u8, mut each: impl FnMut(Record)) -> bool {
    let mut pred = Predictor::new();
    let mut at = 0;
    for _ in 0..count {
        let Some(&head) = body.get(at) else {
            return false;
        };
        at += 1;
        if head & !(GROUP_T | GROUP_COUNTS | GROUP_CMD | GROUP_POSE) != 0 {
            return false;
        }
        let mut w = [0u32; MAX_WORDS];
        for (bit, range) in groups(n) {
            for k in range {
                let r = if head & bit != 0 {
                    0
                } else {
                    match get_varint(body, &mut at) {
                        Some(v) => v,
                        None => return false,
                    }
                };
                w[k] = pred.predict(k).wrapping_add(unzigzag(r) as u32);
            }
        }
        pred.push(&w);
        each(from_words(&w, n));
    }
    at == body.len()
}

// ---------------------------------------------------------------------------------------
// Framing
// ---------------------------------------------------------------------------------------
