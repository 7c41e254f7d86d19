//! The importer's error: what is wrong, with what the bag holds so the user can pick the
//! right topic, joint or frame without another tool.

use std::fmt;
use std::path::PathBuf;

/// A bag that cannot be imported as asked.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportError {
    /// The bag (folder or file) or the file inside it the problem is in.
    pub path: PathBuf,
    /// What is wrong, and what the bag holds instead.
    pub message: String,
}

impl ImportError {
    /// An error about `path`.
    pub fn new(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        ImportError {
            path: path.into(),
            message: message.into(),
        }
    }
}

impl fmt::Display for ImportError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for ImportError {}
