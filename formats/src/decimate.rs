//! Fewer rows for long, fast recordings (docs/formats.md §2, "Fast recordings").
//!
//! Diagnosis replays a recording many times, so its cost and memory grow with the rows.
//! Above about 100 rows/s the extra rows add nothing the models can use: encoder counts
//! are cumulative (the counts at the kept rows carry all the travel), vision samples are
//! kept, and a command held over merged rows is replaced by its time-weighted mean, so
//! the commanded travel between kept rows is exact. A row is kept when it comes at least
//! [`KEEP_FRACTION`] of `1 / max_rate` after the last kept row, or when it has a pose and
//! comes that long after the last kept pose; the last row is always kept. A recording at
//! or below the rate (intervals varying by up to 25 %) keeps every row.

use crate::recording::{Cells, Decimation, Recording, RecordingError, RowSink};
use calib_core::robot::Robot;
use std::path::Path;

/// Default most rows per second diagnosis works on (`wheelcal diagnose --max-rate`).
pub const DEFAULT_MAX_ROW_RATE_HZ: f64 = 100.0;

/// A row is kept this fraction of the target interval after the last kept one: a
/// recording at the target rate whose intervals vary by up to 25 % keeps every row, and
/// one at twice the rate keeps every other row.
pub const KEEP_FRACTION: f64 = 0.75;

/// Merges rows as they come (so a file is never held at its full rate).
#[derive(Debug, Clone)]
pub struct Decimator {
    min_gap_s: f64,
    max_rate_hz: f64,
    last_kept_t: f64,
    last_kept_pose_t: f64,
    /// Per wheel, the command in force (the last one given).
    held: Vec<Option<f64>>,
    /// Per wheel, the integral of the held command since the last kept row, and the time
    /// it covers.
    integral: Vec<(f64, f64)>,
    /// The last row offered, when it was not kept.
    pending: Option<Cells>,
    last_t: f64,
    rows_read: usize,
    rows_kept: usize,
}

impl Decimator {
    /// A decimator for `wheels` wheels to at most about `max_rate_hz` rows/s.
    pub fn new(wheels: usize, max_rate_hz: f64) -> Self {
        Decimator {
            min_gap_s: KEEP_FRACTION / max_rate_hz,
            max_rate_hz,
            last_kept_t: f64::NEG_INFINITY,
            last_kept_pose_t: f64::NEG_INFINITY,
            held: vec![None; wheels],
            integral: vec![(0.0, 0.0); wheels],
            pending: None,
            last_t: f64::NAN,
            rows_read: 0,
            rows_kept: 0,
        }
    }

    /// Offers the next row (times strictly increasing); appended to `rec` if kept.
    pub fn offer(&mut self, rec: &mut Recording, row: Cells) {
        self.rows_read += 1;
        if self.last_t.is_finite() {
            let dt = row.t - self.last_t;
            for (acc, c) in self.integral.iter_mut().zip(&self.held) {
                if let Some(c) = c {
                    acc.0 += c * dt;
                    acc.1 += dt;
                }
            }
        }
        for (h, c) in self.held.iter_mut().zip(&row.cmd) {
            if c.is_some() {
                *h = *c;
            }
        }
        self.last_t = row.t;
        if self.keeps(row.t, row.pose.is_some()) {
            self.keep(rec, row);
        } else {
            self.pending = Some(row);
        }
    }

    /// The rule: a row comes long enough after the last kept row, or it has a pose and
    /// comes long enough after the last kept pose.
    fn keeps(&self, t: f64, has_pose: bool) -> bool {
        t - self.last_kept_t >= self.min_gap_s
            || (has_pose && t - self.last_kept_pose_t >= self.min_gap_s)
    }

    /// Whether [`Decimator::offer`] would keep every row of `rec` (no copy is made).
    fn keeps_all(&self, rec: &Recording) -> bool {
        let (mut last, mut last_pose) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for k in 0..rec.len() {
            let (t, has_pose) = (rec.t[k], rec.x[k].is_some());
            // The last row is always kept.
            let keep = k + 1 == rec.len()
                || t - last >= self.min_gap_s
                || (has_pose && t - last_pose >= self.min_gap_s);
            if !keep {
                return false;
            }
            last = t;
            if has_pose {
                last_pose = t;
            }
        }
        true
    }

    fn keep(&mut self, rec: &mut Recording, mut row: Cells) {
        // The row before's command becomes the mean of what was held since it.
        if self.rows_kept > 0 {
            for (w, acc) in rec.wheels.iter_mut().zip(&self.integral) {
                if let (Some(c), true) = (&mut w.cmd, acc.1 > 0.0) {
                    if let Some(last) = c.last_mut() {
                        *last = Some(acc.0 / acc.1);
                    }
                }
            }
        }
        self.integral.iter_mut().for_each(|a| *a = (0.0, 0.0));
        // A blank command here means the one in force, which the mean above no longer
        // shows.
        row.cmd.clone_from(&self.held);
        self.last_kept_t = row.t;
        if row.pose.is_some() {
            self.last_kept_pose_t = row.t;
        }
        row.push_to(rec);
        self.pending = None;
        self.rows_kept += 1;
    }

    /// Keeps the last row (the recording ends when the file does) and says what was done
    /// (also in `rec.merged` when rows were merged).
    pub fn close(&mut self, rec: &mut Recording) -> Decimation {
        if let Some(row) = self.pending.take() {
            self.keep(rec, row);
        }
        let info = Decimation {
            rows_read: self.rows_read,
            rows_kept: self.rows_kept,
            max_row_rate_hz: self.max_rate_hz,
        };
        if info.merged() {
            rec.merged = Some(info);
        }
        info
    }
}

impl RowSink for Decimator {
    fn push(&mut self, rec: &mut Recording, row: Cells) {
        self.offer(rec, row);
    }

    fn finish(&mut self, rec: &mut Recording) {
        self.close(rec);
    }
}

/// Reads a recording ([`Recording::load`]) merging its rows to about `max_rate_hz` per
/// second as they are read: the file is never held at its full rate.
pub fn load(path: &Path, robot: &Robot, max_rate_hz: f64) -> Result<Recording, RecordingError> {
    Recording::load_into(
        path,
        robot,
        &mut Decimator::new(robot.wheels.len(), max_rate_hz),
    )
}

/// [`load`] on CSV text (`path` only names it in messages).
pub fn parse(
    text: &str,
    path: &Path,
    robot: &Robot,
    max_rate_hz: f64,
) -> Result<Recording, RecordingError> {
    Recording::parse_into(
        text,
        path,
        robot,
        &mut Decimator::new(robot.wheels.len(), max_rate_hz),
    )
}

impl Recording {
    /// This recording with rows merged to at most about `max_rate_hz` rows/s (see the
    /// module's doc); unchanged when no row comes that fast.
    pub fn decimated(self, max_rate_hz: f64) -> (Recording, Decimation) {
        let mut d = Decimator::new(self.wheels.len(), max_rate_hz);
        if d.keeps_all(&self) {
            let n = self.len();
            let info = Decimation {
                rows_read: n,
                rows_kept: n,
                max_row_rate_hz: max_rate_hz,
            };
            return (self, info);
        }
        let mut out = Recording {
            wheels: self
                .wheels
                .iter()
                .map(|w| crate::recording::WheelSeries {
                    name: w.name.clone(),
                    cmd: w.cmd.as_ref().map(|_| Vec::new()),
                    enc: w.enc.as_ref().map(|_| Vec::new()),
                })
                .collect(),
            leg_front: self.leg_front.as_ref().map(|_| Vec::new()),
            leg_rear: self.leg_rear.as_ref().map(|_| Vec::new()),
            notes: self.notes.clone(),
            time_faults: self.time_faults.clone(),
            ..Default::default()
        };
        for k in 0..self.len() {
            d.offer(&mut out, Cells::of(&self, k));
        }
        let mut info = d.close(&mut out);
        if let Some(before) = self.merged {
            // Merged twice: counted from the file's rows.
            info.rows_read = before.rows_read;
            out.merged = Some(info);
        }
        out.shrink_to_fit();
        (out, info)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::presets;

    /// `seconds` of a two-wheel recording at `rate` rows/s (times jittered by up to
    /// `jitter` of a row), sinusoidal held commands, encoders counting their integral,
    /// and a pose every `pose_every` rows.
    fn recording(seconds: f64, rate: f64, jitter: f64, pose_every: usize) -> Recording {
        let robot = presets::mobolab();
        let mut rec = Recording::new(&robot, true, true);
        let n = (seconds * rate) as usize;
        let (mut a, mut b) = (0.0f64, 0.0f64);
        let mut t_prev = 0.0;
        let mut cmd_prev = (0.0, 0.0);
        for k in 0..n {
            // Deterministic jitter without a generator.
            let j = jitter * ((k as f64 * 12.9898).sin() * 43758.5453).fract();
            let t = (k as f64 + j) / rate;
            a += cmd_prev.0 * (t - t_prev);
            b += cmd_prev.1 * (t - t_prev);
            let cmd = (
                3.0 * (1.3 * t).sin() + 0.5,
                2.0 * (0.7 * t).cos() - (k % 7) as f64 * 0.1,
            );
            let row = Cells {
                t,
                cmd: vec![Some(cmd.0), Some(cmd.1)],
                enc: vec![Some((a * 300.0) as i64), Some((b * 300.0) as i64)],
                pose: (k % pose_every == 0).then_some((a * 0.01, b * 0.01, 0.1 * t)),
                legs: [None, None],
            };
            row.push_to(&mut rec);
            (t_prev, cmd_prev) = (t, cmd);
        }
        rec
    }

    /// Integral of wheel `w`'s held command from the first row to each row.
    fn commanded_travel(rec: &Recording, w: usize) -> Vec<(f64, f64)> {
        let c = rec.wheels[w].cmd.as_ref().unwrap();
        let mut s = 0.0;
        let mut out = vec![(rec.t[0], 0.0)];
        for k in 1..rec.len() {
            s += c[k - 1].unwrap() * (rec.t[k] - rec.t[k - 1]);
            out.push((rec.t[k], s));
        }
        out
    }

    #[test]
    fn merged_rows_keep_the_commanded_travel_counts_and_poses() {
        let full = recording(20.0, 600.0, 0.3, 20);
        let (dec, info) = full.clone().decimated(100.0);
        assert_eq!(info.rows_read, full.len());
        assert_eq!(info.rows_kept, dec.len());
        // Rows about every 8.3 ms (the first row at least 7.5 ms after the last kept),
        // plus the 30 Hz pose rows that fall between.
        let per_s = dec.len() as f64 / 20.0;
        assert!((120.0..=150.0).contains(&per_s), "{per_s} rows/s");
        // Every pose sample is kept (30 Hz is under the rate), and the last row.
        assert_eq!(dec.pose_rows().count(), full.pose_rows().count());
        assert_eq!(dec.t.last(), full.t.last());
        // At every kept row, the commanded travel since the start is the full-rate one
        // (rounding only), and the counts and the pose are those of the same row.
        for w in 0..2 {
            let fine = commanded_travel(&full, w);
            let coarse = commanded_travel(&dec, w);
            let mut j = 0;
            for (t, s) in coarse {
                while fine[j].0 < t {
                    j += 1;
                }
                assert_eq!(fine[j].0, t);
                assert!(
                    (fine[j].1 - s).abs() < 1e-9,
                    "wheel {w} at {t}: {s} vs {}",
                    fine[j].1
                );
            }
        }
        let row_of = |t: f64| full.t.iter().position(|&v| v == t).unwrap();
        for k in 0..dec.len() {
            let f = row_of(dec.t[k]);
            for w in 0..2 {
                assert_eq!(
                    dec.wheels[w].enc.as_ref().unwrap()[k],
                    full.wheels[w].enc.as_ref().unwrap()[f]
                );
            }
            assert_eq!(dec.x[k], full.x[f]);
        }
    }

    #[test]
    fn a_recording_at_the_rate_keeps_every_row_and_decimating_twice_changes_nothing() {
        // 100 rows/s with intervals 20 % apart, and 200 rows/s: untouched, then halved.
        let at_rate = recording(10.0, 100.0, 0.1, 3);
        let (same, info) = at_rate.clone().decimated(100.0);
        assert!(!info.merged());
        assert_eq!(same, at_rate);
        let fast = recording(10.0, 200.0, 0.0, 1);
        let (half, info) = fast.decimated(100.0);
        assert_eq!(
            info.rows_kept, 1001,
            "every other row of 2000, and the last"
        );
        let (again, info2) = half.clone().decimated(100.0);
        assert!(!info2.merged());
        assert_eq!(again, half);
    }

    #[test]
    fn reading_with_a_rate_equals_decimating_what_was_read() {
        let robot = presets::mobolab();
        let full = recording(5.0, 500.0, 0.1, 17);
        let mut csv = Vec::new();
        full.write_csv(&mut csv).unwrap();
        let text = String::from_utf8(csv).unwrap();
        let path = std::path::Path::new("fast.csv");
        let read = Recording::parse(&text, path, &robot).unwrap();
        let (expected, info) = read.decimated(100.0);
        let streamed = parse(&text, path, &robot, 100.0).unwrap();
        assert_eq!(streamed, expected);
        assert_eq!(streamed.merged, Some(info));
        assert!(info.rows_kept * 3 < info.rows_read, "{info:?}");
    }
}
