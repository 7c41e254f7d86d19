//! The page of `wheelcal diagnose --report DIR`: the verdict in words and what the
//! findings explain first, then the findings, the error before and after, the caveats,
//! the plots (each with what to see in it) and, folded, the text `diagnose` prints.
//!
//! Built from [`diagnose::Report`]'s fields, never from its text. The verdict is shown
//! by its string ([`diagnose::Verdict::as_str`]): `none` and `unexplained` are put in
//! words, any other string is an effect's id (the finding explaining the most), or a
//! verdict this page does not know yet, shown as it is.

use super::page::Page;
use anyhow::Result;
use diagnose::{Finding, Report};
use std::path::{Path, PathBuf};

/// The plots `diagnose::plots::write_report_dir` writes, in the page's order, with their
/// titles and what to see in each; then one actuator plot per wheel
/// ([`actuator_file`]).
pub const PLOTS: [(&str, &str, &str); 3] = [
    (
        "path.svg",
        "Path",
        "the measured path (motion capture) against dead reckoning with the nominal and with the fitted model: where the nominal line parts from the measured one the model leaves something out, and the fitted line should follow the measured one more closely.",
    ),
    (
        "position_residual.svg",
        "Position error over time",
        "how far each model is from the measured position; shaded windows leave the noise band (red: still off after the fit), and the fitted line should sit below the nominal one.",
    ),
    (
        "heading_residual.svg",
        "Heading error over time",
        "a steady slope is a turn-rate error (wheel sizes or wheelbase), steps at the corners are slip in the turns; the fitted line should stay nearer zero.",
    ),
];

/// The actuator-stage plot of one wheel.
pub fn actuator_file(wheel: &str) -> String {
    format!("actuator_{wheel}.svg")
}

/// An effect id in words (`wheel_scale` -> `wheel scale`).
fn words(id: &str) -> String {
    id.replace('_', " ")
}

fn pct(v: f64) -> String {
    format!("{:.0} %", v * 100.0)
}

fn mm(v: f64) -> String {
    format!("{:.2} mm", v * 1e3)
}

/// A parameter with its one-sigma uncertainty, or "not constrained by the data".
fn param_text(name: &str, v: f64, s: Option<f64>) -> String {
    match s {
        Some(s) if s.is_finite() => format!("{name} = {v:.6} ± {s:.2e}"),
        _ => format!("{name} = {v:.6} (not constrained by the data)"),
    }
}

/// A finding's parameters, one `name = value ± sigma` each, separated by semicolons.
pub fn finding_parameters(f: &Finding) -> String {
    f.parameters
        .iter()
        .map(|(n, v)| param_text(n, *v, f.uncertainties.get(n).copied().flatten()))
        .collect::<Vec<_>>()
        .join("; ")
}

/// The verdict in words: what the recording shows and how much the findings explain.
pub fn verdict_words(r: &Report) -> String {
    let v = r.verdict.as_str();
    let g = &r.rmse.ground;
    let improvement = format!(
        "The fitted model takes the position error from {} to {} RMS (noise {} per axis).",
        mm(g.before_m),
        mm(g.after_m),
        mm(r.noise.pose_sigma_m)
    );
    let explained = format!(
        "The findings explain {} of the error beyond the noise.",
        pct(r.explained_fraction)
    );
    if v == diagnose::VERDICT_NONE {
        return format!(
            "Nothing to correct: the recording stays within its noise of the nominal model ({} RMS, noise {} per axis).",
            mm(g.before_m),
            mm(r.noise.pose_sigma_m)
        );
    }
    if v == diagnose::VERDICT_UNEXPLAINED {
        let found = if r.findings.is_empty() {
            "no effect of the catalogue fits it".to_string()
        } else {
            format!(
                "{} effect(s) fit part of it ({}), not enough to name one as the cause",
                r.findings.len(),
                r.findings
                    .iter()
                    .map(|f| words(&f.effect))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        };
        return format!(
            "Unexplained: the recording leaves its noise band and {found}. {explained} {improvement}"
        );
    }
    // A partial verdict: the family explains at least half, and what is left still
    // depends on the motion (said in words from `depends_on`).
    let left = if r.fit == Some(diagnose::finding::Fit::Partial) {
        match r.depends_on.first() {
            Some(d) => format!(" Partial: what is left depends on {d}."),
            None => " Partial: a remainder is left outside the noise.".to_string(),
        }
    } else {
        String::new()
    };
    match r.findings.iter().find(|f| f.effect == v) {
        Some(f) => format!(
            "Main finding: {} (mechanism: {}, {} fit), explaining {} of the error beyond the noise.{left} {explained} {improvement}",
            words(&f.effect),
            f.mechanism,
            f.fit,
            pct(f.explained_share)
        ),
        None => format!("Verdict: {}.{left} {explained} {improvement}", words(v)),
    }
}

/// The findings table's rows (the one explaining the most first): effect, mechanism and fit, stage, share explained,
/// parameters with their uncertainties, RMSE before -> after, held-out ratio.
pub fn findings_rows(r: &Report) -> Vec<Vec<String>> {
    r.findings
        .iter()
        .map(|f| {
            vec![
                words(&f.effect),
                format!("{} ({} fit)", f.mechanism, f.fit),
                f.stage.as_str().to_string(),
                pct(f.explained_share),
                finding_parameters(f),
                format!("{} → {}", mm(f.rmse_before_m), mm(f.rmse_after_m)),
                format!("{:.3}", f.heldout_ratio),
            ]
        })
        .collect()
}

/// Header of [`findings_rows`].
pub const FINDINGS_HEADER: [&str; 7] = [
    "effect",
    "mechanism",
    "stage",
    "share of the excess explained",
    "parameters (± one sigma)",
    "RMSE before → after",
    "held-out ratio (< 1: predicts unseen data better)",
];

/// Writes `index.html` into `dir`, beside the plots `diagnose::plots::write_report_dir`
/// wrote there (it replaces that function's page); returns its path.
pub fn write(r: &Report, dir: &Path) -> Result<PathBuf> {
    let mut page = Page::new(&format!("wheelcal diagnose: {}", r.robot));
    page.answer(&verdict_words(r));
    page.paragraph(&format!(
        "{} rows, {} pose samples, {:.1} s.",
        r.rows, r.pose_samples, r.duration_s
    ));
    page.heading("Findings");
    if r.findings.is_empty() {
        page.paragraph("No effect of the catalogue was accepted.");
    } else {
        page.table(&FINDINGS_HEADER, &findings_rows(r));
    }
    page.heading("Before and after");
    let mut rows = vec![vec![
        "position (ground stage)".to_string(),
        mm(r.rmse.ground.before_m),
        mm(r.rmse.ground.after_m),
        mm(r.noise.pose_sigma_m),
    ]];
    rows.push(vec![
        "heading".to_string(),
        format!("{:.4} rad", r.heading_rmse_nominal_rad),
        format!("{:.4} rad", r.heading_rmse_final_rad),
        format!("{:.4} rad", r.noise.heading_sigma_rad),
    ]);
    if let Some(a) = r.rmse.actuator {
        rows.push(vec![
            "wheel surface (actuator stage)".to_string(),
            format!("{:.3} mm", a.before_m * 1e3),
            format!("{:.3} mm", a.after_m * 1e3),
            format!("{:.3} mm", r.noise.actuator_sigma_m * 1e3),
        ]);
    }
    page.table(
        &["RMS error", "nominal model", "fitted model", "noise"],
        &rows,
    );
    if !r.depends_on.is_empty() {
        page.heading("What the error left depends on");
        page.list(&r.depends_on);
    }
    let mut caveats: Vec<String> = r
        .separability
        .0
        .advice()
        .map(|a| format!("not separable: {a}"))
        .collect();
    caveats.extend(r.implausible.iter().map(|i| {
        format!(
            "implausible: {} {} = {:.5} outside {:.4}..{:.4}, most likely stands in for {}",
            i.effect, i.parameter, i.value, i.plausible.0, i.plausible.1, i.stands_for
        )
    }));
    caveats.extend(
        r.recording_artefacts
            .iter()
            .map(|a| format!("recording artefact (how the run was logged, not physics): {a}")),
    );
    caveats.extend(r.notes.iter().cloned());
    if !caveats.is_empty() {
        page.heading("Caveats");
        page.list(&caveats);
    }
    page.heading("Plots");
    for (file, title, see) in PLOTS {
        page.image(file, title, see);
    }
    for (wheel, _, _) in &r.plot.act {
        page.image(
            &actuator_file(wheel),
            &format!("Wheel {wheel}, actuator stage"),
            "the encoder against the commanded motion at the wheel surface: a lag, a dead band or steps show as structure the fitted line removes.",
        );
    }
    page.folded_text("Full text output (as diagnose prints it)", &r.to_string());
    page.write(dir)
}
