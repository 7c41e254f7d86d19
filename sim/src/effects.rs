//! The diagnose catalogue (issue 7) as data: [`Effect`] with exactly the catalogue's
//! parameter names, a parser for `ID=name:value,name:value` strings (the `--effect`
//! argument of `wheelcal sim record`), and [`Faults`], the per-robot numbers the simulator
//! runs with once the effects are folded in.
//!
//! Everything here validates: a negative mu or a NaN is an [`EffectError`] naming the
//! effect and parameter, never a panic.

use crate::surface::{CableStrip, Surface, Tilt};
use calib_core::robot::{DriveType, Robot, RobotKind};
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
    /// `mu`: body acceleration bounded by mu * g * (load share on driven wheels).
    LongitudinalSlip {
        /// Friction coefficient (dimensionless).
        mu: f64,
    },
    /// `side_slip_s` = k in v_y = -k * v_x * omega.
    LateralSlip {
        /// k in v_y = -k * v_x * omega (s).
        side_slip_s: f64,
    },
    /// `spacing_m`, `loss_m`: cables across the floor (perpendicular to world x), each
    /// costing a wheel `loss_m` of travel.
    FloorBumps {
        /// Distance between cables along world x (m).
        spacing_m: f64,
        /// Travel a wheel loses crossing one cable (m).
        loss_m: f64,
    },
    /// `backlash_rad`: total dead band between motor and wheel, in wheel radians.
    Backlash {
        /// Total dead band between motor and wheel (wheel rad).
        backlash_rad: f64,
    },
    /// `max_accel_rad_s2`: the stepper loses synchronism above this wheel acceleration.
    MissedSteps {
        /// Largest wheel acceleration the stepper follows (rad/s^2).
        max_accel_rad_s2: f64,
    },
    /// `tau_s`: first-order lag of the wheel rate behind the command.
    MotorLag {
        /// Time constant of the wheel rate's lag (s).
        tau_s: f64,
    },
    /// `deadband_rad_s`: the wheel stays still while |command| is below it.
    CoulombFriction {
        /// Command below which the wheel stays still (rad/s).
        deadband_rad_s: f64,
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

/// The catalogue ids, in issue 7's order, plus the out-of-catalogue control.
pub const EFFECT_IDS: [&str; 10] = [
    "wheel_diameter_mismatch",
    "wheelbase_error",
    "longitudinal_slip",
    "lateral_slip",
    "floor_bumps",
    "backlash",
    "missed_steps",
    "motor_lag",
    "coulomb_friction",
    "tilted_floor",
];

/// A bad effect string or parameter.
#[derive(Debug, Clone, PartialEq)]
pub enum EffectError {
    /// An id not in [`EFFECT_IDS`].
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

    /// True for effects of the diagnose catalogue (all but `tilted_floor`).
    pub fn in_catalogue(&self) -> bool {
        !matches!(self, Effect::TiltedFloor { .. })
    }

    /// Parameters as (name, value), with the catalogue's names.
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
            Effect::LongitudinalSlip { mu } => vec![p("mu", *mu)],
            Effect::LateralSlip { side_slip_s } => vec![p("side_slip_s", *side_slip_s)],
            Effect::FloorBumps { spacing_m, loss_m } => {
                vec![p("spacing_m", *spacing_m), p("loss_m", *loss_m)]
            }
            Effect::Backlash { backlash_rad } => vec![p("backlash_rad", *backlash_rad)],
            Effect::MissedSteps { max_accel_rad_s2 } => {
                vec![p("max_accel_rad_s2", *max_accel_rad_s2)]
            }
            Effect::MotorLag { tau_s } => vec![p("tau_s", *tau_s)],
            Effect::CoulombFriction { deadband_rad_s } => {
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
            "wheel_diameter_mismatch" => Effect::WheelDiameterMismatch {
                ed: Some(1.01),
                radius_scale: Vec::new(),
            },
            "wheelbase_error" => Effect::WheelbaseError { eb: 1.03 },
            "longitudinal_slip" => Effect::LongitudinalSlip { mu: 0.3 },
            "lateral_slip" => Effect::LateralSlip { side_slip_s: 0.05 },
            "floor_bumps" => Effect::FloorBumps {
                spacing_m: 0.03,
                loss_m: 0.0008,
            },
            "backlash" => Effect::Backlash { backlash_rad: 0.05 },
            "missed_steps" => Effect::MissedSteps {
                max_accel_rad_s2: 20.0,
            },
            "motor_lag" => Effect::MotorLag { tau_s: 0.1 },
            "coulomb_friction" => Effect::CoulombFriction {
                deadband_rad_s: 0.5,
            },
            "tilted_floor" => Effect::TiltedFloor {
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
            (Effect::LongitudinalSlip { mu }, "mu") => *mu = v,
            (Effect::LateralSlip { side_slip_s }, "side_slip_s") => *side_slip_s = v,
            (Effect::FloorBumps { spacing_m, .. }, "spacing_m") => *spacing_m = v,
            (Effect::FloorBumps { loss_m, .. }, "loss_m") => *loss_m = v,
            (Effect::Backlash { backlash_rad }, "backlash_rad") => *backlash_rad = v,
            (Effect::MissedSteps { max_accel_rad_s2 }, "max_accel_rad_s2") => *max_accel_rad_s2 = v,
            (Effect::MotorLag { tau_s }, "tau_s") => *tau_s = v,
            (Effect::CoulombFriction { deadband_rad_s }, "deadband_rad_s") => *deadband_rad_s = v,
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
            Effect::LongitudinalSlip { mu } => range(id, "mu", *mu, *mu > 0.0, "positive")?,
            Effect::LateralSlip { side_slip_s } => range(
                id,
                "side_slip_s",
                *side_slip_s,
                side_slip_s.abs() <= 10.0,
                "within [-10, 10] s",
            )?,
            Effect::FloorBumps { spacing_m, loss_m } => {
                range(id, "spacing_m", *spacing_m, *spacing_m > 0.0, "positive")?;
                range(
                    id,
                    "loss_m",
                    *loss_m,
                    *loss_m >= 0.0 && *loss_m < *spacing_m,
                    "non-negative and below spacing_m",
                )?;
            }
            Effect::Backlash { backlash_rad } => range(
                id,
                "backlash_rad",
                *backlash_rad,
                (0.0..=1.0).contains(backlash_rad),
                "within [0, 1] rad",
            )?,
            Effect::MissedSteps { max_accel_rad_s2 } => range(
                id,
                "max_accel_rad_s2",
                *max_accel_rad_s2,
                *max_accel_rad_s2 > 0.0,
                "positive",
            )?,
            Effect::MotorLag { tau_s } => range(
                id,
                "tau_s",
                *tau_s,
                (0.0..=10.0).contains(tau_s),
                "within [0, 10] s",
            )?,
            Effect::CoulombFriction { deadband_rad_s } => range(
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
        for (i, (n, v)) in self.params().iter().enumerate() {
            write!(f, "{}{n}:{v}", if i == 0 { '=' } else { ',' })?;
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
                            let left = w.position().1 >= 0.0;
                            f.radius_scale[i] *= if left {
                                2.0 / (ed + 1.0)
                            } else {
                                2.0 * ed / (ed + 1.0)
                            };
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
                Effect::LongitudinalSlip { mu } => f.mu = Some(*mu),
                Effect::LateralSlip { side_slip_s } => f.side_slip_s = *side_slip_s,
                Effect::FloorBumps { spacing_m, loss_m } => {
                    surface.cables = Some(CableStrip::new(*spacing_m, *loss_m))
                }
                Effect::Backlash { backlash_rad } => f.backlash_rad = *backlash_rad,
                Effect::MissedSteps { max_accel_rad_s2 } => {
                    if robot.drive.kind != DriveType::Stepper {
                        return Err(crate::SimError::NotApplicable {
                            effect: e.id(),
                            reason: "the robot's drive is not a stepper".into(),
                        });
                    }
                    f.max_accel_rad_s2 = Some(*max_accel_rad_s2)
                }
                Effect::MotorLag { tau_s } => f.tau_s = *tau_s,
                Effect::CoulombFriction { deadband_rad_s } => f.deadband_rad_s = *deadband_rad_s,
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
            e,
            Effect::FloorBumps {
                spacing_m: 0.03,
                loss_m: 0.0008
            }
        );
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
}
