//! Calibration computations on measured runs (formats.md §3), shared by the `compute`
//! commands, the guided procedures and the demo.

pub mod circles;
pub mod omni;
pub mod omni_circles;
pub mod plausible;
pub mod procedure;
pub mod saved;
pub mod umbmark;
