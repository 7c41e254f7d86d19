//! The figures of `wheelcal calibrate --report DIR`: per recording the measured path,
//! dead reckoning with the nominal and with the fitted geometry, and the position error
//! over time; the parameters' correlation matrix; an index.html with the summary.
//!
//! The series are the fit's, not a re-derivation. With the default dead-reckoning
//! objective each recording is dead-reckoned from its first measured pose at every pose
//! sample, so the RMS of an error series is the recording's `dead_reckoning_before_m` /
//! `dead_reckoning_after_m`. With `--free-start` each recording's dead reckoning is placed
//! with the start pose and clocks [`calibrate`] fitted for it (nominal geometry: the
//! nuisance of the "before" fit; fitted geometry: the nuisance of the joint fit) through
//! the same residual code, so the RMS of an error series is the recording's
//! `rmse_before_m` / `rmse_after_m`. A held-out recording is dead-reckoned
//! from its first measured pose, as [`Heldout`]'s `rmse_before_m` / `rmse_after_m`.
//!
//! [`calibrate`]: crate::calibrate
//! [`Heldout`]: crate::Heldout

use crate::error::CalibrateError;
use crate::objective::{residuals_into, HEADING_LEVER_M, RES_UNIT_M};
use crate::params::{robot_with, GeomKind};
use crate::result::Calibration;
use crate::series::{Nuisance, Path as DrPath, Series};
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::robot::Robot;
use fitkit::plot::{
    draw_legend, esc, path_chart_titled, plot_box, split_for_legend, time_chart, Layout,
    LegendMark, Paths, PixelBox, BLUE, ORANGE,
};
use formats::recording::Recording;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// One recording's series for the report, at its ground-truth pose samples.
#[derive(Debug, Clone)]
pub struct RecordingSeries {
    /// The recording's name as given.
    pub name: String,
    /// A file- and topic-safe name, unique in the report (`[A-Za-z0-9._-]`).
    pub key: String,
    /// True for the held-out recording (dead-reckoned from its first measured pose),
    /// false for a fitted one (start pose and clocks fitted).
    pub heldout: bool,
    /// Time of each pose sample since the recording's first row, s.
    pub t: Vec<f64>,
    /// Measured (motion-capture) position per pose sample, m.
    pub measured: Vec<(f64, f64)>,
    /// Dead reckoning with the nominal geometry at the pose samples, m.
    pub nominal: Vec<(f64, f64)>,
    /// Dead reckoning with the fitted geometry at the pose samples, m.
    pub fitted: Vec<(f64, f64)>,
    /// Measured heading per pose sample, rad.
    pub heading_measured: Vec<f64>,
    /// Heading of the nominal dead reckoning per pose sample, rad.
    pub heading_nominal: Vec<f64>,
    /// Heading of the fitted dead reckoning per pose sample, rad.
    pub heading_fitted: Vec<f64>,
    /// |nominal - measured| per pose sample, m.
    pub err_nominal: Vec<f64>,
    /// |fitted - measured| per pose sample, m.
    pub err_fitted: Vec<f64>,
}

/// Root mean square of `v` (0 when empty).
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|e| e * e).sum::<f64>() / v.len() as f64).sqrt()
}

impl RecordingSeries {
    /// RMS of the nominal position error, m.
    pub fn rms_nominal_m(&self) -> f64 {
        rms(&self.err_nominal)
    }
    /// RMS of the fitted position error, m.
    pub fn rms_fitted_m(&self) -> f64 {
        rms(&self.err_fitted)
    }
}

/// A dead-reckoned path at the pose samples as the fit compares it.
struct Placed {
    /// Positions, m.
    xy: Vec<(f64, f64)>,
    /// Headings, rad.
    heading: Vec<f64>,
    /// Position errors against the measured poses, m.
    err: Vec<f64>,
}

/// Poses placed by `residuals_into` (the fit's own comparison) and their errors.
fn placed(s: &Series, path: &DrPath, nu: &Nuisance, marker: (f64, f64)) -> Placed {
    let mut r = Vec::with_capacity(3 * s.pose_samples());
    residuals_into(s, path, nu, marker, &mut r);
    let mut p = Placed {
        xy: Vec::with_capacity(s.pose_samples()),
        heading: Vec::with_capacity(s.pose_samples()),
        err: Vec::with_capacity(s.pose_samples()),
    };
    for (j, c) in r.chunks(3).enumerate() {
        let (ex, ey) = (c[0] * RES_UNIT_M, c[1] * RES_UNIT_M);
        p.xy.push((s.px[j] + ex, s.py[j] + ey));
        p.heading
            .push(s.pth[j] + c[2] * RES_UNIT_M / HEADING_LEVER_M);
        p.err.push((ex * ex + ey * ey).sqrt());
    }
    p
}

/// The start pose that dead-reckons `path` from the first measured pose (heading
/// included), with the clocks as recorded: [`crate::dead_reckoning_rmse`]'s
/// placement in the fit's terms.
fn from_first_pose(s: &Series, path: &DrPath) -> Nuisance {
    let k0 = s.pose_row[0];
    let th0 = s.pth[0] - path.th[k0];
    let (c, sn) = (th0.cos(), th0.sin());
    Nuisance {
        x0_m: s.px[0] - (c * path.x[k0] - sn * path.y[k0]),
        y0_m: s.py[0] - (sn * path.x[k0] + c * path.y[k0]),
        theta0_rad: th0,
        time_offset_s: 0.0,
        clock_ratio: 1.0,
    }
}

fn file_key(name: &str, used: &mut Vec<String>) -> String {
    let mut k: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "._-".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    if k.is_empty() {
        k = "recording".into();
    }
    let base = k.clone();
    let mut n = 2;
    while used.contains(&k) {
        k = format!("{base}_{n}");
        n += 1;
    }
    used.push(k.clone());
    k
}

/// Per recording (in `cal`'s order, then the held-out one): the measured path, dead
/// reckoning with `robot` (nominal) and with `cal`'s fitted geometry, and the position
/// errors. `recordings` and `holdout` must be the ones `cal` was computed from.
pub fn calibration_series(
    cal: &Calibration,
    robot: &Robot,
    recordings: &[(String, Recording)],
    holdout: Option<&(String, Recording)>,
) -> Result<Vec<RecordingSeries>, CalibrateError> {
    let err = |m: String| CalibrateError {
        recording: None,
        message: m,
    };
    let names: Vec<&str> = recordings.iter().map(|(n, _)| n.as_str()).collect();
    if names != cal.recordings {
        return Err(err(format!(
            "the calibration was fitted to {:?}, not to {names:?}",
            cal.recordings
        )));
    }
    if cal.robot != robot.name.as_str() || cal.fitted_robot.wheels.len() != robot.wheels.len() {
        return Err(err(format!(
            "the calibration is of robot '{}', not of '{}'",
            cal.robot, robot.name
        )));
    }
    let specs = &cal.specs();
    let nominal: Vec<f64> = specs.iter().map(|s| s.nominal).collect();
    let geom: Vec<f64> = cal.params.iter().map(|p| p.value).collect();
    let at = |k: GeomKind| {
        specs
            .iter()
            .position(|s| s.kind == k)
            .map_or(0.0, |i| geom[i])
    };
    let marker = (at(GeomKind::MarkerX), at(GeomKind::MarkerY));
    let kin = |g: &[f64]| {
        let r = robot_with(robot, specs, g);
        Kinematics::<f64>::new(&r, &Corrections::None)
            .map(|k| (r, k))
            .map_err(|_| err("the robot's wheels cannot resolve the body twist".into()))
    };
    let ((r_nom, kin_nom), (r_fit, kin_fit)) = (kin(&nominal)?, kin(&geom)?);
    let series = recordings
        .iter()
        .map(|(n, r)| Series::new(n, robot, r))
        .collect::<Result<Vec<_>, _>>()?;
    let mut used = Vec::new();
    let mut out = Vec::new();
    // `nuis`: the fit's (nominal, fitted) start pose and clocks of a fitted recording;
    // `None` for the held-out one, dead-reckoned from its first pose without a marker
    // offset (as `dead_reckoning_rmse`).
    let mut one = |s: &Series, nuis: Option<(Nuisance, Nuisance)>| {
        let (mut p_nom, mut p_fit) = (DrPath::default(), DrPath::default());
        s.path(&r_nom, &kin_nom, &mut p_nom);
        // The fitted geometry with its turn law (fitted or given), as the errors reported.
        s.path_with(&r_fit, &kin_fit, &cal.turn_law, &mut p_fit);
        let (nom, fit) = match nuis {
            Some((nu_nom, nu_fit)) => (
                placed(s, &p_nom, &nu_nom, (0.0, 0.0)),
                placed(s, &p_fit, &nu_fit, marker),
            ),
            None => (
                placed(s, &p_nom, &from_first_pose(s, &p_nom), (0.0, 0.0)),
                placed(s, &p_fit, &from_first_pose(s, &p_fit), (0.0, 0.0)),
            ),
        };
        out.push(RecordingSeries {
            name: s.name.clone(),
            key: file_key(&s.name, &mut used),
            heldout: nuis.is_none(),
            t: s.pose_row.iter().map(|&k| s.t[k] - s.t[0]).collect(),
            measured: s.px.iter().copied().zip(s.py.iter().copied()).collect(),
            nominal: nom.xy,
            fitted: fit.xy,
            heading_measured: s.pth.clone(),
            heading_nominal: nom.heading,
            heading_fitted: fit.heading,
            err_nominal: nom.err,
            err_fitted: fit.err,
        });
    };
    for (i, s) in series.iter().enumerate() {
        let Some(fit) = cal.per_recording.get(i) else {
            return Err(err(format!("the calibration has no fit of {}", s.name)));
        };
        one(s, Some((fit.nuisance_nominal, fit.nuisance)));
    }
    if let Some((n, r)) = holdout {
        one(&Series::new(n, robot, r)?, None);
    }
    Ok(out)
}

/// The path figure of one recording (measured, nominal, fitted), legend beside the chart.
pub fn recording_path_chart<DB: DrawingBackend>(
    s: &RecordingSeries,
    root: &DrawingArea<DB, Shift>,
) -> Result<Layout, String> {
    let p = Paths {
        measured: &s.measured,
        nominal: &s.nominal,
        fitted: &s.fitted,
    };
    let title = if s.heldout {
        format!("{} (held out): measured, nominal, fitted", s.name)
    } else {
        format!("{}: measured, nominal, fitted", s.name)
    };
    path_chart_titled(&p, root, &title)
}

/// The position error over time of one recording (nominal and fitted, mm), legend beside
/// the chart.
pub fn recording_error_chart<DB: DrawingBackend>(
    s: &RecordingSeries,
    root: &DrawingArea<DB, Shift>,
) -> Result<Layout, String> {
    let mm = |v: &[f64]| v.iter().map(|e| e * 1e3).collect::<Vec<_>>();
    let (en, ef) = (mm(&s.err_nominal), mm(&s.err_fitted));
    let title = if s.heldout {
        format!(
            "{} (held out): position error, dead reckoning from its first pose",
            s.name
        )
    } else {
        format!(
            "{}: position error, start pose and clocks fitted per geometry",
            s.name
        )
    };
    let (ln, lf) = (
        format!("nominal, RMS {:.2} mm", s.rms_nominal_m() * 1e3),
        format!("fitted, RMS {:.2} mm", s.rms_fitted_m() * 1e3),
    );
    time_chart(
        &[],
        root,
        &title,
        "position error (mm)",
        &s.t,
        &[(&en, ORANGE, &ln), (&ef, BLUE, &lf)],
    )
}

const POSITIVE: RGBColor = RGBColor(214, 39, 40);
const NEUTRAL: RGBColor = RGBColor(235, 235, 235);

/// A correlation's cell colour: white at 0, red towards +1, blue towards -1.
fn corr_color(r: f64) -> RGBColor {
    if !r.is_finite() {
        return NEUTRAL;
    }
    let (c, f) = if r >= 0.0 {
        (POSITIVE, r.min(1.0))
    } else {
        (BLUE, (-r).min(1.0))
    };
    let mix = |a: u8| (255.0 + (f64::from(a) - 255.0) * f).round() as u8;
    RGBColor(mix(c.0), mix(c.1), mix(c.2))
}

/// Pixel size of one correlation cell.
const CELL_PX: u32 = 64;

/// A figure size that fits `g` parameters' correlation grid and its labels.
pub fn correlation_figure_size(g: usize) -> (u32, u32) {
    let g = g.max(1) as u32;
    ((260 + g * CELL_PX + 300).max(720), 110 + g * CELL_PX)
}

/// The correlation matrix of the fitted parameters as a grid of coloured cells with
/// their values (rows named, columns numbered, the diagonal grey); pairs reported not
/// separable are outlined. The legend stands in a column right of the grid.
pub fn correlation_chart<DB: DrawingBackend>(
    cal: &Calibration,
    root: &DrawingArea<DB, Shift>,
) -> Result<Layout, String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let g = cal.params.len();
    let entries = [
        (
            "+1: the data move them together".to_string(),
            LegendMark::Bar(POSITIVE),
        ),
        (
            "-1: one up, the other down".to_string(),
            LegendMark::Bar(BLUE),
        ),
        (
            "0: separate (grey: itself)".to_string(),
            LegendMark::Bar(NEUTRAL),
        ),
        (
            "outlined: not separable".to_string(),
            LegendMark::Bar(BLACK),
        ),
    ];
    let labels: Vec<&str> = entries.iter().map(|(l, _)| l.as_str()).collect();
    let body = root
        .titled(
            "Parameter correlations (what the recordings cannot separate)",
            ("sans-serif", 20),
        )
        .map_err(e)?;
    let (left, column) = split_for_legend(&body, &labels);
    let label_font = ("sans-serif", 14).into_text_style(&left);
    let row_labels: Vec<String> = cal
        .params
        .iter()
        .enumerate()
        .map(|(i, p)| format!("{}  {}", i + 1, p.spec.name))
        .collect();
    let label_w = row_labels
        .iter()
        .map(|l| {
            left.estimate_text_size(l, &label_font)
                .map_or(8 * l.len() as i32, |(w, _)| w as i32)
        })
        .max()
        .unwrap_or(0)
        + 12;
    let (w, h) = left.dim_in_pixel();
    let (margin, header) = (10i32, 26i32);
    let gi = g.max(1) as i32;
    let cell = ((w as i32 - 2 * margin - label_w) / gi)
        .min((h as i32 - 2 * margin - header) / gi)
        .min(CELL_PX as i32)
        .max(8);
    let (gx, gy) = (margin + label_w, margin + header);
    let (bx, by) = left.get_base_pixel();
    let value_font = if cell >= 44 { 14 } else { 10 };
    let centre = Pos::new(HPos::Center, VPos::Center);
    let mut layout = Layout {
        figure: Some(plot_box(root)),
        plot: Some(PixelBox {
            x0: bx + gx,
            y0: by + gy,
            x1: bx + gx + gi * cell,
            y1: by + gy + gi * cell,
        }),
        ..Layout::default()
    };
    let separable = |a: usize, b: usize| {
        let (na, nb) = (&cal.params[a].spec.name, &cal.params[b].spec.name);
        !cal.inseparable
            .pairs()
            .iter()
            .any(|p| (&p[0] == na && &p[1] == nb) || (&p[0] == nb && &p[1] == na))
    };
    for (a, label) in row_labels.iter().enumerate() {
        let y = gy + a as i32 * cell;
        left.draw_text(
            label,
            &label_font.pos(Pos::new(HPos::Right, VPos::Center)),
            (gx - 6, y + cell / 2),
        )
        .map_err(e)?;
        left.draw_text(
            &format!("{}", a + 1),
            &label_font.pos(centre),
            (gx + a as i32 * cell + cell / 2, gy - header / 2),
        )
        .map_err(e)?;
        for b in 0..g {
            let x = gx + b as i32 * cell;
            let r = cal
                .correlations
                .get(a)
                .and_then(|row| row.get(b))
                .copied()
                .unwrap_or(f64::NAN);
            // The diagonal (each parameter with itself) is grey: only pairs tell.
            let fill = if a == b { NEUTRAL } else { corr_color(r) };
            left.draw(&Rectangle::new(
                [(x, y), (x + cell, y + cell)],
                fill.filled(),
            ))
            .map_err(e)?;
            left.draw(&Rectangle::new(
                [(x, y), (x + cell, y + cell)],
                RGBColor(200, 200, 200),
            ))
            .map_err(e)?;
            if a != b && !separable(a, b) {
                left.draw(&Rectangle::new(
                    [(x + 2, y + 2), (x + cell - 2, y + cell - 2)],
                    BLACK.stroke_width(3),
                ))
                .map_err(e)?;
            }
            let text_color = if a != b && r.abs() > 0.6 {
                WHITE
            } else {
                BLACK
            };
            let text = if a == b {
                "1".to_string()
            } else {
                format!("{r:+.2}")
            };
            left.draw_text(
                &text,
                &("sans-serif", value_font)
                    .into_text_style(&left)
                    .color(&text_color)
                    .pos(centre),
                (x + cell / 2, y + cell / 2),
            )
            .map_err(e)?;
            layout.data.push(PixelBox {
                x0: bx + x,
                y0: by + y,
                x1: bx + x + cell,
                y1: by + y + cell,
            });
        }
    }
    layout.legend = Some(draw_legend(&column, &entries, by + gy).map_err(e)?);
    Ok(layout)
}

/// Size of the path figures.
pub const PATH_FIGURE: (u32, u32) = (720, 720);
/// Size of the error-over-time figures.
pub const ERROR_FIGURE: (u32, u32) = (960, 420);

fn svg<F>(file: &Path, size: (u32, u32), draw: F) -> std::io::Result<()>
where
    F: FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Result<Layout, String>,
{
    let root = SVGBackend::new(file, size).into_drawing_area();
    draw(&root).map_err(std::io::Error::other)?;
    root.present()
        .map_err(|e| std::io::Error::other(e.to_string()))
}

/// The path figure's file name of a recording.
pub fn path_file(s: &RecordingSeries) -> String {
    format!("path_{}.svg", s.key)
}

/// The error figure's file name of a recording.
pub fn error_file(s: &RecordingSeries) -> String {
    format!("error_{}.svg", s.key)
}

/// The correlation figure's file name.
pub const CORRELATION_FILE: &str = "correlations.svg";

/// A figure written for the report: its file, title and one sentence saying what to see.
#[derive(Debug, Clone, PartialEq)]
pub struct ReportFigure {
    /// The SVG's file name in the report folder.
    pub file: String,
    /// Its title on the page.
    pub title: String,
    /// What to see in it, one sentence.
    pub what_to_see: String,
}

/// Writes into `dir` (created if missing) `correlations.svg` and per recording
/// `path_<key>.svg` and `error_<key>.svg`; returns them in the page's order with their
/// titles and what to see in each. Fails when the DejaVu Sans font the plots need is
/// missing.
pub fn write_calibration_svgs(
    cal: &Calibration,
    series: &[RecordingSeries],
    dir: &Path,
) -> std::io::Result<Vec<ReportFigure>> {
    fitkit::plot::require_font()?;
    std::fs::create_dir_all(dir)?;
    let mut out = Vec::new();
    svg(
        &dir.join(CORRELATION_FILE),
        correlation_figure_size(cal.params.len()),
        |root| correlation_chart(cal, root),
    )?;
    out.push(ReportFigure {
        file: CORRELATION_FILE.to_string(),
        title: "Parameter correlations".into(),
        what_to_see: "pairs near +1 or -1 (deep red or blue, outlined when not separable) are ones these recordings cannot tell apart: only their combination is known, so record the motion the caveats name to separate them.".into(),
    });
    for s in series {
        let (pf, ef) = (path_file(s), error_file(s));
        svg(&dir.join(&pf), PATH_FIGURE, |root| {
            recording_path_chart(s, root)
        })?;
        svg(&dir.join(&ef), ERROR_FIGURE, |root| {
            recording_error_chart(s, root)
        })?;
        let how = if s.heldout {
            "held out (not fitted), dead-reckoned from its first measured pose"
        } else {
            "a recording the fit used, placed as the fit compared it"
        };
        out.push(ReportFigure {
            file: pf,
            title: format!("{}: path", s.name),
            what_to_see: format!(
                "{how}: the fitted dead reckoning (blue) should follow the measured path more closely than the nominal one (orange)."
            ),
        });
        out.push(ReportFigure {
            file: ef,
            title: format!("{}: position error over time", s.name),
            what_to_see: format!(
                "the error grows along the run as dead reckoning drifts; with the fitted geometry it should stay lower ({:.2} mm RMS nominal, {:.2} mm fitted, {} pose samples).",
                s.rms_nominal_m() * 1e3,
                s.rms_fitted_m() * 1e3,
                s.t.len()
            ),
        });
    }
    Ok(out)
}

/// Writes into `dir` (created if missing) the figures of [`write_calibration_svgs`] and
/// a plain `index.html` showing `summary` and the figures; returns the file names
/// written. (`wheelcal calibrate --report` writes its own page, which leads with the
/// factors, over it.) Fails when the DejaVu Sans font the plots need is missing.
pub fn write_calibration_figures(
    cal: &Calibration,
    series: &[RecordingSeries],
    summary: &str,
    dir: &Path,
) -> std::io::Result<Vec<String>> {
    let figures = write_calibration_svgs(cal, series, dir)?;
    let mut html = format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>wheelcal calibrate: {0}</title>\
         <style>body{{font-family:sans-serif;max-width:1000px;margin:auto}}img{{max-width:100%}}\
         pre{{background:#f4f4f4;padding:8px;white-space:pre-wrap;overflow-wrap:anywhere}}</style></head><body>\
         <h1>wheelcal calibrate: {0}</h1><pre>{1}</pre>",
        esc(&cal.robot),
        esc(summary)
    );
    let mut files = Vec::new();
    for f in &figures {
        html.push_str(&format!(
            "<h2>{}</h2><p>{}</p><img src=\"{}\">",
            esc(&f.title),
            esc(&f.what_to_see),
            f.file
        ));
        files.push(f.file.clone());
    }
    html.push_str("</body></html>\n");
    formats::safe_write::replace_file(&dir.join("index.html"), html.as_bytes())?;
    files.push("index.html".into());
    Ok(files)
}
