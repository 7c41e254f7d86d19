//! The board commands (`info`, `factors`, `drive`, `run`, `status`, `log`, `stop`), as
//! functions over any [`Client`] so the tests drive them through an in-memory link.

use crate::client::{decode_records, Client};
use anyhow::{bail, Context, Result};
use calib_core::motion::{Direction, OmniPath};
use calib_core::protocol::{
    Info, Mode, Num, ProgramKind, ProgramSpec, Record, Status, TrialInfo, Trials,
};
use calib_core::robot::{Robot, MAX_WHEELS};
use calib_core::{Corrections, Twist};
use formats::recording::Recording;
use serde::Serialize;
use std::fmt::Write as _;
use std::io::{Read, Write};
use std::path::Path;
use std::time::{Duration, Instant};

/// `wheelcal info`.
#[derive(Debug, Clone, Serialize)]
pub struct InfoReport {
    /// Firmware version text.
    pub firmware: String,
    /// The board's protocol version.
    pub protocol_version: u16,
    /// The board's schema fingerprint, 8 hex digits.
    pub schema: String,
    /// Name of the robot the board is configured for.
    pub robot: String,
    /// The robot's kind, as in the robot file.
    pub robot_kind: String,
    /// How the wheels are driven, lower case.
    pub drive: String,
    /// Wheels of the configured robot.
    pub wheel_count: u8,
    /// Wheel names, in the robot's wheel order.
    pub wheels: Vec<String>,
    /// Time since boot, s.
    pub uptime_s: f64,
    /// What boot found for the corrections ([`stored_word`]).
    pub corrections_at_boot: String,
    /// What boot found for the parameters ([`stored_word`]).
    pub params_at_boot: String,
    /// Trial-log RAM, bytes.
    pub log_capacity_bytes: u32,
    /// Bytes per log record for this robot.
    pub record_size_bytes: u16,
}

/// What boot found for one stored item, as a JSON word: `loaded`, `none_saved`,
/// `corrupted` (saved once, now unreadable: a lost calibration) or `flash_error`.
pub fn stored_word(s: calib_core::protocol::Stored) -> &'static str {
    use calib_core::protocol::Stored;
    match s {
        Stored::Loaded => "loaded",
        Stored::Missing => "none_saved",
        Stored::Invalid => "corrupted",
        Stored::StorageError => "flash_error",
    }
}

/// The words a user acts on: a corrupted item means a saved calibration was lost.
fn stored_human(word: &str) -> &str {
    match word {
        "loaded" => "loaded",
        "none_saved" => "none saved (nominal)",
        "corrupted" => "corrupted, using nominal",
        "flash_error" => "flash unreadable, using nominal",
        other => other,
    }
}

/// Asks the board for its info and parameters: what `wheelcal info` shows.
pub fn info<L: Read + Write>(c: &mut Client<L>) -> Result<InfoReport> {
    let i: Info = c.info()?;
    let p = c.params()?;
    Ok(InfoReport {
        firmware: i.firmware.to_string(),
        protocol_version: i.protocol_version,
        schema: format!("{:08x}", i.schema),
        robot: p.robot.name.to_string(),
        robot_kind: i.robot_kind.as_str().into(),
        drive: format!("{:?}", i.drive).to_lowercase(),
        wheel_count: i.wheel_count,
        wheels: p.robot.wheels.iter().map(|w| w.name.to_string()).collect(),
        uptime_s: i.uptime_ms as f64 / 1000.0,
        corrections_at_boot: stored_word(i.boot.corrections).into(),
        params_at_boot: stored_word(i.boot.params).into(),
        log_capacity_bytes: i.log_capacity,
        record_size_bytes: i.record_size,
    })
}

impl InfoReport {
    /// The report as text lines for a person.
    pub fn human(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "firmware      {} (protocol v{}, schema {})",
            self.firmware, self.protocol_version, self.schema
        );
        let _ = writeln!(
            s,
            "robot         {} ({}, {} drive), wheels: {}",
            self.robot,
            self.robot_kind,
            self.drive,
            self.wheels.join(", ")
        );
        let _ = writeln!(s, "uptime        {:.1} s", self.uptime_s);
        let _ = writeln!(
            s,
            "at boot       corrections {}, parameters {}",
            stored_human(&self.corrections_at_boot),
            stored_human(&self.params_at_boot)
        );
        let _ = writeln!(
            s,
            "trial log     {} KiB, {} bytes per record",
            self.log_capacity_bytes / 1024,
            self.record_size_bytes
        );
        s
    }
}

/// Corrections in the JSON and text forms people read.
#[derive(Debug, Clone, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum FactorsView {
    /// Nominal geometry, no corrections.
    None,
    /// Differential drive (Borenstein & Feng).
    DiffDrive {
        /// Left wheel's effective radius / nominal radius.
        c_l: f64,
        /// Right wheel's effective radius / nominal radius.
        c_r: f64,
        /// Actual wheelbase / nominal wheelbase.
        e_b: f64,
    },
    /// Omnidirectional robot.
    Omni {
        /// Lateral factor per wheel, in the robot's wheel order.
        f_lat: Vec<f64>,
        /// Longitudinal factor common to all wheels.
        f_lon: f64,
    },
}

impl From<&Corrections> for FactorsView {
    fn from(c: &Corrections) -> Self {
        match c {
            Corrections::None => FactorsView::None,
            Corrections::DiffDrive { c_l, c_r, e_b } => FactorsView::DiffDrive {
                c_l: *c_l,
                c_r: *c_r,
                e_b: *e_b,
            },
            Corrections::Omni { f_lat, f_lon } => FactorsView::Omni {
                f_lat: f_lat.to_vec(),
                f_lon: *f_lon,
            },
        }
    }
}

impl FactorsView {
    /// The factors as one text line.
    pub fn human(&self) -> String {
        match self {
            FactorsView::None => "no corrections (nominal geometry)\n".into(),
            FactorsView::DiffDrive { c_l, c_r, e_b } => {
                format!("c_L = {c_l:.6}  c_R = {c_r:.6}  E_b = {e_b:.6}\n")
            }
            FactorsView::Omni { f_lat, f_lon } => format!(
                "F_lat = [{}]  F_lon = {f_lon:.6}\n",
                f_lat
                    .iter()
                    .map(|v| format!("{v:.6}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}

/// The factors `factors set` asks for: the board's `current` factors with the ones given
/// replaced (nominal where the board holds none or the other kind, `n_wheels` F_lat of 1
/// for an omni robot; the board refuses factors of the wrong kind in its own words).
/// Differential and omni factors do not mix, and at least one factor must be given.
pub fn merge_corrections(
    current: &Corrections,
    n_wheels: usize,
    c_l: Option<f64>,
    c_r: Option<f64>,
    e_b: Option<f64>,
    f_lat: Option<&[f64]>,
    f_lon: Option<f64>,
) -> Result<Corrections> {
    let diff = c_l.is_some() || c_r.is_some() || e_b.is_some();
    let omni = f_lat.is_some() || f_lon.is_some();
    match (diff, omni) {
        (false, false) => bail!(
            "give the factors to change: --c-l, --c-r, --e-b (differential drive) or --f-lat, --f-lon (omni)"
        ),
        (true, true) => {
            bail!("differential (--c-l, --c-r, --e-b) and omni (--f-lat, --f-lon) factors do not mix")
        }
        (true, false) => {
            // Factors of the other kind on the board: nominal here, and the board refuses
            // differential factors on an omni robot in its own words.
            let (l, r, b) = match current {
                Corrections::DiffDrive { c_l, c_r, e_b } => (*c_l, *c_r, *e_b),
                _ => (1.0, 1.0, 1.0),
            };
            Ok(Corrections::DiffDrive {
                c_l: c_l.unwrap_or(l),
                c_r: c_r.unwrap_or(r),
                e_b: e_b.unwrap_or(b),
            })
        }
        (false, true) => {
            let (lat, lon) = match current {
                Corrections::Omni { f_lat, f_lon } => (f_lat.to_vec(), *f_lon),
                _ => (vec![1.0; n_wheels], 1.0),
            };
            let lat = f_lat.map(<[f64]>::to_vec).unwrap_or(lat);
            let f_lat = heapless::Vec::from_slice(&lat)
                .map_err(|_| anyhow::anyhow!("at most {MAX_WHEELS} F_lat factors"))?;
            Ok(Corrections::Omni {
                f_lat,
                f_lon: f_lon.unwrap_or(lon),
            })
        }
    }
}

/// A one-line status.
pub fn status_line(s: &Status) -> String {
    let mode = match s.mode {
        Mode::Idle => "idle".to_string(),
        Mode::Drive => "drive".to_string(),
        Mode::Program { segment, segments } => {
            format!("program {}/{}", segment as u32 + 1, segments)
        }
    };
    let mut line = format!(
        "t {:>8.2} s  {:<12} pose ({:+.4} m, {:+.4} m, {:+.4} rad)  rates [{}]",
        s.uptime_ms as f64 / 1000.0,
        mode,
        s.pose.x,
        s.pose.y,
        s.pose.theta,
        s.wheel_rates
            .iter()
            .map(|r| format!("{r:+.2}"))
            .collect::<Vec<_>>()
            .join(" ")
    );
    if s.estop {
        line.push_str("  E-STOP");
    }
    if let Some(f) = s.fault {
        let _ = write!(line, "  FAULT ({f})");
    }
    if s.dropped_records > 0 {
        let _ = write!(line, "  log dropped {} records", s.dropped_records);
    }
    line
}

/// After Ctrl-C: sends Stop, says so, and watches the board until every wheel is at rest
/// (or [`crate::stop::REST_TIMEOUT`] passes), so the message the user reads is true.
pub fn stop_after_interrupt<L: Read + Write>(
    c: &mut Client<L>,
) -> Result<crate::stop::Interrupted> {
    use crate::stop::{REST_RATE, REST_TIMEOUT};
    c.stop()?;
    eprintln!("\nCtrl-C: stopping the robot...");
    let t0 = Instant::now();
    while t0.elapsed() < REST_TIMEOUT {
        let Ok(s) = c.status() else { break };
        let idle = matches!(s.mode, Mode::Idle);
        // Commands at zero (the stop ramp has ended; an open-loop stepper has no measured
        // rate) and measured rates at rest.
        let still = |v: &[f32]| v.iter().all(|r| r.abs() < REST_RATE);
        if idle && still(&s.wheel_cmds) && still(&s.wheel_rates) {
            return Ok(crate::stop::Interrupted {
                came_to_rest_after: Some(t0.elapsed()),
            });
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    Ok(crate::stop::Interrupted {
        came_to_rest_after: None,
    })
}

/// Waits for a program to end, calling `on_status` now and then; returns the last status.
pub fn wait_program<L: Read + Write>(
    c: &mut Client<L>,
    limit: Duration,
    mut on_status: impl FnMut(&Status),
) -> Result<Status> {
    let t0 = Instant::now();
    let mut seen_busy = false;
    let _guard = crate::stop::Guard::new();
    loop {
        if crate::stop::requested() {
            return Err(stop_after_interrupt(c)?.into());
        }
        let s = c.status()?;
        on_status(&s);
        let idle = matches!(s.mode, Mode::Idle);
        if !idle {
            seen_busy = true;
        }
        // The board starts the program when it answers RunProgram, so idle right after
        // means it already finished (or was stopped).
        if idle && (seen_busy || t0.elapsed() > Duration::from_millis(200)) {
            return Ok(s);
        }
        if t0.elapsed() > limit {
            let _ = c.stop();
            bail!(
                "the program did not finish within {:.0} s; sent Stop",
                limit.as_secs_f64()
            );
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Starts a UMBmark square.
pub fn run_umbmark<L: Read + Write>(
    c: &mut Client<L>,
    dir: Direction,
    side_m: f64,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    start_program(
        c,
        ProgramSpec::Umbmark { side_m, dir },
        log_rate_hz,
        link_timeout_ms,
    )
}

/// Starts an omni path.
pub fn run_omni<L: Read + Write>(
    c: &mut Client<L>,
    path: OmniPath,
    length_m: f64,
    idle: calib_core::protocol::IdleWheels,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    start_program(
        c,
        ProgramSpec::Omni {
            path,
            length_m,
            idle,
        },
        log_rate_hz,
        link_timeout_ms,
    )
}

/// Checks a program with the board's own rule ([`ProgramSpec::validate`] against the
/// board's robot and arena) before anything is sent, then starts it. Returns how long to
/// wait for it before giving up: a minute plus a minute per metre of its longest length,
/// which the check has bounded to the arena. The board stops the program when it hears
/// nothing from this host for `link_timeout_ms` (0: never; [`wait_program`]'s polling
/// keeps it alive).
pub fn start_program<L: Read + Write>(
    c: &mut Client<L>,
    program: ProgramSpec,
    log_rate_hz: u16,
    link_timeout_ms: u16,
) -> Result<Duration> {
    let params = c.params()?;
    let robot = &params.robot;
    let arena = params.safety.arena_m as f64;
    if let Err(why) = program.validate(robot.wheel_count(), robot.kind, arena) {
        bail!("not sent: {why} (the board's arena is {arena} m; `factors`/params set it)");
    }
    let longest = match &program {
        ProgramSpec::Umbmark { side_m, .. } => *side_m,
        ProgramSpec::Omni { length_m, .. } => *length_m,
        ProgramSpec::Custom(_) => arena,
    };
    // Say before the run which trials it will push out of the log (the board cannot tell
    // whether they were pulled).
    let (info, trials) = (c.info()?, c.trials()?);
    let gone = eviction_forecast(
        &trials,
        info.log_capacity,
        info.record_size,
        &program,
        &params.limits,
        log_rate_hz,
    );
    if !gone.is_empty() {
        let ids: Vec<String> = gone.iter().map(u16::to_string).collect();
        eprintln!(
            "note: this run will evict trial(s) {} from the board's log to make room; pull any you still need first (`wheelcal log pull`)",
            ids.join(", ")
        );
    }
    c.run_program(program, log_rate_hz, link_timeout_ms)?;
    Ok(program_time_limit(longest))
}

/// Trials (ids, oldest first) a program logging at `rate_hz` would push out of the
/// board's log: the ring evicts whole trials, oldest first, until the new records fit,
/// and the oldest one when the trial table is full. The program's length comes from the
/// board's own motion profile (`limits`), with 10 % to spare.
pub fn eviction_forecast(
    trials: &Trials,
    capacity: u32,
    record_size: u16,
    program: &ProgramSpec,
    limits: &calib_core::motion::ProfileLimits,
    rate_hz: u16,
) -> Vec<u16> {
    use calib_core::motion::Program;
    if rate_hz == 0 {
        return Vec::new();
    }
    let prog = match program {
        ProgramSpec::Umbmark { side_m, dir } => Program::umbmark_square(*side_m, *dir),
        ProgramSpec::Omni { path, length_m, .. } => Program::omni_path(*path, *length_m),
        ProgramSpec::Custom(segs) => Program {
            segments: segs.clone(),
        },
    };
    let records = (prog.duration(limits) * 1.1 * f64::from(rate_hz)).ceil();
    // The log stores records compressed (about 4.3 bytes for a 32-byte two-wheel record):
    // the size that counts is the one the board's own trials show, the largest of them
    // (issue 23 §5: 32 bytes a record named trials that were never evicted). Without a
    // trial to learn from, the uncompressed size bounds it.
    let per_record = trials
        .trials
        .iter()
        .filter(|t| t.records > 0)
        .map(|t| f64::from(t.bytes) / f64::from(t.records))
        .fold(None, |m: Option<f64>, v| Some(m.map_or(v, |m| m.max(v))))
        .unwrap_or(f64::from(record_size))
        .min(f64::from(record_size));
    let needed = (records * per_record).min(f64::from(capacity));
    let mut used: f64 = trials.trials.iter().map(|t| f64::from(t.bytes)).sum();
    let mut gone = Vec::new();
    for t in &trials.trials {
        let table_full = trials.trials.len() - gone.len() >= calib_core::protocol::MAX_TRIALS;
        if f64::from(capacity) - used >= needed && !table_full {
            break;
        }
        used -= f64::from(t.bytes);
        gone.push(t.id);
    }
    gone
}

/// A minute plus a minute per metre, for any finite length (negative or NaN count as 0,
/// huge values saturate): never panics, whatever the number.
pub fn program_time_limit(length_m: f64) -> Duration {
    let s = 60.0 + 60.0 * length_m.max(0.0);
    Duration::try_from_secs_f64(s).unwrap_or(Duration::from_secs(24 * 3600))
}

/// Drives at a twist for a while, refreshing the command faster than the board's
/// command timeout, then stops.
pub fn drive_for<L: Read + Write>(
    c: &mut Client<L>,
    twist: Twist<f32>,
    duration: Duration,
) -> Result<()> {
    let _guard = crate::stop::Guard::new();
    let t0 = Instant::now();
    let mut refreshed = None::<Instant>;
    while t0.elapsed() < duration {
        if crate::stop::requested() {
            return Err(stop_after_interrupt(c)?.into());
        }
        if refreshed.is_none_or(|r| r.elapsed() >= Duration::from_millis(100)) {
            c.drive(twist, 0)?;
            refreshed = Some(Instant::now());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    c.stop()?;
    Ok(())
}

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
    }
}

/// A board's factors in words for messages (`c_L = 1.000000  c_R = ...`).
pub fn factors_text(c: &Corrections) -> String {
    FactorsView::from(c).human().trim_end().to_string()
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
        .with_context(|| format!("the board has no trial {trial} (see `wheelcal log list`)"))?;
    let robot = c.params()?.robot;
    let t0 = Instant::now();
    let data = c
        .pull_log(trial, Vec::new(), progress)
        .with_context(|| format!("log transfer of trial {trial} failed"))?;
    let secs = t0.elapsed().as_secs_f64();
    let recs = decode_records(&info, &data).map_err(|e| anyhow::anyhow!(e))?;
    if mcap {
        crate::mcap_out::write_trial(&info, &recs, out)
            .with_context(|| format!("cannot write {}", out.display()))?;
    } else {
        let mut w = Vec::new();
        records_to_csv(&robot, &info, &recs, &mut w)?;
        formats::safe_write::replace_file(out, &w)?;
    }
    Ok(PulledTrial {
        trial,
        file: out.display().to_string(),
        records: recs.len(),
        dropped_records: info.dropped,
        bytes: data.len(),
        seconds: secs,
        retries: c.stats.retries,
        partial: info.end == calib_core::protocol::TrialEnd::Running,
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

#[cfg(test)]
mod boot_words {
    use super::*;
    use calib_core::protocol::{ProgramKind, Stored, TrialEnd, MAX_TRIALS};

    fn trial(id: u16, bytes: u32) -> TrialInfo {
        TrialInfo {
            id,
            program: ProgramKind::Drive,
            start_ms: 0,
            rate_hz: 50,
            wheel_count: 2,
            record_size: 32,
            records: bytes / 32,
            bytes,
            dropped: 0,
            end: TrialEnd::Completed,
            corrections: Corrections::None,
        }
    }

    #[test]
    fn a_run_names_the_trials_it_will_evict() {
        let limits = calib_core::motion::ProfileLimits::default();
        let square = ProgramSpec::Umbmark {
            side_m: 4.0,
            dir: Direction::Cw,
        };
        let secs =
            calib_core::motion::Program::umbmark_square(4.0, Direction::Cw).duration(&limits);
        // Bytes the square logs at 50 Hz, 32-byte records, with the 10 % margin.
        let need = (secs * 1.1 * 50.0).ceil() as u32 * 32;
        let list = |sizes: &[u32]| Trials {
            trials: sizes
                .iter()
                .enumerate()
                .map(|(i, &b)| trial(i as u16 + 1, b))
                .collect(),
            evicted: 0,
        };
        // Room enough: nothing goes.
        let cap = 3 * need;
        let f = |t: &Trials| eviction_forecast(t, cap, 32, &square, &limits, 50);
        assert!(f(&list(&[need, need / 2])).is_empty());
        // Full log: the oldest go until the run fits (trial 1 frees `need`).
        assert_eq!(f(&list(&[need, need, need / 2])), vec![1]);
        assert_eq!(f(&list(&[need / 2, need / 2, need * 2])), vec![1, 2]);
        // A full trial table evicts the oldest even with bytes to spare.
        let many = vec![8; MAX_TRIALS];
        assert_eq!(f(&list(&many)), vec![1]);
        // No logging, no eviction.
        assert!(eviction_forecast(&list(&[cap]), cap, 32, &square, &limits, 0).is_empty());
        // Compressed trials (43 bytes per 10 records): the run needs 4.3 / 32 of `need`,
        // so a log with that much free keeps every trial.
        let packed = |sizes: &[u32]| Trials {
            trials: sizes
                .iter()
                .enumerate()
                .map(|(i, &b)| TrialInfo {
                    records: b * 10 / 43,
                    ..trial(i as u16 + 1, b)
                })
                .collect(),
            evicted: 0,
        };
        let small = need * 43 / 320 + need / 100;
        assert!(f(&packed(&[cap - small])).is_empty());
        assert_eq!(f(&packed(&[cap - small / 2])), vec![1]);
    }

    #[test]
    fn a_lost_calibration_is_named() {
        let w = stored_word(Stored::Invalid);
        assert_eq!(stored_human(w), "corrupted, using nominal");
        assert_eq!(
            stored_human(stored_word(Stored::Missing)),
            "none saved (nominal)"
        );
        assert_ne!(stored_word(Stored::Invalid), stored_word(Stored::Missing));
    }
}

#[cfg(test)]
mod merge {
    use super::*;

    /// `factors set --e-b 1.6` keeps the board's c_L and c_R (the help's promise); an
    /// omni robot with no factors gets F_lat 1 for the wheels not given.
    #[test]
    fn only_the_factors_given_change() {
        let cur = Corrections::DiffDrive {
            c_l: 0.998,
            c_r: 1.002,
            e_b: 1.01,
        };
        let m = merge_corrections(&cur, 2, None, None, Some(1.6), None, None).unwrap();
        assert_eq!(
            m,
            Corrections::DiffDrive {
                c_l: 0.998,
                c_r: 1.002,
                e_b: 1.6
            }
        );
        let m =
            merge_corrections(&Corrections::None, 2, Some(1.01), None, None, None, None).unwrap();
        assert_eq!(
            m,
            Corrections::DiffDrive {
                c_l: 1.01,
                c_r: 1.0,
                e_b: 1.0
            }
        );
        let m =
            merge_corrections(&Corrections::None, 4, None, None, None, None, Some(0.94)).unwrap();
        match m {
            Corrections::Omni { f_lat, f_lon } => {
                assert_eq!(f_lat.as_slice(), &[1.0; 4]);
                assert_eq!(f_lon, 0.94);
            }
            other => panic!("{other:?}"),
        }
        // Mixing kinds or nothing given: refused, saying why.
        let e = merge_corrections(&cur, 2, Some(1.0), None, None, None, Some(1.0)).unwrap_err();
        assert!(e.to_string().contains("do not mix"), "{e}");
        let e = merge_corrections(&cur, 2, None, None, None, None, None).unwrap_err();
        assert!(e.to_string().contains("give the factors"), "{e}");
    }
}
