//! sim: a deterministic simulator of wheelcal's robots with the faults the papers measure.
//!
//! The simulator is what a board would see, not a rendering: per-wheel actuator inputs go
//! in at the control rate (1 kHz by default), raw 16-bit wrapping encoder counters, a
//! "vision" pose at 30 Hz and an IMU yaw rate come out, and the ground truth pose is kept
//! separately so tests can compare.
//!
//! Layers, one module each:
//! - [`effects`]: the diagnose catalogue (issue 7) as an [`Effect`] enum with a parser for
//!   `ID=name:value,...` strings, folded into [`Faults`] and a [`Surface`];
//! - [`motor`] (DC: duty -> voltage -> torque), [`stepper`] (steps, pull-out), [`actuator`]
//!   (one wheel: input -> motor angle -> backlash -> wheel angle);
//! - [`encoder`]: quadrature counts of the wheel or motor shaft, 16-bit wrapping;
//! - [`body`]: the actual (faulty) geometry, leg angles, least-squares body motion;
//! - [`ground`]: traction limit, cable crossings, side slip, roughness;
//! - [`surface`]: floor features in world coordinates;
//! - [`sensors`]: vision and IMU noise models;
//! - [`robot`]: [`SimRobot`], the stepped simulation;
//! - [`record`]: whole runs to formats.md §2 recordings with the truth kept beside.
//!
//! Determinism: every random draw comes from ChaCha8 streams seeded from
//! [`SimConfig::seed`]; the same seed and inputs give the same outputs bit for bit.

pub mod actuator;
pub mod body;
pub mod effects;
pub mod encoder;
pub mod error;
pub mod ground;
pub mod motor;
pub mod record;
pub mod robot;
pub mod sensors;
pub mod stepper;
pub mod surface;

pub use effects::{Effect, EffectError, Faults};
pub use error::SimError;
pub use motor::DcParams;
pub use record::{record, LegMotion, Motion, RandomMotion, RecordConfig, SimRecording, TruthRow};

pub use actuator::WheelInput;
pub use robot::{EncoderMount, SimConfig, SimRobot};
pub use sensors::{ImuConfig, VisionConfig};
pub use surface::{CableStrip, Patch, Surface, Tilt};

/// Standard gravity, m/s^2 (traction limits).
pub const G: f64 = 9.81;
