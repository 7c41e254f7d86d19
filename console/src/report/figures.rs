//! Figure descriptions that draw on any plotters backend.

use fitkit::plot::{draw_legend, plot_box, split_for_legend, LegendMark};
pub use fitkit::plot::{Layout, PixelBox};
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

/// Colours for series, in order.
pub const PALETTE: [RGBColor; 6] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
];

/// The drawn figure's layout (legend and data boxes in pixels), or why drawing failed.
type DrawResult = Result<Layout, String>;

/// Something that can be drawn in SVG and PNG; drawing returns where the legend and the
/// data went, so tests can check that no legend covers a data point.
pub trait Figure {
    /// Image size in pixels (width, height).
    fn size(&self) -> (u32, u32) {
        (720, 480)
    }
    /// Draws the figure into an SVG drawing area.
    fn draw_svg(&self, area: &DrawingArea<SVGBackend<'_>, Shift>) -> DrawResult;
    /// Draws the figure into a bitmap (PNG) drawing area.
    fn draw_png(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult;
}

/// Implements both backends with one generic drawing function.
macro_rules! figure_impl {
    ($t:ty) => {
        impl Figure for $t {
            fn draw_svg(&self, area: &DrawingArea<SVGBackend<'_>, Shift>) -> DrawResult {
                self.draw(area)
            }
            fn draw_png(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult {
                self.draw(area)
            }
        }
    };
}

/// A named set of points or a line.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend text.
    pub label: String,
    /// The (x, y) points, in the chart's axis units.
    pub points: Vec<(f64, f64)>,
    /// Draw as a line (else as markers).
    pub line: bool,
    /// Large marker (centroids).
    pub emphasis: bool,
    /// Index into [`PALETTE`] (taken modulo its length).
    pub colour: usize,
}

impl Series {
    /// A series drawn as markers.
    pub fn points(label: &str, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Series {
            label: label.into(),
            points,
            line: false,
            emphasis: false,
            colour,
        }
    }
    /// A series drawn as a line through the points.
    pub fn line(label: &str, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Series {
            label: label.into(),
            points,
            line: true,
            emphasis: false,
            colour,
        }
    }
    /// A single large marker (e.g. a centroid).
    pub fn marker(label: &str, p: (f64, f64), colour: usize) -> Self {
        Series {
            label: label.into(),
            points: vec![p],
            line: false,
            emphasis: true,
            colour,
        }
    }
}

/// An x-y chart of several series, optionally with equal axis scales (positions).
#[derive(Debug, Clone)]
pub struct XyChart {
    /// Title above the chart.
    pub title: String,
    /// Label of the x axis, with its unit.
    pub x_label: String,
    /// Label of the y axis, with its unit.
    pub y_label: String,
    /// The series, drawn in order.
    pub series: Vec<Series>,
    /// Equal scales on both axes, so positions keep their shape.
    pub equal_axes: bool,
    /// Shaded vertical bands (x ranges), e.g. zones or time windows.
    pub bands: Vec<(f64, f64)>,
}

type Chart2d<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// Margin and label areas of the charts (pixels).
const MARGIN: i32 = 12;
const X_LABEL_AREA: i32 = 40;
const Y_LABEL_AREA: i32 = 60;

/// Width over height of the plotting area a chart on `area` gets.
fn plot_aspect<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>) -> f64 {
    let (w, h) = area.dim_in_pixel();
    (f64::from(w) - f64::from(2 * MARGIN + Y_LABEL_AREA)).max(1.0)
        / (f64::from(h) - f64::from(2 * MARGIN + X_LABEL_AREA)).max(1.0)
}

impl XyChart {
    /// Axis ranges with 8 % padding; with equal axes, one unit spans the same pixels on
    /// both axes of a plotting area of width/height `aspect`.
    fn bounds(&self, aspect: f64) -> ((f64, f64), (f64, f64)) {
        let mut xs = (f64::INFINITY, f64::NEG_INFINITY);
        let mut ys = (f64::INFINITY, f64::NEG_INFINITY);
        for p in self.series.iter().flat_map(|s| s.points.iter()) {
            if p.0.is_finite() && p.1.is_finite() {
                xs = (xs.0.min(p.0), xs.1.max(p.0));
                ys = (ys.0.min(p.1), ys.1.max(p.1));
            }
        }
        if !xs.0.is_finite() {
            return ((-1.0, 1.0), (-1.0, 1.0));
        }
        let pad = |r: (f64, f64)| {
            let w = (r.1 - r.0).max(1e-9);
            (r.0 - 0.08 * w, r.1 + 0.08 * w)
        };
        let (mut xs, mut ys) = (pad(xs), pad(ys));
        if self.equal_axes {
            let (cx, cy) = ((xs.0 + xs.1) / 2.0, (ys.0 + ys.1) / 2.0);
            let half_y = ((ys.1 - ys.0) / 2.0).max((xs.1 - xs.0) / 2.0 / aspect);
            let half_x = half_y * aspect;
            xs = (cx - half_x, cx + half_x);
            ys = (cy - half_y, cy + half_y);
        }
        (xs, ys)
    }

    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> DrawResult {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        area.fill(&WHITE).map_err(e)?;
        let body = area.titled(&self.title, ("sans-serif", 20)).map_err(e)?;
        let labels: Vec<&str> = self.series.iter().map(|s| s.label.as_str()).collect();
        // The legend gets its own column right of the chart: it cannot cover a point.
        let (left, column) = split_for_legend(&body, &labels);
        let ((x0, x1), (y0, y1)) = self.bounds(plot_aspect(&left));
        let mut chart: Chart2d<DB> = ChartBuilder::on(&left)
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(e)?;
        for &(a, b) in &self.bands {
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(a, y0), (b, y1)],
                    RGBColor(255, 200, 0).mix(0.25).filled(),
                )))
                .map_err(e)?;
        }
        let mut layout = Layout {
            figure: Some(plot_box(area)),
            plot: Some(plot_box(chart.plotting_area())),
            ..Layout::default()
        };
        let mut entries = Vec::new();
        for s in &self.series {
            let c = PALETTE[s.colour % PALETTE.len()];
            let pts = s
                .points
                .iter()
                .filter(|p| p.0.is_finite() && p.1.is_finite());
            // Half-size of what is drawn at each point, in pixels.
            let (r, mark) = if s.line {
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))
                    .map_err(e)?;
                (2, LegendMark::Line(c))
            } else if s.emphasis {
                chart
                    .draw_series(
                        s.points
                            .iter()
                            .map(|&p| Cross::new(p, 9, c.stroke_width(3))),
                    )
                    .map_err(e)?;
                (11, LegendMark::Cross(c))
            } else {
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, 4, c.filled())))
                    .map_err(e)?;
                (4, LegendMark::Dot(c))
            };
            layout
                .data
                .extend(pts.map(|p| PixelBox::around(chart.backend_coord(p), r)));
            entries.push((s.label.clone(), mark));
        }
        let top = plot_box(chart.plotting_area()).y0;
        layout.legend = Some(draw_legend(&column, &entries, top).map_err(e)?);
        Ok(layout)
    }
}
figure_impl!(XyChart);

/// Grouped bars: one group per category, one bar per series.
#[derive(Debug, Clone)]
pub struct BarChart {
    /// Title above the chart.
    pub title: String,
    /// Label of the y axis, with its unit.
    pub y_label: String,
    /// Category names along the x axis, one bar group each.
    pub categories: Vec<String>,
    /// (series label, one value per category)
    pub series: Vec<(String, Vec<f64>)>,
}

impl BarChart {
    fn draw<DB: DrawingBackend>(&self, area: &DrawingArea<DB, Shift>) -> DrawResult {
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        area.fill(&WHITE).map_err(e)?;
        let n = self.categories.len().max(1);
        let m = self.series.len().max(1);
        let top = self
            .series
            .iter()
            .flat_map(|s| s.1.iter().copied())
            .filter(|v| v.is_finite())
            .fold(0.0f64, f64::max)
            .max(1e-9)
            * 1.15;
        let body = area.titled(&self.title, ("sans-serif", 20)).map_err(e)?;
        let labels: Vec<&str> = self.series.iter().map(|s| s.0.as_str()).collect();
        let (left, column) = split_for_legend(&body, &labels);
        let mut chart: Chart2d<DB> = ChartBuilder::on(&left)
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(0.0..n as f64, 0.0..top)
            .map_err(e)?;
        let cats = self.categories.clone();
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(n * 2 + 1)
            .x_label_formatter(&move |x| {
                let i = (*x - 0.5).round();
                if (x - 0.5 - i).abs() < 1e-6 && i >= 0.0 && (i as usize) < cats.len() {
                    cats[i as usize].clone()
                } else {
                    String::new()
                }
            })
            .y_desc(&self.y_label)
            .draw()
            .map_err(e)?;
        let mut layout = Layout {
            figure: Some(plot_box(area)),
            plot: Some(plot_box(chart.plotting_area())),
            ..Layout::default()
        };
        let w = 0.8 / m as f64;
        let mut entries = Vec::new();
        for (j, (label, vals)) in self.series.iter().enumerate() {
            let c = PALETTE[j % PALETTE.len()];
            let bar = |i: usize, v: f64| {
                let x = i as f64 + 0.1 + j as f64 * w;
                [(x, 0.0), (x + w * 0.95, v)]
            };
            chart
                .draw_series(
                    vals.iter()
                        .enumerate()
                        .map(|(i, &v)| Rectangle::new(bar(i, v), c.filled())),
                )
                .map_err(e)?;
            for (i, &v) in vals.iter().enumerate().filter(|v| v.1.is_finite()) {
                let [a, b] = bar(i, v).map(|p| chart.backend_coord(&p));
                layout.data.push(PixelBox {
                    x0: a.0.min(b.0),
                    y0: a.1.min(b.1),
                    x1: a.0.max(b.0),
                    y1: a.1.max(b.1),
                });
            }
            entries.push((label.clone(), LegendMark::Bar(c)));
        }
        let top_px = plot_box(chart.plotting_area()).y0;
        layout.legend = Some(draw_legend(&column, &entries, top_px).map_err(e)?);
        Ok(layout)
    }
}
figure_impl!(BarChart);
