//! fitkit: what calibrate and diagnose both fit with. The Levenberg-Marquardt solver
//! (`fit`), the robot a geometry vector describes (`geometry`), series helpers
//! (`series`), residual noise statistics (`noise`), the time-step floor, and the plot
//! kit their reports draw with (`plot`). Neither product is imported here: both stand
//! on it.

pub mod fit;
pub mod geometry;
pub mod noise;
pub mod plot;
pub mod series;

/// Shortest time step divided by (s): two rows a nanosecond apart are one instant
/// written twice, and a rate over them must stay finite rather than blow up.
pub const MIN_DT_S: f64 = 1e-9;
