//! Diagnose: placeholder.
