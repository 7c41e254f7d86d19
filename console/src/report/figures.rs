//! Figure descriptions that draw on any plotters backend.

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

type DrawResult = Result<(), String>;

/// Something that can be drawn in SVG and PNG.
pub trait Figure {
    fn size(&self) -> (u32, u32) {
        (720, 480)
    }
    fn draw_svg(&self, area: &DrawingArea<SVGBackend<'_>, Shift>) -> DrawResult;
    fn draw_png(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult;
}

/// Implements both backends with one generic drawing function.
macro_rules! figure_impl {
    ($t:ty) => {
        impl Figure for $t {
            fn draw_svg(&self, area: &DrawingArea<SVGBackend<'_>, Shift>) -> DrawResult {
                self.draw(area).map_err(|e| e.to_string())
            }
            fn draw_png(&self, area: &DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult {
                self.draw(area).map_err(|e| e.to_string())
            }
        }
    };
}

/// A named set of points or a line.
#[derive(Debug, Clone)]
pub struct Series {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    /// Draw as a line (else as markers).
    pub line: bool,
    /// Large marker (centroids).
    pub emphasis: bool,
    pub colour: usize,
}

impl Series {
    pub fn points(label: &str, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Series {
            label: label.into(),
            points,
            line: false,
            emphasis: false,
            colour,
        }
    }
    pub fn line(label: &str, points: Vec<(f64, f64)>, colour: usize) -> Self {
        Series {
            label: label.into(),
            points,
            line: true,
            emphasis: false,
            colour,
        }
    }
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
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub equal_axes: bool,
    /// Shaded vertical bands (x ranges), e.g. zones or time windows.
    pub bands: Vec<(f64, f64)>,
}

impl XyChart {
    fn bounds(&self) -> ((f64, f64), (f64, f64)) {
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
            let half = ((xs.1 - xs.0).max(ys.1 - ys.0)) / 2.0;
            xs = (cx - half * 1.5, cx + half * 1.5);
            ys = (cy - half, cy + half);
        }
        (xs, ys)
    }

    fn draw<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        area.fill(&WHITE)?;
        let ((x0, x1), (y0, y1)) = self.bounds();
        let mut chart = ChartBuilder::on(area)
            .caption(&self.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_desc(&self.x_label)
            .y_desc(&self.y_label)
            .light_line_style(WHITE.mix(0.0))
            .draw()?;
        for &(a, b) in &self.bands {
            chart.draw_series(std::iter::once(Rectangle::new(
                [(a, y0), (b, y1)],
                RGBColor(255, 200, 0).mix(0.25).filled(),
            )))?;
        }
        for s in &self.series {
            let c = PALETTE[s.colour % PALETTE.len()];
            if s.line {
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))?
                    .label(&s.label)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2))
                    });
            } else if s.emphasis {
                chart
                    .draw_series(
                        s.points
                            .iter()
                            .map(|&p| Cross::new(p, 9, c.stroke_width(3))),
                    )?
                    .label(&s.label)
                    .legend(move |(x, y)| Cross::new((x + 9, y), 6, c.stroke_width(3)));
            } else {
                chart
                    .draw_series(s.points.iter().map(|&p| Circle::new(p, 4, c.filled())))?
                    .label(&s.label)
                    .legend(move |(x, y)| Circle::new((x + 9, y), 4, c.filled()));
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()?;
        Ok(())
    }
}
figure_impl!(XyChart);

/// Grouped bars: one group per category, one bar per series.
#[derive(Debug, Clone)]
pub struct BarChart {
    pub title: String,
    pub y_label: String,
    pub categories: Vec<String>,
    /// (series label, one value per category)
    pub series: Vec<(String, Vec<f64>)>,
}

impl BarChart {
    fn draw<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
    ) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
        area.fill(&WHITE)?;
        let n = self.categories.len().max(1);
        let m = self.series.len().max(1);
        let top = self
            .series
            .iter()
            .flat_map(|s| s.1.iter().copied())
            .fold(0.0f64, f64::max)
            .max(1e-9)
            * 1.15;
        let mut chart = ChartBuilder::on(area)
            .caption(&self.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..n as f64, 0.0..top)?;
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
            .draw()?;
        let w = 0.8 / m as f64;
        for (j, (label, vals)) in self.series.iter().enumerate() {
            let c = PALETTE[j % PALETTE.len()];
            chart
                .draw_series(vals.iter().enumerate().map(|(i, &v)| {
                    let x = i as f64 + 0.1 + j as f64 * w;
                    Rectangle::new([(x, 0.0), (x + w * 0.95, v)], c.filled())
                }))?
                .label(label)
                .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 12, y + 5)], c.filled()));
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
        Ok(())
    }
}
figure_impl!(BarChart);
