//! Recordings (docs/formats.md §2): one CSV row per sample with time, per-wheel commands and
//! encoder counts, the measured pose (blank between camera samples) and, for
//! wheeled-legged robots, the leg angles.
//!
//! Read on the host by the diagnose tool and written by the simulator and the console's
//! log export. Every error names the file, the line and the column, because people make
//! these files with their own measuring setups.

use calib_core::robot::{Robot, RobotKind};
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The columns of one wheel.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WheelSeries {
    /// Wheel name, as in the robot file (column prefix).
    pub name: String,
    /// Commanded wheel rate, rad/s; `None` in a row = not recorded at that instant.
    pub cmd: Option<Vec<Option<f64>>>,
    /// Cumulative encoder count.
    pub enc: Option<Vec<Option<i64>>>,
}

/// A whole recording, column-wise.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Recording {
    /// Seconds since start, strictly increasing.
    pub t: Vec<f64>,
    /// One entry per wheel of the robot file, in its order.
    pub wheels: Vec<WheelSeries>,
    /// Measured x of the body origin, world frame (m); `None` = no measurement in that row.
    pub x: Vec<Option<f64>>,
    /// Measured y of the body origin, world frame (m); `None` = no measurement in that row.
    pub y: Vec<Option<f64>>,
    /// Measured heading (rad, wrapped or unwrapped); `None` = no measurement in that row.
    pub theta: Vec<Option<f64>>,
    /// Front leg angle per row (rad), wheeled-legged robots only.
    pub leg_front: Option<Vec<Option<f64>>>,
    /// Rear leg angle per row (rad), wheeled-legged robots only.
    pub leg_rear: Option<Vec<Option<f64>>>,
    /// Notes for the reader (ignored unknown columns).
    pub notes: Vec<String>,
    /// Set when rows were merged (`crate::decimate`): the commands are then means over
    /// the intervals between rows, to be read as held, not as samples of a ramp.
    pub merged: Option<Decimation>,
    /// Where the file's time went back, and how the rows were re-timed (empty when it
    /// increased strictly, or when the recording was not read from a file).
    pub time_faults: TimeFaults,
}

/// Largest step back of `t` (s) the reader re-times: a logger's clock step (ntpd slews
/// offsets below 0.128 s and steps above; a late thread's timestamp is a few rows) is far
/// shorter. Further back is two runs in one file or a clock reset, whose rows cannot be
/// placed: refused.
pub const MAX_TIME_BACK_S: f64 = 1.0;

/// Most places a time going back are listed (all are counted).
pub const MAX_TIME_BACK_LISTED: usize = 1000;

/// Where the time written in a file went back, and what the reader did (formats.md §2).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TimeFaults {
    /// The places, in file order (at most [`MAX_TIME_BACK_LISTED`]).
    pub back: Vec<TimeBack>,
    /// All places (listed or not).
    pub count: usize,
    /// Rows read, and the written steps' median and robust standard deviation (s), over
    /// every row of the file before any merging (0 rows when not read from a file).
    pub rows: usize,
    /// Median written step between rows (s).
    pub step_median_s: f64,
    /// Robust standard deviation of the written steps (1.4826 MAD, s).
    pub step_sd_s: f64,
}

/// One place where the written time went back.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TimeBack {
    /// Line of the file (the header is line 1).
    pub line: usize,
    /// The time written on that line (s).
    pub written_s: f64,
    /// The time it was given (s).
    pub retimed_s: f64,
    /// The clock's error there (s): how far the written time lay behind the re-timed one.
    pub back_s: f64,
    /// True when the clock stepped back and later rows followed it (they were all moved
    /// on by `back_s`); false when this row alone was written early (re-timed halfway
    /// between its neighbours).
    pub clock_step: bool,
}

/// The parse's clock: re-times rows whose written time goes back.
struct Clock {
    /// Added to every written time from here on (the clock's steps back so far).
    offset: f64,
    last_t: f64,
    last_written: f64,
    /// Recent row interval (s), for a row re-timed after a step back.
    dt: f64,
    faults: TimeFaults,
    /// Written steps (f32: 4 bytes a row), for their median and spread.
    steps: Vec<f32>,
}

impl Clock {
    fn new() -> Self {
        Clock {
            offset: 0.0,
            last_t: f64::NEG_INFINITY,
            last_written: f64::NEG_INFINITY,
            dt: f64::NAN,
            faults: TimeFaults::default(),
            steps: Vec::new(),
        }
    }

    fn advance(&mut self, t: f64, written: f64) {
        if self.last_t.is_finite() {
            let step = t - self.last_t;
            // A gap (dropped rows) does not count as the interval.
            if !self.dt.is_finite() {
                self.dt = step;
            } else if step < 3.0 * self.dt {
                self.dt += 0.1 * (step - self.dt);
            }
            if self.last_written.is_finite() {
                self.steps.push((written - self.last_written) as f32);
            }
        }
        self.faults.rows += 1;
        self.last_t = t;
        self.last_written = written;
    }

    fn note(&mut self, b: TimeBack) {
        self.faults.count += 1;
        if self.faults.back.len() < MAX_TIME_BACK_LISTED {
            self.faults.back.push(b);
        }
    }

    /// The held row alone was early: halfway between its neighbours.
    fn single(&mut self, h: &ReadRow, next: f64) -> f64 {
        // (written so that times near f64::MAX do not overflow)
        let t = self.last_t + 0.5 * (next - self.last_t);
        let written = h.written + self.offset;
        self.note(TimeBack {
            line: h.line,
            written_s: h.written,
            retimed_s: t,
            back_s: t - written,
            clock_step: false,
        });
        self.faults.rows += 1;
        self.last_t = t;
        // The next step is measured from the row before this one.
        t
    }

    /// The clock stepped back at the held row: it and every later row move on.
    fn step(&mut self, h: &ReadRow) -> f64 {
        let dt = if self.dt.is_finite() && self.dt > 0.0 {
            self.dt
        } else {
            1e-3
        };
        let t = self.last_t + dt;
        let back = t - (h.written + self.offset);
        self.offset += back;
        self.note(TimeBack {
            line: h.line,
            written_s: h.written,
            retimed_s: t,
            back_s: back,
            clock_step: true,
        });
        self.faults.rows += 1;
        self.last_t = t;
        self.last_written = h.written;
        t
    }

    /// The written steps' median and robust spread.
    fn finish(&mut self) {
        let mut d = std::mem::take(&mut self.steps);
        if d.is_empty() {
            self.faults.step_median_s = f64::NAN;
            self.faults.step_sd_s = f64::NAN;
            return;
        }
        let mid = d.len() / 2;
        d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        let med = d[mid];
        for v in d.iter_mut() {
            *v = (*v - med).abs();
        }
        d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
        self.faults.step_median_s = med as f64;
        self.faults.step_sd_s = 1.4826 * d[mid] as f64;
    }
}

/// One row read, before its time is placed.
struct ReadRow {
    written: f64,
    line: usize,
    enc_cells: Vec<(usize, usize, i64)>,
    cells: Cells,
}

/// The checks between rows (speeds) and what they carry from row to row.
struct Checks {
    rim: Vec<f64>,
    rad_per_count: Option<f64>,
    /// Per wheel, the last encoder sample (t, count).
    last_enc: Vec<Option<(f64, i64)>>,
    /// The last measured pose (t, x, y).
    last_pose: Option<(f64, f64, f64)>,
    pose_travel: f64,
    x_col: usize,
}

impl Checks {
    /// Checks the row at its placed time `t` and hands it to `sink`.
    fn emit(
        &mut self,
        rec: &mut Recording,
        sink: &mut dyn RowSink,
        row: ReadRow,
        t: f64,
        err: &ErrAt<'_>,
        headers: &csv::StringRecord,
    ) -> Result<(), RecordingError> {
        let line = row.line;
        // Speeds between samples: an encoder or pose step no robot makes in the time
        // between two samples is a glitch (a wrapped counter, a swapped marker) or a
        // unit mistake.
        if let Some(rpc) = self.rad_per_count {
            for &(ci, i, v) in &row.enc_cells {
                if let Some((t0, c0)) = self.last_enc[i] {
                    let speed = (v as f64 - c0 as f64).abs() * rpc * self.rim[i] / (t - t0);
                    if speed > MAX_SPEED_M_S {
                        return Err(err(
                            Some(line),
                            Some((ci + 1, headers[ci].to_string())),
                            format!(
                                "the encoder moves {} counts in {:.4} s since the sample before ({c0}), {speed:.3e} m/s at the wheel's rim (at most {MAX_SPEED_M_S} m/s): a glitch or a counter that wrapped",
                                v as i128 - c0 as i128,
                                t - t0
                            ),
                        ));
                    }
                }
                self.last_enc[i] = Some((t, v));
            }
        }
        if let Some((x, y, _)) = row.cells.pose {
            if let Some((t0, x0, y0)) = self.last_pose {
                let step = (x - x0).hypot(y - y0);
                let speed = step / (t - t0);
                if speed > MAX_SPEED_M_S {
                    let hint = if speed / 1000.0 <= MAX_SPEED_M_S {
                        ": looks like millimetres (the pose columns are metres)"
                    } else {
                        ""
                    };
                    return Err(err(
                        Some(line),
                        Some((self.x_col + 1, "x".into())),
                        format!(
                            "the pose moves {step:.4} m in {:.4} s since the measurement before, {speed:.3e} m/s (at most {MAX_SPEED_M_S} m/s){hint}",
                            t - t0
                        ),
                    ));
                }
                self.pose_travel += step;
            }
            self.last_pose = Some((t, x, y));
        }
        let mut cells = row.cells;
        cells.t = t;
        sink.push(rec, cells);
        Ok(())
    }
}

/// A recording that could not be read.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordingError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line (the header is line 1).
    pub line: Option<usize>,
    /// 1-based column number and the column's name.
    pub column: Option<(usize, String)>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for RecordingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
            if let Some((c, _)) = &self.column {
                write!(f, ":{c}")?;
            }
        }
        write!(f, ": ")?;
        if let Some((_, name)) = &self.column {
            write!(f, "column '{name}': ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for RecordingError {}

/// A recording larger than this is refused before it is parsed (the read is capped by the
/// bytes actually read, so a device that never ends fails at once).
pub const MAX_RECORDING_BYTES: u64 = 2 << 30;
/// The pose columns' bound (m): a calibration run stays within a few hundred metres of
/// its origin. A larger value is a unit mistake (millimetres) or a broken cell.
pub const MAX_POSE_M: f64 = 500.0;
/// Fastest body or wheel-rim speed (m/s) a recording may show: 108 km/h, beyond any robot
/// these tools calibrate (the fastest in the papers drive below 2 m/s). Checked on the
/// commanded wheel rates, on the encoders between samples, and on the pose between
/// measurements.
pub const MAX_SPEED_M_S: f64 = 30.0;
/// Largest heading (rad): 1600 turns unwrapped.
pub const MAX_HEADING_RAD: f64 = 1e4;
/// Largest leg angle (rad): one turn either way. A vertical leg is pi/2; 90 is degrees.
pub const MAX_LEG_RAD: f64 = std::f64::consts::TAU;
/// Longest step in `t` between consecutive rows (s). No calibration run pauses for an
/// hour; a longer step is a logger that changed clocks (t = 0, then Unix time) or a typo,
/// and would make any gap analysis meaningless.
pub const MAX_GAP_S: f64 = 3600.0;
/// Pose travel (m) above which encoders that never change are an error, not a robot
/// standing still.
pub const STILL_ENCODER_TRAVEL_M: f64 = 0.1;

#[derive(Clone, Copy, PartialEq)]
enum Col {
    T,
    Cmd(usize),
    Enc(usize),
    X,
    Y,
    Theta,
    LegFront,
    LegRear,
    Ignored,
}

impl Recording {
    /// Releases the columns' spare capacity.
    pub fn shrink_to_fit(&mut self) {
        self.t.shrink_to_fit();
        self.x.shrink_to_fit();
        self.y.shrink_to_fit();
        self.theta.shrink_to_fit();
        for legs in [&mut self.leg_front, &mut self.leg_rear]
            .into_iter()
            .flatten()
        {
            legs.shrink_to_fit();
        }
        for w in &mut self.wheels {
            if let Some(c) = &mut w.cmd {
                c.shrink_to_fit();
            }
            if let Some(e) = &mut w.enc {
                e.shrink_to_fit();
            }
        }
    }

    /// An empty recording with the robot's wheels and the given columns present.
    pub fn new(robot: &Robot, with_cmd: bool, with_enc: bool) -> Self {
        let legs = robot.kind == RobotKind::WheeledLegged;
        Recording {
            wheels: robot
                .wheels
                .iter()
                .map(|w| WheelSeries {
                    name: w.name.to_string(),
                    cmd: with_cmd.then(Vec::new),
                    enc: with_enc.then(Vec::new),
                })
                .collect(),
            leg_front: legs.then(Vec::new),
            leg_rear: legs.then(Vec::new),
            ..Default::default()
        }
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// Appends a row. Slices must have one value per wheel when the columns exist.
    pub fn push_row(&mut self, row: Row<'_>) {
        let n = self.wheels.len();
        Cells {
            t: row.t,
            cmd: (0..n)
                .map(|i| row.cmd.and_then(|v| v.get(i).copied()))
                .collect(),
            enc: (0..n)
                .map(|i| row.enc.and_then(|v| v.get(i).copied()))
                .collect(),
            pose: row.pose,
            legs: [row.legs.map(|l| l.0), row.legs.map(|l| l.1)],
        }
        .push_to(self);
    }

    /// Rows where the pose was measured.
    pub fn pose_rows(&self) -> impl Iterator<Item = (usize, f64, f64, f64)> + '_ {
        (0..self.len()).filter_map(move |i| match (self.x[i], self.y[i], self.theta[i]) {
            (Some(x), Some(y), Some(t)) => Some((i, x, y, t)),
            _ => None,
        })
    }

    /// Reads and checks a recording against the robot it was made with.
    pub fn load(path: &Path, robot: &Robot) -> Result<Self, RecordingError> {
        Self::load_into(path, robot, &mut AllRows)
    }

    /// [`Recording::load`], each row handed to `sink` (which may merge rows).
    pub fn load_into(
        path: &Path,
        robot: &Robot,
        sink: &mut dyn RowSink,
    ) -> Result<Self, RecordingError> {
        let text =
            crate::text_file::read_capped(path, MAX_RECORDING_BYTES, "recording").map_err(|e| {
                RecordingError {
                    path: path.to_path_buf(),
                    line: None,
                    column: None,
                    message: e.0,
                }
            })?;
        Self::parse_into(&text, path, robot, sink)
    }

    /// Parses CSV text; `path` is only used in messages.
    pub fn parse(text: &str, path: &Path, robot: &Robot) -> Result<Self, RecordingError> {
        Self::parse_into(text, path, robot, &mut AllRows)
    }

    /// [`Recording::parse`], each row handed to `sink`.
    ///
    /// The phases: the header names the columns (`columns`, `required_columns`); each
    /// row is read into its cells and placed in time (`Parse::row`, which re-times a
    /// clock's step back) before the checks between rows hand it to `sink`; then the
    /// whole recording is checked (`whole_recording`).
    pub fn parse_into(
        text: &str,
        path: &Path,
        robot: &Robot,
        sink: &mut dyn RowSink,
    ) -> Result<Self, RecordingError> {
        let err = |line: Option<usize>, column: Option<(usize, String)>, message: String| {
            RecordingError {
                path: path.to_path_buf(),
                line,
                column,
                message,
            }
        };
        let mut reader = csv::ReaderBuilder::new()
            .has_headers(true)
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let headers = reader
            .headers()
            .map_err(|e| err(Some(1), None, format!("cannot read the header row: {e}")))?
            .clone();
        if headers.iter().all(|h| h.is_empty()) {
            return Err(err(Some(1), None, "empty recording: no header row".into()));
        }
        let mut rec = Recording::new(robot, false, false);
        let cols = columns(&headers, robot, &mut rec, &err)?;
        required_columns(&headers, robot, &rec, &err)?;
        let mut parse = Parse::new(robot, &headers, &cols, &err);
        let mut record = csv::StringRecord::new();
        let mut lines = crate::text_file::LineCounter::new(text);
        loop {
            let line = lines.line_at(reader.position().byte());
            match reader.read_record(&mut record) {
                Ok(false) => break,
                Ok(true) => {}
                Err(e) => return Err(err(Some(line), None, format!("malformed CSV row: {e}"))),
            }
            let line = record.position().map_or(line, |p| lines.line_at(p.byte()));
            parse.row(&record, line, &mut rec, sink)?;
        }
        let pose_travel = parse.finish(&mut rec, sink)?;
        whole_recording(rec, sink, &cols, &headers, pose_travel, &err)
    }

    /// Writes the recording as docs/formats.md §2 CSV.
    pub fn write_csv<W: Write>(&self, out: W) -> std::io::Result<()> {
        let mut w = csv::Writer::from_writer(out);
        let mut header = vec!["t".to_string()];
        for s in &self.wheels {
            if s.cmd.is_some() {
                header.push(format!("cmd_{}", s.name));
            }
        }
        for s in &self.wheels {
            if s.enc.is_some() {
                header.push(format!("enc_{}", s.name));
            }
        }
        header.extend(["x", "y", "theta"].map(String::from));
        if self.leg_front.is_some() {
            header.push("leg_front".into());
        }
        if self.leg_rear.is_some() {
            header.push("leg_rear".into());
        }
        w.write_record(&header)?;
        let f = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
        let mut row = Vec::with_capacity(header.len());
        for i in 0..self.len() {
            row.clear();
            row.push(format!("{}", self.t[i]));
            for s in &self.wheels {
                if let Some(c) = &s.cmd {
                    row.push(f(c[i]));
                }
            }
            for s in &self.wheels {
                if let Some(e) = &s.enc {
                    row.push(e[i].map_or(String::new(), |v| v.to_string()));
                }
            }
            row.push(f(self.x[i]));
            row.push(f(self.y[i]));
            row.push(f(self.theta[i]));
            if let Some(l) = &self.leg_front {
                row.push(f(l[i]));
            }
            if let Some(l) = &self.leg_rear {
                row.push(f(l[i]));
            }
            w.write_record(&row)?;
        }
        w.flush()
    }

    /// Writes to a file.
    pub fn save(&self, path: &Path) -> std::io::Result<()> {
        let file = std::fs::File::create(path)?;
        self.write_csv(std::io::BufWriter::new(file))
    }
}

/// How the parser's phases make an error: the line, the column (1-based number and
/// name) and the message; the file is the closure's.
type ErrAt<'e> = dyn Fn(Option<usize>, Option<(usize, String)>, String) -> RecordingError + 'e;

/// The header row as columns, each header checked and the recording's optional series
/// made for the columns present: a wheel's `cmd_`/`enc_` columns name a wheel of the robot
/// file, a leg column only counts on a wheeled-legged robot, and unknown columns are
/// noted and ignored (people add their own).
fn columns(
    headers: &csv::StringRecord,
    robot: &Robot,
    rec: &mut Recording,
    err: &ErrAt<'_>,
) -> Result<Vec<Col>, RecordingError> {
    let mut cols = Vec::with_capacity(headers.len());
    let mut seen = std::collections::HashSet::new();
    for (ci, h) in headers.iter().enumerate() {
        let at = Some((ci + 1, h.to_string()));
        if !seen.insert(h.to_string()) {
            return Err(err(Some(1), at, "duplicate column".into()));
        }
        let wheel = |prefix: &str| -> Result<Option<usize>, RecordingError> {
            match h.strip_prefix(prefix) {
                None => Ok(None),
                Some(name) => robot.wheel_index(name).map(Some).ok_or_else(|| {
                    let names: Vec<&str> = robot.wheels.iter().map(|w| w.name.as_str()).collect();
                    err(
                        Some(1),
                        at.clone(),
                        format!(
                            "no wheel '{name}' in the robot file (its wheels: {})",
                            names.join(", ")
                        ),
                    )
                }),
            }
        };
        let col = match h {
            "t" => Col::T,
            "x" => Col::X,
            "y" => Col::Y,
            "theta" => Col::Theta,
            "leg_front" => Col::LegFront,
            "leg_rear" => Col::LegRear,
            _ => {
                if let Some(i) = wheel("cmd_")? {
                    rec.wheels[i].cmd = Some(Vec::new());
                    Col::Cmd(i)
                } else if let Some(i) = wheel("enc_")? {
                    rec.wheels[i].enc = Some(Vec::new());
                    Col::Enc(i)
                } else {
                    rec.notes
                        .push(format!("ignored unknown column '{h}' (column {})", ci + 1));
                    Col::Ignored
                }
            }
        };
        if matches!(col, Col::LegFront | Col::LegRear) {
            if robot.kind != RobotKind::WheeledLegged {
                rec.notes.push(format!(
                    "ignored column '{h}': the robot is not wheeled_legged"
                ));
                cols.push(Col::Ignored);
                continue;
            }
            if col == Col::LegFront {
                rec.leg_front = Some(Vec::new());
            } else {
                rec.leg_rear = Some(Vec::new());
            }
        }
        cols.push(col);
    }
    Ok(cols)
}

/// The columns a recording cannot do without, refused at the header rather than at a
/// row: time and pose, a wheeled-legged robot's legs, and a command or an encoder for
/// every driven wheel.
fn required_columns(
    headers: &csv::StringRecord,
    robot: &Robot,
    rec: &Recording,
    err: &ErrAt<'_>,
) -> Result<(), RecordingError> {
    for required in ["t", "x", "y", "theta"] {
        if !headers.iter().any(|h| h == required) {
            return Err(err(
                Some(1),
                None,
                format!("missing required column '{required}'"),
            ));
        }
    }
    if robot.kind == RobotKind::WheeledLegged {
        // The columns themselves, not `rec.leg_*`: a wheeled-legged recording starts
        // with empty leg series, so those are always present.
        for name in ["leg_front", "leg_rear"] {
            if !headers.iter().any(|h| h == name) {
                return Err(err(
                    Some(1),
                    None,
                    format!("missing column '{name}' (required for wheeled_legged robots)"),
                ));
            }
        }
    }
    for (w, wheel) in rec.wheels.iter().zip(&robot.wheels) {
        if wheel.driven && w.cmd.is_none() && w.enc.is_none() {
            return Err(err(
                Some(1),
                None,
                format!(
                    "driven wheel '{}' needs a 'cmd_{0}' or an 'enc_{0}' column",
                    w.name
                ),
            ));
        }
    }
    Ok(())
}

/// The state of one parse from row to row: the columns, the clock that places each row
/// in time, the row held back while its time is decided, the checks between rows, and
/// one row's buffers, reused for every row (the parser is a hot path: 3.6 M rows).
struct Parse<'a> {
    headers: &'a csv::StringRecord,
    cols: &'a [Col],
    err: &'a ErrAt<'a>,
    /// Index of the `t` column.
    t_col: usize,
    clock: Clock,
    /// A row whose time went back, until the next row says how to re-time it.
    held: Option<ReadRow>,
    checks: Checks,
    enc_cells: Vec<(usize, usize, i64)>,
    cmd_row: Vec<Option<f64>>,
    enc_row: Vec<Option<i64>>,
}

impl<'a> Parse<'a> {
    fn new(
        robot: &Robot,
        headers: &'a csv::StringRecord,
        cols: &'a [Col],
        err: &'a ErrAt<'a>,
    ) -> Self {
        Parse {
            headers,
            cols,
            err,
            t_col: cols.iter().position(|c| *c == Col::T).unwrap_or(0),
            clock: Clock::new(),
            held: None,
            checks: Checks {
                rim: robot.wheels.iter().map(|w| w.radius_m.abs()).collect(),
                rad_per_count: robot.drive.rad_per_count(),
                last_enc: vec![None; robot.wheels.len()],
                last_pose: None,
                pose_travel: 0.0,
                x_col: cols.iter().position(|c| *c == Col::X).unwrap_or(0),
            },
            enc_cells: Vec::new(),
            cmd_row: vec![None; robot.wheels.len()],
            enc_row: vec![None; robot.wheels.len()],
        }
    }

    /// One CSV row: its cells read, each checked on its own (a number, finite,
    /// physically plausible), then the row placed in time ([`Parse::place`]). One call
    /// for both: the row then never travels in a `Result` (it did: 0.6 % more
    /// instructions for the whole read of 200 k rows under callgrind).
    fn row(
        &mut self,
        record: &csv::StringRecord,
        line: usize,
        rec: &mut Recording,
        sink: &mut dyn RowSink,
    ) -> Result<(), RecordingError> {
        let (headers, err) = (self.headers, self.err);
        if record.len() != headers.len() {
            return Err(err(
                Some(line),
                None,
                format!(
                    "row has {} cells, the header has {}",
                    record.len(),
                    headers.len()
                ),
            ));
        }
        let mut t = None;
        let mut pose = [None; 3];
        let mut legs = [None; 2];
        self.enc_cells.clear();
        self.cmd_row.iter_mut().for_each(|c| *c = None);
        self.enc_row.iter_mut().for_each(|c| *c = None);
        for (ci, (cell, col)) in record.iter().zip(self.cols).enumerate() {
            if *col == Col::Ignored {
                continue;
            }
            let at = || Some((ci + 1, headers[ci].to_string()));
            if cell.is_empty() {
                if *col == Col::T {
                    return Err(err(Some(line), at(), "time must not be blank".into()));
                }
                continue;
            }
            if let Col::Enc(i) = col {
                let v: i64 = cell.parse().map_err(|_| {
                    err(
                        Some(line),
                        at(),
                        format!("encoder count must be an integer, got '{cell}'"),
                    )
                })?;
                self.enc_row[*i] = Some(v);
                self.enc_cells.push((ci, *i, v));
                continue;
            }
            let v: f64 = cell
                .parse()
                .map_err(|_| err(Some(line), at(), format!("not a number: '{cell}'")))?;
            if !v.is_finite() {
                return Err(err(
                    Some(line),
                    at(),
                    format!("must be a finite number, got '{cell}'"),
                ));
            }
            if let Some(why) = implausible(*col, v, &|i| self.checks.rim[i]) {
                return Err(err(Some(line), at(), why));
            }
            match col {
                Col::T => t = Some(v),
                Col::X => pose[0] = Some(v),
                Col::Y => pose[1] = Some(v),
                Col::Theta => pose[2] = Some(v),
                Col::LegFront => legs[0] = Some(v),
                Col::LegRear => legs[1] = Some(v),
                Col::Cmd(i) => self.cmd_row[*i] = Some(v),
                Col::Enc(_) | Col::Ignored => {}
            }
        }
        let written = t.expect("t column exists and is never blank");
        if pose.iter().any(Option::is_some) && !pose.iter().all(Option::is_some) {
            return Err(err(
                Some(line),
                None,
                "x, y and theta must be all given or all blank".into(),
            ));
        }
        let row = ReadRow {
            written,
            line,
            enc_cells: self.enc_cells.clone(),
            cells: Cells {
                t: written,
                cmd: self.cmd_row.clone(),
                enc: self.enc_row.clone(),
                pose: match pose {
                    [Some(x), Some(y), Some(th)] => Some((x, y, th)),
                    _ => None,
                },
                legs,
            },
        };
        self.place(row, rec, sink)
    }

    /// Places `row` in time and hands it on through the checks between rows: a row
    /// whose time goes back (by at most [`MAX_TIME_BACK_S`]) is held until the next row
    /// tells a clock's step from one early row; further back, or a gap over
    /// [`MAX_GAP_S`], is refused.
    fn place(
        &mut self,
        row: ReadRow,
        rec: &mut Recording,
        sink: &mut dyn RowSink,
    ) -> Result<(), RecordingError> {
        let (headers, err, clock) = (self.headers, self.err, &mut self.clock);
        let (written, line) = (row.written, row.line);
        // A row whose time goes back waits for the next row, which tells whether the
        // clock stepped back (later rows follow it) or this row alone was written
        // early (the next row is beyond the row before it).
        if let Some(h) = self.held.take() {
            let next = written + clock.offset;
            // A clock step keeps the written interval from the held row to this one
            // (one row); a single early row leaves this one two rows after the row
            // before it. Whichever the written times fit better (a step back of
            // under two rows leaves this row beyond the row before either way).
            let dt = clock.dt;
            let single = next > clock.last_t
                && (!dt.is_finite()
                    || ((next - clock.last_t) - 2.0 * dt).abs()
                        <= ((written - h.written) - dt).abs());
            let t_h = if single {
                clock.single(&h, next)
            } else {
                clock.step(&h)
            };
            self.checks.emit(rec, sink, h, t_h, err, headers)?;
        }
        let t = written + clock.offset;
        let t_col = self.t_col;
        let t_at = || Some((t_col + 1, "t".to_string()));
        if t <= clock.last_t {
            if clock.last_t - t > MAX_TIME_BACK_S {
                return Err(err(
                    Some(line),
                    t_at(),
                    format!(
                        "time must increase: {} after {} goes back {:.6} s, more than a logger's clock step (at most {MAX_TIME_BACK_S} s): two runs in one file, or a clock reset",
                        short(written),
                        short(clock.last_written),
                        clock.last_t - t
                    ),
                ));
            }
            if !clock.dt.is_finite() {
                // No row interval yet (the first rows): nothing to re-time it by.
                return Err(err(
                    Some(line),
                    t_at(),
                    format!(
                        "time must increase: {} after {} on the first rows, before the row interval is known (a later step back of at most {MAX_TIME_BACK_S} s is re-timed)",
                        short(written),
                        short(clock.last_written)
                    ),
                ));
            }
            self.held = Some(row);
            return Ok(());
        }
        if clock.last_t.is_finite() && t - clock.last_t > MAX_GAP_S {
            return Err(err(
                Some(line),
                t_at(),
                format!(
                    "time jumps by {:.6e} s (from {} s on the row before to {} s): no run pauses for over {MAX_GAP_S} s; a logger that changed clocks (Unix time?) or a broken cell",
                    t - clock.last_t,
                    short(clock.last_written),
                    short(written)
                ),
            ));
        }
        clock.advance(t, written);
        self.checks.emit(rec, sink, row, t, err, headers)
    }

    /// After the last row: a row still held followed a clock's step back (nothing came
    /// after it), and the clock's faults and written steps go to the recording. Returns
    /// the pose's travel, for the whole recording's checks.
    fn finish(
        mut self,
        rec: &mut Recording,
        sink: &mut dyn RowSink,
    ) -> Result<f64, RecordingError> {
        if let Some(h) = self.held.take() {
            let t_h = self.clock.step(&h);
            self.checks
                .emit(rec, sink, h, t_h, self.err, self.headers)?;
        }
        self.clock.finish();
        rec.time_faults = self.clock.faults;
        Ok(self.checks.pose_travel)
    }
}

/// The checks only the whole recording can answer, once `sink` has had every row: rows
/// and a measured pose at all, and encoders that move while the body travels
/// `pose_travel`. The columns' spare capacity is released on the way.
fn whole_recording(
    mut rec: Recording,
    sink: &mut dyn RowSink,
    cols: &[Col],
    headers: &csv::StringRecord,
    pose_travel: f64,
    err: &ErrAt<'_>,
) -> Result<Recording, RecordingError> {
    sink.finish(&mut rec);
    if rec.is_empty() {
        return Err(err(
            None,
            None,
            "empty recording: a header but no rows".into(),
        ));
    }
    // The columns grew by doubling; a long recording would otherwise hold up to twice
    // its size for as long as it is kept.
    rec.shrink_to_fit();
    if rec.pose_rows().next().is_none() {
        return Err(err(
            None,
            None,
            "no row has a measured pose (x, y, theta)".into(),
        ));
    }
    // Encoders that never change while the body travels: unplugged, or the wrong
    // columns. Only when every encoder column is still (one idle wheel is normal).
    let enc_cols: Vec<(usize, &Vec<Option<i64>>)> = cols
        .iter()
        .enumerate()
        .filter_map(|(ci, c)| match c {
            Col::Enc(i) => rec.wheels[*i].enc.as_ref().map(|e| (ci, e)),
            _ => None,
        })
        .filter(|(_, e)| e.iter().any(Option::is_some))
        .collect();
    let still = |e: &Vec<Option<i64>>| {
        let mut v = e.iter().flatten();
        let first = v.next();
        v.all(|c| Some(c) == first)
    };
    if !enc_cols.is_empty()
        && pose_travel > STILL_ENCODER_TRAVEL_M
        && enc_cols.iter().all(|(_, e)| still(e))
    {
        let names: Vec<&str> = enc_cols.iter().map(|(ci, _)| &headers[*ci]).collect();
        let ci = enc_cols[0].0;
        return Err(err(
            None,
            Some((ci + 1, headers[ci].to_string())),
            format!(
                "the encoders ({}) never change while the measured pose travels {pose_travel:.2} m: encoders unplugged, or the wrong columns",
                names.join(", ")
            ),
        ));
    }
    Ok(rec)
}

/// Why a finite cell `v` of column `col` is not a physical value, if it is not.
fn implausible(col: Col, v: f64, rim: &dyn Fn(usize) -> f64) -> Option<String> {
    match col {
        Col::X | Col::Y if v.abs() > MAX_POSE_M => {
            let hint = if v.abs() / 1000.0 <= MAX_POSE_M {
                ": looks like millimetres (the pose columns are metres)"
            } else {
                ""
            };
            Some(format!(
                "{} m is farther than a run goes (at most {MAX_POSE_M} m from the origin){hint}",
                short(v)
            ))
        }
        Col::Theta if v.abs() > MAX_HEADING_RAD => Some(format!(
            "heading {} rad is over {} turns",
            short(v),
            (MAX_HEADING_RAD / std::f64::consts::TAU).round()
        )),
        Col::LegFront | Col::LegRear if v.abs() > MAX_LEG_RAD => {
            let hint = if v.to_radians().abs() <= MAX_LEG_RAD {
                format!(
                    ": looks like degrees ({v} deg = {:.4} rad; leg angles are radians, a vertical leg is 1.5708)",
                    v.to_radians()
                )
            } else {
                String::new()
            };
            Some(format!("leg angle {} rad is more than a turn{hint}", short(v)))
        }
        Col::Cmd(i) if v.abs() * rim(i) > MAX_SPEED_M_S => Some(format!(
            "{} rad/s is {:.3e} m/s at the wheel's rim: no motor of a robot this tool calibrates reaches it (at most {MAX_SPEED_M_S} m/s)",
            short(v),
            v.abs() * rim(i)
        )),
        _ => None,
    }
}

/// A value as a person reads it: plain when moderate, in exponent form when huge or tiny
/// (a 1e300 cell printed plainly is 300 digits).
fn short(v: f64) -> String {
    if v != 0.0 && !(1e-3..1e6).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// What merging fast rows did (`crate::decimate`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Decimation {
    /// Rows in the file.
    pub rows_read: usize,
    /// Rows kept.
    pub rows_kept: usize,
    /// The rate asked for (rows/s).
    pub max_row_rate_hz: f64,
}

impl Decimation {
    /// Whether rows were merged.
    pub fn merged(&self) -> bool {
        self.rows_kept < self.rows_read
    }

    /// One line for a report's notes.
    pub fn note(&self) -> String {
        format!(
            "{} of {} rows kept (merged to about {:.0} rows/s, formats.md §2; commands averaged over the merged rows, counts and poses as sampled at the kept rows)",
            self.rows_kept,
            self.rows_read,
            self.max_row_rate_hz
        )
    }
}

/// One row's cells, as read (blank = `None`): what a parser hands its [`RowSink`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cells {
    /// Time (s).
    pub t: f64,
    /// Command per wheel of the robot (rad/s).
    pub cmd: Vec<Option<f64>>,
    /// Encoder count per wheel of the robot.
    pub enc: Vec<Option<i64>>,
    /// Measured pose.
    pub pose: Option<(f64, f64, f64)>,
    /// Leg angles (front, rear).
    pub legs: [Option<f64>; 2],
}

impl Cells {
    /// Row `k` of `rec`.
    pub fn of(rec: &Recording, k: usize) -> Cells {
        Cells {
            t: rec.t[k],
            cmd: rec
                .wheels
                .iter()
                .map(|w| w.cmd.as_ref().and_then(|c| c[k]))
                .collect(),
            enc: rec
                .wheels
                .iter()
                .map(|w| w.enc.as_ref().and_then(|e| e[k]))
                .collect(),
            pose: match (rec.x[k], rec.y[k], rec.theta[k]) {
                (Some(x), Some(y), Some(th)) => Some((x, y, th)),
                _ => None,
            },
            legs: [
                rec.leg_front.as_ref().and_then(|l| l[k]),
                rec.leg_rear.as_ref().and_then(|l| l[k]),
            ],
        }
    }

    /// Appends the row to the columns `rec` has.
    pub fn push_to(&self, rec: &mut Recording) {
        rec.t.push(self.t);
        for (i, w) in rec.wheels.iter_mut().enumerate() {
            if let Some(c) = &mut w.cmd {
                c.push(self.cmd.get(i).copied().flatten());
            }
            if let Some(e) = &mut w.enc {
                e.push(self.enc.get(i).copied().flatten());
            }
        }
        let (x, y, th) = match self.pose {
            Some((x, y, th)) => (Some(x), Some(y), Some(th)),
            None => (None, None, None),
        };
        rec.x.push(x);
        rec.y.push(y);
        rec.theta.push(th);
        if let Some(f) = &mut rec.leg_front {
            f.push(self.legs[0]);
        }
        if let Some(r) = &mut rec.leg_rear {
            r.push(self.legs[1]);
        }
    }
}

/// Where a parser puts each row it read.
pub trait RowSink {
    /// Appends (or merges) one row.
    fn push(&mut self, rec: &mut Recording, row: Cells);
    /// Called once after the last row.
    fn finish(&mut self, rec: &mut Recording);
}

/// Every row as read.
pub struct AllRows;

impl RowSink for AllRows {
    fn push(&mut self, rec: &mut Recording, row: Cells) {
        row.push_to(rec);
    }

    fn finish(&mut self, _: &mut Recording) {}
}

/// One row to append with [`Recording::push_row`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Row<'a> {
    /// Time since start (s).
    pub t: f64,
    /// Commanded wheel rates (rad/s), one per wheel.
    pub cmd: Option<&'a [f64]>,
    /// Cumulative encoder counts, one per wheel.
    pub enc: Option<&'a [i64]>,
    /// Measured pose (x m, y m, theta rad).
    pub pose: Option<(f64, f64, f64)>,
    /// Leg angles (front, rear) in rad.
    pub legs: Option<(f64, f64)>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::presets;

    fn sample() -> &'static str {
        "t,cmd_left,cmd_right,enc_left,enc_right,x,y,theta,extra\n\
         0.0,1.0,1.0,100,-5,0,0,0,7\n\
         0.01,1.0,1.5,103,-2,,,,7\n\
         0.02,1.0,1.5,106,2,0.001,0.0,0.01,7\n"
    }

    #[test]
    fn reads_columns_in_any_order_with_blanks() {
        let r = presets::mobolab();
        let rec = Recording::parse(sample(), Path::new("rec.csv"), &r).unwrap();
        assert_eq!(rec.len(), 3);
        assert_eq!(
            rec.wheels[1].enc.as_ref().unwrap(),
            &vec![Some(-5), Some(-2), Some(2)]
        );
        assert_eq!(rec.x, vec![Some(0.0), None, Some(0.001)]);
        assert_eq!(rec.pose_rows().count(), 2);
        assert_eq!(rec.notes.len(), 1);
        assert!(rec.notes[0].contains("'extra'"));
        // Reordered columns read the same.
        let reordered = "x,y,theta,t,enc_right,enc_left\n0,0,0,0,1,2\n";
        let rec2 = Recording::parse(reordered, Path::new("r.csv"), &r).unwrap();
        assert_eq!(rec2.wheels[0].enc.as_ref().unwrap()[0], Some(2));
    }

    #[test]
    fn round_trips_through_csv() {
        let r = presets::mobolab();
        let rec = Recording::parse(sample(), Path::new("rec.csv"), &r).unwrap();
        let mut buf = Vec::new();
        rec.write_csv(&mut buf).unwrap();
        let again =
            Recording::parse(std::str::from_utf8(&buf).unwrap(), Path::new("x"), &r).unwrap();
        assert_eq!(again.t, rec.t);
        assert_eq!(again.wheels, rec.wheels);
        assert_eq!(again.theta, rec.theta);
    }

    fn error_of(text: &str) -> RecordingError {
        Recording::parse(text, Path::new("runs/r.csv"), &presets::mobolab()).unwrap_err()
    }

    #[test]
    fn errors_name_file_line_and_column() {
        let e = error_of("t,enc_left,enc_right,x,y,theta\n0,1,2,0,0,0\n0.1,1.5,2,,,\n");
        assert_eq!(
            e.to_string(),
            "runs/r.csv:3:2: column 'enc_left': encoder count must be an integer, got '1.5'"
        );
        // A time going back further than a clock step (formats.md §2).
        let e = error_of("t,enc_left,enc_right,x,y,theta\n0,1,2,0,0,0\n2,1,2,,,\n0.5,1,2,,,\n");
        assert_eq!((e.line, e.column.as_ref().map(|c| c.0)), (Some(4), Some(1)));
        assert!(e.message.contains("time must increase"), "{e}");
        let e = error_of("t,enc_left,enc_right,x,y,theta\n0,1,2,NaN,0,0\n");
        assert_eq!(e.line, Some(2));
        assert!(e.to_string().contains("column 'x'"));
        let e = error_of("t,enc_left,enc_wheel3,x,y,theta\n");
        assert!(e.message.contains("no wheel 'wheel3'"), "{e}");
        let e = error_of("t,enc_left,x,y,theta\n0,1,0,0,0\n");
        assert!(e.message.contains("'right'"), "{e}");
        let e = error_of("t,enc_left,enc_right,x,y\n0,1,2,0,0\n");
        assert!(e.message.contains("missing required column 'theta'"));
        let e = error_of("t,enc_left,enc_right,x,y,theta\n");
        assert!(e.message.contains("empty recording"));
        let e = error_of("");
        assert!(e.message.contains("empty recording"));
        let e = error_of("t,enc_left,enc_right,x,y,theta\n0,1,2,0,0,0\n0.1,1,2,0\n");
        assert_eq!(e.line, Some(3));
    }

    #[test]
    fn reads_the_real_recordings() {
        for dir in ["diff-square-run-01", "omni3-square-run-01"] {
            let d = testdata::real(dir);
            let robot = crate::robot_file::load(&d.join("robot.toml")).unwrap();
            let rec = Recording::load(&d.join("recording.csv"), &robot).unwrap();
            // 69 s at 20 Hz and 51 s at 25 Hz (data/real/README.md).
            let expected_rows = if dir.starts_with("diff") {
                69.0 * 20.0
            } else {
                51.0 * 25.0
            };
            assert!(
                (rec.len() as f64 - expected_rows).abs() < 0.05 * expected_rows,
                "{dir}: {}",
                rec.len()
            );
            assert_eq!(
                rec.pose_rows().next().map(|p| (p.1, p.2, p.3)),
                Some((0.0, 0.0, 0.0))
            );
        }
    }

    /// A logger's clock going back: a step (later rows follow it) moves the rows on, a
    /// row written early alone is placed between its neighbours; both are listed with
    /// their line and size, and the times increase strictly.
    #[test]
    fn times_going_back_are_retimed_and_listed() {
        let text = "t,enc_left,enc_right,x,y,theta\n\
                    0.00,0,0,0,0,0\n0.01,1,1,,,\n0.02,2,2,,,\n0.005,3,3,,,\n0.015,4,4,,,\n\
                    0.025,5,5,,,\n0.005,6,6,,,\n0.045,7,7,,,\n0.055,8,8,,,\n0.055,9,9,,,\n";
        let rec = Recording::parse(text, Path::new("r.csv"), &presets::mobolab()).unwrap();
        assert!(rec.t.windows(2).all(|w| w[1] > w[0]), "{:?}", rec.t);
        let f = &rec.time_faults;
        assert_eq!(f.count, 3, "{f:?}");
        // Line 5: the clock stepped back 25 ms (written 0.005 after 0.02).
        assert_eq!((f.back[0].line, f.back[0].clock_step), (5, true));
        assert!((f.back[0].back_s - 0.025).abs() < 1e-9, "{f:?}");
        // Line 8: one row written 30 ms early (0.005 + 0.025 between 0.025 + 0.025 and
        // 0.045 + 0.025).
        assert_eq!((f.back[1].line, f.back[1].clock_step), (8, false));
        assert!((f.back[1].back_s - 0.030).abs() < 1e-9, "{f:?}");
        // Line 11: a repeated time at the end, placed one interval on.
        // A clock step back of under two rows (80 ms at 50 ms rows) is a step too.
        let text = "t,enc_left,enc_right,x,y,theta\n0,0,0,0,0,0\n0.05,1,1,,,\n0.1,2,2,,,\n\
                    0.07,3,3,,,\n0.12,4,4,,,\n0.17,5,5,,,\n";
        let r2 = Recording::parse(text, Path::new("r.csv"), &presets::mobolab()).unwrap();
        let b = &r2.time_faults.back;
        assert_eq!((b.len(), b[0].line, b[0].clock_step), (1, 5, true), "{b:?}");
        assert!((b[0].back_s - 0.08).abs() < 1e-9, "{b:?}");
        assert!((r2.t[5] - 0.25).abs() < 1e-9, "{:?}", r2.t);
        assert_eq!((f.back[2].line, f.back[2].clock_step), (11, true));
        assert_eq!(rec.len(), 10);
    }

    /// Issue 13.7: the check for the leg columns could not fire (the recording starts with
    /// empty leg series), so a wheeled-legged recording without them was accepted.
    #[test]
    fn wheeled_legged_recordings_need_both_leg_columns() {
        let wlr = crate::robot_file::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/wlr.toml"),
        )
        .unwrap();
        let wheels: Vec<String> = wlr
            .wheels
            .iter()
            .map(|w| format!("enc_{}", w.name))
            .collect();
        let head = format!("t,x,y,theta,{}", wheels.join(","));
        let zeros = vec!["0"; wheels.len()].join(",");
        for (extra_cols, extra_vals, missing) in [
            ("", "", Some("leg_front")),
            (",leg_front", ",0.1", Some("leg_rear")),
            (",leg_rear", ",0.1", Some("leg_front")),
            (",leg_front,leg_rear", ",0.1,0.2", None),
        ] {
            let text = format!("{head}{extra_cols}\n0,0,0,0,{zeros}{extra_vals}\n");
            let got = Recording::parse(&text, Path::new("wlr.csv"), &wlr);
            match missing {
                Some(name) => {
                    let e = got.unwrap_err().to_string();
                    assert!(e.contains(name) && e.contains("wlr.csv"), "{e}");
                }
                None => {
                    let rec = got.unwrap();
                    assert_eq!(rec.leg_front.as_deref(), Some(&[Some(0.1)][..]));
                    assert_eq!(rec.leg_rear.as_deref(), Some(&[Some(0.2)][..]));
                }
            }
        }
    }
}
