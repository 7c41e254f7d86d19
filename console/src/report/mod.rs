//! HTML reports with SVG and PNG plots (plotters), as the papers show their results.
//!
//! Each figure is a small value that knows how to draw itself on any plotters backend, so
//! one description renders to both SVG (for the HTML page) and PNG (for slides). Text
//! layout needs a TrueType font: DejaVu Sans (Debian's fonts-dejavu-core) is loaded from
//! the system; without it the report fails with a message saying what to install.

pub mod figures;
pub mod omni;
pub mod umbmark;

use anyhow::{Context, Result};
use figures::Figure;
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Registers the plots' font once (shared with diagnose's plots); false when none is
/// installed.
pub fn font_available() -> bool {
    diagnose::plots::register_font()
}

/// Renders a figure as `<name>.svg` and (font permitting) `<name>.png` in `dir`.
pub fn save_figure(fig: &dyn Figure, dir: &Path, name: &str) -> Result<PathBuf> {
    if !font_available() {
        anyhow::bail!(
            "plots need the DejaVu Sans font (looked in {}): apt-get install fonts-dejavu-core",
            diagnose::plots::FONT_PATHS.join(", ")
        );
    }
    let (w, h) = fig.size();
    let svg = dir.join(format!("{name}.svg"));
    {
        let root = SVGBackend::new(&svg, (w, h)).into_drawing_area();
        fig.draw_svg(&root)
            .map_err(|e| anyhow::anyhow!("drawing {name}.svg: {e}"))?;
        root.present()
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", svg.display()))?;
    }
    {
        let png = dir.join(format!("{name}.png"));
        let root = BitMapBackend::new(&png, (w, h)).into_drawing_area();
        fig.draw_png(&root)
            .map_err(|e| anyhow::anyhow!("drawing {name}.png: {e}"))?;
        root.present()
            .map_err(|e| anyhow::anyhow!("writing {}: {e}", png.display()))?;
    }
    Ok(svg)
}

/// An HTML page assembled from sections.
pub struct Page {
    title: String,
    body: String,
}

impl Page {
    pub fn new(title: &str) -> Self {
        Page {
            title: title.to_string(),
            body: String::new(),
        }
    }

    pub fn heading(&mut self, text: &str) {
        self.body.push_str(&format!("<h2>{}</h2>\n", escape(text)));
    }

    pub fn paragraph(&mut self, text: &str) {
        self.body.push_str(&format!("<p>{}</p>\n", escape(text)));
    }

    /// A table from a header row and rows of cells.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.body.push_str("<table>\n<tr>");
        for h in header {
            self.body.push_str(&format!("<th>{}</th>", escape(h)));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                self.body.push_str(&format!("<td>{}</td>", escape(c)));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// Embeds a figure saved next to the page.
    pub fn figure(
        &mut self,
        fig: &dyn Figure,
        dir: &Path,
        name: &str,
        caption: &str,
    ) -> Result<()> {
        save_figure(fig, dir, name)?;
        let png_note = format!(" (<a href=\"{name}.png\">PNG</a>)");
        self.body.push_str(&format!(
            "<figure><img src=\"{name}.svg\" alt=\"{}\"><figcaption>{}{png_note}</figcaption></figure>\n",
            escape(caption),
            escape(caption)
        ));
        Ok(())
    }

    /// Writes `index.html` into `dir` and returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        let path = dir.join("index.html");
        let html = format!(
            "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title>\n<style>\
             body{{font-family:sans-serif;max-width:960px;margin:2em auto;color:#222}}\
             table{{border-collapse:collapse;margin:1em 0}}td,th{{border:1px solid #bbb;padding:4px 8px;text-align:right}}\
             figure{{margin:1em 0}}img{{max-width:100%}}figcaption{{color:#555;font-size:90%}}</style></head>\n\
             <body><h1>{t}</h1>\n{b}<p style=\"color:#777\">wheelcal {v}</p></body></html>\n",
            t = escape(&self.title),
            b = self.body,
            v = env!("CARGO_PKG_VERSION")
        );
        std::fs::write(&path, html).with_context(|| format!("cannot write {}", path.display()))?;
        Ok(path)
    }
}

/// Creates the report directory.
pub fn prepare_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create report directory {}", dir.display()))
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}
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
