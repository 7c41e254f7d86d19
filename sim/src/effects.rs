//! The diagnose catalogue as data: [`Effect`] with exactly the catalogue's
//! parameter names, a parser for `ID=name:value,name:value` strings (the `--effect`
//! argument of `wheelcal sim record`), and [`Faults`], the per-robot numbers the simulator
//! runs with once the effects are folded in.
//!
//! Everything here validates: a negative mu or a NaN is an [`EffectError`] naming the
//! effect and parameter, never a panic.

use crate::surface::{CableStrip, Surface, Tilt};
use calib_core::robot::{DriveType, Robot, RobotKind};
use formats::catalogue as cat;
use std::fmt;

/// One effect of the catalogue (plus `tilted_floor`, deliberately outside it).
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// `ed` = D_right / D_left (differential drive, mean diameter kept), and/or
    /// `radius_scale_<wheel>` = actual / nominal radius of one wheel.
    WheelDiameterMismatch {
        /// D_right / D_left (differential drive), if given.
        ed: Option<f64>,
        /// (wheel name, actual / nominal radius) per `radius_scale_<wheel>` given.
        radius_scale: Vec<(String, f64)>,
    },
    /// `eb` = actual / nominal wheel separation (every wheel's l).
    WheelbaseError {
        /// Actual / nominal wheel separation.
        eb: f64,
    },
    /// `mu`: acceleration bounded by mu * g * (load share on driven wheels). Mechanisms:
    /// `wheel` (each wheel's contact speed, the default), `body` (the body's linear
    /// acceleration; heading unaffected), `creep` (no hard limit: each contact slips by
    /// `creep_s` times its acceleration, i.e. slip proportional to the drive force).
    LongitudinalSlip {
        /// Friction coefficient (dimensionless).
        mu: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `creep`: slip per unit of contact acceleration (s).
        creep_s: f64,
    },
    /// `side_slip_s` = k in v_y = -k * v_x * omega (`linear`), or `saturating`:
    /// v_y = -sat tanh(k v_x omega / sat) with `sat_m_s` the largest side-slip speed.
    LateralSlip {
        /// k in v_y = -k * v_x * omega (s).
        side_slip_s: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `saturating`: largest side-slip speed (m/s).
        sat_m_s: f64,
    },
    /// `spacing_m`, `loss_m`: cables across the floor (perpendicular to world x), each
    /// costing a wheel `loss_m` of travel. Mechanisms: `whole` floor (default), `region`
    /// (only for `start_m` <= world x <= `end_m`), `irregular` (each cable moved by up to
    /// `jitter` spacings, pseudo-randomly).
    FloorBumps {
        /// Distance between cables along world x (m).
        spacing_m: f64,
        /// Travel a wheel loses crossing one cable (m).
        loss_m: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `region`: where the cables start, world x (m).
        start_m: f64,
        /// `region`: where the cables end, world x (m).
        end_m: f64,
        /// `irregular`: largest shift of a cable, in spacings.
        jitter: f64,
    },
    /// `backlash_rad`: total dead band between motor and wheel, in wheel radians
    /// (`symmetric`), or `asymmetric`: `backlash_rad * (1 + asymmetry)` lost when the motor
    /// turns forward again, `backlash_rad * (1 - asymmetry)` when it turns backward.
    Backlash {
        /// Total dead band between motor and wheel (wheel rad).
        backlash_rad: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `asymmetric`: the share by which forward and backward play differ.
        asymmetry: f64,
    },
    /// `max_accel_rad_s2`: the stepper loses synchronism above this wheel acceleration.
    /// Mechanisms: `pull_out` (rotor dynamics, default), `quanta` (while the commanded
    /// acceleration is over the limit, one electrical cycle of four full steps is dropped
    /// at random, `rate_hz` times a second on average), `stall` (over the limit the rotor
    /// stops until the command comes back to rest).
    MissedSteps {
        /// Largest wheel acceleration the stepper follows (rad/s^2).
        max_accel_rad_s2: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `quanta`: mean rate of dropped electrical cycles while over the limit (Hz).
        rate_hz: f64,
    },
    /// `tau_s`: first-order lag of the wheel rate behind the command (`first_order`), or a
    /// pure transport `delay` of `tau_s`, or a `slew` limit of `slew_rad_s2` on the rate.
    MotorLag {
        /// Time constant (first order) or delay (s).
        tau_s: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
        /// `slew`: largest change of the wheel rate (rad/s^2).
        slew_rad_s2: f64,
    },
    /// `deadband_rad_s`: the wheel stays still while |command| is below it (`dead_band`).
    CoulombFriction {
        /// Command below which the wheel stays still (rad/s).
        deadband_rad_s: f64,
        /// How the effect is produced (see the variant's doc).
        mechanism: Mechanism,
    },
    /// Not in the catalogue: a constant world drift `drift_m_s` towards `direction_rad`
    /// while the robot moves.
    TiltedFloor {
        /// Drift speed while moving (m/s).
        drift_m_s: f64,
        /// World direction of the drift (rad).
        direction_rad: f64,
    },
}

pub use crate::error::EffectError;
pub use formats::catalogue::EFFECT_IDS;

/// How an effect comes about: every catalogue effect has several physical mechanisms,
/// chosen with `mechanism:<name>` in the effect string.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Mechanism {
    /// longitudinal_slip: per-wheel traction limit.
    Wheel,
    /// longitudinal_slip: bound on the body's linear acceleration.
    Body,
    /// longitudinal_slip: slip proportional to the drive force, no hard limit.
    Creep,
    /// lateral_slip: v_y = -k v_x omega.
    Linear,
    /// lateral_slip: slip speed saturating at `sat_m_s`.
    Saturating,
    /// floor_bumps: cables over the whole floor.
    Whole,
    /// floor_bumps: cables only in a strip of the floor.
    Region,
    /// floor_bumps: irregular spacing.
    Irregular,
    /// backlash: same play both ways.
    Symmetric,
    /// backlash: different loss on the two reversal directions.
    Asymmetric,
    /// missed_steps: rotor pull-out dynamics.
    PullOut,
    /// missed_steps: random quanta of four full steps while over the limit.
    Quanta,
    /// missed_steps: full stall until the command rests.
    Stall,
    /// motor_lag: first-order lag.
    FirstOrder,
    /// motor_lag: transport delay.
    Delay,
    /// motor_lag: slew-rate limit.
    Slew,
    /// coulomb_friction: dead band around zero command.
    DeadBand,
}

impl Mechanism {
    /// (mechanism, name, effect id) of every mechanism the simulator makes, from the one
    /// catalogue table ([`formats::catalogue`]).
    pub const ALL: [(Mechanism, &'static str, &'static str); 17] = [
        (Mechanism::Wheel, cat::MECH_WHEEL.0, cat::MECH_WHEEL.1),
        (Mechanism::Body, cat::MECH_BODY.0, cat::MECH_BODY.1),
        (Mechanism::Creep, cat::MECH_CREEP.0, cat::MECH_CREEP.1),
        (Mechanism::Linear, cat::MECH_LINEAR.0, cat::MECH_LINEAR.1),
        (
            Mechanism::Saturating,
            cat::MECH_SATURATING.0,
            cat::MECH_SATURATING.1,
        ),
        (Mechanism::Whole, cat::MECH_WHOLE.0, cat::MECH_WHOLE.1),
        (Mechanism::Region, cat::MECH_REGION.0, cat::MECH_REGION.1),
        (
            Mechanism::Irregular,
            cat::MECH_IRREGULAR.0,
            cat::MECH_IRREGULAR.1,
        ),
        (
            Mechanism::Symmetric,
            cat::MECH_SYMMETRIC.0,
            cat::MECH_SYMMETRIC.1,
        ),
        (
            Mechanism::Asymmetric,
            cat::MECH_ASYMMETRIC.0,
            cat::MECH_ASYMMETRIC.1,
        ),
        (
            Mechanism::PullOut,
            cat::MECH_PULL_OUT.0,
            cat::MECH_PULL_OUT.1,
        ),
        (Mechanism::Quanta, cat::MECH_QUANTA.0, cat::MECH_QUANTA.1),
        (Mechanism::Stall, cat::MECH_STALL.0, cat::MECH_STALL.1),
        (
            Mechanism::FirstOrder,
            cat::MECH_FIRST_ORDER.0,
            cat::MECH_FIRST_ORDER.1,
        ),
        (Mechanism::Delay, cat::MECH_DELAY.0, cat::MECH_DELAY.1),
        (Mechanism::Slew, cat::MECH_SLEW.0, cat::MECH_SLEW.1),
        (
            Mechanism::DeadBand,
            cat::MECH_DEAD_BAND.0,
            cat::MECH_DEAD_BAND.1,
        ),
    ];

    /// The name used in `--effect ID=...,mechanism:NAME`.
    pub fn name(self) -> &'static str {
        Mechanism::ALL
            .iter()
            .find(|m| m.0 == self)
            .map_or("?", |m| m.1)
    }

    /// The catalogue id this mechanism belongs to.
    pub fn effect(self) -> &'static str {
        Mechanism::ALL
            .iter()
            .find(|m| m.0 == self)
            .map_or("?", |m| m.2)
    }

    /// The mechanism called `name` for effect `id`.
    pub fn parse(id: &str, name: &str) -> Option<Mechanism> {
        Mechanism::ALL
            .iter()
            .find(|m| m.1 == name && m.2 == id)
            .map(|m| m.0)
    }

    /// The first (default) mechanism of an effect.
    pub fn default_for(id: &str) -> Option<Mechanism> {
        Mechanism::ALL.iter().find(|m| m.2 == id).map(|m| m.0)
    }
}

fn range(
    effect: &'static str,
    name: &str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), EffectError> {
    if value.is_finite() && ok {
        Ok(())
    } else {
        Err(EffectError::OutOfRange {
            effect,
            name: name.to_string(),
            value,
            expected,
        })
    }
}

impl Effect {
    /// The catalogue id.
    pub fn id(&self) -> &'static str {
        match self {
            Effect::WheelDiameterMismatch { .. } => EFFECT_IDS[0],
            Effect::WheelbaseError { .. } => EFFECT_IDS[1],
            Effect::LongitudinalSlip { .. } => EFFECT_IDS[2],
            Effect::LateralSlip { .. } => EFFECT_IDS[3],
            Effect::FloorBumps { .. } => EFFECT_IDS[4],
            Effect::Backlash { .. } => EFFECT_IDS[5],
            Effect::MissedSteps { .. } => EFFECT_IDS[6],
            Effect::MotorLag { .. } => EFFECT_IDS[7],
            Effect::CoulombFriction { .. } => EFFECT_IDS[8],
            Effect::TiltedFloor { .. } => EFFECT_IDS[9],
        }
    }

    /// The mechanism, for effects that have several.
    pub fn mechanism(&self) -> Option<Mechanism> {
        match self {
            Effect::LongitudinalSlip { mechanism, .. }
            | Effect::LateralSlip { mechanism, .. }
            | Effect::FloorBumps { mechanism, .. }
            | Effect::Backlash { mechanism, .. }
            | Effect::MissedSteps { mechanism, .. }
            | Effect::MotorLag { mechanism, .. }
            | Effect::CoulombFriction { mechanism, .. } => Some(*mechanism),
            _ => None,
        }
    }

    fn mechanism_mut(&mut self) -> Option<&mut Mechanism> {
        match self {
            Effect::LongitudinalSlip { mechanism, .. }
            | Effect::LateralSlip { mechanism, .. }
            | Effect::FloorBumps { mechanism, .. }
            | Effect::Backlash { mechanism, .. }
            | Effect::MissedSteps { mechanism, .. }
            | Effect::MotorLag { mechanism, .. }
            | Effect::CoulombFriction { mechanism, .. } => Some(mechanism),
            _ => None,
        }
    }

    /// Parameters as (name, value), with the catalogue's names (plus the mechanism's own).
    pub fn params(&self) -> Vec<(String, f64)> {
        let p = |n: &str, v: f64| (n.to_string(), v);
        match self {
            Effect::WheelDiameterMismatch { ed, radius_scale } => {
                let mut v: Vec<_> = ed.iter().map(|e| p("ed", *e)).collect();
                for (w, s) in radius_scale {
                    v.push((format!("radius_scale_{w}"), *s));
                }
                v
            }
            Effect::WheelbaseError { eb } => vec![p("eb", *eb)],
            Effect::LongitudinalSlip {
                mu,
                mechanism,
                creep_s,
            } => match mechanism {
                Mechanism::Creep => vec![p("creep_s", *creep_s)],
                _ => vec![p("mu", *mu)],
            },
            Effect::LateralSlip {
                side_slip_s,
                mechanism,
                sat_m_s,
            } => {
                let mut v = vec![p("side_slip_s", *side_slip_s)];
                if *mechanism == Mechanism::Saturating {
                    v.push(p("sat_m_s", *sat_m_s));
                }
                v
            }
            Effect::FloorBumps {
                spacing_m,
                loss_m,
                mechanism,
                start_m,
                end_m,
                jitter,
            } => {
                let mut v = vec![p("spacing_m", *spacing_m), p("loss_m", *loss_m)];
                match mechanism {
                    Mechanism::Region => {
                        v.push(p("start_m", *start_m));
                        v.push(p("end_m", *end_m));
                    }
                    Mechanism::Irregular => v.push(p("jitter", *jitter)),
                    _ => {}
                }
                v
            }
            Effect::Backlash {
                backlash_rad,
                mechanism,
                asymmetry,
            } => {
                let mut v = vec![p("backlash_rad", *backlash_rad)];
                if *mechanism == Mechanism::Asymmetric {
                    v.push(p("asymmetry", *asymmetry));
                }
                v
            }
            Effect::MissedSteps {
                max_accel_rad_s2,
                mechanism,
                rate_hz,
            } => {
                let mut v = vec![p("max_accel_rad_s2", *max_accel_rad_s2)];
                if *mechanism == Mechanism::Quanta {
                    v.push(p("rate_hz", *rate_hz));
                }
                v
            }
            Effect::MotorLag {
                tau_s,
                mechanism,
                slew_rad_s2,
            } => match mechanism {
                Mechanism::Slew => vec![p("slew_rad_s2", *slew_rad_s2)],
                _ => vec![p("tau_s", *tau_s)],
            },
            Effect::CoulombFriction { deadband_rad_s, .. } => {
                vec![p("deadband_rad_s", *deadband_rad_s)]
            }
            Effect::TiltedFloor {
                drift_m_s,
                direction_rad,
            } => vec![
                p("drift_m_s", *drift_m_s),
                p("direction_rad", *direction_rad),
            ],
        }
    }

    /// Parses `ID` or `ID=name:value,name:value`. Missing parameters take the defaults
    /// of [`Effect::default_for`]; unknown ones are errors.
    pub fn parse(text: &str) -> Result<Effect, EffectError> {
        let text = text.trim();
        let (id, rest) = match text.split_once('=') {
            Some((id, rest)) => (id.trim(), Some(rest)),
            None => (text, None),
        };
        let mut effect = Effect::default_for(id)?;
        let mut ed_given = false;
        if let Some(rest) = rest {
            for item in rest.split(',').map(str::trim).filter(|s| !s.is_empty()) {
                let (name, value) = item.split_once(':').ok_or_else(|| EffectError::Malformed {
                    text: item.to_string(),
                    reason: "expected name:value".into(),
                })?;
                let (name, value) = (name.trim(), value.trim());
                if name == "mechanism" {
                    let id = effect.id();
                    let m = Mechanism::parse(id, value).ok_or_else(|| EffectError::Malformed {
                        text: item.to_string(),
                        reason: format!(
                            "'{value}' is not a mechanism of {id} (known: {})",
                            Mechanism::ALL
                                .iter()
                                .filter(|m| m.2 == id)
                                .map(|m| m.1)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    })?;
                    match effect.mechanism_mut() {
                        Some(slot) => *slot = m,
                        None => {
                            return Err(EffectError::UnknownParameter {
                                effect: id.to_string(),
                                name: name.to_string(),
                            })
                        }
                    }
                    continue;
                }
                let v: f64 = value.parse().map_err(|_| EffectError::Malformed {
                    text: item.to_string(),
                    reason: format!("'{value}' is not a number"),
                })?;
                if name == "ed" {
                    ed_given = true;
                }
                effect.set_param(name, v)?;
            }
        }
        // Giving only radius scales means no ed.
        if let Effect::WheelDiameterMismatch { ed, radius_scale } = &mut effect {
            if !ed_given && !radius_scale.is_empty() {
                *ed = None;
            }
        }
        effect.validate()?;
        Ok(effect)
    }

    /// The effect with typical, clearly visible parameters.
    pub fn default_for(id: &str) -> Result<Effect, EffectError> {
        Ok(match id {
            cat::WHEEL_DIAMETER_MISMATCH => Effect::WheelDiameterMismatch {
                ed: Some(1.01),
                radius_scale: Vec::new(),
            },
            cat::WHEELBASE_ERROR => Effect::WheelbaseError { eb: 1.03 },
            cat::LONGITUDINAL_SLIP => Effect::LongitudinalSlip {
                mu: 0.3,
                mechanism: Mechanism::Wheel,
                creep_s: 0.05,
            },
            cat::LATERAL_SLIP => Effect::LateralSlip {
                side_slip_s: 0.05,
                mechanism: Mechanism::Linear,
                sat_m_s: 0.01,
            },
            cat::FLOOR_BUMPS => Effect::FloorBumps {
                spacing_m: 0.03,
                loss_m: 0.0008,
                mechanism: Mechanism::Whole,
                start_m: 0.0,
                end_m: 1.0,
                jitter: 0.4,
            },
            cat::BACKLASH => Effect::Backlash {
                backlash_rad: 0.05,
                mechanism: Mechanism::Symmetric,
                asymmetry: 0.5,
            },
            cat::MISSED_STEPS => Effect::MissedSteps {
                max_accel_rad_s2: 20.0,
                mechanism: Mechanism::PullOut,
                rate_hz: 10.0,
            },
            cat::MOTOR_LAG => Effect::MotorLag {
                tau_s: 0.1,
                mechanism: Mechanism::FirstOrder,
                slew_rad_s2: 20.0,
            },
            cat::COULOMB_FRICTION => Effect::CoulombFriction {
                deadband_rad_s: 0.5,
                mechanism: Mechanism::DeadBand,
            },
            cat::TILTED_FLOOR => Effect::TiltedFloor {
                drift_m_s: 0.005,
                direction_rad: std::f64::consts::FRAC_PI_2,
            },
            other => return Err(EffectError::UnknownEffect(other.to_string())),
        })
    }

    fn set_param(&mut self, name: &str, v: f64) -> Result<(), EffectError> {
        let unknown = |e: &Effect| EffectError::UnknownParameter {
            effect: e.id().to_string(),
            name: name.to_string(),
        };
        match (&mut *self, name) {
            (Effect::WheelDiameterMismatch { ed, .. }, "ed") => *ed = Some(v),
            (Effect::WheelDiameterMismatch { radius_scale, .. }, n)
                if n.starts_with("radius_scale_") && n.len() > "radius_scale_".len() =>
            {
                let wheel = n["radius_scale_".len()..].to_string();
                radius_scale.retain(|(w, _)| *w != wheel);
                radius_scale.push((wheel, v));
            }
            (Effect::WheelbaseError { eb }, "eb") => *eb = v,
            (Effect::LongitudinalSlip { mu, .. }, "mu") => *mu = v,
            (Effect::LongitudinalSlip { creep_s, .. }, "creep_s") => *creep_s = v,
            (Effect::LateralSlip { side_slip_s, .. }, "side_slip_s") => *side_slip_s = v,
            (Effect::LateralSlip { sat_m_s, .. }, "sat_m_s") => *sat_m_s = v,
            (Effect::FloorBumps { spacing_m, .. }, "spacing_m") => *spacing_m = v,
            (Effect::FloorBumps { loss_m, .. }, "loss_m") => *loss_m = v,
            (Effect::FloorBumps { start_m, .. }, "start_m") => *start_m = v,
            (Effect::FloorBumps { end_m, .. }, "end_m") => *end_m = v,
            (Effect::FloorBumps { jitter, .. }, "jitter") => *jitter = v,
            (Effect::Backlash { backlash_rad, .. }, "backlash_rad") => *backlash_rad = v,
            (Effect::Backlash { asymmetry, .. }, "asymmetry") => *asymmetry = v,
            (
                Effect::MissedSteps {
                    max_accel_rad_s2, ..
                },
                "max_accel_rad_s2",
            ) => *max_accel_rad_s2 = v,
            (Effect::MissedSteps { rate_hz, .. }, "rate_hz") => *rate_hz = v,
            (Effect::MotorLag { tau_s, .. }, "tau_s") => *tau_s = v,
            (Effect::MotorLag { slew_rad_s2, .. }, "slew_rad_s2") => *slew_rad_s2 = v,
            (Effect::CoulombFriction { deadband_rad_s, .. }, "deadband_rad_s") => {
                *deadband_rad_s = v
            }
            (Effect::TiltedFloor { drift_m_s, .. }, "drift_m_s") => *drift_m_s = v,
            (Effect::TiltedFloor { direction_rad, .. }, "direction_rad") => *direction_rad = v,
            (e, _) => return Err(unknown(e)),
        }
        Ok(())
    }

    /// Checks every parameter is finite and physically possible.
    pub fn validate(&self) -> Result<(), EffectError> {
        let id = self.id();
        match self {
            Effect::WheelDiameterMismatch { ed, radius_scale } => {
                if let Some(e) = ed {
                    range(id, "ed", *e, (0.5..=2.0).contains(e), "within [0.5, 2]")?;
                }
                for (w, s) in radius_scale {
                    let n = format!("radius_scale_{w}");
                    range(id, &n, *s, (0.5..=2.0).contains(s), "within [0.5, 2]")?;
                }
                if ed.is_none() && radius_scale.is_empty() {
                    return Err(EffectError::MissingParameter {
                        effect: id,
                        name: "ed",
                    });
                }
            }
            Effect::WheelbaseError { eb } => {
                range(id, "eb", *eb, (0.5..=2.0).contains(eb), "within [0.5, 2]")?
            }
            Effect::LongitudinalSlip { mu, creep_s, .. } => {
                range(id, "mu", *mu, *mu > 0.0, "positive")?;
                range(
                    id,
                    "creep_s",
                    *creep_s,
                    (0.0..=10.0).contains(creep_s),
                    "within [0, 10] s",
                )?;
            }
            Effect::LateralSlip {
                side_slip_s,
                sat_m_s,
                ..
            } => {
                range(
                    id,
                    "side_slip_s",
                    *side_slip_s,
                    side_slip_s.abs() <= 10.0,
                    "within [-10, 10] s",
                )?;
                range(id, "sat_m_s", *sat_m_s, *sat_m_s > 0.0, "positive")?;
            }
            Effect::FloorBumps {
                spacing_m,
                loss_m,
                start_m,
                end_m,
                jitter,
                ..
            } => {
                range(id, "start_m", *start_m, true, "finite")?;
                range(id, "end_m", *end_m, *end_m > *start_m, "above start_m")?;
                range(
                    id,
                    "jitter",
                    *jitter,
                    (0.0..0.5).contains(jitter),
                    "within [0, 0.5)",
                )?;
                range(id, "spacing_m", *spacing_m, *spacing_m > 0.0, "positive")?;
                range(
                    id,
                    "loss_m",
                    *loss_m,
                    *loss_m >= 0.0 && *loss_m < *spacing_m,
                    "non-negative and below spacing_m",
                )?;
            }
            Effect::Backlash {
                backlash_rad,
                asymmetry,
                ..
            } => {
                range(
                    id,
                    "backlash_rad",
                    *backlash_rad,
                    (0.0..=1.0).contains(backlash_rad),
                    "within [0, 1] rad",
                )?;
                range(
                    id,
                    "asymmetry",
                    *asymmetry,
                    (-1.0..=1.0).contains(asymmetry),
                    "within [-1, 1]",
                )?;
            }
            Effect::MissedSteps {
                max_accel_rad_s2,
                rate_hz,
                ..
            } => {
                range(
                    id,
                    "max_accel_rad_s2",
                    *max_accel_rad_s2,
                    *max_accel_rad_s2 > 0.0,
                    "positive",
                )?;
                range(
                    id,
                    "rate_hz",
                    *rate_hz,
                    (0.0..=1000.0).contains(rate_hz),
                    "within [0, 1000]",
                )?;
            }
            Effect::MotorLag {
                tau_s, slew_rad_s2, ..
            } => {
                range(
                    id,
                    "tau_s",
                    *tau_s,
                    (0.0..=10.0).contains(tau_s),
                    "within [0, 10] s",
                )?;
                range(
                    id,
                    "slew_rad_s2",
                    *slew_rad_s2,
                    *slew_rad_s2 > 0.0,
                    "positive",
                )?;
            }
            Effect::CoulombFriction { deadband_rad_s, .. } => range(
                id,
                "deadband_rad_s",
                *deadband_rad_s,
                *deadband_rad_s >= 0.0,
                "non-negative",
            )?,
            Effect::TiltedFloor {
                drift_m_s,
                direction_rad,
            } => {
                range(
                    id,
                    "drift_m_s",
                    *drift_m_s,
                    drift_m_s.abs() <= 1.0,
                    "within [-1, 1] m/s",
                )?;
                range(id, "direction_rad", *direction_rad, true, "finite")?;
            }
        }
        Ok(())
    }
}

impl fmt::Display for Effect {
    /// The `ID=name:value,...` form [`Effect::parse`] reads back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.id())?;
        let mut first = true;
        let mut sep = |f: &mut fmt::Formatter<'_>| {
            let c = if first { '=' } else { ',' };
            first = false;
            write!(f, "{c}")
        };
        if let Some(m) = self.mechanism() {
            if Mechanism::default_for(self.id()) != Some(m) {
                sep(f)?;
                write!(f, "mechanism:{}", m.name())?;
            }
        }
        for (n, v) in self.params() {
            sep(f)?;
            write!(f, "{n}:{v}")?;
        }
        Ok(())
    }
}

/// The numbers the simulator runs with: nominal = all neutral ([`Faults::none`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Faults {
    /// Actual / nominal radius per wheel (robot order).
    pub radius_scale: Vec<f64>,
    /// Actual / nominal distance of every wheel from the body origin.
    pub wheelbase_scale: f64,
    /// Friction coefficient; `None` = unlimited traction (pure rolling).
    pub mu: Option<f64>,
    /// Share of the weight on the driven wheels; `None` = from the robot (1 for diff
    /// drive and omni, whose castors are taken as unloaded; by moment balance for
    /// wheeled-legged robots).
    pub driven_load_share: Option<f64>,
    /// k in v_y = -k v_x omega.
    pub side_slip_s: f64,
    /// Total play between motor and wheel, wheel radians.
    pub backlash_rad: f64,
    /// Stepper pull-out: largest wheel acceleration the rotor follows.
    pub max_accel_rad_s2: Option<f64>,
    /// First-order lag of the actuator.
    pub tau_s: f64,
    /// Commands below this (rad/s) leave the wheel still.
    pub deadband_rad_s: f64,
    /// Non-systematic floor roughness: each wheel's travel gets a random walk of this
    /// many metres per square-root metre travelled.
    pub travel_noise_m_per_sqrt_m: f64,
    /// The mechanisms of the effects above and their extra parameters.
    pub mech: MechanismFaults,
}

/// Which mechanism produces each effect, with the parameters only some mechanisms have.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MechanismFaults {
    /// How longitudinal slip is produced.
    pub slip: Mechanism,
    /// Creep: slip speed per unit contact acceleration, s.
    pub creep_s: f64,
    /// How lateral slip is produced.
    pub lateral: Mechanism,
    /// Saturating lateral slip: largest side-slip speed, m/s.
    pub lateral_sat_m_s: f64,
    /// Symmetric or asymmetric backlash.
    pub backlash: Mechanism,
    /// Asymmetric backlash: the share by which forward and backward play differ.
    pub backlash_asymmetry: f64,
    /// How a stepper misses steps.
    pub missed: Mechanism,
    /// Quanta: mean drops per second while over the limit.
    pub missed_rate_hz: f64,
    /// How the wheel rate lags the command.
    pub lag: Mechanism,
    /// Slew: largest change of the wheel rate, rad/s^2 (`None`: no slew limit).
    pub slew_rad_s2: Option<f64>,
}

impl Default for MechanismFaults {
    fn default() -> Self {
        MechanismFaults {
            slip: Mechanism::Wheel,
            creep_s: 0.0,
            lateral: Mechanism::Linear,
            lateral_sat_m_s: f64::INFINITY,
            backlash: Mechanism::Symmetric,
            backlash_asymmetry: 0.0,
            missed: Mechanism::PullOut,
            missed_rate_hz: 0.0,
            lag: Mechanism::FirstOrder,
            slew_rad_s2: None,
        }
    }
}

impl Faults {
    /// No faults for a robot with `n` wheels.
    pub fn none(n: usize) -> Self {
        Faults {
            radius_scale: vec![1.0; n],
            wheelbase_scale: 1.0,
            mu: None,
            driven_load_share: None,
            side_slip_s: 0.0,
            backlash_rad: 0.0,
            max_accel_rad_s2: None,
            tau_s: 0.0,
            deadband_rad_s: 0.0,
            travel_noise_m_per_sqrt_m: 0.0,
            mech: MechanismFaults::default(),
        }
    }

    /// Folds `effects` into faults and a floor for `robot`, starting from `surface`.
    pub fn from_effects(
        robot: &Robot,
        effects: &[Effect],
        mut surface: Surface,
    ) -> Result<(Faults, Surface), crate::SimError> {
        let mut f = Faults::none(robot.wheel_count());
        for e in effects {
            e.validate()?;
            match e {
                Effect::WheelDiameterMismatch { ed, radius_scale } => {
                    if let Some(ed) = ed {
                        if robot.kind != RobotKind::DiffDrive {
                            return Err(crate::SimError::NotApplicable {
                                effect: e.id(),
                                reason: "ed is for differential drives; use radius_scale_<wheel>"
                                    .into(),
                            });
                        }
                        // Borenstein: the mean diameter stays nominal, D_R / D_L = ed.
                        for (i, w) in robot.wheels.iter().enumerate() {
                            f.radius_scale[i] *= calib_core::umbmark::wheel_factor(w, *ed);
                        }
                    }
                    for (name, s) in radius_scale {
                        let i = robot
                            .wheel_index(name)
                            .ok_or_else(|| EffectError::UnknownWheel { name: name.clone() })?;
                        f.radius_scale[i] *= s;
                    }
                }
                Effect::WheelbaseError { eb } => f.wheelbase_scale *= eb,
                Effect::LongitudinalSlip {
                    mu,
                    mechanism,
                    creep_s,
                } => {
                    f.mech.slip = *mechanism;
                    if *mechanism == Mechanism::Creep {
                        f.mech.creep_s = *creep_s;
                    } else {
                        f.mu = Some(*mu);
                    }
                }
                Effect::LateralSlip {
                    side_slip_s,
                    mechanism,
                    sat_m_s,
                } => {
                    f.side_slip_s = *side_slip_s;
                    f.mech.lateral = *mechanism;
                    if *mechanism == Mechanism::Saturating {
                        f.mech.lateral_sat_m_s = *sat_m_s;
                    }
                }
                Effect::FloorBumps {
                    spacing_m,
                    loss_m,
                    mechanism,
                    start_m,
                    end_m,
                    jitter,
                } => {
                    let mut c = CableStrip::new(*spacing_m, *loss_m);
                    match mechanism {
                        Mechanism::Region => {
                            c.start_m = *start_m;
                            c.end_m = *end_m;
                        }
                        Mechanism::Irregular => c.jitter = *jitter,
                        _ => {}
                    }
                    surface.cables = Some(c)
                }
                Effect::Backlash {
                    backlash_rad,
                    mechanism,
                    asymmetry,
                } => {
                    f.backlash_rad = *backlash_rad;
                    f.mech.backlash = *mechanism;
                    if *mechanism == Mechanism::Asymmetric {
                        f.mech.backlash_asymmetry = *asymmetry;
                    }
                }
                Effect::MissedSteps {
                    max_accel_rad_s2,
                    mechanism,
                    rate_hz,
                } => {
                    f.mech.missed = *mechanism;
                    f.mech.missed_rate_hz = *rate_hz;
                    if robot.drive.kind != DriveType::Stepper {
                        return Err(crate::SimError::NotApplicable {
                            effect: e.id(),
                            reason: "the robot's drive is not a stepper".into(),
                        });
                    }
                    f.max_accel_rad_s2 = Some(*max_accel_rad_s2)
                }
                Effect::MotorLag {
                    tau_s,
                    mechanism,
                    slew_rad_s2,
                } => {
                    f.mech.lag = *mechanism;
                    match mechanism {
                        Mechanism::Slew => f.mech.slew_rad_s2 = Some(*slew_rad_s2),
                        _ => f.tau_s = *tau_s,
                    }
                }
                Effect::CoulombFriction { deadband_rad_s, .. } => {
                    f.deadband_rad_s = *deadband_rad_s
                }
                Effect::TiltedFloor {
                    drift_m_s,
                    direction_rad,
                } => {
                    surface.tilt = Some(Tilt {
                        drift_m_s: *drift_m_s,
                        direction_rad: *direction_rad,
                    })
                }
            }
        }
        Ok((f, surface))
    }

    /// Checks the numbers (for faults built by hand rather than from effects).
    pub fn validate(&self, n_wheels: usize) -> Result<(), crate::SimError> {
        use crate::error::check_range;
        if self.radius_scale.len() != n_wheels {
            return Err(crate::SimError::Config {
                field: "faults.radius_scale",
                message: format!("needs {n_wheels} values, got {}", self.radius_scale.len()),
            });
        }
        for s in &self.radius_scale {
            check_range("faults.radius_scale", *s, 0.25, 4.0)?;
        }
        check_range("faults.wheelbase_scale", self.wheelbase_scale, 0.25, 4.0)?;
        if let Some(mu) = self.mu {
            check_range("faults.mu", mu, 1e-6, 100.0)?;
        }
        if let Some(s) = self.driven_load_share {
            check_range("faults.driven_load_share", s, 0.0, 1.0)?;
        }
        check_range("faults.side_slip_s", self.side_slip_s, -10.0, 10.0)?;
        check_range("faults.backlash_rad", self.backlash_rad, 0.0, 1.0)?;
        if let Some(a) = self.max_accel_rad_s2 {
            check_range("faults.max_accel_rad_s2", a, 1e-9, 1e9)?;
        }
        check_range("faults.tau_s", self.tau_s, 0.0, 10.0)?;
        check_range("faults.deadband_rad_s", self.deadband_rad_s, 0.0, 1e6)?;
        check_range(
            "faults.travel_noise_m_per_sqrt_m",
            self.travel_noise_m_per_sqrt_m,
            0.0,
            1.0,
        )?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::robot::presets;

    #[test]
    fn parses_the_catalogue_strings() {
        let e = Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0008").unwrap();
        assert_eq!(
            e.params(),
            vec![("spacing_m".into(), 0.03), ("loss_m".into(), 0.0008)]
        );
        assert_eq!(e.mechanism(), Some(Mechanism::Whole));
        assert_eq!(Effect::parse(&e.to_string()).unwrap(), e);
        let e = Effect::parse("wheel_diameter_mismatch=radius_scale_w2:1.02").unwrap();
        assert_eq!(
            e,
            Effect::WheelDiameterMismatch {
                ed: None,
                radius_scale: vec![("w2".into(), 1.02)]
            }
        );
        assert_eq!(Effect::parse("backlash").unwrap().id(), "backlash");
        for id in EFFECT_IDS {
            let e = Effect::parse(id).unwrap();
            assert_eq!(Effect::parse(&e.to_string()).unwrap(), e);
        }
    }

    #[test]
    fn mechanisms_parse_and_print_back() {
        let e = Effect::parse("longitudinal_slip=mu:0.15,mechanism:body").unwrap();
        assert_eq!(e.mechanism(), Some(Mechanism::Body));
        assert_eq!(e.to_string(), "longitudinal_slip=mechanism:body,mu:0.15");
        assert_eq!(Effect::parse(&e.to_string()).unwrap(), e);
        for (m, name, id) in Mechanism::ALL {
            let e = Effect::parse(&format!("{id}=mechanism:{name}")).unwrap();
            assert_eq!(e.mechanism(), Some(m));
            assert_eq!(Effect::parse(&e.to_string()).unwrap(), e);
        }
        let e = Effect::parse("floor_bumps=mechanism:region,start_m:1,end_m:2").unwrap();
        let (_, s) = Faults::from_effects(&presets::omni4(), &[e], Surface::flat()).unwrap();
        let c = s.cables.unwrap();
        assert_eq!((c.start_m, c.end_m), (1.0, 2.0));
        assert!(Effect::parse("backlash=mechanism:body").is_err());
        assert!(Effect::parse("wheelbase_error=mechanism:body").is_err());
        assert!(Effect::parse("floor_bumps=mechanism:region,start_m:2,end_m:1").is_err());
    }

    #[test]
    fn bad_strings_are_errors_not_panics() {
        for bad in [
            "longitudinal_slip=mu:-0.3",
            "longitudinal_slip=mu:NaN",
            "longitudinal_slip=mu",
            "longitudinal_slip=mu:abc",
            "longitudinal_slip=grip:0.3",
            "warp_drive",
            "floor_bumps=spacing_m:0.03,loss_m:0.05",
            "backlash=backlash_rad:inf",
            "",
            "=",
            "wheel_diameter_mismatch=radius_scale_:1.0",
        ] {
            assert!(Effect::parse(bad).is_err(), "{bad} accepted");
        }
        let e = Effect::parse("longitudinal_slip=mu:-0.3").unwrap_err();
        assert!(e.to_string().contains("mu") && e.to_string().contains("-0.3"));
    }

    #[test]
    fn ed_keeps_the_mean_diameter() {
        let r = presets::mobolab();
        let e = Effect::parse("wheel_diameter_mismatch=ed:1.01").unwrap();
        let (f, _) = Faults::from_effects(&r, &[e], Surface::flat()).unwrap();
        assert!((f.radius_scale[1] / f.radius_scale[0] - 1.01).abs() < 1e-12);
        assert!((f.radius_scale[0] + f.radius_scale[1] - 2.0).abs() < 1e-12);
        let bad = Effect::parse("wheel_diameter_mismatch=radius_scale_w9:1.01").unwrap();
        assert!(Faults::from_effects(&r, &[bad], Surface::flat()).is_err());
        let ms = Effect::parse("missed_steps").unwrap();
        assert!(Faults::from_effects(&presets::omni4(), &[ms], Surface::flat()).is_err());
    }

    /// Drives a DC diff drive (r 0.05, track 0.4) with wheel rates (left, right) for each
    /// tick; returns the robot.
    fn drive_diff(
        effect: &str,
        rates: impl Fn(usize) -> (f64, f64),
        ticks: usize,
    ) -> crate::SimRobot {
        use calib_core::robot::Drive;
        let r = presets::diff_drive("d", 0.05, 0.40, Drive::default());
        let e = Effect::parse(effect).unwrap();
        let cfg = crate::SimConfig {
            random_counter_start: false,
            ..Default::default()
        };
        let mut sim = crate::SimRobot::with_effects(&r, &[e], Surface::flat(), cfg).unwrap();
        let left = r.wheels.iter().position(|w| w.is_left()).unwrap();
        for k in 0..ticks {
            let (l, rr) = rates(k);
            let mut inp = [crate::WheelInput::Rate(rr), crate::WheelInput::Rate(rr)];
            inp[left] = crate::WheelInput::Rate(l);
            sim.step(1e-3, &inp).unwrap();
        }
        sim
    }

    #[test]
    fn slip_mechanisms_in_numbers() {
        // Body bound, mu 0.1: a step to 0.5 m/s reaches only mu g t = 0.0981 m/s after
        // 0.1 s; a turn on the spot (no linear acceleration) is not held back at all.
        let s = drive_diff(
            "longitudinal_slip=mu:0.1,mechanism:body",
            |_| (10.0, 10.0),
            100,
        );
        assert!(
            (s.true_twist().vx - 0.0981).abs() < 1e-3,
            "{:?}",
            s.true_twist()
        );
        let s = drive_diff(
            "longitudinal_slip=mu:0.1,mechanism:body",
            |_| (-2.0, 2.0),
            100,
        );
        assert!((s.true_pose().theta - 0.1 * 2.0 * 0.05 / 0.2).abs() < 1e-9);
        // The per-wheel limit does hold the turn back.
        let s = drive_diff("longitudinal_slip=mu:0.1", |_| (-2.0, 2.0), 100);
        assert!(s.true_pose().theta < 0.9 * 0.05);
        // Creep 0.05 s: a 1 s ramp at 0.5 m/s^2 lags by creep_s a (t - creep_s) =
        // 0.02375 m once the slip has settled at creep_s a.
        let s = drive_diff(
            "longitudinal_slip=mechanism:creep,creep_s:0.05",
            |k| {
                let v = 0.5 * (k as f64 + 1.0) * 1e-3;
                (v / 0.05, v / 0.05)
            },
            1000,
        );
        let ideal = 0.5 * 0.5 * 1.0 * 1.0;
        assert!(
            (ideal - s.true_pose().x - 0.02375).abs() < 1e-3,
            "{}",
            s.true_pose().x
        );
        // Saturating side slip: 0.3 m/s on a 1 rad/s arc, k 0.05 s: linear -0.015 m/s,
        // saturated at 5 mm/s: -0.005 tanh(3) = -0.004975 m/s.
        let arc = |_| ((0.3 - 0.2) / 0.05, (0.3 + 0.2) / 0.05);
        let s = drive_diff("lateral_slip=side_slip_s:0.05", arc, 10);
        assert!(
            (s.true_twist().vy + 0.015).abs() < 1e-9,
            "{:?}",
            s.true_twist()
        );
        let s = drive_diff(
            "lateral_slip=side_slip_s:0.05,mechanism:saturating,sat_m_s:0.005",
            arc,
            10,
        );
        assert!((s.true_twist().vy + 0.005 * 3f64.tanh()).abs() < 1e-9);
    }
}
