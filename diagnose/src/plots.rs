//! The `--report DIR` output: SVG plots (path, residuals over time with the windows
//! shaded, before/after overlays) and an index.html that shows them with the summary.

use crate::report::Report;
use crate::Stage;
use plotters::prelude::*;
use std::path::Path;

type PlotResult = Result<(), Box<dyn std::error::Error>>;

fn bounds(series: &[&[(f64, f64)]]) -> (f64, f64, f64, f64) {
    let mut b = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for s in series {
        for &(x, y) in s.iter() {
            if x.is_finite() && y.is_finite() {
                b = (b.0.min(x), b.1.max(x), b.2.min(y), b.3.max(y));
            }
        }
    }
    if !b.0.is_finite() {
        return (0.0, 1.0, 0.0, 1.0);
    }
    let pad = |lo: f64, hi: f64| {
        let d = ((hi - lo) * 0.05).max(1e-6);
        (lo - d, hi + d)
    };
    let (x0, x1) = pad(b.0, b.1);
    let (y0, y1) = pad(b.2, b.3);
    (x0, x1, y0, y1)
}

const BLUE: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const GREEN: RGBColor = RGBColor(44, 160, 44);

fn path_plot(r: &Report, file: &Path) -> PlotResult {
    let p = &r.plot;
    let (mut x0, mut x1, mut y0, mut y1) = bounds(&[&p.measured, &p.nominal, &p.fitted]);
    // Equal axis scales so the path keeps its shape.
    let (dx, dy) = (x1 - x0, y1 - y0);
    if dx > dy {
        let c = 0.5 * (y0 + y1);
        (y0, y1) = (c - dx / 2.0, c + dx / 2.0);
    } else {
        let c = 0.5 * (x0 + x1);
        (x0, x1) = (c - dy / 2.0, c + dy / 2.0);
    }
    let root = SVGBackend::new(file, (720, 720)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Path: measured, nominal model, fitted model",
            ("sans-serif", 20),
        )
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()?;
    for (data, color, label) in [
        (&p.measured, BLACK, "measured"),
        (&p.nominal, ORANGE, "nominal model"),
        (&p.fitted, BLUE, "fitted model"),
    ] {
        chart
            .draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(2)))?
            .label(label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

fn shade_windows<DB: DrawingBackend>(
    chart: &mut ChartContext<
        '_,
        DB,
        Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
    >,
    r: &Report,
    stage: Stage,
    y0: f64,
    y1: f64,
) -> PlotResult
where
    DB::ErrorType: 'static,
{
    let rects: Vec<_> = r
        .windows
        .iter()
        .filter(|w| w.stage == stage)
        .map(|w| {
            let c = if w.explained_by_fit {
                GREEN.mix(0.15)
            } else {
                RED.mix(0.15)
            };
            Rectangle::new([(w.t_start_s, y0), (w.t_end_s, y1)], c.filled())
        })
        .collect();
    chart.draw_series(rects)?;
    Ok(())
}

fn time_plot(
    r: &Report,
    file: &Path,
    title: &str,
    ylabel: &str,
    t: &[f64],
    series: &[(&[f64], RGBColor, &str)],
    stage: Stage,
) -> PlotResult {
    let root = SVGBackend::new(file, (960, 420)).into_drawing_area();
    root.fill(&WHITE)?;
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|(v, _, _)| t.iter().copied().zip(v.iter().copied()).collect())
        .collect();
    let refs: Vec<&[(f64, f64)]> = pts.iter().map(|v| v.as_slice()).collect();
    let (x0, x1, y0, y1) = bounds(&refs);
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc(ylabel)
        .draw()?;
    shade_windows(&mut chart, r, stage, y0, y1)?;
    for (data, (_, color, label)) in pts.iter().zip(series) {
        let color = *color;
        chart
            .draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(1)))?
            .label(*label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Writes the plots and index.html into `dir` (created if needed).
/// Where the plots' font is looked for (Debian's fonts-dejavu-core and its usual
/// relatives).
pub const FONT_PATHS: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Registers DejaVu Sans as plotters' "sans-serif" once; false when no font is found.
/// Text layout needs a TrueType font (plotters' `ab_glyph` backend), for SVG too; every
/// report of the workspace (diagnose's and the console's) goes through this.
pub fn register_font() -> bool {
    static FONT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *FONT.get_or_init(|| {
        FONT_PATHS.iter().any(|p| match std::fs::read(p) {
            Ok(bytes) => {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok()
            }
            Err(_) => false,
        })
    })
}

/// Writes `r` into `dir` (created if missing): the SVG plots, `index.html` with the
/// summary and `report.json`. Fails when the DejaVu Sans font the plots need is missing.
pub fn write_report_dir(r: &Report, dir: &Path) -> std::io::Result<()> {
    if !register_font() {
        return Err(std::io::Error::other(format!(
            "plots need the DejaVu Sans font (looked in {}): apt-get install fonts-dejavu-core",
            FONT_PATHS.join(", ")
        )));
    }
    std::fs::create_dir_all(dir)?;
    let err = |e: Box<dyn std::error::Error>| std::io::Error::other(e.to_string());
    let p = &r.plot;
    let mut images = vec![("path.svg", "Path")];
    path_plot(r, &dir.join("path.svg")).map_err(err)?;
    let to_mm = |v: &[f64]| v.iter().map(|x| x * 1e3).collect::<Vec<_>>();
    let (en, ef) = (to_mm(&p.err_nominal), to_mm(&p.err_fitted));
    time_plot(
        r,
        &dir.join("position_residual.svg"),
        "Position error |measured - model| (windows shaded: red = still off after the fit)",
        "error (mm)",
        &p.pose_t,
        &[(&en, ORANGE, "nominal"), (&ef, BLUE, "fitted")],
        Stage::Ground,
    )
    .map_err(err)?;
    images.push(("position_residual.svg", "Position residual over time"));
    time_plot(
        r,
        &dir.join("heading_residual.svg"),
        "Heading error (measured - model)",
        "error (rad)",
        &p.pose_t,
        &[
            (&p.heading_nominal, ORANGE, "nominal"),
            (&p.heading_fitted, BLUE, "fitted"),
        ],
        Stage::Ground,
    )
    .map_err(err)?;
    images.push(("heading_residual.svg", "Heading residual over time"));
    let mut act_files = Vec::new();
    for (name, a, b) in &p.act {
        let file = format!("actuator_{name}.svg");
        let (a, b) = (to_mm(a), to_mm(b));
        time_plot(
            r,
            &dir.join(&file),
            &format!("Wheel {name}: encoder - commanded motion at the wheel surface"),
            "error (mm)",
            &p.act_t,
            &[(&a, ORANGE, "nominal"), (&b, BLUE, "fitted")],
            Stage::Actuator,
        )
        .map_err(err)?;
        act_files.push(file);
    }
    let mut html = String::from(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>wheelcal diagnose</title>\
         <style>body{font-family:sans-serif;max-width:1000px;margin:auto}img{max-width:100%}\
         pre{background:#f4f4f4;padding:8px}</style></head><body>",
    );
    html.push_str(&format!(
        "<h1>wheelcal diagnose: {}</h1><h2>Verdict: {}</h2><pre>{}</pre>",
        esc(&r.robot),
        esc(&r.verdict),
        esc(&r.to_string())
    ));
    for (f, title) in &images {
        html.push_str(&format!("<h3>{title}</h3><img src=\"{f}\">"));
    }
    for f in &act_files {
        html.push_str(&format!("<h3>Actuator stage</h3><img src=\"{f}\">"));
    }
    html.push_str("</body></html>\n");
    std::fs::write(dir.join("index.html"), html)?;
    std::fs::write(dir.join("report.json"), r.to_json())?;
    Ok(())
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}
