//! `wheelcal diagnose`.

use crate::cli::DiagnoseArgs;
use crate::output::Output;
use anyhow::{Context, Result};
use formats::robot_file;

/// Where simulation and recording part, and the physics left out.
pub fn run(a: DiagnoseArgs, out: Output) -> Result<()> {
    let files = crate::calibrate_cmd::expand(&a.recording)?;
    if files.len() > 1 {
        return crate::calibrate_cmd::diagnose_many(&a, &files, out);
    }
    let recording = &files[0];
    let robot = robot_file::load(&a.robot)?;
    // Long work says so on stderr (a large recording reads and fits for a minute).
    let busy = crate::progress::Progress::start(&format!("reading {}", recording.display()));
    let rec = crate::commands::import::load_recording(recording, &robot, &a.bag)?;
    for n in &rec.notes {
        out.note(&format!("{}: {n}", recording.display()));
    }
    let opts = diagnose::Options {
        max_effects: a.max_effects.into(),
    };
    busy.set_message(format!("diagnosing {} rows", rec.len()));
    let rep =
        diagnose::diagnose(&robot, &rec, &opts).with_context(|| recording.display().to_string())?;
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
