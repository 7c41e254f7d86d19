//! The trial list, log chunks and the fixed-size log record.

#[allow(unused_imports)]
use super::*;

/// The trial list.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Trials {
    /// Trials still stored, oldest first.
    pub trials: Vec<TrialInfo, MAX_TRIALS>,
    /// Trials evicted since boot to make room for newer ones.
    pub evicted: u32,
}

/// A trial's header.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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
    /// One of 001's straight omni paths.
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
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
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
}

/// Part of a trial's record bytes.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
/// is in [`SCHEMA`]), so log transfer is almost all payload.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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

// ---------------------------------------------------------------------------------------
// Framing
// ---------------------------------------------------------------------------------------
