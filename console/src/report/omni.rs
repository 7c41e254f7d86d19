//! The omni report: the radial errors before/after (Fig. 5) and Table II of the omni
//! calibration method of [Redundant omni].

use super::figures::{BarChart, Series, XyChart};
use super::page::{prepare_dir, Page};
use crate::calibration::omni::OmniReport;
use anyhow::Result;
use std::path::{Path, PathBuf};

/// Writes the omni report (index.html and its figures) into `dir`; returns the page's path.
pub fn write(rep: &OmniReport, dir: &Path) -> Result<PathBuf> {
    prepare_dir(dir)?;
    let mut page = Page::new(&format!("Omni calibration: {}", rep.robot));
    let f_lat: Vec<String> = rep.f_lat.iter().map(|v| format!("{v:.5}")).collect();
    let improvement = rep
        .improvement_index_percent
        .map(|i| format!("; mean radial error {i:.1} % better after"))
        .unwrap_or_default();
    page.answer(&format!(
        "Factors: F_lat {} ({}), F_lon {:.5}{improvement}. The board takes them with `wheelcal factors set --f-lat {} --f-lon {:.5}` (or `wheelcal apply` on omni compute's --json result).",
        f_lat.join(", "),
        rep.wheels.join(", "),
        rep.f_lon,
        f_lat.join(","),
        rep.f_lon
    ));
    page.paragraph("Lateral (F_lat) and longitudinal (F_lon) corrective factors of the omni calibration method ([Redundant omni]) from straight-path runs; final wheel rates = F_lon * F_lat * J * twist ([Redundant omni] eq. 6).");
    page.heading("Factors");
    let rows: Vec<Vec<String>> = rep
        .wheels
        .iter()
        .enumerate()
        .map(|(i, w)| {
            vec![
                w.clone(),
                rep.wheel_ratio[i].map_or("-".into(), |k| format!("{k:.5}")),
                format!("{:.5}", rep.f_lat[i]),
            ]
        })
        .collect();
    page.table(&["wheel", "effective ratio k", "F_lat"], &rows);
    page.paragraph(&format!("F_lon = {:.5}", rep.f_lon));
    page.heading("Radial errors (omni calibration, [Redundant omni] Table II)");
    let mut rows = Vec::new();
    for (phase, ps) in [("before", &rep.before), ("after", &rep.after)] {
        for p in ps {
            rows.push(vec![
                phase.to_string(),
                p.path.clone(),
                p.runs.to_string(),
                format!("{:.2}", p.mean_radial_error_m * 1e3),
                format!("{:.2}", p.std_dev_radial_m * 1e3),
                p.skewness.map_or("-".into(), |v| format!("{v:.3}")),
                p.kurtosis.map_or("-".into(), |v| format!("{v:.3}")),
            ]);
        }
    }
    page.table(
        &[
            "phase",
            "path",
            "runs",
            "mean mm",
            "sd mm",
            "skewness",
            "excess kurtosis",
        ],
        &rows,
    );
    if let Some(i) = rep.improvement_index_percent {
        page.paragraph(&format!(
            "Mean error improvement index ([Redundant omni] eq. 8): {i:.1} %"
        ));
    }
    page.figure(
        &radial_errors(rep),
        dir,
        "radial_errors",
        "Radial end error of each run, before and after calibration.",
    )?;
    page.figure(
        &mean_radial(rep),
        dir,
        "mean_radial",
        "Mean radial error per path before and after.",
    )?;
    page.paragraph(
        "Citation keys in square brackets refer to docs/references.md in the wheelcal repository.",
    );
    page.write(dir)
}

/// Radial end error of each run, before and after ([Redundant omni] Fig. 5).
pub fn radial_errors(rep: &OmniReport) -> XyChart {
    let mut series = Vec::new();
    for (k, (phase, ps)) in [("before", &rep.before), ("after", &rep.after)]
        .into_iter()
        .enumerate()
    {
        for (j, p) in ps.iter().enumerate() {
            let pts = p
                .radial_errors_m
                .iter()
                .enumerate()
                .map(|(i, e)| ((i + 1) as f64, e * 1e3))
                .collect();
            series.push(Series::line(&format!("{} {phase}", p.path), pts, k * 2 + j));
        }
    }
    XyChart {
        title: "Radial error per run ([Redundant omni] Fig. 5)".into(),
        x_label: "run".into(),
        y_label: "radial error (mm)".into(),
        series,
        equal_axes: false,
        bands: vec![],
    }
}

/// Mean radial error per path, before and after.
pub fn mean_radial(rep: &OmniReport) -> BarChart {
    let cats: Vec<String> = rep.before.iter().map(|p| p.path.clone()).collect();
    let mean_of = |ps: &Vec<crate::calibration::omni::PathStats>, path: &str| {
        ps.iter()
            .find(|p| p.path == path)
            .map_or(0.0, |p| p.mean_radial_error_m * 1e3)
    };
    BarChart {
        title: "Mean radial error".into(),
        y_label: "mm".into(),
        categories: cats.clone(),
        series: vec![
            (
                "before".into(),
                cats.iter().map(|c| mean_of(&rep.before, c)).collect(),
            ),
            (
                "after".into(),
                cats.iter().map(|c| mean_of(&rep.after, c)).collect(),
            ),
        ],
    }
}
