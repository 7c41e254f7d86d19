//! MCAP output for Foxglove Studio and PlotJuggler: a pulled trial with one JSON channel
//! per signal group, and replayed paths (nominal and fitted) from the diagnose report.
//!
//! Messages are JSON with a JSON Schema per channel (MCAP's `jsonschema` encoding), which
//! both viewers read without plugins. Timestamps are nanoseconds of the board's uptime
//! (trial start + record time) for trials, and of the replay's own clock for paths.

use anyhow::{Context, Result};
use calib_core::protocol::{Record, TrialInfo};
use mcap::records::MessageHeader;
use serde_json::json;
use std::collections::BTreeMap;
use std::io::{Seek, Write};
use std::path::Path;

/// Topics of a trial's channels, in the order they are written.
pub const TRIAL_TOPICS: [&str; 4] = [
    "/wheelcal/commands",
    "/wheelcal/encoders",
    "/wheelcal/odometry",
    "/wheelcal/status",
];

fn number_array(desc: &str) -> serde_json::Value {
    json!({"type": "array", "items": {"type": "number"}, "description": desc})
}

struct Out<W: Write + Seek> {
    w: mcap::Writer<W>,
    seq: BTreeMap<u16, u32>,
}

impl<W: Write + Seek> Out<W> {
    fn new(w: W) -> Result<Self> {
        Ok(Out {
            w: mcap::Writer::new(w).context("cannot start the MCAP file")?,
            seq: BTreeMap::new(),
        })
    }
    fn channel(&mut self, topic: &str, name: &str, schema: serde_json::Value) -> Result<u16> {
        let s = self
            .w
            .add_schema(name, "jsonschema", schema.to_string().as_bytes())?;
        Ok(self.w.add_channel(s, topic, "json", &BTreeMap::new())?)
    }
    fn put(&mut self, channel: u16, t_ns: u64, msg: &serde_json::Value) -> Result<()> {
        let seq = self.seq.entry(channel).or_insert(0);
        *seq += 1;
        self.w.write_to_known_channel(
            &MessageHeader {
                channel_id: channel,
                sequence: *seq,
                log_time: t_ns,
                publish_time: t_ns,
            },
            msg.to_string().as_bytes(),
        )?;
        Ok(())
    }
    fn finish(mut self) -> Result<()> {
        self.w.finish().context("cannot finish the MCAP file")?;
        Ok(())
    }
}

fn create(out: &Path) -> Result<std::io::BufWriter<std::fs::File>> {
    let f =
        std::fs::File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    Ok(std::io::BufWriter::new(f))
}

/// Writes a trial's records as MCAP: commands (rad/s), encoder counts, the board's
/// odometry pose, and the board's status at the trial's start and end (its header).
pub fn write_trial(info: &TrialInfo, recs: &[Record], out: &Path) -> Result<()> {
    let n = info.wheel_count as usize;
    let mut o = Out::new(create(out)?)?;
    let cmd = o.channel(
        TRIAL_TOPICS[0],
        "wheelcal.Commands",
        json!({"type": "object", "properties": {
            "t": {"type": "number", "description": "s since the trial's start"},
            "cmd": number_array("commanded wheel rates, rad/s, wheel 1 first")}}),
    )?;
    let enc = o.channel(
        TRIAL_TOPICS[1],
        "wheelcal.Encoders",
        json!({"type": "object", "properties": {
            "t": {"type": "number"},
            "counts": number_array("encoder counts since the trial's start, wheel 1 first")}}),
    )?;
    let odo = o.channel(
        TRIAL_TOPICS[2],
        "wheelcal.Pose2D",
        json!({"type": "object", "properties": {
            "t": {"type": "number"},
            "x": {"type": "number", "description": "m"},
            "y": {"type": "number", "description": "m"},
            "theta": {"type": "number", "description": "rad"}}}),
    )?;
    let status = o.channel(
        TRIAL_TOPICS[3],
        "wheelcal.TrialStatus",
        json!({"type": "object", "description": "the board's trial header (wheelcal log list)"}),
    )?;
    let start_ns = info.start_ms * 1_000_000;
    let mut wraps = 0u64;
    let mut last = 0u32;
    let mut t_end = start_ns;
    o.put(status, start_ns, &json!({"phase": "start", "trial": info}))?;
    for r in recs {
        if r.t_us < last {
            wraps += 1; // the u32 microsecond clock wraps after 71 minutes
        }
        last = r.t_us;
        let us = wraps * (1u64 << 32) + r.t_us as u64;
        let t_ns = start_ns + us * 1000;
        let t = us as f64 * 1e-6;
        o.put(cmd, t_ns, &json!({"t": t, "cmd": &r.cmd[..n]}))?;
        o.put(enc, t_ns, &json!({"t": t, "counts": &r.counts[..n]}))?;
        o.put(
            odo,
            t_ns,
            &json!({"t": t, "x": r.pose.x, "y": r.pose.y, "theta": r.pose.theta}),
        )?;
        t_end = t_ns;
    }
    o.put(status, t_end, &json!({"phase": "end", "trial": info}))?;
    o.finish()
}

/// One replayed path: a name (its topic is `/paths/<name>`, or `<prefix>/<name>` with
/// [`write_paths_under`]), sample times (s) and positions `(x m, y m)`.
pub struct PathSeries<'a> {
    /// The path's name (`measured`, `nominal`, `fitted`).
    pub name: &'a str,
    /// Sample times (s).
    pub t: &'a [f64],
    /// Positions (m) in the recording's world frame.
    pub xy: &'a [(f64, f64)],
}

/// Writes replayed paths (e.g. nominal and fitted, from the diagnose report) as MCAP,
/// one `wheelcal.Position2D` channel per path, on topic `/paths/<name>`.
pub fn write_paths(paths: &[PathSeries<'_>], out: &Path) -> Result<()> {
    write_paths_under("/paths", paths, out)
}

/// [`write_paths`] with the topics `<prefix>/<name>` (`prefix` empty: `/<name>`, as
/// `calibrate --report` writes `/<recording>/measured`).
pub fn write_paths_under(prefix: &str, paths: &[PathSeries<'_>], out: &Path) -> Result<()> {
    let mut o = Out::new(create(out)?)?;
    for p in paths {
        let ch = o.channel(
            &format!("{prefix}/{}", p.name),
            "wheelcal.Position2D",
            json!({"type": "object", "properties": {
                "t": {"type": "number"},
                "x": {"type": "number", "description": "m"},
                "y": {"type": "number", "description": "m"}}}),
        )?;
        for (&t, &(x, y)) in p.t.iter().zip(p.xy) {
            let t_ns = (t.max(0.0) * 1e9).round() as u64;
            o.put(ch, t_ns, &json!({"t": t, "x": x, "y": y}))?;
        }
    }
    o.finish()
}

/// The diagnose report's measured, nominal and fitted paths as MCAP (beside its HTML).
pub fn write_report_paths(rep: &diagnose::Report, out: &Path) -> Result<()> {
    let p = &rep.plot;
    let series = [
        ("measured", &p.measured),
        ("nominal", &p.nominal),
        ("fitted", &p.fitted),
    ];
    let paths: Vec<PathSeries<'_>> = series
        .iter()
        .map(|(name, xy)| PathSeries {
            name,
            t: &p.pose_t,
            xy,
        })
        .collect();
    write_paths(&paths, out)
}
