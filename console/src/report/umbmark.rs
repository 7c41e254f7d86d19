//! The UMBmark report: the figures 13-26 and Table 1 of [Measuring errors] for one robot.

use super::figures::{BarChart, Series, XyChart};
use super::page::{prepare_dir, Page};
use crate::calibration::umbmark::{DirectionStats, PhaseStats, UmbmarkReport};
use anyhow::Result;
use calib_core::stats;
use std::path::{Path, PathBuf};

/// Distances of the end points from the origin ([Measuring errors] eqs. 14-15) and their
/// normal model.
struct Distances {
    mean: f64,
    sd: f64,
    min: f64,
    max: f64,
}

fn distances(d: &DirectionStats) -> Distances {
    let e: Vec<f64> = d.points.iter().map(|p| p.x_m.hypot(p.y_m)).collect();
    Distances {
        mean: stats::mean(&e).unwrap_or(0.0),
        sd: stats::sample_std_dev(&e).unwrap_or(0.0),
        min: e.iter().copied().fold(f64::INFINITY, f64::min),
        max: e.iter().copied().fold(f64::NEG_INFINITY, f64::max),
    }
}

/// The three zones of the error distribution of [Measuring errors]: [min, max] seen in
/// trials, [0, min), and beyond max, as probabilities under the fitted normal curve (eq. 18).
pub fn zone_probabilities(d: &DirectionStats) -> [f64; 3] {
    let z = distances(d);
    if z.sd <= 0.0 {
        return [1.0, 0.0, 0.0];
    }
    let p =
        |a: f64, b: f64| stats::normal_probability_between(z.mean, z.sd, a, b).unwrap_or(f64::NAN);
    [p(z.min, z.max), p(0.0, z.min), p(z.max, f64::INFINITY)]
}

fn pdf_curve(d: &DirectionStats) -> Vec<(f64, f64)> {
    let z = distances(d);
    let sd = z.sd.max(1e-6);
    (0..=200)
        .map(|i| {
            let x = (z.mean - 4.0 * sd + 8.0 * sd * i as f64 / 200.0).max(0.0);
            (
                x * 1e3,
                stats::normal_pdf(x, z.mean, sd).unwrap_or(0.0) / 1e3,
            )
        })
        .collect()
}

/// Writes `index.html` with the figures into `dir`.
pub fn write(rep: &UmbmarkReport, dir: &Path) -> Result<PathBuf> {
    prepare_dir(dir)?;
    let mut page = Page::new(&format!("UMBmark: {}", rep.robot));
    let after = match (rep.e_max_sys_after_m, rep.improvement) {
        (Some(a), Some(k)) => format!(
            "; E_max,sys {:.2} mm before, {:.2} mm after ({k:.1}x smaller)",
            rep.e_max_sys_before_m * 1e3,
            a * 1e3
        ),
        _ => format!("; E_max,sys {:.2} mm", rep.e_max_sys_before_m * 1e3),
    };
    page.answer(&format!(
        "Factors (exact model): c_L {:.6}, c_R {:.6}, E_b {:.6}{after}. The board takes them with `wheelcal factors set --c-l {:.6} --c-r {:.6} --e-b {:.6}` (or `wheelcal apply` on umbmark compute's --json result).",
        rep.c_l, rep.c_r, rep.eb, rep.c_l, rep.c_r, rep.eb
    ));
    page.paragraph(&format!(
        "{} m bidirectional square (UMBmark, [Borenstein 1996]), nominal wheelbase {:.4} m. Errors are measured minus odometry end positions in the start frame.",
        rep.side_m, rep.wheelbase_nominal_m
    ));
    page.heading("Correction factors");
    let row = |name: &str, e: &crate::calibration::umbmark::Estimate| {
        vec![
            name.to_string(),
            format!("{:.6}", e.ed),
            format!("{:.6}", e.eb),
            format!("{:.6}", e.c_l),
            format!("{:.6}", e.c_r),
            format!("{:.5}", e.wheelbase_m),
            format!("{:.6}", e.alpha_rad),
            format!("{:.6}", e.beta_rad),
        ]
    };
    page.table(
        &[
            "estimator",
            "E_d",
            "E_b",
            "c_L",
            "c_R",
            "wheelbase m",
            "alpha rad",
            "beta rad",
        ],
        &[
            row("closed form", &rep.closed_form),
            row("exact model (recommended)", &rep.exact),
        ],
    );
    page.heading("E_max,sys (UMBmark accuracy, [Measuring errors] Table 1)");
    page.table(
        &[
            "robot",
            "before mm",
            "after mm",
            "improvement",
            "P_e ([Measuring errors] eq. 19)",
        ],
        &[vec![
            rep.robot.clone(),
            format!("{:.2}", rep.e_max_sys_before_m * 1e3),
            rep.e_max_sys_after_m
                .map_or("-".into(), |v| format!("{:.2}", v * 1e3)),
            rep.improvement.map_or("-".into(), |v| format!("{v:.1}x")),
            rep.p_e
                .map_or("-".into(), |v| format!("{:.1} %", v * 100.0)),
        ]],
    );
    if let Some(c) = &rep.circles {
        page.heading("Circle test: the turn law squares cannot show");
        let rows: Vec<Vec<String>> = c
            .radii
            .iter()
            .map(|r| {
                vec![
                    format!("{:.3}", r.radius_m),
                    format!("{} / {}", r.runs_cw, r.runs_ccw),
                    format!("{:.5} / {:.5}", r.gain_cw, r.gain_ccw),
                    format!("{:.2}", r.share),
                    format!("{:+.5} ± {:.5}", r.e_b_arc, r.sigma),
                    format!("{:.5}", r.e_d),
                ]
            })
            .collect();
        page.table(
            &[
                "radius m",
                "runs cw / ccw",
                "heading gain cw / ccw",
                "law's share 1 - rho^2",
                "e_b_arc",
                "E_d",
            ],
            &rows,
        );
        page.paragraph(&c.verdict);
    }

    let phases = phases(rep);
    page.heading("End positions (UMBmark, [Measuring errors] Figs. 13-21)");
    page.figure(
        &end_positions(rep),
        dir,
        "end_positions",
        "Measured minus odometry end positions of each run, cw and ccw, with their centroids.",
    )?;

    page.heading("Normal distribution of the errors ([Measuring errors] Figs. 22-23, eq. 18)");
    page.figure(
        &normal_curves(rep),
        dir,
        "normal_curves",
        "Normal curves of the end-point distance e with each phase's mean and standard deviation.",
    )?;

    page.heading(
        "Convergence: probability of ending within 3 cm of the centroid ([Measuring errors] Fig. 24)",
    );
    page.figure(
        &p_within_3cm(rep),
        dir,
        "p_within_3cm",
        "Probability, under a normal model with each direction's spreads, that a run ends within 3 cm of its centroid.",
    )?;

    page.heading("Error zones ([Measuring errors] Figs. 25-26)");
    let mut zone_rows = Vec::new();
    for (name, ph) in &phases {
        for (dir_name, d) in [("cw", &ph.cw), ("ccw", &ph.ccw)] {
            let z = zone_probabilities(d);
            zone_rows.push(vec![
                format!("{dir_name} {name}"),
                format!("{:.3}", z[0]),
                format!("{:.3}", z[1]),
                format!("{:.3}", z[2]),
            ]);
        }
    }
    page.table(
        &[
            "run set",
            "zone 1: min..max seen",
            "zone 2: 0..min",
            "zone 3: > max",
        ],
        &zone_rows,
    );
    page.figure(
        &zones(rep),
        dir,
        "zones",
        "Zone 1: between the smallest and largest error seen; zone 2: below the smallest; zone 3: above the largest.",
    )?;
    page.paragraph(
        "Citation keys in square brackets refer to docs/references.md in the wheelcal repository.",
    );
    page.write(dir)
}

/// The phases present, before first.
fn phases(rep: &UmbmarkReport) -> Vec<(&'static str, &PhaseStats)> {
    let mut phases = vec![("before", &rep.before)];
    if let Some(a) = &rep.after {
        phases.push(("after", a));
    }
    phases
}

/// End-position errors of each run with the centroids ([Measuring errors] Figs. 13-21).
pub fn end_positions(rep: &UmbmarkReport) -> XyChart {
    let phases = phases(rep);
    let mut series = Vec::new();
    for (k, (name, ph)) in phases.iter().enumerate() {
        for (j, (dir_name, d)) in [("cw", &ph.cw), ("ccw", &ph.ccw)].into_iter().enumerate() {
            let colour = k * 2 + j;
            series.push(Series::points(
                &format!("{dir_name} {name}"),
                d.points
                    .iter()
                    .map(|p| (p.x_m * 1e3, p.y_m * 1e3))
                    .collect(),
                colour,
            ));
            series.push(Series::marker(
                &format!("centroid {dir_name} {name}"),
                (d.centroid.x_m * 1e3, d.centroid.y_m * 1e3),
                colour,
            ));
        }
    }
    series.push(Series::marker("start (odometry end)", (0.0, 0.0), 5));
    XyChart {
        title: "End-position errors and centroids".into(),
        x_label: "x error (mm)".into(),
        y_label: "y error (mm)".into(),
        series,
        equal_axes: true,
        bands: vec![],
    }
}

/// Normal curves of the end-point distance ([Measuring errors] Figs. 22-23).
pub fn normal_curves(rep: &UmbmarkReport) -> XyChart {
    let phases = phases(rep);
    let mut curves = Vec::new();
    for (k, (name, ph)) in phases.iter().enumerate() {
        curves.push(Series::line(
            &format!("cw {name}"),
            pdf_curve(&ph.cw),
            k * 2,
        ));
        curves.push(Series::line(
            &format!("ccw {name}"),
            pdf_curve(&ph.ccw),
            k * 2 + 1,
        ));
    }
    XyChart {
        title: "Distance of the end point from the origin".into(),
        x_label: "e (mm)".into(),
        y_label: "probability density (1/mm)".into(),
        series: curves,
        equal_axes: false,
        bands: vec![],
    }
}

/// P(end within 3 cm of the centroid) per phase and direction ([Measuring errors] Fig. 24).
pub fn p_within_3cm(rep: &UmbmarkReport) -> BarChart {
    let phases = phases(rep);
    BarChart {
        title: "P(end within 3 cm of centroid)".into(),
        y_label: "probability".into(),
        categories: phases.iter().map(|(n, _)| n.to_string()).collect(),
        series: vec![
            (
                "cw".into(),
                phases.iter().map(|(_, p)| p.cw.p_within_3cm).collect(),
            ),
            (
                "ccw".into(),
                phases.iter().map(|(_, p)| p.ccw.p_within_3cm).collect(),
            ),
        ],
    }
}

/// Error occurrence probability per zone ([Measuring errors] Figs. 25-26).
pub fn zones(rep: &UmbmarkReport) -> BarChart {
    let mut series = Vec::new();
    for (name, ph) in phases(rep) {
        for (dir_name, d) in [("cw", &ph.cw), ("ccw", &ph.ccw)] {
            series.push((format!("{dir_name} {name}"), zone_probabilities(d).to_vec()));
        }
    }
    BarChart {
        title: "Error occurrence probability per zone".into(),
        y_label: "probability".into(),
        categories: vec!["min..max".into(), "0..min".into(), "> max".into()],
        series,
    }
}
