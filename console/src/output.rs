//! Output conventions: a human summary by default, or with `--json` exactly one JSON
//! object on stdout and nothing else there (docs/formats.md §4).

use serde::Serialize;

/// Where results go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Output {
    /// A human summary on stdout.
    Human,
    /// Exactly one JSON object on stdout.
    Json,
}

impl Output {
    /// `Json` when `--json` was given, else `Human`.
    pub fn from_flag(json: bool) -> Self {
        if json {
            Output::Json
        } else {
            Output::Human
        }
    }

    /// Prints a result: JSON as one line, or the human text.
    pub fn emit<T: Serialize>(
        self,
        value: &T,
        human: impl FnOnce() -> String,
    ) -> anyhow::Result<()> {
        // A reader that went away (`| head`) is not an error of ours.
        self.emit_more(value, human).map(|_| ())
    }

    /// [`Output::emit`] for one result of a stream: `false` when the reader has gone
    /// (a broken pipe, `| head -1`), so the stream ends and releases what it holds (the
    /// port) instead of writing into nothing forever.
    pub fn emit_more<T: Serialize>(
        self,
        value: &T,
        human: impl FnOnce() -> String,
    ) -> anyhow::Result<bool> {
        let text = match self {
            Output::Json => format!("{}\n", serde_json::to_string(value)?),
            Output::Human => human(),
        };
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
            Ok(()) => Ok(true),
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(false),
            // Standard output is a file or device that failed (`> /dev/full`): say so.
            Err(e) => Err(anyhow::anyhow!("cannot write to standard output: {e}")),
        }
    }

    /// Progress and notes go to stderr so stdout stays machine-readable.
    pub fn note(self, text: &str) {
        eprintln!("{text}");
    }
}

/// A point in metres, serialised as `{x_m, y_m}`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PointM {
    /// x, m.
    pub x_m: f64,
    /// y, m.
    pub y_m: f64,
}

impl From<(f64, f64)> for PointM {
    fn from(p: (f64, f64)) -> Self {
        PointM { x_m: p.0, y_m: p.1 }
    }
}
