//! The trial log: each trial's records, compressed into blocks
//! ([`calib_core::protocol::BlockEncoder`], a key frame per block), in a RAM byte ring,
//! with a header per trial kept in a small table. The block being built is staged
//! outside the ring and stored whole when it is full or the trial ends, so the ring only
//! ever holds whole blocks and a host never reads one that is still growing.
//!
//! # When the ring fills
//! Trials are contiguous in the ring, oldest first. A record that does not fit first
//! evicts the oldest *finished* trials, one whole trial at a time (counted in
//! `evicted_trials`; the host sees the trial disappear from the list). When only the
//! running trial is left, the ring never overwrites that trial's beginning: new records
//! are dropped and counted in the trial's header (`dropped`) and in the status
//! (`dropped_records`), so a host always knows the trial's end is missing. Starting a trial
//! when the header table is full evicts the oldest trial the same way.
//!
//! Byte offsets are relative to the trial's start and never move while the trial is kept,
//! so a download can resume at any offset.

use calib_core::protocol::{
    BlockEncoder, ProgramKind, Record, Rejection, TrialEnd, TrialInfo, Trials, LOG_BLOCK_MAX,
    MAX_LOG_CHUNK, MAX_TRIALS,
};
use calib_core::Corrections;
use heapless::Deque;

#[derive(Debug, Clone)]
struct Entry {
    info: TrialInfo,
    /// Absolute ring position of the first byte.
    start: u64,
}

/// A ring over a caller's buffer (on the board: 64 KiB of CCM RAM) holding up to
/// [`MAX_TRIALS`] trials.
pub struct TrialLog<'a> {
    buf: &'a mut [u8],
    /// Absolute position of the oldest byte kept.
    head: u64,
    /// Absolute position one past the newest byte.
    tail: u64,
    trials: Deque<Entry, MAX_TRIALS>,
    recording: bool,
    next_id: u16,
    dropped_total: u32,
    evicted_total: u32,
    /// The running trial's block being built.
    block: BlockEncoder,
}

impl<'a> TrialLog<'a> {
    /// A log over `buf` (its contents are ignored).
    pub fn new(buf: &'a mut [u8]) -> Self {
        TrialLog {
            buf,
            head: 0,
            tail: 0,
            trials: Deque::new(),
            recording: false,
            next_id: 1,
            dropped_total: 0,
            evicted_total: 0,
            block: BlockEncoder::new(0),
        }
    }

    /// Size of the log ring (bytes).
    pub fn capacity(&self) -> usize {
        self.buf.len()
    }

    /// Free bytes of the log ring.
    pub fn free(&self) -> usize {
        self.buf.len() - (self.tail - self.head) as usize
    }

    /// Records dropped since boot because the running trial filled the ring.
    pub fn dropped_total(&self) -> u32 {
        self.dropped_total
    }

    /// Trials evicted since boot to make room.
    pub fn evicted_total(&self) -> u32 {
        self.evicted_total
    }

    /// Id of the trial being recorded.
    pub fn recording(&self) -> Option<u16> {
        if self.recording {
            self.trials.back().map(|e| e.info.id)
        } else {
            None
        }
    }

    fn evict_oldest(&mut self) {
        if self.trials.pop_front().is_some() {
            self.evicted_total = self.evicted_total.saturating_add(1);
            self.head = self.trials.front().map_or(self.tail, |e| e.start);
        }
    }

    /// Starts a new trial (finishing a running one as stopped); returns its id.
    pub fn start(
        &mut self,
        program: ProgramKind,
        start_ms: u64,
        rate_hz: u16,
        wheel_count: u8,
        record_size: u16,
        corrections: &Corrections,
    ) -> u16 {
        if self.recording {
            self.finish(TrialEnd::Stopped);
        }
        if self.trials.is_full() {
            self.evict_oldest();
        }
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1).max(1);
        let info = TrialInfo {
            id,
            program,
            start_ms,
            rate_hz,
            wheel_count,
            record_size,
            records: 0,
            bytes: 0,
            dropped: 0,
            end: TrialEnd::Running,
            corrections: corrections.clone(),
        };
        // Capacity was made above.
        let _ = self.trials.push_back(Entry {
            info,
            start: self.tail,
        });
        self.recording = true;
        self.block = BlockEncoder::new(wheel_count as usize);
        id
    }

    /// Adds one record to the running trial's block, storing the block first when it is
    /// full; false if no trial runs or the stored block was dropped (ring full).
    pub fn log_record(&mut self, rec: &Record) -> bool {
        if !self.recording {
            return false;
        }
        let mut stored = true;
        if self.block.is_full() {
            stored = self.store_block();
        }
        self.block.push(rec) && stored
    }

    /// Moves the staged block into the ring.
    fn store_block(&mut self) -> bool {
        let mut tmp = [0u8; LOG_BLOCK_MAX];
        let records = self.block.records() as u32;
        let Some(b) = self.block.take() else {
            return true;
        };
        let len = b.len();
        tmp[..len].copy_from_slice(b);
        self.store(&tmp[..len], records)
    }

    /// Appends raw bytes counted as one record (tests of the ring).
    pub fn append(&mut self, rec: &[u8]) -> bool {
        self.store(rec, 1)
    }

    /// Appends `rec` (holding `records` records) to the running trial; false if none runs
    /// or it was dropped.
    fn store(&mut self, rec: &[u8], records: u32) -> bool {
        if !self.recording {
            return false;
        }
        while self.free() < rec.len() && self.trials.len() > 1 {
            self.evict_oldest();
        }
        let fits = self.free() >= rec.len();
        let Some(active) = self.trials.back_mut() else {
            return false;
        };
        if !fits {
            active.info.dropped = active.info.dropped.saturating_add(records);
            self.dropped_total = self.dropped_total.saturating_add(records);
            return false;
        }
        active.info.records += records;
        active.info.bytes += rec.len() as u32;
        let cap = self.buf.len();
        let at = (self.tail % cap as u64) as usize;
        let first = rec.len().min(cap - at);
        self.buf[at..at + first].copy_from_slice(&rec[..first]);
        self.buf[..rec.len() - first].copy_from_slice(&rec[first..]);
        self.tail += rec.len() as u64;
        true
    }

    /// Ends the running trial.
    pub fn finish(&mut self, end: TrialEnd) {
        if self.recording {
            self.store_block();
            if let Some(e) = self.trials.back_mut() {
                e.info.end = end;
            }
            self.recording = false;
        }
    }

    /// Forgets every trial (not while one is recording: the caller checks). The eviction
    /// count restarts too: it tells the host that older trials are missing from the list,
    /// and after a clear none is (`log list` said the cleared trials "were
    /// evicted").
    pub fn clear(&mut self) {
        self.block.take();
        self.trials.clear();
        self.head = self.tail;
        self.recording = false;
        self.evicted_total = 0;
    }

    /// The stored trials' headers, oldest first, and the eviction count.
    pub fn list(&self) -> Trials {
        Trials {
            trials: self.trials.iter().map(|e| e.info.clone()).collect(),
            evicted: self.evicted_total,
        }
    }

    /// Header of trial `id`, if it is still stored.
    pub fn info(&self, id: u16) -> Option<&TrialInfo> {
        self.trials
            .iter()
            .find(|e| e.info.id == id)
            .map(|e| &e.info)
    }

    /// Up to `max_len` bytes (and at most [`MAX_LOG_CHUNK`]) of trial `id` from `offset`,
    /// contiguous in RAM: a chunk that would cross the ring's end stops there and the host
    /// asks again from where it got to. Returns the bytes and the trial's length.
    pub fn read(&self, id: u16, offset: u32, max_len: u16) -> Result<(&[u8], u32), Rejection> {
        let e = self
            .trials
            .iter()
            .find(|e| e.info.id == id)
            .ok_or(Rejection::NoSuchTrial)?;
        let total = e.info.bytes;
        if offset > total {
            return Err(Rejection::BadOffset { total });
        }
        let want = (total - offset)
            .min(max_len as u32)
            .min(MAX_LOG_CHUNK as u32) as usize;
        let cap = self.buf.len() as u64;
        if cap == 0 {
            return Ok((&[], total));
        }
        let at = ((e.start + offset as u64) % cap) as usize;
        let len = want.min(cap as usize - at);
        Ok((&self.buf[at..at + len], total))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn start(log: &mut TrialLog<'_>) -> u16 {
        log.start(ProgramKind::Drive, 0, 100, 2, 10, &Corrections::None)
    }

    fn pull(log: &TrialLog<'_>, id: u16) -> Vec<u8> {
        let mut out = Vec::new();
        loop {
            let (b, total) = log.read(id, out.len() as u32, 7).unwrap();
            out.extend_from_slice(b);
            if out.len() as u32 == total {
                return out;
            }
            assert!(!b.is_empty());
        }
    }

    #[test]
    fn full_ring_evicts_finished_trials_then_drops_and_counts() {
        let mut buf = [0u8; 100];
        let mut log = TrialLog::new(&mut buf);
        let a = start(&mut log);
        for i in 0..6u8 {
            assert!(log.append(&[i; 10]));
        }
        log.finish(TrialEnd::Completed);
        let b = start(&mut log);
        // 60 bytes used by a: b's 5th record needs a's space, so a is evicted whole.
        for i in 0..10u8 {
            assert!(log.append(&[100 + i; 10]), "record {i}");
        }
        assert!(log.info(a).is_none());
        assert_eq!(log.evicted_total(), 1);
        // A clear forgets the evictions with the trials: nothing older is missing.
        let mut buf2 = [0u8; 100];
        let mut other = TrialLog::new(&mut buf2);
        start(&mut other);
        for i in 0..16u8 {
            other.append(&[i; 10]);
        }
        other.finish(TrialEnd::Completed);
        start(&mut other);
        for i in 0..6u8 {
            other.append(&[i; 10]);
        }
        other.finish(TrialEnd::Completed);
        assert_eq!(other.evicted_total(), 1);
        other.clear();
        assert_eq!((other.list().trials.len(), other.list().evicted), (0, 0));
        // b now fills the ring alone: further records are dropped, counted, never silent.
        assert!(!log.append(&[0xEE; 10]));
        assert!(!log.append(&[0xEE; 10]));
        let info = log.info(b).unwrap().clone();
        assert_eq!((info.records, info.bytes, info.dropped), (10, 100, 2));
        assert_eq!(log.dropped_total(), 2);
        // The ring wrapped: reads stop at the end and resume, content intact and in order.
        let got = pull(&log, b);
        let want: Vec<u8> = (0..10u8).flat_map(|i| [100 + i; 10]).collect();
        assert_eq!(got, want);
    }

    #[test]
    fn bad_reads_are_rejected() {
        let mut buf = [0u8; 100];
        let mut log = TrialLog::new(&mut buf);
        let a = start(&mut log);
        log.append(&[1; 10]);
        assert_eq!(log.read(a + 1, 0, 10), Err(Rejection::NoSuchTrial));
        assert_eq!(log.read(a, 11, 10), Err(Rejection::BadOffset { total: 10 }));
        assert_eq!(log.read(a, 10, 10).unwrap().0.len(), 0);
        log.finish(TrialEnd::Stopped);
        assert_eq!(log.list().trials[0].end, TrialEnd::Stopped);
    }

    #[test]
    fn header_table_full_evicts_oldest() {
        let mut buf = [0u8; 100];
        let mut log = TrialLog::new(&mut buf);
        for _ in 0..MAX_TRIALS + 2 {
            start(&mut log);
            log.append(&[0; 5]);
        }
        let ids: Vec<u16> = log.list().trials.iter().map(|t| t.id).collect();
        assert_eq!(ids, (3..=MAX_TRIALS as u16 + 2).collect::<Vec<_>>());
        assert_eq!(log.evicted_total(), 2);
        // Every finished trial was ended as stopped by the next start.
        assert!(log.list().trials[..MAX_TRIALS - 1]
            .iter()
            .all(|t| t.end == TrialEnd::Stopped));
    }
}
