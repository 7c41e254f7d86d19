//! Per-wheel mechanisms (each wheel its own copy of one parameter) and the one-value
//! form each stands beside: a per-wheel form is tried only where one value leaves the
//! stage outside the noise, and kept only where it holds out clearly better than one
//! value for every wheel.

use crate::effects::Effect;

/// A per-wheel mechanism is kept only when its held-out ratio is below this share of the
/// one-value form's: each wheel its own value must halve what one value for every wheel
/// leaves held out, not just fit a rugged cost more closely. Measured
/// (`per_wheel_traction.rs`): on equal traction the two mus came out 0.118 and 0.121
/// (their fit sigmas 6e-5: a rugged cost's sigmas say nothing), beat one mu by 44 in BIC
/// and held out at 0.90 of one mu's ratio; a payload off-centre at 0.012 of it and a
/// slipping hub at 0.001.
pub const PER_WHEEL_HELDOUT_SHARE: f64 = 0.5;

/// The one-value mechanism whose per-wheel form `e` is (each wheel its own copy of the
/// same parameter), if it has one.
pub(super) fn one_value_form(e: Effect) -> Option<Effect> {
    match e {
        Effect::SlipPerWheel => Some(Effect::LongitudinalSlip),
        Effect::BacklashPerWheel => Some(Effect::Backlash),
        Effect::LagPerWheel => Some(Effect::MotorLag),
        Effect::DelayPerWheel => Some(Effect::LagDelay),
        Effect::SlewPerWheel => Some(Effect::LagSlew),
        Effect::DeadBandPerWheel => Some(Effect::CoulombFriction),
        _ => None,
    }
}
