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
        let text = match self {
            Output::Json => format!("{}\n", serde_json::to_string(value)?),
            Output::Human => human(),
        };
        use std::io::Write;
        let mut out = std::io::stdout().lock();
        match out.write_all(text.as_bytes()).and_then(|_| out.flush()) {
            // A reader that went away (`| head`) is not an error of ours.
            Err(e) if e.kind() == std::io::ErrorKind::BrokenPipe => Ok(()),
            r => r.map_err(Into::into),
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
