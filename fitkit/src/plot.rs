//! The plot kit calibrate's and diagnose's reports (and the console's) draw with: equal-
//! scale path charts and time charts whose legend stands in a column beside the chart,
//! the layout of every drawn box (so tests can prove no legend covers data), the font.

use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;

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

/// A rectangle in the backend's pixels (x0, y0 top left; x1, y1 bottom right).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelBox {
    /// Left edge (px).
    pub x0: i32,
    /// Top edge (px).
    pub y0: i32,
    /// Right edge (px).
    pub x1: i32,
    /// Bottom edge (px).
    pub y1: i32,
}

impl PixelBox {
    /// The box of a marker of half-size `r` around a pixel.
    pub fn around((x, y): (i32, i32), r: i32) -> Self {
        PixelBox {
            x0: x - r,
            y0: y - r,
            x1: x + r,
            y1: y + r,
        }
    }
    /// True when the two boxes share any pixel (touching edges count).
    pub fn overlaps(&self, o: &PixelBox) -> bool {
        self.x0 <= o.x1 && o.x0 <= self.x1 && self.y0 <= o.y1 && o.y0 <= self.y1
    }
    /// True when `o` lies wholly inside this box.
    pub fn contains(&self, o: &PixelBox) -> bool {
        self.x0 <= o.x0 && o.x1 <= self.x1 && self.y0 <= o.y0 && o.y1 <= self.y1
    }
}

/// Where a figure put its legend and its data, in the pixel mapping it drew with: the
/// evidence for "no legend covers a data point", checked by the tests.
#[derive(Debug, Clone, Default)]
pub struct Layout {
    /// The whole figure.
    pub figure: Option<PixelBox>,
    /// The plotting area (inside the axes).
    pub plot: Option<PixelBox>,
    /// The legend's frame.
    pub legend: Option<PixelBox>,
    /// One box per drawn data point (marker extent, line vertex, bar).
    pub data: Vec<PixelBox>,
}

impl Layout {
    /// Data boxes the legend overlaps (empty when none is covered).
    pub fn covered(&self) -> Vec<PixelBox> {
        match self.legend {
            Some(l) => self
                .data
                .iter()
                .filter(|d| d.overlaps(&l))
                .copied()
                .collect(),
            None => Vec::new(),
        }
    }

    /// The checks of "no legend covers a data point": a legend wholly inside the figure,
    /// overlapping no data box, and every data point's centre inside the plotting area
    /// (so the boxes are the drawn points in the drawn mapping).
    pub fn check(&self) -> Result<(), String> {
        let (Some(fig), Some(plot), Some(legend)) = (self.figure, self.plot, self.legend) else {
            return Err(format!("incomplete layout {self:?}"));
        };
        if !fig.contains(&legend) {
            return Err(format!("legend {legend:?} not inside the figure {fig:?}"));
        }
        let covered = self.covered();
        if !covered.is_empty() {
            return Err(format!(
                "legend {legend:?} covers {} data point(s), first {:?}",
                covered.len(),
                covered[0]
            ));
        }
        for d in &self.data {
            let c = ((d.x0 + d.x1) / 2, (d.y0 + d.y1) / 2);
            if !plot.contains(&PixelBox::around(c, 0)) {
                return Err(format!("data point {d:?} outside the plot {plot:?}"));
            }
        }
        Ok(())
    }
}

/// How a legend entry is marked.
#[derive(Debug, Clone, Copy)]
pub enum LegendMark {
    /// A line in this colour.
    Line(RGBColor),
    /// A filled dot.
    Dot(RGBColor),
    /// A cross (a centroid).
    Cross(RGBColor),
    /// A filled bar.
    Bar(RGBColor),
}

const LEGEND_FONT: u32 = 15;
const LEGEND_PAD: i32 = 8;
const LEGEND_MARK_W: i32 = 26;

fn legend_row_h<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, label: &str) -> (i32, i32) {
    let (w, h) = area
        .estimate_text_size(label, &("sans-serif", LEGEND_FONT).into_text_style(area))
        .unwrap_or((8 * label.len() as u32, LEGEND_FONT));
    (w as i32, (h as i32).max(14) + 6)
}

/// Splits a figure into the chart (left) and a legend column (right) as wide as the
/// labels need: the legend then lies outside the plotting area, so it can cover no data
/// however the points fall.
pub fn split_for_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    labels: &[&str],
) -> (DrawingArea<DB, Shift>, DrawingArea<DB, Shift>) {
    let text_w = labels
        .iter()
        .map(|l| legend_row_h(area, l).0)
        .max()
        .unwrap_or(0);
    let col_w = text_w + LEGEND_MARK_W + 3 * LEGEND_PAD;
    let (w, _) = area.dim_in_pixel();
    // Never take more than 40 % of the figure (very long labels are cut at the edge).
    let col_w = col_w.min(w as i32 * 2 / 5);
    area.split_horizontally(w as i32 - col_w)
}

/// Draws the legend framed at the top of `column` (level with `top_px`, the plotting
/// area's top in backend pixels) and returns its frame in backend pixels.
pub fn draw_legend<DB: DrawingBackend>(
    column: &DrawingArea<DB, Shift>,
    entries: &[(String, LegendMark)],
    top_px: i32,
) -> Result<PixelBox, DrawingAreaErrorKind<DB::ErrorType>> {
    let (bx, by) = column.get_base_pixel();
    let rows: Vec<(i32, i32)> = entries
        .iter()
        .map(|(l, _)| legend_row_h(column, l))
        .collect();
    let text_w = rows.iter().map(|r| r.0).max().unwrap_or(0);
    let (cw, _) = column.dim_in_pixel();
    let x0 = LEGEND_PAD;
    let x1 = (x0 + LEGEND_MARK_W + text_w + LEGEND_PAD).min(cw as i32 - 2);
    let y0 = (top_px - by).max(0);
    let y1 = y0 + LEGEND_PAD + rows.iter().map(|r| r.1).sum::<i32>();
    column.draw(&Rectangle::new([(x0, y0), (x1, y1)], WHITE.filled()))?;
    column.draw(&Rectangle::new([(x0, y0), (x1, y1)], BLACK))?;
    let style = ("sans-serif", LEGEND_FONT).into_text_style(column).pos(
        plotters::style::text_anchor::Pos::new(
            plotters::style::text_anchor::HPos::Left,
            plotters::style::text_anchor::VPos::Center,
        ),
    );
    let mut y = y0 + LEGEND_PAD / 2;
    for ((label, mark), (_, h)) in entries.iter().zip(&rows) {
        let cy = y + h / 2;
        let mx = x0 + LEGEND_PAD;
        match *mark {
            LegendMark::Line(c) => column.draw(&PathElement::new(
                vec![(mx, cy), (mx + 16, cy)],
                c.stroke_width(2),
            ))?,
            LegendMark::Dot(c) => column.draw(&Circle::new((mx + 8, cy), 4, c.filled()))?,
            LegendMark::Cross(c) => column.draw(&Cross::new((mx + 8, cy), 6, c.stroke_width(3)))?,
            LegendMark::Bar(c) => column.draw(&Rectangle::new(
                [(mx + 2, cy - 5), (mx + 14, cy + 5)],
                c.filled(),
            ))?,
        }
        column.draw_text(label, &style, (x0 + LEGEND_MARK_W, cy))?;
        y += h;
    }
    Ok(PixelBox {
        x0: bx + x0,
        y0: by + y0,
        x1: bx + x1,
        y1: by + y1,
    })
}

/// The backend-pixel box of a chart's plotting area.
pub fn plot_box<DB: DrawingBackend, CT: plotters::coord::CoordTranslate>(
    a: &DrawingArea<DB, CT>,
) -> PixelBox {
    let (xr, yr) = a.get_pixel_range();
    PixelBox {
        x0: xr.start,
        y0: yr.start,
        x1: xr.end,
        y1: yr.end,
    }
}

/// The fitted model's colour (matplotlib's first).
pub const BLUE: RGBColor = RGBColor(31, 119, 180);
/// The nominal model's colour.
pub const ORANGE: RGBColor = RGBColor(255, 127, 14);
/// A window the fit explains.
pub const GREEN: RGBColor = RGBColor(44, 160, 44);

/// Boxes of the vertices of a line drawn with stroke `w`, in backend pixels.
pub fn vertex_boxes<DB: DrawingBackend>(
    chart: &ChartContext<'_, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    data: &[(f64, f64)],
    w: i32,
) -> Vec<PixelBox> {
    data.iter()
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .map(|p| PixelBox::around(chart.backend_coord(p), w))
        .collect()
}

/// A 2-D chart of f64 coordinates.
pub type Chart2d<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The three paths a path chart draws, (x, y) in m.
#[derive(Debug, Clone, Copy)]
pub struct Paths<'a> {
    /// Measured.
    pub measured: &'a [(f64, f64)],
    /// The nominal model's.
    pub nominal: &'a [(f64, f64)],
    /// The fitted model's.
    pub fitted: &'a [(f64, f64)],
}

/// The path chart (measured, nominal model, fitted model; equal axis scales) under
/// `title`.
pub fn path_chart_titled<DB: DrawingBackend>(
    p: &Paths<'_>,
    root: &DrawingArea<DB, Shift>,
    title: &str,
) -> Result<Layout, String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let lines = [
        (p.measured, BLACK, "measured"),
        (p.nominal, ORANGE, "nominal model"),
        (p.fitted, BLUE, "fitted model"),
    ];
    let body = root.titled(title, ("sans-serif", 20)).map_err(e)?;
    let (left, column) = split_for_legend(&body, &lines.map(|l| l.2));
    let (margin, xl, yl) = (10, 40, 60);
    let (w, h) = left.dim_in_pixel();
    let aspect = (w as f64 - 2.0 * margin as f64 - yl as f64).max(1.0)
        / (h as f64 - 2.0 * margin as f64 - xl as f64).max(1.0);
    let (mut x0, mut x1, mut y0, mut y1) = bounds(&[p.measured, p.nominal, p.fitted]);
    // Equal axis scales (in pixels) so the path keeps its shape.
    let (cx, cy) = (0.5 * (x0 + x1), 0.5 * (y0 + y1));
    let half_y = (0.5 * (y1 - y0)).max(0.5 * (x1 - x0) / aspect);
    let half_x = half_y * aspect;
    (x0, x1, y0, y1) = (cx - half_x, cx + half_x, cy - half_y, cy + half_y);
    let mut chart: Chart2d<DB> = ChartBuilder::on(&left)
        .margin(margin)
        .x_label_area_size(xl)
        .y_label_area_size(yl)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("x (m)")
        .y_desc("y (m)")
        .draw()
        .map_err(e)?;
    let mut layout = Layout {
        figure: Some(plot_box(root)),
        plot: Some(plot_box(chart.plotting_area())),
        ..Layout::default()
    };
    let mut entries = Vec::new();
    for (data, color, label) in lines {
        chart
            .draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(2)))
            .map_err(e)?;
        layout.data.extend(vertex_boxes(&chart, data, 2));
        entries.push((label.to_string(), LegendMark::Line(color)));
    }
    let top = plot_box(chart.plotting_area()).y0;
    layout.legend = Some(draw_legend(&column, &entries, top).map_err(e)?);
    Ok(layout)
}

/// A span of time shaded behind a time chart's lines: green when the fit explains it,
/// red when it is still off.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Shade {
    /// Start, s.
    pub t_start_s: f64,
    /// End, s.
    pub t_end_s: f64,
    /// Whether the fit explains it (green) or not (red).
    pub explained: bool,
}

/// A time chart (series over time, `shades` behind them) on any backend; the legend
/// stands in a column right of the chart.
pub fn time_chart<DB: DrawingBackend>(
    shades: &[Shade],
    root: &DrawingArea<DB, Shift>,
    title: &str,
    ylabel: &str,
    t: &[f64],
    series: &[(&[f64], RGBColor, &str)],
) -> Result<Layout, String> {
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let pts: Vec<Vec<(f64, f64)>> = series
        .iter()
        .map(|(v, _, _)| t.iter().copied().zip(v.iter().copied()).collect())
        .collect();
    let refs: Vec<&[(f64, f64)]> = pts.iter().map(|v| v.as_slice()).collect();
    let (x0, x1, y0, y1) = bounds(&refs);
    let body = root.titled(title, ("sans-serif", 18)).map_err(e)?;
    let labels: Vec<&str> = series.iter().map(|s| s.2).collect();
    let (left, column) = split_for_legend(&body, &labels);
    let mut chart: Chart2d<DB> = ChartBuilder::on(&left)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("t (s)")
        .y_desc(ylabel)
        .draw()
        .map_err(e)?;
    let rects: Vec<_> = shades
        .iter()
        .map(|s| {
            let c = if s.explained {
                GREEN.mix(0.15)
            } else {
                RED.mix(0.15)
            };
            Rectangle::new([(s.t_start_s, y0), (s.t_end_s, y1)], c.filled())
        })
        .collect();
    chart.draw_series(rects).map_err(e)?;
    let mut layout = Layout {
        figure: Some(plot_box(root)),
        plot: Some(plot_box(chart.plotting_area())),
        ..Layout::default()
    };
    let mut entries = Vec::new();
    for (data, (_, color, label)) in pts.iter().zip(series) {
        let color = *color;
        chart
            .draw_series(LineSeries::new(data.iter().copied(), color.stroke_width(1)))
            .map_err(e)?;
        layout.data.extend(vertex_boxes(&chart, data, 1));
        entries.push((label.to_string(), LegendMark::Line(color)));
    }
    let top = plot_box(chart.plotting_area()).y0;
    layout.legend = Some(draw_legend(&column, &entries, top).map_err(e)?);
    Ok(layout)
}

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

/// [`register_font`], or the error every report gives without the font: where it was
/// looked for and the package that installs it.
pub fn require_font() -> std::io::Result<()> {
    if register_font() {
        return Ok(());
    }
    Err(std::io::Error::other(format!(
        "plots need the DejaVu Sans font (looked in {}): apt-get install fonts-dejavu-core",
        FONT_PATHS.join(", ")
    )))
}

/// `s` escaped for HTML text.
pub fn esc(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn check_sees_a_covered_point() {
        let b = |x0, y0, x1, y1| PixelBox { x0, y0, x1, y1 };
        let mut l = Layout {
            figure: Some(b(0, 0, 100, 100)),
            plot: Some(b(10, 10, 70, 90)),
            legend: Some(b(50, 12, 68, 30)),
            data: vec![b(20, 20, 28, 28), b(60, 20, 62, 22)],
        };
        assert!(l.check().unwrap_err().contains("covers 1 data point"));
        l.data.pop();
        assert!(l.check().is_ok());
        l.legend = Some(b(90, 12, 110, 30));
        assert!(l.check().unwrap_err().contains("not inside the figure"));
    }
}
