//! Mechanism families (issue 11): every catalogue effect can come about in more than one
//! physical way; each is fitted as a variant and the best is named in the finding.

use crate::effects::Effect;

/// The mechanism a plain catalogue fit stands for.
pub fn default_name(e: Effect) -> &'static str {
    match e {
        Effect::WheelDiameterMismatch | Effect::WheelbaseError => "geometry",
        Effect::LongitudinalSlip => "wheel",
        Effect::LateralSlip => "linear",
        Effect::FloorBumps => "whole",
        Effect::Backlash => "symmetric",
        Effect::MissedSteps => "pull_out",
        Effect::MotorLag => "first_order",
        Effect::CoulombFriction => "dead_band",
    }
}
