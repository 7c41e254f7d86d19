//! The board's trial log: `log list`'s rows and the transfer of a trial into a recording
//! (CSV with the board's odometry, or MCAP).

use super::factors::FactorsView;
use crate::client::{decode_records, Client};
use anyhow::{bail, Context, Result};
use calib_core::protocol::{Num, ProgramKind, Record, TrialInfo, Trials};
use calib_core::robot::Robot;
use formats::recording::Recording;
use serde::Serialize;
use std::fmt::Write as _;
use std::io::{Read, Write};
use std::path::Path;
use std::time::Instant;

/// How a trial ended, as `log list` prints it (snake case, one word per state).
pub fn trial_end_text(end: calib_core::protocol::TrialEnd) -> &'static str {
    match end {
        calib_core::protocol::TrialEnd::Running => "running",
        calib_core::protocol::TrialEnd::Completed => "completed",
        calib_core::protocol::TrialEnd::Stopped => "stopped",
        calib_core::protocol::TrialEnd::EStop => "estop",
        calib_core::protocol::TrialEnd::Fault => "fault",
        calib_core::protocol::TrialEnd::CommandTimeout => "command_timeout",
        calib_core::protocol::TrialEnd::LinkLost => "link_lost",
    }
}

/// A trial's program in words (`umbmark cw, side 0.5 m`), not Rust's debug text.
pub fn program_text(p: &ProgramKind) -> String {
    match p {
        ProgramKind::Drive => "drive".into(),
        ProgramKind::Umbmark { side_m, dir } => {
            format!("umbmark {}, side {} m", dir.as_str(), Num(*side_m as f64))
        }
        ProgramKind::Omni { path, length_m } => {
            format!("omni {}, {} m", path.as_str(), Num(*length_m as f64))
        }
        ProgramKind::Custom { segments: 1 } => "custom, 1 segment".into(),
        ProgramKind::Custom { segments } => format!("custom, {segments} segments"),
        ProgramKind::Circle {
            radius_m,
            dir,
            laps,
        } => format!(
            "circle {}, radius {} m, {laps} lap{}",
            dir.as_str(),
            Num(*radius_m as f64),
            if *laps == 1 { "" } else { "s" }
        ),
    }
}

/// `log list` rows.
#[derive(Debug, Clone, Serialize)]
pub struct TrialRow {
    /// Trial id.
    pub trial: u16,
    /// What was run, in words ([`program_text`]).
    pub program: String,
    /// Board uptime at the first record, s.
    pub start_s: f64,
    /// Record rate, Hz.
    pub rate_hz: u16,
    /// Records stored.
    pub records: u32,
    /// Log bytes stored.
    pub bytes: u32,
    /// Records not stored because the log was full.
    pub dropped_records: u32,
    /// How the trial ended, lower case (`running` while it records).
    pub end: String,
    /// Corrections in force during the trial.
    pub corrections: FactorsView,
}

/// `log list`: the board's stored trials.
#[derive(Debug, Clone, Serialize)]
pub struct TrialList {
    /// The trials, as the board lists them.
    pub trials: Vec<TrialRow>,
    /// Trials evicted since boot to make room for newer ones.
    pub evicted_trials: u32,
}

/// The board's trial list as `log list` rows.
pub fn trial_list(t: &Trials) -> TrialList {
    TrialList {
        trials: t
            .trials
            .iter()
            .map(|i| TrialRow {
                trial: i.id,
                program: program_text(&i.program),
                start_s: i.start_ms as f64 / 1000.0,
                rate_hz: i.rate_hz,
                records: i.records,
                bytes: i.bytes,
                dropped_records: i.dropped,
                end: trial_end_text(i.end).into(),
                corrections: (&i.corrections).into(),
            })
            .collect(),
        evicted_trials: t.evicted,
    }
}

impl TrialList {
    /// The list as a text table.
    pub fn human(&self) -> String {
        let mut s = format!(
            "{:>5} {:<42} {:>8} {:>6} {:>8} {:>8} {:<10}\n",
            "trial", "program", "start s", "Hz", "records", "dropped", "end"
        );
        for r in &self.trials {
            let _ = writeln!(
                s,
                "{:>5} {:<42} {:>8.1} {:>6} {:>8} {:>8} {:<10}",
                r.trial, r.program, r.start_s, r.rate_hz, r.records, r.dropped_records, r.end
            );
        }
        if self.evicted_trials > 0 {
            let _ = writeln!(
                s,
                "({} older trials were evicted to make room)",
                self.evicted_trials
            );
        }
        s
    }
}

/// Converts a trial's records into a recording (docs/formats.md §2): `cmd_` and `enc_`
/// columns from the board, pose columns blank (the board does not measure its pose), and
/// the board's odometry as extra `odo_x`, `odo_y`, `odo_theta` columns.
pub fn records_to_csv(
    robot: &Robot,
    info: &TrialInfo,
    recs: &[Record],
    out: &mut impl Write,
) -> Result<()> {
    let n = info.wheel_count as usize;
    if n != robot.wheel_count() {
        bail!(
            "trial {} has {} wheels, the board's robot {}",
            info.id,
            n,
            robot.wheel_count()
        );
    }
    let mut rec = Recording::new(robot, true, true);
    let mut odo = Vec::with_capacity(recs.len());
    let mut wraps = 0u64;
    let mut last = 0u32;
    for r in recs {
        if r.t_us < last {
            wraps += 1; // the u32 microsecond clock wraps after 71 minutes
        }
        last = r.t_us;
        let t = (wraps * (1u64 << 32) + r.t_us as u64) as f64 * 1e-6;
        let cmd: Vec<f64> = r.cmd[..n].iter().map(|&v| v as f64).collect();
        let enc: Vec<i64> = r.counts[..n].iter().map(|&v| v as i64).collect();
        rec.push_row(formats::recording::Row {
            t,
            cmd: Some(&cmd),
            enc: Some(&enc),
            pose: None,
            legs: None,
        });
        odo.push(r.pose);
    }
    // Write the standard columns, then append the odometry columns.
    let mut buf = Vec::new();
    rec.write_csv(&mut buf)?;
    let text = String::from_utf8(buf).context("CSV is UTF-8")?;
    for (i, line) in text.lines().enumerate() {
        if i == 0 {
            writeln!(out, "{line},odo_x,odo_y,odo_theta")?;
        } else {
            let p = odo[i - 1];
            writeln!(out, "{line},{},{},{}", p.x, p.y, p.theta)?;
        }
    }
    Ok(())
}

/// Pulls a trial and writes it as CSV; `progress(done, total)` per chunk.
pub fn pull_trial<L: Read + Write>(
    c: &mut Client<L>,
    trial: u16,
    out: &Path,
    progress: impl FnMut(u64, u64),
) -> Result<PulledTrial> {
    pull_trial_with(c, trial, out, None, progress)
}

/// [`pull_trial`], and with `tum` the board's odometry as a TUM trajectory
/// (`odometry.txt`, stamped with the board's uptime in s) in that folder
/// ([`crate::tum`]).
pub fn pull_trial_with<L: Read + Write>(
    c: &mut Client<L>,
    trial: u16,
    out: &Path,
    tum: Option<&Path>,
    progress: impl FnMut(u64, u64),
) -> Result<PulledTrial> {
    // The format follows the name: refuse a name that says another one (`x.json` got a
    // CSV) before anything is transferred, and an existing file of another kind.
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    let mcap = match ext.as_deref() {
        Some("mcap") => true,
        Some("csv") => false,
        _ => bail!(
            "--out {}: a trial is written as CSV (a name ending in .csv) or MCAP (.mcap)",
            out.display()
        ),
    };
    formats::safe_write::check_target(
        out,
        if mcap { "MCAP file" } else { "recording CSV" },
        |head| {
            if mcap {
                head.starts_with(b"\x89MCAP")
            } else {
                head.starts_with(b"t,")
            }
        },
    )?;
    let trials = c.trials()?;
    let info = trials
        .trials
        .iter()
        .find(|t| t.id == trial)
        .cloned()
        .with_context(|| {
            format!(
                "the board has no trial {trial}: it keeps the last {} trials, a newer program evicting the oldest ({} evicted since boot; `wheelcal log list` shows those it holds)",
                calib_core::protocol::MAX_TRIALS,
                trials.evicted
            )
        })?;
    let robot = c.params()?.robot;
    let t0 = Instant::now();
    let data = c
        .pull_log(trial, Vec::new(), progress)
        .with_context(|| format!("log transfer of trial {trial} failed"))?;
    let secs = t0.elapsed().as_secs_f64();
    let recs = decode_records(&info, &data)?;
    if mcap {
        crate::mcap_out::write_trial(&robot, &info, &recs, out)
            .with_context(|| format!("cannot write {}", out.display()))?;
    } else {
        let mut w = Vec::new();
        records_to_csv(&robot, &info, &recs, &mut w)?;
        formats::safe_write::replace_file(out, &w)?;
    }
    let tum = match tum {
        Some(dir) => {
            let start_s = info.start_ms as f64 * 1e-3;
            let mut clock = crate::mcap_out::TrialClock::new();
            let poses: Vec<crate::tum::Stamped> = recs
                .iter()
                .map(|r| {
                    let t = start_s + clock.us(r.t_us) as f64 * 1e-6;
                    (t, r.pose.x as f64, r.pose.y as f64, r.pose.theta as f64)
                })
                .collect();
            crate::tum::write_dir(dir, &[("odometry".to_string(), poses)])?
        }
        None => Vec::new(),
    };
    Ok(PulledTrial {
        trial,
        file: out.display().to_string(),
        records: recs.len(),
        dropped_records: info.dropped,
        bytes: data.len(),
        seconds: secs,
        retries: c.stats.retries,
        partial: info.end == calib_core::protocol::TrialEnd::Running,
        tum,
    })
}

/// What [`pull_trial`] did.
#[derive(Debug, Clone, Serialize)]
pub struct PulledTrial {
    /// Trial id.
    pub trial: u16,
    /// The file written (CSV, or MCAP for a `.mcap` name).
    pub file: String,
    /// Records decoded and written.
    pub records: usize,
    /// Records the board did not store because the log was full.
    pub dropped_records: u32,
    /// Log bytes transferred.
    pub bytes: usize,
    /// Time the transfer took, s.
    pub seconds: f64,
    /// Resends on this connection so far (the client's running count).
    pub retries: u32,
    /// The trial was still running when pulled: the file holds only its start.
    pub partial: bool,
    /// TUM trajectory files written (`--tum`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub tum: Vec<String>,
}

impl PulledTrial {
    /// Warnings a user must see with the pulled file.
    pub fn warnings(&self) -> String {
        let mut s = String::new();
        if self.partial {
            s.push_str("; PARTIAL: the trial was still running, the file holds only what was logged so far (pull again when it has ended)");
        }
        if self.dropped_records > 0 {
            let _ = write!(
                s,
                "; WARNING: the board dropped {} records (log full): the trial is missing its end",
                self.dropped_records
            );
        }
        s
    }
}
