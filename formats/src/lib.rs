//! formats: the host's readers and writers of wheelcal's files (`docs/formats.md`):
//! robot descriptions (TOML, §1), recordings (CSV, §2) and runs files (CSV, §3).
//!
//! They live apart from calib-core because they need std, csv and toml, while calib-core
//! is the `no_std` core the firmware links. Every error names the file, line and column.

pub mod catalogue;
pub mod decimate;
pub mod recording;
pub mod robot_file;
pub mod runs_file;
pub mod safe_write;
pub mod text_file;
