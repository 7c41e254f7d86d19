//! `wheelcal diagnose`: one recording diagnosed alone, or several jointly (shared
//! geometry).

use crate::args::DiagnoseArgs;
use crate::output::Output;
use crate::recordings;
use anyhow::{Context, Result};
use formats::robot_file;
use std::path::PathBuf;

/// Where simulation and recording part, and the physics left out.
pub fn run(a: DiagnoseArgs, out: Output) -> Result<()> {
    let files = recordings::expand(&a.recording)?;
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
    busy.set_message(format!("diagnosing {} rows", rec.len()));
    let rep = diagnose::diagnose_owned(&robot, rec, &opts)
        .with_context(|| recording.display().to_string())?;
    busy.finish();
    if let Some(dir) = &a.report {
        diagnose::plots::require_font()?;
        formats::safe_write::claim_dir(dir)?;
        diagnose::plots::write_report_dir(&rep, dir)
            .with_context(|| format!("cannot write the report into {}", dir.display()))?;
        out.note(&format!("report: {}", dir.join("index.html").display()));
        // The replayed paths for Foxglove / PlotJuggler beside the HTML.
        crate::mcap_out::write_report_paths(&rep, &dir.join("paths.mcap"))?;
    }
    if let Some(p) = &a.write_robot {
        diagnose::write_robot(&robot, &rep, p)
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!("fitted robot: {}", p.display()));
    }
    out.emit(&rep, || rep.to_string())
}

/// `wheelcal diagnose` with several recordings: shared geometry, per-recording nuisance,
/// each recording diagnosed against the shared geometry.
fn diagnose_many(a: &DiagnoseArgs, files: &[PathBuf], out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    let recs = files
        .iter()
        .map(|f| recordings::load(f, &robot, &a.robot, &a.bag))
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
    if let Some(p) = &a.write_robot {
        formats::robot_file::write(p, &rep.geometry.robot_toml())
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!("fitted robot: {}", p.display()));
    }
    out.emit(&rep, || rep.to_string())
}
