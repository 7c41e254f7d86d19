//! `wheelcal diagnose`: one recording diagnosed alone, or several jointly (shared
//! geometry).

use crate::args::DiagnoseArgs;
use crate::mcap_out::{self, ReportPoses};
use crate::output::Output;
use crate::recordings;
use anyhow::{Context, Result};
use formats::robot_file;
use std::path::PathBuf;

/// Where simulation and recording part, and the physics left out.
pub fn run(a: DiagnoseArgs, out: Output) -> Result<()> {
    let files = recordings::expand_distinct(&a.recording, out)?;
    if files.len() > 1 {
        return diagnose_many(&a, &files, out);
    }
    let recording = &files[0];
    let robot = robot_file::load(&a.robot)?;
    // Long work says so on stderr (a large recording reads and fits for a minute).
    let busy = crate::progress::Progress::start(&format!("reading {}", recording.display()));
    let rec = recordings::load_recording_at(recording, &robot, &a.bag, a.max_row_rate_hz())?;
    for n in &rec.notes {
        out.note(&format!("{}: {n}", recording.display()));
    }
    let opts = diagnose::Options {
        max_effects: a.max_effects.into(),
        max_row_rate_hz: a.max_row_rate_hz(),
    };
    // The measured headings, for the paths' poses (the report keeps positions and
    // heading errors only).
    let measured: Vec<(f64, f64, f64)> = if a.report.is_some() || a.tum.is_some() {
        rec.pose_rows().map(|(_, x, y, th)| (x, y, th)).collect()
    } else {
        Vec::new()
    };
    busy.set_message(format!("diagnosing {} rows", rec.len()));
    let rep = diagnose::diagnose_owned(&robot, rec, &opts)
        .with_context(|| recording.display().to_string())?;
    busy.finish();
    let poses = if a.report.is_some() || a.tum.is_some() {
        let p = mcap_out::report_poses(&rep, &measured);
        if p.is_none() {
            out.note("the report's pose samples do not match the recording's: paths written with the measured heading unknown (yaw 0)");
        }
        Some(p.unwrap_or_else(|| unknown_headings(&rep)))
    } else {
        None
    };
    if let (Some(dir), Some(poses)) = (&a.tum, &poses) {
        let files: Vec<(String, Vec<crate::tum::Stamped>)> = poses
            .iter()
            .map(|(name, p)| {
                let t = &rep.plot.pose_t;
                let v = t.iter().zip(p).map(|(&t, &(x, y, th))| (t, x, y, th));
                (name.to_string(), v.collect())
            })
            .collect();
        for f in crate::tum::write_dir(dir, &files)? {
            out.note(&format!("TUM trajectory: {f}"));
        }
    }
    if let Some(dir) = &a.report {
        fitkit::plot::require_font()?;
        formats::safe_write::claim_dir(dir)?;
        diagnose::plots::write_report_dir(&rep, dir)
            .with_context(|| format!("cannot write the report into {}", dir.display()))?;
        // The page that leads with the verdict, over the plain one written with the plots.
        crate::report::diagnose::write(&rep, dir)
            .with_context(|| format!("cannot write the report into {}", dir.display()))?;
        out.note(&format!("report: {}", dir.join("index.html").display()));
        // The replayed paths for Foxglove / PlotJuggler beside the HTML.
        if let Some(poses) = &poses {
            mcap_out::write_report_paths(&rep, poses, &dir.join("paths.mcap"))?;
        }
    }
    if let Some(p) = &a.write_robot {
        diagnose::write_robot(&robot, &rep, p)
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!("fitted robot: {}", p.display()));
    }
    out.emit(&rep, || rep.to_string())
}

/// The report's paths with yaw 0 (when the measured headings cannot be matched).
fn unknown_headings(rep: &diagnose::Report) -> ReportPoses {
    let p = &rep.plot;
    let zero = |xy: &[(f64, f64)]| xy.iter().map(|&(x, y)| (x, y, 0.0)).collect();
    [
        ("measured", zero(&p.measured)),
        ("nominal", zero(&p.nominal)),
        ("fitted", zero(&p.fitted)),
    ]
}

/// `wheelcal diagnose` with several recordings: shared geometry, per-recording nuisance,
/// each recording diagnosed against the shared geometry.
fn diagnose_many(a: &DiagnoseArgs, files: &[PathBuf], out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    let recs = files
        .iter()
        .map(|f| recordings::load_for_diagnosis(f, &robot, &a.robot, &a.bag))
        .collect::<Result<Vec<_>>>()?;
    let opts = diagnose::Options {
        max_effects: a.max_effects.into(),
        max_row_rate_hz: a.max_row_rate_hz(),
    };
    let rep = diagnose::multi::diagnose_many(&robot, &recs, &opts).map_err(|mut e| {
        // Name the file, not only the short name; the error stays the diagnosis's.
        let file = e
            .recording
            .as_ref()
            .and_then(|n| recs.iter().position(|(r, _)| r == n))
            .map(|i| files[i].display().to_string());
        if file.is_some() {
            e.recording = file;
        }
        e
    })?;
    if a.report.is_some() {
        out.note(
            "--report with several recordings: see calibrate --report (plots are per recording)",
        );
    }
    if a.tum.is_some() {
        out.note("--tum with several recordings: not written (the paths are per recording; diagnose each alone)");
    }
    if let Some(p) = &a.write_robot {
        formats::robot_file::write(p, &rep.geometry.robot_toml())
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!("fitted robot: {}", p.display()));
    }
    out.emit(&rep, || rep.to_string())
}
