//! Why calibration cannot run ([`CalibrateError`]). Kept at the bottom of calibrate's
//! modules: reading a recording ([`Series::new`](crate::Series::new)) refuses
//! with it as the checks before and after the fit do.

use std::fmt;

/// Why calibration cannot run.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateError {
    /// The recording at fault (its name as given), if one is.
    pub recording: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for CalibrateError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.recording {
            Some(r) => write!(f, "{r}: {}", self.message),
            None => f.write_str(&self.message),
        }
    }
}

impl std::error::Error for CalibrateError {}
