//! The robot description of docs/formats.md §1, validated, in SI units and radians.
//!
//! Parsing TOML is a host convenience (`robot_file`, feature `std`); this module is what
//! the firmware keeps in RAM and flash, so it is plain data with bounded sizes.

use core::fmt;
use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

/// Most wheels a robot may have (the 4-wheel omni of [Redundant omni] and the
/// wheeled-legged robot of [Korayem et al.] have four; eight leaves room without making the
/// firmware's tables large).
pub const MAX_WHEELS: usize = 8;

/// Weight of a standard wheel's sliding constraint relative to its rolling constraint.
///
/// Small on purpose: the sliding rows only have to pin down what the rolling rows cannot
/// see (a differential drive's sideways velocity). A skid-steered robot with four standard
/// wheels ([Korayem et al.]'s wheeled-legged robot) can only turn by skidding, so its sliding
/// constraints contradict each other while turning; weighted equally they would shrink the
/// turn rate the wheels measure. Weighted 1e-3, they move the estimate by ~1e-6 relative.
pub const SLIDING_WEIGHT: f64 = 1e-3;
/// Longest wheel name, in bytes.
pub const NAME_LEN: usize = 16;

/// A wheel's name: `[a-z0-9_]+`, unique within a robot.
pub type WheelName = String<NAME_LEN>;

/// What kind of chassis: decides which wheel constraints hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RobotKind {
    /// Two standard wheels on one axle (castors ignored).
    DiffDrive,
    /// Swedish (omni or mecanum) wheels: no sliding constraint.
    Omni,
    /// The planar wheeled-legged robot of [Korayem et al.]: standard wheels whose contact
    /// points move with the leg angles.
    WheeledLegged,
    /// Skid-steer: two or more standard wheels on each side, each side driven together
    /// (Husky, Jackal, most 4WD rovers). It turns by skidding, so its effective wheel
    /// separation is well above the track ([Mandow et al.]); it drives and dead-reckons as
    /// a differential drive whose E_b carries that.
    SkidSteer,
}

impl RobotKind {
    /// Standard wheels cannot slide sideways; Swedish wheels can (their rollers turn).
    pub fn wheels_have_sliding_constraint(self) -> bool {
        !matches!(self, RobotKind::Omni)
    }

    /// The name used in robot files.
    pub fn as_str(self) -> &'static str {
        match self {
            RobotKind::DiffDrive => "diff_drive",
            RobotKind::Omni => "omni",
            RobotKind::WheeledLegged => "wheeled_legged",
            RobotKind::SkidSteer => "skid_steer",
        }
    }
}

/// How the wheels are driven.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum DriveType {
    /// Stepper motors: the commanded rate becomes step pulses.
    Stepper,
    /// DC motors under PI velocity control from their encoders.
    Dc,
}

/// Motor, gearing and encoder, common to all wheels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Drive {
    /// Stepper or DC.
    pub kind: DriveType,
    /// Full steps per motor revolution (stepper only; 200 for 1.8 deg/step).
    pub steps_per_rev: u32,
    /// Microsteps per full step (stepper only).
    pub microsteps: u32,
    /// Motor revolutions per wheel revolution (78/16 = 4.875 in [Measuring errors]).
    pub gear_ratio: f64,
    /// Encoder counts per WHEEL revolution as read (480 ppr x4 = 1920); 0 = no encoder.
    pub encoder_counts_per_rev: f64,
}

impl Default for Drive {
    fn default() -> Self {
        Drive {
            kind: DriveType::Dc,
            steps_per_rev: 200,
            microsteps: 1,
            gear_ratio: 1.0,
            encoder_counts_per_rev: DEFAULT_COUNTS_PER_REV,
        }
    }
}

/// 480-ppr quadrature encoder read on all four edges.
pub const DEFAULT_COUNTS_PER_REV: f64 = 1920.0;

impl Drive {
    /// Microsteps per wheel radian (stepper drives).
    pub fn steps_per_wheel_rad(&self) -> f64 {
        self.steps_per_rev as f64 * self.microsteps as f64 * self.gear_ratio
            / core::f64::consts::TAU
    }

    /// Wheel radians per encoder count, or `None` without encoders.
    pub fn rad_per_count(&self) -> Option<f64> {
        (self.encoder_counts_per_rev > 0.0)
            .then(|| core::f64::consts::TAU / self.encoder_counts_per_rev)
    }
}

/// One wheel, with Siegwart & Nourbakhsh's parameters (angles in radians).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Wheel {
    /// Unique name (`[a-z0-9_]+`, at most [`NAME_LEN`] characters).
    pub name: WheelName,
    /// Wheel radius (m).
    pub radius_m: f64,
    /// Polar angle of the wheel centre from body x.
    pub alpha_rad: f64,
    /// Distance of the wheel centre from the body origin.
    pub l_m: f64,
    /// Wheel plane angle relative to the chassis.
    pub beta_rad: f64,
    /// Roller angle (0 for standard and 90-deg-roller omni wheels, 45 deg for mecanum).
    pub gamma_rad: f64,
    /// False for free-spinning wheels (their encoders still see ground motion).
    pub driven: bool,
}

impl Wheel {
    /// Position of the wheel centre in the body frame.
    pub fn position(&self) -> (f64, f64) {
        (
            self.l_m * libm::cos(self.alpha_rad),
            self.l_m * libm::sin(self.alpha_rad),
        )
    }

    /// Borenstein's left wheel: the one on the +y side of the body (y >= 0). Every left /
    /// right split (c_L and c_R, E_d) uses this rule.
    pub fn is_left(&self) -> bool {
        self.position().1 >= 0.0
    }

    /// A standard wheel whose rolling direction is the body's +-x axis (a skid-steer or
    /// differential-drive wheel), within 1e-6 rad.
    pub fn rolls_along_body_x(&self) -> bool {
        let r = self.rolling_row();
        self.gamma_rad.abs() < 1e-6 && r[1].abs() < 1e-6
    }

    /// Siegwart's rolling row [sin(a+b+g), -cos(a+b+g), -l cos(b+g)]: dotted with the body
    /// twist it gives r cos(g) phidot.
    pub fn rolling_row(&self) -> [f64; 3] {
        let abg = self.alpha_rad + self.beta_rad + self.gamma_rad;
        [
            libm::sin(abg),
            -libm::cos(abg),
            -self.l_m * libm::cos(self.beta_rad + self.gamma_rad),
        ]
    }

    /// The wheel's rows in the stacked constraint system for effective radius `r` and its
    /// distance scaled by `l_scale`: the rolling row in rad/m (divided by r cos gamma),
    /// and the sliding row weighted by [`SLIDING_WEIGHT`] / r.
    pub fn constraint_rows(&self, r: f64, l_scale: f64) -> ([f64; 3], [f64; 3]) {
        let mut wheel = self.clone();
        wheel.l_m *= l_scale;
        let k = 1.0 / (r * libm::cos(self.gamma_rad));
        let row = wheel.rolling_row();
        let s = wheel.sliding_row();
        let ks = SLIDING_WEIGHT / r;
        (
            [row[0] * k, row[1] * k, row[2] * k],
            [s[0] * ks, s[1] * ks, s[2] * ks],
        )
    }

    /// The sliding row [cos(a+b), sin(a+b), l sin b] of a standard wheel: its dot product
    /// with the body twist is the wheel's sideways velocity, which must be zero.
    pub fn sliding_row(&self) -> [f64; 3] {
        let ab = self.alpha_rad + self.beta_rad;
        [
            libm::cos(ab),
            libm::sin(ab),
            self.l_m * libm::sin(self.beta_rad),
        ]
    }
}

/// Leg geometry of the wheeled-legged robot ([Korayem et al.]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Legs {
    /// Hip to wheel centre.
    pub length_m: f64,
    /// Hip to hip along x.
    pub body_length_m: f64,
    /// Body mass (kg).
    pub body_mass_kg: f64,
    /// Mass of one leg (kg).
    pub leg_mass_kg: f64,
}

impl Legs {
    /// Wheel-centre x of the front and rear pairs for leg angles measured from body +x
    /// towards -z (pi/2 = vertical leg), docs/formats.md §1.
    pub fn wheel_x(&self, leg_front_rad: f64, leg_rear_rad: f64) -> (f64, f64) {
        (
            self.body_length_m / 2.0 + self.length_m * libm::cos(leg_front_rad),
            -self.body_length_m / 2.0 + self.length_m * libm::cos(leg_rear_rad),
        )
    }

    /// Share of the weight on the front pair by moment balance about the rear contact,
    /// mass at the body origin. `None` when the contacts coincide along x.
    pub fn front_load_share(&self, leg_front_rad: f64, leg_rear_rad: f64) -> Option<f64> {
        let (xf, xr) = self.wheel_x(leg_front_rad, leg_rear_rad);
        let span = xf - xr;
        (span.abs() > 1e-9).then(|| ((0.0 - xr) / span).clamp(0.0, 1.0))
    }
}

/// A validated robot: construct with [`Robot::new`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Robot {
    /// Free-text robot name (truncated to 32 characters).
    pub name: String<32>,
    /// Differential drive, omni, wheeled-legged or skid-steer.
    pub kind: RobotKind,
    /// Motor, gearing and encoder.
    pub drive: Drive,
    /// The wheels, in the order used for wheel values everywhere.
    pub wheels: Vec<Wheel, MAX_WHEELS>,
    /// Leg geometry (wheeled-legged robots only).
    pub legs: Option<Legs>,
}

/// Which value of a robot description is wrong.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Field {
    /// `name`: a wheel's name.
    Name,
    /// `kind`: the robot kind.
    Kind,
    /// `wheels`: the wheel list as a whole.
    Wheels,
    /// `radius_m`.
    RadiusM,
    /// `alpha_deg`.
    AlphaDeg,
    /// `l_m`.
    LM,
    /// `beta_deg`.
    BetaDeg,
    /// `gamma_deg`.
    GammaDeg,
    /// `drive.steps_per_rev`.
    StepsPerRev,
    /// `drive.microsteps`.
    Microsteps,
    /// `drive.gear_ratio`.
    GearRatio,
    /// `drive.encoder_counts_per_rev`.
    EncoderCountsPerRev,
    /// `legs`: the leg geometry.
    Legs,
}

impl Field {
    /// The key as written in the robot file.
    pub fn key(self) -> &'static str {
        match self {
            Field::Name => "name",
            Field::Kind => "kind",
            Field::Wheels => "wheels",
            Field::RadiusM => "radius_m",
            Field::AlphaDeg => "alpha_deg",
            Field::LM => "l_m",
            Field::BetaDeg => "beta_deg",
            Field::GammaDeg => "gamma_deg",
            Field::StepsPerRev => "drive.steps_per_rev",
            Field::Microsteps => "drive.microsteps",
            Field::GearRatio => "drive.gear_ratio",
            Field::EncoderCountsPerRev => "drive.encoder_counts_per_rev",
            Field::Legs => "legs",
        }
    }
}

/// What is wrong with it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Problem {
    /// NaN or infinite.
    NotFinite,
    /// Must be positive; the value given.
    NotPositive(f64),
    /// Must not be negative; the value given.
    Negative(f64),
    /// cos(gamma) = 0: the wheel's rollers are parallel to its axle and it cannot drive.
    RollerParallelToAxle,
    /// Two wheels share a name.
    DuplicateName,
    /// Name empty, too long, or not `[a-z0-9_]+`.
    BadName,
    /// Fewer than 2 wheels; the count given.
    TooFewWheels(u32),
    /// More than [`MAX_WHEELS`] wheels; the count given.
    TooManyWheels(u32),
    /// The wheel constraints do not determine (vx, vy, omega): rank < 3.
    SingularJacobian,
    /// Legs given for a robot that is not wheeled_legged, or missing for one that is.
    LegsMismatch,
    /// A skid-steer robot needs at least two wheels on each side; the counts given
    /// (left = +y, right = -y).
    SkidSteerSides {
        /// Wheels with y > 0.
        left: u32,
        /// Wheels with y < 0.
        right: u32,
    },
    /// A skid-steer wheel must be a standard wheel rolling along the body's x axis
    /// (alpha + beta = +-90 deg, gamma = 0).
    NotAlongBodyX,
    /// Wrong number of wheels for the kind (a differential drive has 2).
    WrongWheelCount {
        /// The robot kind.
        kind: RobotKind,
        /// Wheels the kind needs.
        expected: u32,
        /// Wheels given.
        got: u32,
    },
}

/// A robot description error that names the wheel (if any) and the field.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotError {
    /// Index and name of the wheel concerned.
    pub wheel: Option<(usize, WheelName)>,
    /// Which value is wrong.
    pub field: Field,
    /// What is wrong with it.
    pub problem: Problem,
}

impl fmt::Display for RobotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if let Some((i, name)) = &self.wheel {
            write!(f, "wheel {} ('{}'): ", i + 1, name)?;
        }
        write!(f, "{}: ", self.field.key())?;
        match self.problem {
            Problem::NotFinite => write!(f, "must be a finite number"),
            Problem::NotPositive(v) => write!(f, "must be positive, got {}", crate::num::Num(v)),
            Problem::Negative(v) => write!(f, "must not be negative, got {}", crate::num::Num(v)),
            Problem::RollerParallelToAxle => write!(
                f,
                "cos(gamma) = 0: rollers parallel to the axle cannot drive (use gamma 0 or 45 deg)"
            ),
            Problem::DuplicateName => write!(f, "duplicate wheel name"),
            Problem::BadName => write!(f, "must be 1 to {NAME_LEN} characters of [a-z0-9_]"),
            Problem::TooFewWheels(n) => write!(f, "need at least 2 wheels, got {n}"),
            Problem::TooManyWheels(n) => write!(f, "at most {MAX_WHEELS} wheels, got {n}"),
            Problem::SingularJacobian => write!(
                f,
                "the wheels cannot resolve the body twist (vx, vy, omega): the Jacobian has rank < 3"
            ),
            Problem::LegsMismatch => write!(
                f,
                "[legs] is required for kind = \"wheeled_legged\" and not allowed otherwise"
            ),
            Problem::SkidSteerSides { left, right } => write!(
                f,
                "kind \"skid_steer\" needs at least 2 wheels on each side, got {left} left (y > 0) and {right} right (y < 0)"
            ),
            Problem::NotAlongBodyX => write!(
                f,
                "a skid-steer wheel rolls along the body's x axis: alpha + beta must be +-90 deg and gamma 0"
            ),
            Problem::WrongWheelCount { kind, expected, got } => write!(
                f,
                "kind \"{}\" needs {expected} wheels, got {got}",
                kind.as_str()
            ),
        }
    }
}

impl core::error::Error for RobotError {}

impl RobotError {
    fn robot(field: Field, problem: Problem) -> Self {
        RobotError {
            wheel: None,
            field,
            problem,
        }
    }
}

/// Checks a name is `[a-z0-9_]+`.
pub fn valid_wheel_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= NAME_LEN
        && name
            .bytes()
            .all(|b| b.is_ascii_lowercase() || b.is_ascii_digit() || b == b'_')
}

impl Robot {
    /// Validates a description: every failure names the wheel and field.
    pub fn new(
        name: &str,
        kind: RobotKind,
        drive: Drive,
        wheels: &[Wheel],
        legs: Option<Legs>,
    ) -> Result<Robot, RobotError> {
        let mut robot_name = String::new();
        for c in name.chars() {
            if robot_name.push(c).is_err() {
                break; // free text: truncate rather than reject
            }
        }
        if wheels.len() < 2 {
            return Err(RobotError::robot(
                Field::Wheels,
                Problem::TooFewWheels(wheels.len() as u32),
            ));
        }
        if wheels.len() > MAX_WHEELS {
            return Err(RobotError::robot(
                Field::Wheels,
                Problem::TooManyWheels(wheels.len() as u32),
            ));
        }
        if kind == RobotKind::DiffDrive && wheels.len() != 2 {
            return Err(RobotError::robot(
                Field::Wheels,
                Problem::WrongWheelCount {
                    kind,
                    expected: 2,
                    got: wheels.len() as u32,
                },
            ));
        }
        if (kind == RobotKind::WheeledLegged) != legs.is_some() {
            return Err(RobotError::robot(Field::Legs, Problem::LegsMismatch));
        }
        validate_drive(&drive)?;
        if let Some(l) = &legs {
            for v in [l.length_m, l.body_length_m, l.body_mass_kg] {
                check_positive(v, Field::Legs, None)?;
            }
            check_non_negative(l.leg_mass_kg, Field::Legs, None)?;
        }
        let mut list: Vec<Wheel, MAX_WHEELS> = Vec::new();
        for (i, w) in wheels.iter().enumerate() {
            let who = Some((i, w.name.clone()));
            if !valid_wheel_name(&w.name) {
                return Err(RobotError {
                    wheel: who,
                    field: Field::Name,
                    problem: Problem::BadName,
                });
            }
            if wheels[..i].iter().any(|o| o.name == w.name) {
                return Err(RobotError {
                    wheel: who,
                    field: Field::Name,
                    problem: Problem::DuplicateName,
                });
            }
            check_positive(w.radius_m, Field::RadiusM, who.clone())?;
            check_finite(w.alpha_rad, Field::AlphaDeg, who.clone())?;
            check_non_negative(w.l_m, Field::LM, who.clone())?;
            check_finite(w.beta_rad, Field::BetaDeg, who.clone())?;
            check_finite(w.gamma_rad, Field::GammaDeg, who.clone())?;
            if libm::cos(w.gamma_rad).abs() < 1e-6 {
                return Err(RobotError {
                    wheel: who,
                    field: Field::GammaDeg,
                    problem: Problem::RollerParallelToAxle,
                });
            }
            if kind == RobotKind::SkidSteer && !w.rolls_along_body_x() {
                return Err(RobotError {
                    wheel: who,
                    field: Field::BetaDeg,
                    problem: Problem::NotAlongBodyX,
                });
            }
            // Capacity checked above.
            let _ = list.push(w.clone());
        }
        if kind == RobotKind::SkidSteer {
            let side = |left: bool| {
                list.iter()
                    .filter(|w| if left { w.is_left() } else { !w.is_left() })
                    .count() as u32
            };
            let (left, right) = (side(true), side(false));
            if left < 2 || right < 2 {
                return Err(RobotError::robot(
                    Field::Wheels,
                    Problem::SkidSteerSides { left, right },
                ));
            }
        }
        let robot = Robot {
            name: robot_name,
            kind,
            drive,
            wheels: list,
            legs,
        };
        if !robot.resolves_body_twist() {
            return Err(RobotError::robot(Field::Wheels, Problem::SingularJacobian));
        }
        Ok(robot)
    }

    /// Number of wheels.
    pub fn wheel_count(&self) -> usize {
        self.wheels.len()
    }

    /// Index of the wheel with this name.
    pub fn wheel_index(&self, name: &str) -> Option<usize> {
        self.wheels.iter().position(|w| w.name == name)
    }

    /// True when the stacked rolling (and, for standard wheels, sliding) constraints have
    /// rank 3, so encoders determine the body twist.
    pub fn resolves_body_twist(&self) -> bool {
        let (m, _) = self.normal_matrix(|i| self.wheels[i].radius_m, 1.0);
        let scale = m[0][0] * m[1][1] * m[2][2];
        scale.is_finite()
            && scale > 0.0
            && crate::linalg::det3(&m).abs() > crate::linalg::SINGULAR_RATIO * scale
    }

    /// The stacked constraint system's normal matrix (rolling rows, plus the sliding rows
    /// where the kind has them) and the rolling rows, in f64, with wheel `i`'s effective
    /// radius `radius(i)` and every wheel distance scaled by `l_scale` (how corrections
    /// enter). Kinematics inverts it; [`Robot::new`] checks its rank.
    pub fn normal_matrix(
        &self,
        radius: impl Fn(usize) -> f64,
        l_scale: f64,
    ) -> ([[f64; 3]; 3], [[f64; 3]; MAX_WHEELS]) {
        let mut rolling = [[0.0; 3]; MAX_WHEELS];
        let mut m = [[0.0; 3]; 3];
        let use_sliding = self.kind.wheels_have_sliding_constraint();
        for (i, w) in self.wheels.iter().enumerate() {
            let (roll, slide) = w.constraint_rows(radius(i), l_scale);
            rolling[i] = roll;
            for a in 0..3 {
                for b in 0..3 {
                    m[a][b] += roll[a] * roll[b];
                    if use_sliding {
                        m[a][b] += slide[a] * slide[b];
                    }
                }
            }
        }
        (m, rolling)
    }

    /// Half the wheel separation of a differential drive (the `l` of either wheel).
    pub fn half_wheelbase_m(&self) -> f64 {
        self.mean_wheel_distance_m()
    }

    /// The wheels' mean distance from the body origin (m; 0 without wheels): the lever at
    /// which a turn counts against travel (an omni robot's turn ratio, calibration's
    /// samples of turns in place).
    // Inlined: called out of line, the firmware image grew by 168 bytes.
    #[inline]
    pub fn mean_wheel_distance_m(&self) -> f64 {
        self.wheels.iter().map(|w| w.l_m).sum::<f64>() / self.wheels.len().max(1) as f64
    }
}

fn validate_drive(d: &Drive) -> Result<(), RobotError> {
    check_positive(d.gear_ratio, Field::GearRatio, None)?;
    check_non_negative(d.encoder_counts_per_rev, Field::EncoderCountsPerRev, None)?;
    if d.kind == DriveType::Stepper {
        if d.steps_per_rev == 0 {
            return Err(RobotError::robot(
                Field::StepsPerRev,
                Problem::NotPositive(0.0),
            ));
        }
        if d.microsteps == 0 {
            return Err(RobotError::robot(
                Field::Microsteps,
                Problem::NotPositive(0.0),
            ));
        }
    }
    Ok(())
}

fn check_finite(v: f64, field: Field, wheel: Option<(usize, WheelName)>) -> Result<(), RobotError> {
    if v.is_finite() {
        Ok(())
    } else {
        Err(RobotError {
            wheel,
            field,
            problem: Problem::NotFinite,
        })
    }
}

fn check_positive(
    v: f64,
    field: Field,
    wheel: Option<(usize, WheelName)>,
) -> Result<(), RobotError> {
    check_finite(v, field, wheel.clone())?;
    if v > 0.0 {
        Ok(())
    } else {
        Err(RobotError {
            wheel,
            field,
            problem: Problem::NotPositive(v),
        })
    }
}

fn check_non_negative(
    v: f64,
    field: Field,
    wheel: Option<(usize, WheelName)>,
) -> Result<(), RobotError> {
    check_finite(v, field, wheel.clone())?;
    if v >= 0.0 {
        Ok(())
    } else {
        Err(RobotError {
            wheel,
            field,
            problem: Problem::Negative(v),
        })
    }
}

/// Builders for the robots the papers describe, so tests and the firmware's defaults do not
/// depend on files.
pub mod presets {
    use super::*;

    fn wheel(name: &str, r: f64, alpha_deg: f64, l: f64, beta_deg: f64, driven: bool) -> Wheel {
        let mut n = WheelName::new();
        let _ = n.push_str(name);
        Wheel {
            name: n,
            radius_m: r,
            alpha_rad: alpha_deg.to_radians(),
            l_m: l,
            beta_rad: beta_deg.to_radians(),
            gamma_rad: 0.0,
            driven,
        }
    }

    /// A differential drive with wheels `left` (alpha 90, beta 0) and `right` (alpha -90,
    /// beta 180), so positive rates drive both forward.
    pub fn diff_drive(name: &str, radius_m: f64, wheelbase_m: f64, drive: Drive) -> Robot {
        let wheels = [
            wheel("left", radius_m, 90.0, wheelbase_m / 2.0, 0.0, true),
            wheel("right", radius_m, -90.0, wheelbase_m / 2.0, 180.0, true),
        ];
        Robot::new(name, RobotKind::DiffDrive, drive, &wheels, None)
            .expect("preset geometry is valid")
    }

    /// A four-wheel skid-steer robot: wheels at (+-wheelbase/2, +-track/2), each rolling
    /// along body x (beta = 90 deg - alpha, so positive rates drive forward), order
    /// front_left, rear_left, front_right, rear_right.
    pub fn skid4(name: &str, radius_m: f64, track_m: f64, wheelbase_m: f64, drive: Drive) -> Robot {
        let at = |n: &str, x: f64, y: f64| {
            let alpha = libm::atan2(y, x).to_degrees();
            wheel(n, radius_m, alpha, libm::hypot(x, y), 90.0 - alpha, true)
        };
        let (a, b) = (wheelbase_m / 2.0, track_m / 2.0);
        let wheels = [
            at("front_left", a, b),
            at("rear_left", -a, b),
            at("front_right", a, -b),
            at("rear_right", -a, -b),
        ];
        Robot::new(name, RobotKind::SkidSteer, drive, &wheels, None)
            .expect("preset geometry is valid")
    }

    /// The four-wheel omni robot of [Redundant omni]: wheels at alpha 90, 180, 270, 0 deg,
    /// r = 0.03 m, l = 0.035 m, 480-ppr encoders.
    pub fn omni4() -> Robot {
        let wheels = [
            wheel("w1", 0.03, 90.0, 0.035, 0.0, true),
            wheel("w2", 0.03, 180.0, 0.035, 0.0, true),
            wheel("w3", 0.03, 270.0, 0.035, 0.0, true),
            wheel("w4", 0.03, 0.0, 0.035, 0.0, true),
        ];
        Robot::new("omni4", RobotKind::Omni, Drive::default(), &wheels, None)
            .expect("preset geometry is valid")
    }

    /// A three-wheel omni robot with wheels 120 deg apart.
    pub fn omni3(radius_m: f64, l_m: f64) -> Robot {
        let wheels = [
            wheel("w1", radius_m, 60.0, l_m, 0.0, true),
            wheel("w2", radius_m, 180.0, l_m, 0.0, true),
            wheel("w3", radius_m, 300.0, l_m, 0.0, true),
        ];
        Robot::new("omni3", RobotKind::Omni, Drive::default(), &wheels, None)
            .expect("preset geometry is valid")
    }

    /// MoboLab of [Measuring errors]: stepper, 1.8 deg/step, 78/16 gears, 100 mm wheels.
    /// The paper gives no wheelbase; 0.40 m suits its 60 cm square chassis.
    pub fn mobolab() -> Robot {
        let drive = Drive {
            kind: DriveType::Stepper,
            steps_per_rev: 200,
            microsteps: 1,
            gear_ratio: 78.0 / 16.0,
            encoder_counts_per_rev: DEFAULT_COUNTS_PER_REV,
        };
        diff_drive("mobolab", 0.05, 0.40, drive)
    }
}

#[cfg(test)]
mod tests {
    use super::presets::*;
    use super::*;

    #[test]
    fn diff_drive_rows_follow_siegwart() {
        let r = mobolab();
        // Left wheel: [1, 0, -l]; right: [1, 0, +l] (alpha -90 + beta 180 = 90).
        let l = r.wheels[0].rolling_row();
        let rr = r.wheels[1].rolling_row();
        assert!((l[0] - 1.0).abs() < 1e-12 && l[1].abs() < 1e-12 && (l[2] + 0.2).abs() < 1e-12);
        assert!((rr[0] - 1.0).abs() < 1e-12 && rr[1].abs() < 1e-12 && (rr[2] - 0.2).abs() < 1e-12);
    }

    #[test]
    fn errors_name_wheel_and_field() {
        let mut w = mobolab().wheels.clone();
        w[1].radius_m = -0.05;
        let e = Robot::new("x", RobotKind::DiffDrive, Drive::default(), &w, None).unwrap_err();
        assert_eq!(e.field, Field::RadiusM);
        assert_eq!(e.wheel.as_ref().map(|(i, _)| *i), Some(1));
        let text = std::format!("{e}");
        assert!(text.contains("'right'") && text.contains("radius_m") && text.contains("-0.05"));

        let mut w = mobolab().wheels.clone();
        w[1].name = w[0].name.clone();
        let e = Robot::new("x", RobotKind::DiffDrive, Drive::default(), &w, None).unwrap_err();
        assert_eq!(e.problem, Problem::DuplicateName);

        let mut w = omni4().wheels.clone();
        w[2].gamma_rad = core::f64::consts::FRAC_PI_2;
        let e = Robot::new("x", RobotKind::Omni, Drive::default(), &w, None).unwrap_err();
        assert_eq!(
            (e.field, e.problem),
            (Field::GammaDeg, Problem::RollerParallelToAxle)
        );
    }

    #[test]
    fn skid_steer_needs_two_wheels_a_side_rolling_along_x() {
        let r = skid4("rover", 0.1, 0.4, 0.31, Drive::default());
        assert_eq!(r.wheels.iter().filter(|w| w.is_left()).count(), 2);
        for w in &r.wheels {
            // Every wheel's rolling row is [1, 0, -y]: positive rates drive forward.
            let (_, y) = w.position();
            let row = w.rolling_row();
            assert!((row[0] - 1.0).abs() < 1e-12 && row[1].abs() < 1e-12);
            assert!((row[2] + y).abs() < 1e-12, "{row:?} at y {y}");
        }
        let three = &r.wheels[..3];
        let e = Robot::new("x", RobotKind::SkidSteer, Drive::default(), three, None).unwrap_err();
        assert_eq!(e.problem, Problem::SkidSteerSides { left: 2, right: 1 });
        let mut text = heapless::String::<200>::new();
        core::fmt::write(&mut text, format_args!("{e}")).unwrap();
        assert!(text.contains("2 left (y > 0) and 1 right"), "{text}");
        let mut turned = r.wheels.clone();
        turned[2].beta_rad += 0.1;
        let e = Robot::new("x", RobotKind::SkidSteer, Drive::default(), &turned, None).unwrap_err();
        assert_eq!(e.problem, Problem::NotAlongBodyX);
        assert_eq!(e.wheel.map(|(i, _)| i), Some(2));
    }

    #[test]
    fn singular_geometry_is_rejected() {
        // Two omni wheels cannot resolve three degrees of freedom.
        let w = &omni4().wheels[..2];
        let e = Robot::new("x", RobotKind::Omni, Drive::default(), w, None).unwrap_err();
        assert_eq!(e.problem, Problem::SingularJacobian);
        // Three omni wheels all rolling along x cannot see vy.
        let mut w = omni4().wheels.clone();
        w.truncate(3);
        for wh in w.iter_mut() {
            wh.alpha_rad = core::f64::consts::FRAC_PI_2;
            wh.beta_rad = 0.0;
        }
        w[1].l_m = 0.05;
        w[2].l_m = 0.07;
        let e = Robot::new("x", RobotKind::Omni, Drive::default(), &w, None).unwrap_err();
        assert_eq!(e.problem, Problem::SingularJacobian);
    }

    #[test]
    fn load_share_by_moment_balance() {
        let legs = Legs {
            length_m: 0.135,
            body_length_m: 0.35,
            body_mass_kg: 2.8,
            leg_mass_kg: 0.1,
        };
        let v = core::f64::consts::FRAC_PI_2;
        // Vertical legs: contacts at +-0.175, mass in the middle: half each.
        assert!((legs.front_load_share(v, v).unwrap() - 0.5).abs() < 1e-12);
        // Rear leg swept back to 150 deg: rear contact at -0.175 - 0.135*cos(30deg) = -0.2919;
        // front at +0.175: share = 0.2919 / 0.4669.
        let s = legs.front_load_share(v, 150f64.to_radians()).unwrap();
        let xr = -0.175 - 0.135 * (30f64.to_radians()).cos();
        assert!((s - (-xr) / (0.175 - xr)).abs() < 1e-12);
        assert!((s - 0.6252).abs() < 1e-3);
    }
}
