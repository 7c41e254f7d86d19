//! HTML reports with SVG and PNG plots (plotters), as the papers show their results.
//!
//! Each figure is a small value that knows how to draw itself on any plotters backend, so
//! one description renders to both SVG (for the HTML page) and PNG (for slides). Text
//! layout needs a TrueType font: DejaVu Sans (Debian's fonts-dejavu-core) is loaded from
//! the system; without it the report fails with a message saying what to install.

pub mod calibrate;
pub mod diagnose;
pub mod figures;
pub mod omni;
pub mod page;
pub mod umbmark;

pub use page::{font_available, prepare_dir, save_figure, Page};

#[cfg(test)]
mod tests {
    use super::*;
    use figures::{Series, XyChart};

    #[test]
    fn writes_svg_png_and_page() {
        let dir = std::env::temp_dir().join(format!("wheelcal-report-{}", std::process::id()));
        prepare_dir(&dir).unwrap();
        let fig = XyChart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            series: vec![Series::line("a", vec![(0.0, 0.0), (1.0, 2.0)], 0)],
            equal_axes: false,
            bands: vec![(0.2, 0.4)],
        };
        let mut page = Page::new("T & <test>");
        page.figure(&fig, &dir, "fig", "caption").unwrap();
        let index = page.write(&dir).unwrap();
        let html = std::fs::read_to_string(index).unwrap();
        assert!(html.contains("T &amp; &lt;test&gt;") && html.contains("fig.svg"));
        let svg = std::fs::read_to_string(dir.join("fig.svg")).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("polyline"));
        // A 720 x 480 PNG with content: more than the ~2 kB of a blank image.
        let png = std::fs::metadata(dir.join("fig.png")).unwrap().len();
        assert!(png > 5_000, "png {png} bytes");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}

/// "No legend, label or annotation may cover a data point": every report figure
/// is drawn with data of the kind that used to sit under the legend, and its layout (the
/// legend's and the points' pixel boxes, from the drawing's own coordinate mapping) must
/// show no overlap.
#[cfg(test)]
mod legend_tests {
    use super::figures::{Figure, Layout};
    use crate::calibration::{omni, umbmark};
    use calib_core::motion::Direction;
    use calib_core::robot::presets;
    use calib_core::umbmark::square_end_error;
    use formats::runs_file::RunsFile;
    use std::path::Path;

    fn layout(fig: &dyn Figure) -> Layout {
        assert!(
            super::font_available(),
            "DejaVu Sans needed for text layout"
        );
        let mut svg = String::new();
        let (w, h) = fig.size();
        let l = {
            let root = plotters::prelude::SVGBackend::with_string(&mut svg, (w, h));
            fig.draw_svg(&plotters::prelude::IntoDrawingArea::into_drawing_area(root))
                .unwrap()
        };
        assert!(svg.contains("<svg"));
        l
    }

    fn assert_clear(name: &str, fig: &dyn Figure, n_points: usize) {
        let l = layout(fig);
        assert_eq!(l.data.len(), n_points, "{name}: data boxes");
        if let Err(e) = l.check() {
            panic!("{name}: {e}");
        }
    }

    /// A demo-like UMBmark: E_d 1.01, E_b 1.04 on a 4 m square before (tens of mm, cw
    /// and ccw far apart), a few mm after, +-3 mm scatter; the clockwise "before"
    /// centroid sat under the old lower-right legend.
    fn umbmark_report() -> umbmark::UmbmarkReport {
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\n");
        for (phase, ed, eb) in [("before", 1.01, 1.04), ("after", 1.0005, 1.001)] {
            for (dir, name) in [(Direction::Cw, "cw"), (Direction::Ccw, "ccw")] {
                let (x, y, _) = square_end_error(ed, eb, 4.0, 0.4, dir).unwrap();
                for k in 0..5 {
                    let n = 0.003 * ((k as f64) * 1.7).sin();
                    text.push_str(&format!("umbmark,{name},4,{},{},,{phase}\n", x + n, y - n));
                }
            }
        }
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        umbmark::compute(&presets::mobolab(), &runs).unwrap()
    }

    #[test]
    fn umbmark_legends_cover_no_data() {
        let rep = umbmark_report();
        // 20 runs + 4 centroids + the start marker.
        assert_clear("end_positions", &super::umbmark::end_positions(&rep), 25);
        let curves = super::umbmark::normal_curves(&rep);
        let n: usize = curves.series.iter().map(|s| s.points.len()).sum();
        assert!(n > 100);
        assert_clear("normal_curves", &curves, n);
        assert_clear("p_within_3cm", &super::umbmark::p_within_3cm(&rep), 4);
        assert_clear("zones", &super::umbmark::zones(&rep), 12);
    }

    #[test]
    fn omni_legends_cover_no_data() {
        // Before: radial errors growing with the run (the old legend's corner); after: small.
        let mut text = String::from("test,path,length_m,x_err_m,y_err_m,theta_err_rad,phase\n");
        for p in ["4W-1", "4W-2"] {
            for k in 0..6 {
                let e = 0.02 + 0.004 * k as f64;
                text.push_str(&format!("omni,{p},0.6,-{e},0.004,,\n"));
                text.push_str(&format!("omni,{p},0.6,-{},0.001,,after\n", e / 10.0));
            }
        }
        let runs = RunsFile::parse(&text, Path::new("r.csv")).unwrap();
        let rep = omni::compute(
            &presets::omni4(),
            &runs,
            calib_core::omni_cal::IdleWheels::Released,
        )
        .unwrap();
        assert_clear("radial_errors", &super::omni::radial_errors(&rep), 24);
        assert_clear("mean_radial", &super::omni::mean_radial(&rep), 4);
    }
}
