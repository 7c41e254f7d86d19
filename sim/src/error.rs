//! One error type for everything the simulator refuses: user input never panics.

use formats::catalogue::EFFECT_IDS;
use std::fmt;

/// Why a simulation could not be built or run.
#[derive(Debug)]
pub enum SimError {
    /// A bad `--effect` string or parameter.
    Effect(EffectError),
    /// A configuration value out of range: which one and why.
    Config {
        /// The configuration value's name.
        field: &'static str,
        /// Why it is refused.
        message: String,
    },
    /// The effect does not apply to this robot (e.g. missed steps on a DC drive).
    NotApplicable {
        /// The effect's id.
        effect: &'static str,
        /// Why it does not apply.
        reason: String,
    },
    /// The driven wheels (with the faults applied) cannot determine the body motion.
    SingularGeometry,
    /// `step` got a different number of inputs than the robot has wheels.
    InputCount {
        /// Wheels the robot has.
        expected: usize,
        /// Inputs given.
        got: usize,
    },
    /// A robot description built by the simulator failed calib-core's validation.
    Robot(calib_core::robot::RobotError),
    /// Writing a recording failed.
    Io {
        /// The file.
        path: std::path::PathBuf,
        /// The I/O error.
        error: std::io::Error,
    },
}

impl fmt::Display for SimError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SimError::Effect(e) => write!(f, "{e}"),
            SimError::Config { field, message } => write!(f, "{field}: {message}"),
            SimError::NotApplicable { effect, reason } => {
                write!(f, "effect {effect} does not apply: {reason}")
            }
            SimError::SingularGeometry => write!(
                f,
                "the driven wheels cannot determine the body motion (rank < 3)"
            ),
            SimError::InputCount { expected, got } => {
                write!(f, "expected {expected} wheel inputs, got {got}")
            }
            SimError::Robot(e) => write!(f, "robot: {e}"),
            // The OS error is the `source()`.
            SimError::Io { path, .. } => write!(f, "cannot write {}", path.display()),
        }
    }
}

impl std::error::Error for SimError {
    /// The OS error under a failed write stays an error (not text) so callers can walk
    /// the chain; an effect error is shown as itself (transparent).
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SimError::Io { error, .. } => Some(error),
            _ => None,
        }
    }
}

impl From<EffectError> for SimError {
    fn from(e: EffectError) -> Self {
        SimError::Effect(e)
    }
}

/// Checks a configuration number is finite and within `[lo, hi]`.
pub(crate) fn check_range(field: &'static str, v: f64, lo: f64, hi: f64) -> Result<(), SimError> {
    if !v.is_finite() {
        return Err(SimError::Config {
            field,
            message: format!("must be a finite number, got {v}"),
        });
    }
    if v < lo || v > hi {
        return Err(SimError::Config {
            field,
            message: format!("must be within [{lo}, {hi}], got {v}"),
        });
    }
    Ok(())
}

/// A bad effect string or parameter.
#[derive(Debug, Clone, PartialEq)]
pub enum EffectError {
    /// An id not in the catalogue ([`EFFECT_IDS`]).
    UnknownEffect(String),
    /// A parameter the effect does not have.
    UnknownParameter {
        /// The effect's id.
        effect: String,
        /// The parameter's name.
        name: String,
    },
    /// `name:value` without a colon, or a value that is not a number.
    Malformed {
        /// The offending text.
        text: String,
        /// What is wrong with it.
        reason: String,
    },
    /// A value outside what is physically possible.
    OutOfRange {
        /// The effect's id.
        effect: &'static str,
        /// The parameter's name.
        name: String,
        /// The value given.
        value: f64,
        /// What the value must be (e.g. "within [0.5, 2]").
        expected: &'static str,
    },
    /// A required parameter is missing.
    MissingParameter {
        /// The effect's id.
        effect: &'static str,
        /// The parameter's name.
        name: &'static str,
    },
    /// `radius_scale_<wheel>` names a wheel the robot does not have.
    UnknownWheel {
        /// The wheel name given.
        name: String,
    },
}

impl fmt::Display for EffectError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EffectError::UnknownEffect(id) => write!(
                f,
                "unknown effect '{id}' (known: {})",
                EFFECT_IDS.join(", ")
            ),
            EffectError::UnknownParameter { effect, name } => {
                write!(f, "effect {effect}: unknown parameter '{name}'")
            }
            EffectError::Malformed { text, reason } => write!(f, "'{text}': {reason}"),
            EffectError::OutOfRange {
                effect,
                name,
                value,
                expected,
            } => write!(f, "effect {effect}: {name} = {value} must be {expected}"),
            EffectError::MissingParameter { effect, name } => {
                write!(f, "effect {effect}: parameter {name} is required")
            }
            EffectError::UnknownWheel { name } => write!(
                f,
                "effect wheel_diameter_mismatch: the robot has no wheel '{name}'"
            ),
        }
    }
}

impl std::error::Error for EffectError {}
