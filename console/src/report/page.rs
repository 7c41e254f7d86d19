//! The report pages: an HTML page assembled from sections ([`Page`]) and the figures saved
//! beside it as SVG and PNG ([`save_figure`]).

use super::figures::Figure;
use anyhow::{Context, Result};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// Registers the plots' font once (shared with diagnose's plots); false when none is
/// installed.
pub fn font_available() -> bool {
    fitkit::plot::register_font()
}

/// Renders a figure as `<name>.svg` and (font permitting) `<name>.png` in `dir`.
pub fn save_figure(fig: &dyn Figure, dir: &Path, name: &str) -> Result<PathBuf> {
    fitkit::plot::require_font()?;
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
    /// An empty page with this title.
    pub fn new(title: &str) -> Self {
        Page {
            title: title.to_string(),
            body: String::new(),
        }
    }

    /// Adds a section heading.
    pub fn heading(&mut self, text: &str) {
        self.body.push_str(&format!("<h2>{}</h2>\n", escape(text)));
    }

    /// Adds a paragraph of text (HTML-escaped).
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
                // Figures right-aligned, words left.
                let numeric = c
                    .chars()
                    .next()
                    .is_some_and(|ch| ch.is_ascii_digit() || "+-.".contains(ch));
                let class = if numeric { " class=\"n\"" } else { "" };
                self.body
                    .push_str(&format!("<td{class}>{}</td>", escape(c)));
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

    /// Embeds an image already written beside the page (`src`, relative), with its
    /// title and one sentence saying what to see in it.
    pub fn image(&mut self, src: &str, title: &str, what_to_see: &str) {
        self.body.push_str(&format!(
            "<figure><figcaption><b>{}</b>: {}</figcaption><img src=\"{}\" alt=\"{}\"></figure>\n",
            escape(title),
            escape(what_to_see),
            escape(src),
            escape(title)
        ));
    }

    /// A paragraph in bold type on a tinted band: the answer the page leads with.
    pub fn answer(&mut self, text: &str) {
        self.body
            .push_str(&format!("<p class=\"answer\">{}</p>\n", escape(text)));
    }

    /// A command to copy (one line, wrapped when it is longer than the page).
    pub fn command(&mut self, cmd: &str) {
        self.body.push_str(&format!(
            "<pre class=\"cmd\"><code>{}</code></pre>\n",
            escape(cmd)
        ));
    }

    /// A bulleted list of plain-text items (nothing when empty).
    pub fn list(&mut self, items: &[String]) {
        if items.is_empty() {
            return;
        }
        self.body.push_str("<ul>\n");
        for i in items {
            self.body.push_str(&format!("<li>{}</li>\n", escape(i)));
        }
        self.body.push_str("</ul>\n");
    }

    /// The full text output, folded: shown on a click, wrapped so that no line makes the
    /// page scroll sideways.
    pub fn folded_text(&mut self, summary: &str, text: &str) {
        self.body.push_str(&format!(
            "<details><summary>{}</summary><pre class=\"text\">{}</pre></details>\n",
            escape(summary),
            escape(text)
        ));
    }

    /// Writes `index.html` into `dir` and returns its path.
    pub fn write(&self, dir: &Path) -> Result<PathBuf> {
        let path = dir.join("index.html");
        formats::safe_write::replace_file(&path, self.html().as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        Ok(path)
    }

    /// The page as HTML.
    pub fn html(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\">\
             <meta name=\"viewport\" content=\"width=device-width, initial-scale=1\"><title>{t}</title>\n\
             <style>{STYLE}</style></head>\n\
             <body><h1>{t}</h1>\n{b}<p class=\"version\">wheelcal {v}</p></body></html>\n",
            t = escape(&self.title),
            b = self.body,
            v = env!("CARGO_PKG_VERSION")
        )
    }
}

/// The pages' style: a column at most 1100 px wide; text, table cells and the folded
/// output wrap anywhere rather than widen the page (no sideways scroll at any width);
/// figures at most the column's width.
const STYLE: &str = "body{font-family:sans-serif;max-width:1100px;margin:1.5em auto;padding:0 1em;color:#222;line-height:1.4;overflow-wrap:break-word}\
h1{font-size:1.6em;margin:0 0 .4em}h2{font-size:1.25em;margin:1.4em 0 .4em;border-bottom:1px solid #ddd}\
.answer{font-size:1.15em;font-weight:bold;background:#eef4fb;border-left:5px solid #2a6fb0;padding:.5em .8em}\
table{border-collapse:collapse;margin:.6em 0;max-width:100%}td,th{border:1px solid #bbb;padding:3px 8px;text-align:left;vertical-align:top}\
th{background:#f2f2f2}td.n{text-align:right;white-space:nowrap}\
figure{margin:1.2em 0}img{max-width:100%;height:auto;display:block}figcaption{color:#444;margin:.3em 0}\
pre{white-space:pre-wrap;overflow-wrap:anywhere;background:#f4f4f4;padding:8px;max-width:100%;box-sizing:border-box}\
pre.cmd{background:#1f2933;color:#f5f7fa;font-size:1.05em}\
details{margin:1.5em 0}summary{cursor:pointer;font-weight:bold}.version{color:#777}";

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
