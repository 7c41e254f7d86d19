//! The catalogue of physics a plain kinematic model leaves out, each as an augmentation of
//! the nominal model with the catalogue's parameter names.
//!
//! Parameters are fitted in an internal coordinate (log for quantities that must stay
//! positive) so the optimiser cannot leave the physical domain; `value` converts back.

use calib_core::robot::{DriveType, Robot, RobotKind};
use serde::Serialize;
use std::fmt;

/// Which model stage an effect acts on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Stage {
    /// Commands -> wheel motion (compared with encoders).
    Actuator,
    /// Wheel motion -> body motion (compared with measured poses).
    Ground,
}

impl Stage {
    /// The stage's name in reports: "actuator" or "ground".
    pub fn as_str(self) -> &'static str {
        match self {
            Stage::Actuator => "actuator",
            Stage::Ground => "ground",
        }
    }
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// Largest single-wheel mounting angle error tried, rad (about 11 degrees).
pub const SINGLE_WHEEL_ANGLE_RAD: f64 = 0.2;

/// A catalogue effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, PartialOrd, Ord)]
#[serde(rename_all = "snake_case")]
pub enum Effect {
    /// Wheel radii off their nominal values: Borenstein's `ed` = D_R / D_L (mean diameter
    /// kept) on a differential drive, one radius scale per wheel otherwise.
    WheelDiameterMismatch,
    /// Wheel distances from the centre scaled by `eb` (Borenstein's wheelbase error).
    WheelbaseError,
    /// Traction limit: a driven wheel's contact speed changes by at most `mu` g (times
    /// the share of the weight on driven wheels) per second; beyond that it slips.
    LongitudinalSlip,
    /// Side slip in turns: v_y = -`side_slip_s` v_x omega.
    LateralSlip,
    /// Cables across the floor every `spacing_m` in world x: a driven wheel crossing one
    /// loses up to `loss_m` of travel (its rolling direction's share of the crossing).
    FloorBumps,
    /// Gear play between motor and wheel, `backlash_rad` in all.
    Backlash,
    /// Stepper pull-out: the rotor follows with at most `max_accel_rad_s2` and loses
    /// steps when it falls behind.
    MissedSteps,
    /// First-order lag from commanded to actual wheel rate, time constant `tau_s`.
    MotorLag,
    /// Dead band: commands below `deadband_rad_s` leave the wheel still.
    CoulombFriction,
    /// Differential drive: mean actual / nominal wheel diameter (a wrong nominal
    /// diameter, worn tyres, a gear ratio off by a little). With `ed` and `eb`, D_L, D_R
    /// and b are all free.
    WheelScale,
    // Mechanism variants: the same catalogue effect made another way. Each
    // reports its catalogue id and its own `mechanism`.
    /// longitudinal_slip: a bound on the body's linear acceleration (heading free).
    SlipBody,
    /// longitudinal_slip: creep, slip proportional to the contact's acceleration.
    SlipCreep,
    /// longitudinal_slip: each driven wheel its own traction limit (`mu_<wheel>`).
    SlipPerWheel,
    /// lateral_slip: slip speed saturating at `sat_m_s`.
    LateralSaturating,
    /// floor_bumps: only within `start_m` <= world x <= `end_m`.
    BumpsRegion,
    /// backlash: different play taken up on forward and backward reversals.
    BacklashAsymmetric,
    /// backlash: each wheel's own play (`backlash_rad_<wheel>`).
    BacklashPerWheel,
    /// missed_steps: quanta of one electrical cycle while over the acceleration limit.
    MissedQuanta,
    /// missed_steps: full stall over the limit until the command rests.
    MissedStall,
    /// motor_lag: pure transport delay.
    LagDelay,
    /// motor_lag: slew-rate limit.
    LagSlew,
    /// Coulomb friction against a velocity loop of finite gain: every command
    /// loses `droop_rad_s` in its sign, |w| = max(|cmd| - droop, 0).
    FrictionDroop,
    /// motor_lag: each wheel's own time constant (`tau_s_<wheel>`).
    LagPerWheel,
    /// motor_lag: each wheel's own transport delay (`delay_s_<wheel>`).
    DelayPerWheel,
    /// motor_lag: each wheel's own acceleration limit (`slew_rad_s2_<wheel>`).
    SlewPerWheel,
    /// coulomb_friction: each wheel's own dead band (`deadband_rad_s_<wheel>`).
    DeadBandPerWheel,
    /// One omni wheel (by index) mounted at an angle off its nominal `alpha` by
    /// `alpha_offset_rad`: the geometry's one-parameter alternative to every radius.
    WheelAngle(u8),
    /// One omni wheel (by index) mounted with its distance from the centre scaled by
    /// `l_scale`: the one-parameter alternative to a wheelbase error of every wheel.
    WheelPosition(u8),
}

/// How a parameter is mapped to the optimiser's coordinate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Scale {
    /// Fitted as is.
    Linear,
    /// Fitted as ln(value): stays positive, steps are relative.
    Log,
}

/// One fitted parameter's description.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// The parameter's name in reports (the catalogue's name where it has one).
    pub name: String,
    /// How the optimiser sees the value.
    pub scale: Scale,
    /// Value meaning "no effect" (or, for thresholds, a value beyond any data).
    pub null: f64,
    /// Plausible range, used for the starting grid and as bounds.
    pub min: f64,
    /// Upper end of the plausible range.
    pub max: f64,
}

impl ParamSpec {
    fn new(name: &str, scale: Scale, null: f64, min: f64, max: f64) -> Self {
        ParamSpec {
            name: name.into(),
            scale,
            null,
            min,
            max,
        }
    }

    /// Value -> optimiser coordinate.
    pub fn internal(&self, v: f64) -> f64 {
        match self.scale {
            Scale::Linear => v,
            Scale::Log => v.max(1e-300).ln(),
        }
    }

    /// Optimiser coordinate -> value.
    pub fn value(&self, u: f64) -> f64 {
        match self.scale {
            Scale::Linear => u,
            Scale::Log => u.exp(),
        }
    }

    /// Bounds in the optimiser coordinate.
    pub fn bounds(&self) -> (f64, f64) {
        (self.internal(self.min), self.internal(self.max))
    }

    /// Whether `v` sits on the bound of the range nearest "no effect" (within
    /// [`EDGE_SHARE`] of the range in the optimiser coordinate), for a parameter whose
    /// null lies outside its range: the fit wanted no effect there (a wheel without the
    /// per-wheel form's lag), and the bound is the range's, not a measurement.
    pub fn at_null_edge(&self, v: f64) -> bool {
        let (lo, hi) = self.bounds();
        let tol = EDGE_SHARE * (hi - lo);
        self.null_bound()
            .is_some_and(|b| (self.internal(v) - self.internal(b)).abs() <= tol)
    }

    /// The bound of the range nearest "no effect", for a parameter whose null lies
    /// outside its range.
    pub fn null_bound(&self) -> Option<f64> {
        if self.null < self.min {
            Some(self.min)
        } else if self.null > self.max {
            Some(self.max)
        } else {
            None
        }
    }
}

/// The share of a parameter's range (optimiser coordinate) within which a value counts
/// as on its bound: half a percent, well under what any fit resolves (the per-wheel
/// delay's range, 1e-4 to 2 s, is 9.9 in log: 0.05, a 5 % step).
pub const EDGE_SHARE: f64 = 0.005;

impl Effect {
    /// Every effect: the catalogue's own first, then the mechanism variants.
    pub const ALL: [Effect; 26] = [
        Effect::WheelDiameterMismatch,
        Effect::WheelbaseError,
        Effect::LongitudinalSlip,
        Effect::LateralSlip,
        Effect::FloorBumps,
        Effect::Backlash,
        Effect::MissedSteps,
        Effect::MotorLag,
        Effect::CoulombFriction,
        Effect::WheelScale,
        Effect::SlipBody,
        Effect::SlipCreep,
        Effect::LateralSaturating,
        Effect::BumpsRegion,
        Effect::BacklashAsymmetric,
        Effect::BacklashPerWheel,
        Effect::MissedQuanta,
        Effect::MissedStall,
        Effect::LagDelay,
        Effect::LagSlew,
        Effect::FrictionDroop,
        Effect::SlipPerWheel,
        Effect::LagPerWheel,
        Effect::DelayPerWheel,
        Effect::SlewPerWheel,
        Effect::DeadBandPerWheel,
    ];

    /// The catalogue effect this is a mechanism of (itself for the catalogue's own).
    pub fn base(self) -> Effect {
        match self {
            Effect::SlipBody | Effect::SlipCreep | Effect::SlipPerWheel => Effect::LongitudinalSlip,
            Effect::LateralSaturating => Effect::LateralSlip,
            Effect::BumpsRegion => Effect::FloorBumps,
            Effect::BacklashAsymmetric | Effect::BacklashPerWheel => Effect::Backlash,
            Effect::MissedQuanta | Effect::MissedStall => Effect::MissedSteps,
            Effect::LagDelay
            | Effect::LagSlew
            | Effect::LagPerWheel
            | Effect::DelayPerWheel
            | Effect::SlewPerWheel => Effect::MotorLag,
            Effect::FrictionDroop | Effect::DeadBandPerWheel => Effect::CoulombFriction,
            // A single omni wheel's mounting: another way the geometry is off.
            Effect::WheelAngle(_) | Effect::WheelPosition(_) => Effect::WheelDiameterMismatch,
            e => e,
        }
    }

    /// The mechanism's name (as the sim crate's `mechanism:<name>`), from the one
    /// catalogue table ([`formats::catalogue`]).
    pub fn mechanism(self) -> &'static str {
        use formats::catalogue as c;
        match self {
            Effect::WheelDiameterMismatch
            | Effect::WheelbaseError
            | Effect::WheelScale
            | Effect::WheelAngle(_)
            | Effect::WheelPosition(_) => c::GEOMETRY,
            Effect::LongitudinalSlip => c::MECH_WHEEL.0,
            Effect::LateralSlip => c::MECH_LINEAR.0,
            Effect::FloorBumps => c::MECH_WHOLE.0,
            Effect::Backlash => c::MECH_SYMMETRIC.0,
            Effect::MissedSteps => c::MECH_PULL_OUT.0,
            Effect::MotorLag => c::MECH_FIRST_ORDER.0,
            Effect::CoulombFriction => c::MECH_DEAD_BAND.0,
            Effect::SlipBody => c::MECH_BODY.0,
            Effect::SlipCreep => c::MECH_CREEP.0,
            Effect::SlipPerWheel => c::MECH_SLIP_PER_WHEEL.0,
            Effect::LateralSaturating => c::MECH_SATURATING.0,
            Effect::BumpsRegion => c::MECH_REGION.0,
            Effect::BacklashAsymmetric => c::MECH_ASYMMETRIC.0,
            Effect::BacklashPerWheel => c::MECH_PER_WHEEL.0,
            Effect::MissedQuanta => c::MECH_QUANTA.0,
            Effect::MissedStall => c::MECH_STALL.0,
            Effect::LagDelay => c::MECH_DELAY.0,
            Effect::LagSlew => c::MECH_SLEW.0,
            Effect::FrictionDroop => c::MECH_DROOP.0,
            Effect::LagPerWheel => c::MECH_FIRST_ORDER_PER_WHEEL.0,
            Effect::DelayPerWheel => c::MECH_DELAY_PER_WHEEL.0,
            Effect::SlewPerWheel => c::MECH_SLEW_PER_WHEEL.0,
            Effect::DeadBandPerWheel => c::MECH_DEAD_BAND_PER_WHEEL.0,
        }
    }

    /// The catalogue id ([`formats::catalogue`]).
    pub fn id(self) -> &'static str {
        use formats::catalogue as c;
        match self {
            Effect::WheelDiameterMismatch => c::WHEEL_DIAMETER_MISMATCH,
            Effect::WheelbaseError => c::WHEELBASE_ERROR,
            Effect::LongitudinalSlip => c::LONGITUDINAL_SLIP,
            Effect::LateralSlip => c::LATERAL_SLIP,
            Effect::FloorBumps => c::FLOOR_BUMPS,
            Effect::Backlash => c::BACKLASH,
            Effect::MissedSteps => c::MISSED_STEPS,
            Effect::MotorLag => c::MOTOR_LAG,
            Effect::CoulombFriction => c::COULOMB_FRICTION,
            Effect::WheelScale => c::WHEEL_SCALE,
            Effect::WheelAngle(_) => c::WHEEL_ANGLE_ERROR,
            Effect::WheelPosition(_) => c::WHEEL_POSITION_ERROR,
            e => e.base().id(),
        }
    }

    /// The model stage the effect acts on (that of its catalogue effect).
    pub fn stage(self) -> Stage {
        match self.base() {
            Effect::Backlash | Effect::MissedSteps | Effect::MotorLag | Effect::CoulombFriction => {
                Stage::Actuator
            }
            _ => Stage::Ground,
        }
    }

    /// The parameters fitted for this robot, catalogue names first.
    pub fn params(self, robot: &Robot) -> Vec<ParamSpec> {
        use Scale::*;
        // One log-scaled copy of a parameter per wheel (`<name>_<wheel>`).
        let per_wheel = |name: &str, null: f64, min: f64, max: f64| -> Vec<ParamSpec> {
            robot
                .wheels
                .iter()
                .map(|w| ParamSpec::new(&format!("{name}_{}", w.name), Log, null, min, max))
                .collect()
        };
        match self {
            Effect::WheelDiameterMismatch => {
                if robot.kind == RobotKind::DiffDrive {
                    vec![ParamSpec::new("ed", Linear, 1.0, 0.8, 1.25)]
                } else {
                    robot
                        .wheels
                        .iter()
                        .map(|w| {
                            ParamSpec::new(
                                &format!("radius_scale_{}", w.name),
                                Linear,
                                1.0,
                                0.8,
                                1.25,
                            )
                        })
                        .collect()
                }
            }
            Effect::WheelbaseError => vec![ParamSpec::new("eb", Linear, 1.0, 0.7, 1.4)],
            Effect::WheelScale => vec![ParamSpec::new("scale", Linear, 1.0, 0.8, 1.25)],
            Effect::LongitudinalSlip => vec![ParamSpec::new("mu", Log, 1e3, 0.01, 5.0)],
            Effect::LateralSlip => vec![ParamSpec::new("side_slip_s", Linear, 0.0, -2.0, 2.0)],
            Effect::FloorBumps => vec![
                ParamSpec::new("spacing_m", Log, 0.03, 0.005, 1.0),
                ParamSpec::new("loss_m", Log, 1e-9, 1e-6, 0.05),
            ],
            Effect::Backlash => vec![ParamSpec::new("backlash_rad", Log, 1e-9, 1e-4, 1.0)],
            Effect::MissedSteps => {
                vec![ParamSpec::new("max_accel_rad_s2", Log, 1e9, 0.1, 1e4)]
            }
            Effect::MotorLag => vec![ParamSpec::new("tau_s", Log, 1e-9, 1e-4, 5.0)],
            Effect::CoulombFriction => {
                vec![ParamSpec::new("deadband_rad_s", Log, 1e-9, 1e-3, 50.0)]
            }
            Effect::SlipBody => vec![ParamSpec::new("mu", Log, 1e3, 0.01, 5.0)],
            Effect::SlipCreep => vec![ParamSpec::new("creep_s", Log, 1e-9, 1e-3, 2.0)],
            Effect::SlipPerWheel => robot
                .wheels
                .iter()
                .filter(|w| w.driven)
                .map(|w| ParamSpec::new(&format!("mu_{}", w.name), Log, 1e3, 0.01, 5.0))
                .collect(),
            Effect::LateralSaturating => vec![
                ParamSpec::new("side_slip_s", Log, 1e-9, 1e-3, 2.0),
                ParamSpec::new("sat_m_s", Log, 1e3, 1e-4, 1.0),
            ],
            Effect::BumpsRegion => vec![
                ParamSpec::new("spacing_m", Log, 0.03, 0.005, 1.0),
                ParamSpec::new("loss_m", Log, 1e-9, 1e-6, 0.05),
                ParamSpec::new("start_m", Linear, -1e3, -1e3, 1e3),
                ParamSpec::new("end_m", Linear, 1e3, -1e3, 1e3),
            ],
            Effect::BacklashPerWheel => robot
                .wheels
                .iter()
                .map(|w| ParamSpec::new(&format!("backlash_rad_{}", w.name), Log, 1e-9, 1e-4, 1.0))
                .collect(),
            Effect::BacklashAsymmetric => vec![
                ParamSpec::new("backlash_rad", Log, 1e-9, 1e-4, 1.0),
                ParamSpec::new("asymmetry", Linear, 0.0, -0.95, 0.95),
            ],
            Effect::MissedQuanta => vec![
                ParamSpec::new("max_accel_rad_s2", Log, 1e9, 0.1, 1e4),
                ParamSpec::new("rate_hz", Log, 1e-9, 0.01, 500.0),
            ],
            Effect::MissedStall => {
                vec![ParamSpec::new("max_accel_rad_s2", Log, 1e9, 0.1, 1e4)]
            }
            Effect::LagDelay => vec![ParamSpec::new("tau_s", Log, 1e-9, 1e-4, 2.0)],
            Effect::LagSlew => vec![ParamSpec::new("slew_rad_s2", Log, 1e9, 0.05, 1e4)],
            Effect::FrictionDroop => vec![ParamSpec::new("droop_rad_s", Log, 1e-9, 1e-3, 50.0)],
            Effect::LagPerWheel => per_wheel("tau_s", 1e-9, 1e-4, 5.0),
            Effect::DelayPerWheel => per_wheel("delay_s", 1e-9, 1e-4, 2.0),
            Effect::SlewPerWheel => per_wheel("slew_rad_s2", 1e9, 0.05, 1e4),
            Effect::DeadBandPerWheel => per_wheel("deadband_rad_s", 1e-9, 1e-3, 50.0),
            Effect::WheelAngle(i) => {
                let name = robot.wheels.get(i as usize).map_or("", |w| w.name.as_str());
                vec![ParamSpec::new(
                    &format!("alpha_offset_rad_{name}"),
                    Linear,
                    0.0,
                    -SINGLE_WHEEL_ANGLE_RAD,
                    SINGLE_WHEEL_ANGLE_RAD,
                )]
            }
            Effect::WheelPosition(i) => {
                let name = robot.wheels.get(i as usize).map_or("", |w| w.name.as_str());
                vec![ParamSpec::new(
                    &format!("l_scale_{name}"),
                    Linear,
                    1.0,
                    0.8,
                    1.25,
                )]
            }
        }
    }

    /// The effects worth trying on `robot`: the catalogue's, and on omni robots (three
    /// wheels or more) one mounting angle and one wheel distance per wheel.
    pub fn candidates(robot: &Robot) -> Vec<Effect> {
        let mut out = Effect::ALL.to_vec();
        if matches!(robot.kind, RobotKind::Omni) && robot.wheels.len() >= 3 {
            for i in 0..robot.wheels.len() as u8 {
                out.push(Effect::WheelAngle(i));
                out.push(Effect::WheelPosition(i));
            }
        }
        out
    }

    /// A number unique to the effect (wheel included), for cache keys.
    pub fn code(self) -> f64 {
        let per_wheel = |base: f64, i: u8| base + f64::from(i);
        match self {
            Effect::WheelAngle(i) => per_wheel(100.0, i),
            Effect::WheelPosition(i) => per_wheel(200.0, i),
            e => Effect::ALL.iter().position(|x| *x == e).unwrap_or(99) as f64,
        }
    }

    /// Whether the effect can act on this robot and recording at all.
    pub fn applies(self, robot: &Robot, has_commands: bool) -> bool {
        match self.stage() {
            Stage::Actuator => {
                let stepper = robot.drive.kind == DriveType::Stepper;
                has_commands
                    && match self.base() {
                        Effect::MissedSteps => stepper,
                        // On a stepper a rate limit is the pull-out's business.
                        _ if matches!(self, Effect::LagSlew | Effect::SlewPerWheel) => !stepper,
                        _ => true,
                    }
            }
            // Omni robots' per-wheel radius scales already hold a common scale.
            Stage::Ground => self != Effect::WheelScale || robot.kind == RobotKind::DiffDrive,
        }
    }

    /// Whether the cost of this one-parameter effect is rugged at a finer scale than its
    /// start grid: piecewise flat for a threshold that changes the model only where a
    /// command or an acceleration crosses it (a dead band, a pull-out or stall limit), or
    /// with several valleys within a grid cell for a traction limit (which engages at some
    /// speed changes and not others). `select` zooms into the grid's best cell first; a
    /// smooth effect (a lag, a delay, a slew limit, play, droop) goes straight to the local
    /// fit, which finds the same minimum (the mechanisms and generator suites agreed to 1e-8,
    /// except a slew on a flat valley: 641 -> 640 rad/s^2).
    pub fn rugged_cost(self) -> bool {
        matches!(
            self,
            Effect::CoulombFriction
                | Effect::MissedSteps
                | Effect::MissedStall
                | Effect::LongitudinalSlip
                | Effect::SlipBody
                | Effect::SlipCreep
                | Effect::SlipPerWheel
        )
    }

    /// Grid of starting points (values) for the parameters, or `None` to start at the
    /// null value: threshold effects have flat cost on one side, so a local optimiser
    /// started in the flat part never moves.
    pub fn start_grid(self, robot: &Robot) -> Vec<Vec<f64>> {
        let log_grid = |lo: f64, hi: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| (lo.ln() + (hi / lo).ln() * i as f64 / (n - 1) as f64).exp())
                .collect()
        };
        let singles = |v: Vec<f64>| v.into_iter().map(|x| vec![x]).collect();
        let n = self.params(robot).len();
        let one_or_all = |values: Vec<f64>, none: f64| -> Vec<Vec<f64>> {
            let mut g: Vec<Vec<f64>> = Vec::new();
            for j in 0..n {
                for &v in &values {
                    let mut x = vec![none; n];
                    x[j] = v;
                    g.push(x);
                }
            }
            g.extend(values.iter().map(|&v| vec![v; n]));
            g
        };
        match self {
            Effect::WheelDiameterMismatch => vec![vec![1.0; n]],
            Effect::WheelbaseError => vec![vec![1.0]],
            Effect::WheelScale => vec![vec![1.0]],
            Effect::LateralSlip => vec![vec![0.0]],
            Effect::LongitudinalSlip => singles(log_grid(0.02, 3.0, 12)),
            Effect::Backlash => singles(log_grid(0.002, 0.5, 10)),
            // Losses start abruptly below the true limit: a fine grid.
            Effect::MissedSteps => singles(log_grid(1.0, 3000.0, 64)),
            Effect::MotorLag => singles(log_grid(0.003, 1.0, 10)),
            Effect::CoulombFriction => singles(log_grid(0.02, 20.0, 12)),
            Effect::SlipBody => singles(log_grid(0.02, 3.0, 8)),
            Effect::SlipCreep => singles(log_grid(0.005, 0.5, 6)),
            // One wheel slipping (the others at no limit), for each wheel, and all alike.
            Effect::SlipPerWheel => {
                let mut g: Vec<Vec<f64>> = Vec::new();
                for j in 0..n {
                    for v in log_grid(0.02, 3.0, 6) {
                        let mut x = vec![1e3; n];
                        x[j] = v;
                        g.push(x);
                    }
                }
                g.extend(log_grid(0.02, 3.0, 6).into_iter().map(|v| vec![v; n]));
                g
            }
            Effect::LateralSaturating => {
                let mut g = Vec::new();
                for k in log_grid(0.01, 0.5, 3) {
                    for sat in log_grid(0.002, 0.05, 3) {
                        g.push(vec![k, sat]);
                    }
                }
                g
            }
            Effect::BacklashPerWheel => log_grid(0.002, 0.5, 10)
                .into_iter()
                .map(|b| vec![b; n])
                .collect(),
            Effect::BacklashAsymmetric => {
                let mut g = Vec::new();
                for b in log_grid(0.002, 0.5, 10) {
                    for a in [-0.5, 0.0, 0.5] {
                        g.push(vec![b, a]);
                    }
                }
                g
            }
            Effect::MissedQuanta => {
                let mut g = Vec::new();
                for a in log_grid(1.0, 3000.0, 24) {
                    for r in log_grid(1.0, 100.0, 3) {
                        g.push(vec![a, r]);
                    }
                }
                g
            }
            Effect::MissedStall => singles(log_grid(1.0, 3000.0, 64)),
            Effect::LagDelay => singles(log_grid(0.003, 1.0, 12)),
            Effect::LagSlew => singles(log_grid(0.5, 200.0, 16)),
            Effect::FrictionDroop => singles(log_grid(0.02, 20.0, 12)),
            // One wheel with the effect (the others at no effect), for each wheel, and
            // every wheel alike: a limit or band that never binds leaves the cost flat,
            // so a start with both wheels low cannot lift one of them.
            Effect::LagPerWheel => one_or_all(log_grid(0.003, 1.0, 6), 1e-4),
            Effect::DelayPerWheel => one_or_all(log_grid(0.003, 1.0, 6), 1e-4),
            Effect::SlewPerWheel => one_or_all(log_grid(0.5, 200.0, 16), 1e4),
            Effect::DeadBandPerWheel => one_or_all(log_grid(0.02, 20.0, 6), 1e-3),
            Effect::WheelAngle(_) => vec![vec![0.0]],
            Effect::WheelPosition(_) => vec![vec![1.0]],
            // From the data: see `select::region::region_grid`.
            Effect::BumpsRegion => Vec::new(),
            Effect::FloorBumps => {
                let mut g = Vec::new();
                // Crossings make the cost a comb in the spacing; the travel lost per
                // metre (loss / spacing) is what the grid must get close to.
                for s in log_grid(0.01, 0.3, 12) {
                    for frac in log_grid(0.003, 0.1, 3) {
                        g.push(vec![s, s * frac]);
                    }
                }
                g
            }
        }
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.id())
    }
}

/// A model: the nominal kinematics plus some effects with parameter values.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Model {
    /// The effects added to the nominal model, each with its parameter values (not the
    /// optimiser's coordinates) in the order of [`Effect::params`].
    pub effects: Vec<(Effect, Vec<f64>)>,
}

impl Model {
    /// The parameter values of `e`, if the model has it.
    pub fn get(&self, e: Effect) -> Option<&[f64]> {
        self.effects
            .iter()
            .find(|(x, _)| *x == e)
            .map(|(_, p)| p.as_slice())
    }

    /// A copy with `e` at `params` (replacing its values if `e` is already there).
    pub fn with(&self, e: Effect, params: Vec<f64>) -> Model {
        let mut m = self.clone();
        if let Some(slot) = m.effects.iter_mut().find(|(x, _)| *x == e) {
            slot.1 = params;
        } else {
            m.effects.push((e, params));
        }
        m
    }

    /// Per-wheel radius multipliers and the wheelbase multiplier of the geometry effects.
    pub fn geometry(&self, robot: &Robot) -> (Vec<f64>, f64) {
        let n = robot.wheels.len();
        let mut scales = vec![1.0; n];
        if let Some(p) = self.get(Effect::WheelDiameterMismatch) {
            if robot.kind == RobotKind::DiffDrive && p.len() == 1 {
                // Borenstein: ed = D_right / D_left with the mean diameter kept.
                let ed = p[0];
                for (i, w) in robot.wheels.iter().enumerate() {
                    scales[i] = calib_core::umbmark::wheel_factor(w, ed);
                }
            } else {
                for (s, v) in scales.iter_mut().zip(p) {
                    *s = *v;
                }
            }
        }
        if let Some(p) = self.get(Effect::WheelScale) {
            scales.iter_mut().for_each(|s| *s *= p[0]);
        }
        let eb = self.get(Effect::WheelbaseError).map_or(1.0, |p| p[0]);
        (scales, eb)
    }

    /// The robot with the fitted geometry applied (radii, wheel distances, a single
    /// wheel's mounting).
    pub fn apply_geometry(&self, robot: &Robot) -> Robot {
        let (scales, eb) = self.geometry(robot);
        let mut out = self.apply_mounting(robot);
        for (w, s) in out.wheels.iter_mut().zip(scales) {
            w.radius_m *= s;
            w.l_m *= eb;
        }
        out
    }

    /// `robot` with the single-wheel mounting effects applied (angle offset, distance
    /// scale); the other geometry stays nominal.
    pub fn apply_mounting(&self, robot: &Robot) -> Robot {
        let mut out = robot.clone();
        for (e, p) in &self.effects {
            match *e {
                Effect::WheelAngle(i) => {
                    if let (Some(w), Some(v)) = (out.wheels.get_mut(i as usize), p.first()) {
                        // Moving the wheel round the centre keeps its rolling direction
                        // relative to the radius (beta), as a misplaced mount does.
                        w.alpha_rad += v;
                    }
                }
                Effect::WheelPosition(i) => {
                    if let (Some(w), Some(v)) = (out.wheels.get_mut(i as usize), p.first()) {
                        w.l_m *= v;
                    }
                }
                _ => {}
            }
        }
        out
    }
}
