//! Measured end positions of calibration runs (docs/formats.md §3), one CSV row per run.
//!
//! The guided procedures append to these files as each run is measured, so a person can
//! stop and resume; the compute commands read them. Errors name the file, the line and
//! what to fix, and the semantic checks (both directions present, at least two runs each,
//! one side length) point at the offending rows.

use calib_core::circle_test::CircleRun;
use calib_core::motion::{Direction, OmniPath};
use calib_core::protocol::MAX_LAPS;
use std::fmt;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Which calibration a run belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TestKind {
    /// UMBmark square runs (differential drive).
    Umbmark,
    /// Omni straight-path runs ([Redundant omni]).
    Omni,
    /// Circles driven both ways (wheelcal's extension of the format: the circle test of
    /// `umbmark compute`, [`calib_core::circle_test`]); `length_m` is the radius and the
    /// optional `laps` column the laps (1 when missing).
    Circle,
}

impl TestKind {
    /// The name in the file's `test` column.
    pub fn as_str(self) -> &'static str {
        match self {
            TestKind::Umbmark => "umbmark",
            TestKind::Omni => "omni",
            TestKind::Circle => "circle",
        }
    }
}

/// A runs file's header, its column names trimmed; None when the file is absent or
/// empty.
fn header_of(path: &Path) -> std::io::Result<Option<Vec<String>>> {
    match std::fs::read_to_string(path) {
        Ok(text) => Ok(text
            .lines()
            .next()
            .filter(|l| !l.trim().is_empty())
            .map(|l| l.split(',').map(|c| c.trim().to_string()).collect())),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(e),
    }
}

/// Before or after the factors were applied.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Phase {
    /// Measured before the calibration factors were applied (the default).
    Before,
    /// Measured with the new factors applied.
    After,
}

impl Phase {
    /// Lower-case name as written in the file's `phase` column.
    pub fn as_str(self) -> &'static str {
        match self {
            Phase::Before => "before",
            Phase::After => "after",
        }
    }
}

/// One measured run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunRow {
    /// Line in the file (1 = header); 0 for rows not read from a file.
    pub line: usize,
    /// Which calibration.
    pub test: TestKind,
    /// `cw`/`ccw` for UMBmark; a path name such as `4W-1` for omni.
    pub path: String,
    /// UMBmark: side L of the square; omni: commanded straight length (m).
    pub length_m: f64,
    /// End error along the commanded direction (m), measured minus odometry.
    pub x_err_m: f64,
    /// End error to the left of the commanded direction (m), measured minus odometry.
    pub y_err_m: f64,
    /// End heading error (rad), measured minus odometry, when measured.
    pub theta_err_rad: Option<f64>,
    /// Before or after the factors were applied.
    pub phase: Phase,
    /// Circle runs: the laps driven (1 for every other test).
    pub laps: u8,
}

impl RunRow {
    /// The UMBmark direction, for UMBmark rows.
    pub fn direction(&self) -> Option<Direction> {
        match self.path.as_str() {
            "cw" => Some(Direction::Cw),
            "ccw" => Some(Direction::Ccw),
            _ => None,
        }
    }
}

/// A problem with a runs file.
#[derive(Debug, Clone, PartialEq)]
pub struct RunsError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line (1 = header), when known.
    pub line: Option<usize>,
    /// The column's name, when known.
    pub column: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for RunsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let Some(l) = self.line {
            write!(f, ":{l}")?;
        }
        write!(f, ": ")?;
        if let Some(c) = &self.column {
            write!(f, "column '{c}': ")?;
        }
        write!(f, "{}", self.message)
    }
}

impl std::error::Error for RunsError {}

/// A runs file in memory.
#[derive(Debug, Clone, PartialEq)]
pub struct RunsFile {
    /// The file (named in error messages).
    pub path: PathBuf,
    /// The rows, in file order.
    pub rows: Vec<RunRow>,
}

/// UMBmark runs of one phase, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct UmbmarkRuns {
    /// Side of the square (m).
    pub side_m: f64,
    /// (x_err, y_err) per run.
    pub cw: Vec<(f64, f64)>,
    /// (x_err, y_err) per ccw run (m).
    pub ccw: Vec<(f64, f64)>,
}

/// Omni runs of one path and phase.
#[derive(Debug, Clone, PartialEq)]
pub struct OmniPathRuns {
    /// Path name as in the file (e.g. `4W-1`).
    pub path: String,
    /// [Redundant omni]'s named path, when it is one.
    pub omni_path: Option<OmniPath>,
    /// Commanded straight length (m).
    pub length_m: f64,
    /// (x_err, y_err, theta_err) per run.
    pub runs: Vec<(f64, f64, Option<f64>)>,
}

/// A runs file larger than this is refused (a row per run: a few hundred bytes each).
pub const MAX_FILE_BYTES: u64 = 16 << 20;

const HEADER: [&str; 7] = [
    "test",
    "path",
    "length_m",
    "x_err_m",
    "y_err_m",
    "theta_err_rad",
    "phase",
];

impl RunsFile {
    /// An empty runs file named `path` (nothing is read or written).
    pub fn new(path: &Path) -> Self {
        RunsFile {
            path: path.to_path_buf(),
            rows: Vec::new(),
        }
    }

    fn error(&self, line: Option<usize>, column: Option<&str>, message: String) -> RunsError {
        RunsError {
            path: self.path.clone(),
            line,
            column: column.map(str::to_string),
            message,
        }
    }

    /// Reads a runs file.
    pub fn load(path: &Path) -> Result<Self, RunsError> {
        let text =
            crate::text_file::read_capped(path, MAX_FILE_BYTES, "runs file").map_err(|e| {
                RunsError {
                    path: path.to_path_buf(),
                    line: None,
                    column: None,
                    message: e.0,
                }
            })?;
        Self::parse(&text, path)
    }

    /// Parses CSV text; `path` is used in messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, RunsError> {
        let mut file = RunsFile::new(path);
        let mut reader = csv::ReaderBuilder::new()
            .trim(csv::Trim::All)
            .from_reader(text.as_bytes());
        let headers = reader
            .headers()
            .map_err(|e| file.error(Some(1), None, format!("cannot read the header row: {e}")))?
            .clone();
        let find = |name: &str| headers.iter().position(|h| h == name);
        let mut idx = [None; 7];
        for (i, name) in HEADER.iter().enumerate() {
            idx[i] = find(name);
            if i < 5 && idx[i].is_none() {
                return Err(file.error(
                    Some(1),
                    None,
                    format!("missing column '{name}' (a runs file has test, path, length_m, x_err_m, y_err_m[, theta_err_rad, phase])"),
                ));
            }
        }
        let laps_col = find("laps");
        let mut record = csv::StringRecord::new();
        let mut lines = crate::text_file::LineCounter::new(text);
        loop {
            let line = lines.line_at(reader.position().byte());
            match reader.read_record(&mut record) {
                Ok(false) => break,
                Ok(true) => {}
                Err(e) => {
                    return Err(file.error(Some(line), None, format!("malformed CSV row: {e}")))
                }
            }
            let line = record.position().map_or(line, |p| lines.line_at(p.byte()));
            if record.iter().all(str::is_empty) {
                continue;
            }
            let cell = |k: usize| idx[k].and_then(|i| record.get(i)).unwrap_or("");
            let num = |k: usize, required: bool| -> Result<Option<f64>, RunsError> {
                let c = cell(k);
                if c.is_empty() {
                    return if required {
                        Err(file.error(Some(line), Some(HEADER[k]), "missing value".into()))
                    } else {
                        Ok(None)
                    };
                }
                match c.parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(Some(v)),
                    _ => Err(file.error(
                        Some(line),
                        Some(HEADER[k]),
                        format!("not a number: '{c}' (metres or radians, '.' decimal point)"),
                    )),
                }
            };
            let test = match cell(0) {
                "umbmark" => TestKind::Umbmark,
                "omni" => TestKind::Omni,
                "circle" => TestKind::Circle,
                other => {
                    return Err(file.error(
                        Some(line),
                        Some("test"),
                        format!("unknown test '{other}' (expected umbmark, omni or circle)"),
                    ))
                }
            };
            let path_name = cell(1).to_string();
            if test != TestKind::Omni && path_name != "cw" && path_name != "ccw" {
                let what = if test == TestKind::Umbmark {
                    "UMBmark"
                } else {
                    "circle"
                };
                return Err(file.error(
                    Some(line),
                    Some("path"),
                    format!("unknown {what} path '{path_name}' (expected cw or ccw)"),
                ));
            }
            let laps = match (laps_col.and_then(|i| record.get(i)).unwrap_or(""), test) {
                ("", _) => 1,
                (c, TestKind::Circle) => match c.parse::<u8>() {
                    Ok(n) if (1..=MAX_LAPS).contains(&n) => n,
                    _ => {
                        return Err(file.error(
                            Some(line),
                            Some("laps"),
                            format!("'{c}' is not a whole number of laps from 1 to {MAX_LAPS}"),
                        ))
                    }
                },
                (c, _) => {
                    return Err(file.error(
                        Some(line),
                        Some("laps"),
                        format!("'{c}': only circle rows have laps"),
                    ))
                }
            };
            if test == TestKind::Omni && path_name.is_empty() {
                return Err(file.error(
                    Some(line),
                    Some("path"),
                    "missing path name (e.g. 4W-1)".into(),
                ));
            }
            let length_m = num(2, true)?.unwrap_or(0.0);
            if length_m <= 0.0 {
                return Err(file.error(
                    Some(line),
                    Some("length_m"),
                    format!("must be positive, got {length_m}"),
                ));
            }
            let phase = match cell(6) {
                "" | "before" => Phase::Before,
                "after" => Phase::After,
                other => {
                    return Err(file.error(
                        Some(line),
                        Some("phase"),
                        format!("unknown phase '{other}' (expected before or after)"),
                    ))
                }
            };
            file.rows.push(RunRow {
                line,
                test,
                path: path_name,
                length_m,
                x_err_m: num(3, true)?.unwrap_or(0.0),
                y_err_m: num(4, true)?.unwrap_or(0.0),
                theta_err_rad: num(5, false)?,
                phase,
                laps,
            });
        }
        Ok(file)
    }

    /// The UMBmark runs of a phase, checked: both directions, at least two runs each, and
    /// one side length. `Ok(None)` when the file has no UMBmark rows of that phase.
    pub fn umbmark(&self, phase: Phase) -> Result<Option<UmbmarkRuns>, RunsError> {
        let rows: Vec<&RunRow> = self
            .rows
            .iter()
            .filter(|r| r.test == TestKind::Umbmark && r.phase == phase)
            .collect();
        if rows.is_empty() {
            return Ok(None);
        }
        let side = rows[0].length_m;
        if let Some(r) = rows
            .iter()
            .find(|r| (r.length_m - side).abs() > 1e-9 * side.max(1.0))
        {
            return Err(self.error(
                Some(r.line),
                Some("length_m"),
                format!(
                    "side {} m disagrees with {} m on line {}: one UMBmark computation needs one square size",
                    r.length_m, side, rows[0].line
                ),
            ));
        }
        let pick = |d: &str| {
            rows.iter()
                .filter(|r| r.path == d)
                .map(|r| (r.x_err_m, r.y_err_m))
                .collect::<Vec<_>>()
        };
        let (cw, ccw) = (pick("cw"), pick("ccw"));
        for (name, runs) in [("cw", &cw), ("ccw", &ccw)] {
            if runs.len() < 2 {
                return Err(self.error(
                    None,
                    None,
                    format!(
                        "{} phase has {} {name} run(s): UMBmark needs at least 2 runs in each direction (cw and ccw); add rows with path = {name}",
                        phase.as_str(),
                        runs.len()
                    ),
                ));
            }
        }
        Ok(Some(UmbmarkRuns {
            side_m: side,
            cw,
            ccw,
        }))
    }

    /// The omni runs of a phase, grouped by path (in first-seen order); each path needs at
    /// least two runs and one length.
    pub fn omni(&self, phase: Phase) -> Result<Vec<OmniPathRuns>, RunsError> {
        let mut out: Vec<(OmniPathRuns, usize)> = Vec::new();
        for r in self
            .rows
            .iter()
            .filter(|r| r.test == TestKind::Omni && r.phase == phase)
        {
            match out.iter_mut().find(|(p, _)| p.path == r.path) {
                Some((p, first)) => {
                    if (p.length_m - r.length_m).abs() > 1e-9 * p.length_m.max(1.0) {
                        return Err(self.error(
                            Some(r.line),
                            Some("length_m"),
                            format!(
                                "path {} length {} m disagrees with {} m on line {}",
                                r.path, r.length_m, p.length_m, first
                            ),
                        ));
                    }
                    p.runs.push((r.x_err_m, r.y_err_m, r.theta_err_rad));
                }
                None => out.push((
                    OmniPathRuns {
                        path: r.path.clone(),
                        omni_path: match r.path.as_str() {
                            "4W-1" => Some(OmniPath::W1),
                            "4W-2" => Some(OmniPath::W2),
                            _ => None,
                        },
                        length_m: r.length_m,
                        runs: vec![(r.x_err_m, r.y_err_m, r.theta_err_rad)],
                    },
                    r.line,
                )),
            }
        }
        for (p, _) in &out {
            if p.runs.len() < 2 {
                return Err(self.error(
                    None,
                    None,
                    format!(
                        "path {} has {} {} run(s): need at least 2",
                        p.path,
                        p.runs.len(),
                        phase.as_str()
                    ),
                ));
            }
        }
        Ok(out.into_iter().map(|(p, _)| p).collect())
    }

    /// The circle runs of a phase, as [`calib_core::circle_test`] reads them (its
    /// computation checks the directions and counts per radius, naming the radius).
    pub fn circles(&self, phase: Phase) -> Vec<CircleRun> {
        self.rows
            .iter()
            .filter(|r| r.test == TestKind::Circle && r.phase == phase)
            .filter_map(|r| {
                Some(CircleRun {
                    dir: r.direction()?,
                    radius_m: r.length_m,
                    laps: r.laps,
                    x_err_m: r.x_err_m,
                    y_err_m: r.y_err_m,
                    theta_err_rad: r.theta_err_rad,
                })
            })
            .collect()
    }

    /// Appends one run to a runs file on disk, writing the header first if the file is new:
    /// what the guided procedures call after each measurement, so nothing is lost on a stop.
    pub fn append(path: &Path, row: &RunRow) -> std::io::Result<()> {
        Self::append_with(path, row, false)
    }

    /// Whether circle rows of several laps can be appended to `path`: it does not exist
    /// yet or is empty (it will get the column), or its header has a `laps` column.
    pub fn takes_laps(path: &Path) -> bool {
        match header_of(path) {
            Ok(Some(h)) => h.iter().any(|c| c == "laps"),
            // Absent or empty (it will get the column), or unreadable (appending says why).
            _ => true,
        }
    }

    /// [`RunsFile::append`], the cells written in the order of the file's own header (so
    /// a file whose columns a person reordered, or that has a `laps` column, stays
    /// consistent). A new file gets the standard columns, and `laps` too when `laps` is
    /// set (a procedure that will append circle rows). A circle row of more than one lap
    /// needs that column: refused, writing nothing, on a file without it.
    pub fn append_with(path: &Path, row: &RunRow, laps: bool) -> std::io::Result<()> {
        let invalid = |m: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, m);
        let existing = header_of(path)?;
        let header: Vec<String> = match &existing {
            Some(h) => h.clone(),
            None => HEADER
                .iter()
                .copied()
                .chain(laps.then_some("laps"))
                .map(str::to_string)
                .collect(),
        };
        if row.test == TestKind::Circle && row.laps != 1 && !header.iter().any(|h| h == "laps") {
            return Err(invalid(format!(
                "{} has no laps column for a circle of {} laps: start a new runs file",
                path.display(),
                row.laps
            )));
        }
        let cell = |name: &str| -> String {
            match name {
                "test" => row.test.as_str().into(),
                "path" => row.path.clone(),
                "length_m" => row.length_m.to_string(),
                "x_err_m" => row.x_err_m.to_string(),
                "y_err_m" => row.y_err_m.to_string(),
                "theta_err_rad" => row.theta_err_rad.map_or(String::new(), |v| v.to_string()),
                "phase" => row.phase.as_str().into(),
                "laps" if row.test == TestKind::Circle => row.laps.to_string(),
                _ => String::new(),
            }
        };
        let mut s = String::new();
        if existing.is_none() {
            s.push_str(&header.join(","));
            s.push('\n');
        }
        s.push_str(&header.iter().map(|h| cell(h)).collect::<Vec<_>>().join(","));
        s.push('\n');
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(path)?;
        f.write_all(s.as_bytes())?;
        f.sync_data()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "test,path,length_m,x_err_m,y_err_m\n\
        umbmark,cw,4,0.01,0.02\n\
        umbmark,cw,4,0.012,0.018\n\
        umbmark,ccw,4,-0.03,0.01\n\
        umbmark,ccw,4,-0.028,0.012\n";

    #[test]
    fn reads_umbmark_runs() {
        let f = RunsFile::parse(GOOD, Path::new("runs.csv")).unwrap();
        let u = f.umbmark(Phase::Before).unwrap().unwrap();
        assert_eq!(u.side_m, 4.0);
        assert_eq!(u.cw, vec![(0.01, 0.02), (0.012, 0.018)]);
        assert_eq!(u.ccw.len(), 2);
        assert_eq!(f.umbmark(Phase::After).unwrap(), None);
    }

    #[test]
    fn bad_files_say_where_and_what_to_fix() {
        let p = Path::new("runs.csv");
        let e = RunsFile::parse(&GOOD.replace("0.012,0.018", "0.012,abc"), p).unwrap_err();
        assert_eq!(e.to_string(), "runs.csv:3: column 'y_err_m': not a number: 'abc' (metres or radians, '.' decimal point)");
        let e = RunsFile::parse(
            &GOOD.replace("umbmark,ccw,4,-0.03", "umbmak,ccw,4,-0.03"),
            p,
        )
        .unwrap_err();
        assert_eq!(e.line, Some(4));
        assert!(e.message.contains("unknown test 'umbmak'"));
        let e = RunsFile::parse(
            &GOOD.replace("umbmark,ccw,4,-0.03", "umbmark,left,4,-0.03"),
            p,
        )
        .unwrap_err();
        assert!(e.message.contains("expected cw or ccw"));
        // One direction only.
        let one_dir = GOOD.replace("ccw", "cw");
        let e = RunsFile::parse(&one_dir, p)
            .unwrap()
            .umbmark(Phase::Before)
            .unwrap_err();
        assert!(e.message.contains("0 ccw run(s)"), "{e}");
        // One run in a direction.
        let short: String = GOOD.lines().take(4).collect::<Vec<_>>().join("\n");
        let e = RunsFile::parse(&short, p)
            .unwrap()
            .umbmark(Phase::Before)
            .unwrap_err();
        assert!(e.message.contains("1 ccw run(s)"), "{e}");
        // Lengths that disagree.
        let e = RunsFile::parse(
            &GOOD.replace("umbmark,ccw,4,-0.028", "umbmark,ccw,3,-0.028"),
            p,
        )
        .unwrap()
        .umbmark(Phase::Before)
        .unwrap_err();
        assert_eq!((e.line, e.column.as_deref()), (Some(5), Some("length_m")));
        let e = RunsFile::parse("test,path,length_m,x_err_m\n", p).unwrap_err();
        assert!(e.message.contains("missing column 'y_err_m'"));
    }

    #[test]
    fn circle_rows_sit_beside_the_squares() {
        // Two radii, one with laps given; the squares read as before.
        let text = "test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase,laps\n\
            umbmark,cw,4,0.01,0.02,,,\n\
            umbmark,cw,4,0.012,0.018,,,\n\
            umbmark,ccw,4,-0.03,0.01,,,\n\
            umbmark,ccw,4,-0.028,0.012,,,\n\
            circle,cw,0.5,-0.031,0.001,,before,\n\
            circle,ccw,0.5,-0.029,-0.001,,,\n\
            circle,cw,0.3,-0.05,0,-0.1,,3\n";
        let f = RunsFile::parse(text, Path::new("runs.csv")).unwrap();
        assert_eq!(f.umbmark(Phase::Before).unwrap().unwrap().cw.len(), 2);
        let c = f.circles(Phase::Before);
        assert_eq!(c.len(), 3);
        assert_eq!(
            (c[0].dir, c[0].radius_m, c[0].laps),
            (Direction::Cw, 0.5, 1)
        );
        assert_eq!((c[1].dir, c[1].x_err_m), (Direction::Ccw, -0.029));
        assert_eq!((c[2].laps, c[2].theta_err_rad), (3, Some(-0.1)));
        assert!(f.circles(Phase::After).is_empty());
        // Laps outside 1..=10, laps on a square, and a circle path that is no direction.
        let p = Path::new("runs.csv");
        let bad = |t: &str| RunsFile::parse(t, p).unwrap_err();
        let head = "test,path,length_m,x_err_m,y_err_m,laps\n";
        let e = bad(&format!("{head}circle,cw,0.5,0,0,11\n"));
        assert_eq!((e.line, e.column.as_deref()), (Some(2), Some("laps")));
        assert!(e.message.contains("from 1 to 10"), "{e}");
        assert!(bad(&format!("{head}circle,cw,0.5,0,0,1.5\n"))
            .message
            .contains("whole number"));
        assert!(bad(&format!("{head}umbmark,cw,4,0,0,2\n"))
            .message
            .contains("only circle rows have laps"));
        assert!(bad(&format!("{head}circle,left,0.5,0,0,1\n"))
            .message
            .contains("unknown circle path 'left'"));
        // Appended: a file started without a laps column refuses a circle of 3 laps and
        // writes nothing; one started with it reads back every row as written.
        let dir = std::env::temp_dir().join(format!("wheelcal-circle-{}", std::process::id()));
        let _ = std::fs::remove_file(&dir);
        RunsFile::append(&dir, &f.rows[0]).unwrap();
        let before = std::fs::read_to_string(&dir).unwrap();
        assert!(!RunsFile::takes_laps(&dir));
        let e = RunsFile::append(&dir, &f.rows[6]).unwrap_err();
        assert!(e.to_string().contains("no laps column"), "{e}");
        assert_eq!(std::fs::read_to_string(&dir).unwrap(), before);
        std::fs::remove_file(&dir).unwrap();
        assert!(RunsFile::takes_laps(&dir));
        for r in &f.rows {
            RunsFile::append_with(&dir, r, true).unwrap();
        }
        assert!(RunsFile::takes_laps(&dir));
        let back = RunsFile::load(&dir).unwrap();
        let strip = |rows: &[RunRow]| {
            rows.iter()
                .map(|r| RunRow {
                    line: 0,
                    ..r.clone()
                })
                .collect::<Vec<_>>()
        };
        assert_eq!(strip(&back.rows), strip(&f.rows));
        std::fs::remove_file(&dir).unwrap();
    }

    #[test]
    fn append_then_read_back() {
        let dir = std::env::temp_dir().join(format!("wheelcal-runs-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("runs.csv");
        let _ = std::fs::remove_file(&p);
        for (i, path) in ["4W-1", "4W-1", "4W-2", "4W-2"].iter().enumerate() {
            let row = RunRow {
                line: 0,
                test: TestKind::Omni,
                path: path.to_string(),
                length_m: 0.6,
                x_err_m: -0.05 - i as f64 * 0.001,
                y_err_m: 0.01,
                theta_err_rad: None,
                phase: Phase::Before,
                laps: 1,
            };
            RunsFile::append(&p, &row).unwrap();
        }
        let f = RunsFile::load(&p).unwrap();
        let o = f.omni(Phase::Before).unwrap();
        assert_eq!(o.len(), 2);
        assert_eq!(o[1].omni_path, Some(OmniPath::W2));
        assert!((o[1].runs[1].0 + 0.053).abs() < 1e-12);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
