//! The `--report DIR` output: SVG plots (path, residuals over time with the windows
//! shaded, before/after overlays) and an index.html that shows them with the summary.

use crate::report::{PlotData, Report};
use crate::windows::Window;
use crate::Stage;
use fitkit::plot::{esc, path_chart_titled, require_font, Layout, Paths, Shade, BLUE, ORANGE};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::path::Path;

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// The paths of a diagnosis's plot data.
fn paths(p: &PlotData) -> Paths<'_> {
    Paths {
        measured: &p.measured,
        nominal: &p.nominal,
        fitted: &p.fitted,
    }
}

/// The path plot on any backend; the legend stands in a column right of the chart.
pub fn path_chart<DB: DrawingBackend>(
    p: &PlotData,
    root: &DrawingArea<DB, Shift>,
) -> Result<Layout, String> {
    path_chart_titled(
        &paths(p),
        root,
        "Path: measured, nominal model, fitted model",
    )
}

fn path_plot(r: &Report, file: &Path) -> PlotResult {
    let root = SVGBackend::new(file, (720, 720)).into_drawing_area();
    path_chart(&r.plot, &root)?;
    root.present()?;
    Ok(())
}

/// A time chart with the windows of `stage` shaded (diagnose's residual plots).
pub fn time_chart<DB: DrawingBackend>(
    windows: &[Window],
    root: &DrawingArea<DB, Shift>,
    title: &str,
    ylabel: &str,
    t: &[f64],
    series: &[(&[f64], RGBColor, &str)],
    stage: Stage,
) -> Result<Layout, String> {
    let shades: Vec<Shade> = windows
        .iter()
        .filter(|w| w.stage == stage)
        .map(|w| Shade {
            t_start_s: w.t_start_s,
            t_end_s: w.t_end_s,
            explained: w.explained_by_fit,
        })
        .collect();
    fitkit::plot::time_chart(&shades, root, title, ylabel, t, series)
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
    time_chart(&r.windows, &root, title, ylabel, t, series, stage)?;
    root.present()?;
    Ok(())
}

/// Writes `r` into `dir` (created if missing): the SVG plots, `index.html` with the
/// summary and `report.json`. Fails when the DejaVu Sans font the plots need is missing.
pub fn write_report_dir(r: &Report, dir: &Path) -> std::io::Result<()> {
    require_font()?;
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
        esc(r.verdict.as_str()),
        esc(&r.to_string())
    ));
    for (f, title) in &images {
        html.push_str(&format!("<h3>{title}</h3><img src=\"{f}\">"));
    }
    for f in &act_files {
        html.push_str(&format!("<h3>Actuator stage</h3><img src=\"{f}\">"));
    }
    html.push_str("</body></html>\n");
    formats::safe_write::replace_file(&dir.join("index.html"), html.as_bytes())?;
    formats::safe_write::replace_file(&dir.join("report.json"), r.to_json().as_bytes())?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use fitkit::plot::register_font;

    fn assert_clear(name: &str, l: &Layout, n_points: usize) {
        assert_eq!(l.data.len(), n_points, "{name}: data boxes");
        if let Err(e) = l.check() {
            panic!("{name}: {e}");
        }
    }

    /// Data that fill every corner of the plot: whatever corner a legend inside the
    /// axes took, it would cover some.
    fn corners(n: usize) -> Vec<(f64, f64)> {
        (0..n)
            .map(|i| {
                let a = i as f64 / n as f64 * std::f64::consts::TAU;
                (
                    a.cos().signum() * 2.0 + 0.1 * a.sin(),
                    a.sin().signum() * 1.0,
                )
            })
            .collect()
    }

    #[test]
    fn path_legend_covers_no_data() {
        assert!(register_font(), "DejaVu Sans needed for text layout");
        let pts = corners(40);
        let p = PlotData {
            measured: pts.clone(),
            nominal: pts.iter().map(|&(x, y)| (x * 0.98, y * 1.02)).collect(),
            fitted: pts.iter().map(|&(x, y)| (x * 1.01, y)).collect(),
            ..PlotData::default()
        };
        let mut svg = String::new();
        let layout = {
            let root = SVGBackend::with_string(&mut svg, (720, 720)).into_drawing_area();
            path_chart(&p, &root).unwrap()
        };
        assert_clear("path", &layout, 120);
        // Equal scales: one metre spans the same pixels on both axes (within 2 %).
        let span = |v: &mut dyn Iterator<Item = f64>| {
            v.fold((f64::INFINITY, f64::NEG_INFINITY), |a, x| {
                (a.0.min(x), a.1.max(x))
            })
        };
        let (mx, my) = (
            span(&mut p.measured.iter().map(|q| q.0)),
            span(&mut p.measured.iter().map(|q| q.1)),
        );
        let m = &layout.data[..40];
        let (px, py) = (
            span(&mut m.iter().map(|d| f64::from(d.x0 + d.x1) / 2.0)),
            span(&mut m.iter().map(|d| f64::from(d.y0 + d.y1) / 2.0)),
        );
        let (sx, sy) = ((px.1 - px.0) / (mx.1 - mx.0), (py.1 - py.0) / (my.1 - my.0));
        assert!((sx / sy - 1.0).abs() < 0.02, "px per m: x {sx}, y {sy}");
        assert!(svg.contains("fitted model"));
    }

    #[test]
    fn time_legend_covers_no_data() {
        assert!(register_font());
        let t: Vec<f64> = (0..200).map(|i| i as f64 * 0.05).collect();
        // A residual at its largest at the end (where legends usually sit).
        let a: Vec<f64> = t.iter().map(|t| t * t).collect();
        let b: Vec<f64> = t.iter().map(|t| 100.0 - t * t).collect();
        let mut svg = String::new();
        let layout = {
            let root = SVGBackend::with_string(&mut svg, (960, 420)).into_drawing_area();
            time_chart(
                &[],
                &root,
                "residual",
                "error (mm)",
                &t,
                &[(&a, ORANGE, "nominal"), (&b, BLUE, "fitted")],
                Stage::Ground,
            )
            .unwrap()
        };
        assert_clear("time", &layout, 400);
    }
}
