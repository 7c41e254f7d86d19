//! sim: a deterministic simulator of wheelcal's robots with the faults the papers measure.
//!
//! The simulator is what a board would see, not a rendering: per-wheel actuator inputs go
//! in at the control rate (1 kHz by default), raw 16-bit wrapping encoder counters, a
//! "vision" pose at 30 Hz and an IMU yaw rate come out, and the ground truth pose is kept
//! separately so tests can compare.
//!
//! Layers, one module each:
//! - [`effects`]: the diagnose catalogue as an [`Effect`] enum with a parser for
//!   `ID=name:value,...` strings, folded into [`Faults`] and a [`Surface`];
//! - [`motor`] (DC: duty -> voltage -> torque), [`stepper`] (steps, pull-out), [`actuator`]
//!   (one wheel: input -> motor angle -> backlash -> wheel angle);
//! - [`encoder`]: quadrature counts of the wheel or motor shaft, 16-bit wrapping;
//! - [`body`]: the actual (faulty) geometry, leg angles, least-squares body motion;
//! - [`ground`]: traction limit, cable crossings, side slip, roughness;
//! - [`surface`]: floor features in world coordinates;
//! - [`sensors`]: vision and IMU noise models;
//! - [`robot`]: [`SimRobot`], the stepped simulation;
//! - [`mod@record`]: whole runs to docs/formats.md §2 recordings with the truth kept beside.
//!
//! A board's view, one tick at a time:
//!
//! ```
//! use calib_core::odometry::Pose;
//! use calib_core::robot::presets;
//! use sim::{Effect, SimConfig, SimRobot, Surface, WheelInput};
//!
//! let robot = presets::omni4();
//! let effects = [Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0008")?];
//! // Start between two cables (exactly on one, rounding decides which side a wheel is).
//! let cfg = SimConfig { start: Pose::new(0.001, 0.0, 0.0), ..SimConfig::default() };
//! let mut sim = SimRobot::with_effects(&robot, &effects, Surface::flat(), cfg)?;
//! for _ in 0..1000 {
//!     // 0.1 m/s along body x: wheels 1 and 3 at +-0.1/0.03 rad/s.
//!     let w = 0.1 / 0.03;
//!     sim.step(1e-3, &[WheelInput::Rate(w), WheelInput::Rate(0.0), WheelInput::Rate(-w), WheelInput::Rate(0.0)])?;
//!     let _raw: u16 = sim.encoder_raw(0); // what the timer shows
//!     if let Some((_t, _pose)) = sim.vision() { /* a 30 Hz camera frame */ }
//! }
//! // 0.1 m commanded, three cables crossed at 0.8 mm each.
//! assert!((sim.true_pose().x - (0.101 - 3.0 * 0.0008)).abs() < 1e-9);
//! # Ok::<(), sim::SimError>(())
//! ```
//!
//! Whole runs: [`record()`] (robot + effects + [`Motion`] + seed -> docs/formats.md §2
//! recording and truth), [`SimRecording::write_dir`] (CSV + robot TOML + truth).
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
pub mod skid;
pub mod stepper;
pub mod surface;

pub use effects::{Effect, EffectError, Faults};
pub use error::SimError;
pub use motor::DcParams;
pub use record::{
    record, ActuatorMode, LegMotion, Motion, RandomMotion, RecordConfig, SimRecording, TruthRow,
};

pub use actuator::WheelInput;
pub use robot::{EncoderMount, SimConfig, SimRobot};
pub use sensors::{ImuConfig, VisionConfig};
pub use skid::Tyre;
pub use surface::{CableStrip, Patch, Surface, Tilt};

/// Standard gravity, m/s^2 (traction limits).
pub const G: f64 = 9.81;
