//! Robot parameters, safety settings and motion programs, with their validation.

#[allow(unused_imports)]
use super::*;
use crate::motion::Program;

/// Robot geometry and the settings that go with it, persisted together.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Params {
    /// Geometry of the robot and its wheels.
    pub robot: Robot,
    /// Wheel velocity controller gains.
    pub gains: PiGains,
    /// Speed and acceleration limits of the motion profiles.
    pub limits: ProfileLimits,
    /// When the board stops the motors by itself.
    pub safety: Safety,
}

/// When the board stops the motors by itself.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Safety {
    /// Drive commands older than this stop the motors.
    pub command_timeout_ms: u16,
    /// A wheel commanded above `stall_min_rate` whose encoder does not move for this long
    /// is a fault.
    pub stall_timeout_ms: u16,
    /// rad/s.
    pub stall_min_rate: f32,
    /// An encoder moving more than this in one tick is a fault (a glitch or a wrap missed).
    pub max_jump_counts: u32,
    /// Largest distance a program may drive (m): the size of the floor the robot runs
    /// on. A UMBmark side, an omni path or a custom segment longer than this is refused,
    /// so a typo (`--length=-50`, `--side 40`) never sends the robot across the lab.
    pub arena_m: f32,
}

impl Default for Safety {
    fn default() -> Self {
        Safety {
            command_timeout_ms: 250,
            stall_timeout_ms: 50,
            stall_min_rate: 0.5,
            max_jump_counts: 2000,
            arena_m: 10.0,
        }
    }
}

/// The settings [`Params::validate`] checks, in order; a rejection names one by its index.
pub const SETTING_NAMES: [&str; 14] = [
    "gains.kp",
    "gains.ki",
    "gains.kff",
    "gains.kstatic",
    "gains.out_max",
    "limits.v_max",
    "limits.a_max",
    "limits.omega_max",
    "limits.alpha_max",
    "safety.command_timeout_ms",
    "safety.stall_timeout_ms",
    "safety.stall_min_rate",
    "safety.max_jump_counts",
    "safety.arena_m",
];

/// Why a [`Params`] was refused.
#[derive(Debug, Clone, PartialEq)]
pub enum ParamsError {
    /// The robot geometry is invalid.
    Robot(RobotError),
    /// A setting is out of its range.
    Setting {
        /// Name of the setting.
        name: &'static str,
        /// Smallest value allowed.
        min: f64,
        /// Largest value allowed.
        max: f64,
        /// The value given.
        value: f64,
    },
}

impl fmt::Display for ParamsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamsError::Robot(e) => write!(f, "robot: {e}"),
            ParamsError::Setting {
                name,
                min,
                max,
                value,
            } => write!(
                f,
                "{name} = {} is outside [{}, {}]",
                Num(*value),
                Num(*min),
                Num(*max)
            ),
        }
    }
}

impl Params {
    /// Checks every value: the robot through [`Robot::new`] (a robot that arrives over the
    /// wire was never validated), the rest against sane ranges (NaN fails every range).
    pub fn validate(&self) -> Result<(), ParamsError> {
        let r = &self.robot;
        Robot::new(&r.name, r.kind, r.drive, &r.wheels, r.legs).map_err(ParamsError::Robot)?;
        let g = &self.gains;
        let l = &self.limits;
        let s = &self.safety;
        // (value, min, max) in the order of SETTING_NAMES.
        let ranges: [(f64, f64, f64); 14] = [
            (g.kp as f64, 0.0, 100.0),
            (g.ki as f64, 0.0, 1000.0),
            (g.kff as f64, 0.0, 100.0),
            (g.kstatic as f64, 0.0, 1.0),
            (g.out_max as f64, 0.01, 1.0),
            (l.v_max, 1e-3, 5.0),
            (l.a_max, 1e-3, 20.0),
            (l.omega_max, 1e-3, 20.0),
            (l.alpha_max, 1e-3, 100.0),
            (s.command_timeout_ms as f64, 10.0, 10_000.0),
            (s.stall_timeout_ms as f64, 5.0, 5_000.0),
            (s.stall_min_rate as f64, 0.0, 100.0),
            (s.max_jump_counts as f64, 1.0, 32_767.0),
            (s.arena_m as f64, 0.5, 1000.0),
        ];
        for (name, (value, min, max)) in SETTING_NAMES.into_iter().zip(ranges) {
            if !(min..=max).contains(&value) {
                return Err(ParamsError::Setting {
                    name,
                    min,
                    max,
                    value,
                });
            }
        }
        Ok(())
    }
}

/// A motion program as the host asks for it.
// Messages are built once per frame and never moved in bulk; no_std has no Box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum ProgramSpec {
    /// Borenstein's square.
    Umbmark {
        /// Side length (m).
        side_m: f64,
        /// Turning sense.
        dir: Direction,
    },
    /// [Redundant omni]'s straight omni paths.
    Omni {
        /// Which path.
        path: OmniPath,
        /// Commanded length (m).
        length_m: f64,
        /// What the wheels the path does not drive do: released (drive cut) or held at
        /// zero speed by their velocity loops ([Redundant omni] does both, one per path).
        idle: IdleWheels,
    },
    /// Up to [`MAX_SEGMENTS`] segments.
    Custom(Vec<Segment, MAX_SEGMENTS>),
    /// A circle driven forward ([`Program::circle`](crate::motion::Program::circle)):
    /// the arcs a turn-radius law needs, which squares lack.
    Circle {
        /// Radius (m).
        radius_m: f64,
        /// Turning sense.
        dir: Direction,
        /// Times round, 1 to [`MAX_LAPS`].
        laps: u8,
    },
}

/// Most laps a circle program drives.
pub const MAX_LAPS: u8 = 10;

/// Tightest arc a program drives (m): below it the speed an arc may take within the
/// turn-rate limit (omega_max x r) is a crawl, and a robot turns in place instead.
pub const MIN_ARC_RADIUS_M: f64 = 0.01;

impl ProgramSpec {
    /// Checks every number is finite and within reach before anything moves: sides and
    /// path lengths positive and at most `arena_m` (the board's [`Safety::arena_m`]),
    /// custom straights and translations within the arena, turns of at most 100 rad,
    /// pauses of at most 10 min, circles and arcs from [`MIN_ARC_RADIUS_M`] to the arena
    /// (a circle's diameter within it, 1 to [`MAX_LAPS`] laps), and that wheel indices
    /// exist. The board refuses a program
    /// that fails, and the console runs the same check before sending.
    pub fn validate(
        &self,
        wheel_count: usize,
        kind: RobotKind,
        arena_m: f64,
    ) -> Result<(), ProgramError> {
        use ProgramField as F;
        let fin = |v: f64, max: f64, field: ProgramField| -> Result<(), ProgramError> {
            if v.is_finite() && v.abs() <= max {
                Ok(())
            } else {
                Err(ProgramError::OutOfRange {
                    field,
                    value: v,
                    max,
                })
            }
        };
        let positive = |v: f64, field: ProgramField| -> Result<(), ProgramError> {
            if v > 0.0 {
                Ok(())
            } else {
                Err(ProgramError::NotPositive { field, value: v })
            }
        };
        let at_least = |v: f64, min: f64, field: ProgramField| -> Result<(), ProgramError> {
            if v >= min {
                Ok(())
            } else {
                Err(ProgramError::TooSmall {
                    field,
                    value: v,
                    min,
                })
            }
        };
        match self {
            ProgramSpec::Umbmark { side_m, .. } => {
                fin(*side_m, arena_m, F::SideM)?;
                positive(*side_m, F::SideM)?;
            }
            ProgramSpec::Omni { length_m, .. } => {
                if kind != RobotKind::Omni {
                    return Err(ProgramError::NeedsOmni { robot: kind });
                }
                fin(*length_m, arena_m, F::LengthM)?;
                positive(*length_m, F::LengthM)?;
            }
            ProgramSpec::Circle { radius_m, laps, .. } => {
                // Its diameter within the arena.
                fin(*radius_m, arena_m / 2.0, F::RadiusM)?;
                at_least(*radius_m, MIN_ARC_RADIUS_M, F::RadiusM)?;
                if *laps == 0 {
                    return Err(ProgramError::NotPositive {
                        field: F::Laps,
                        value: 0.0,
                    });
                }
                fin(f64::from(*laps), f64::from(MAX_LAPS), F::Laps)?;
            }
            ProgramSpec::Custom(segs) => {
                if segs.is_empty() {
                    return Err(ProgramError::NoSegments);
                }
                for s in segs {
                    match *s {
                        Segment::Straight { distance_m } => fin(distance_m, arena_m, F::DistanceM)?,
                        Segment::Turn { angle_rad } => fin(angle_rad, 100.0, F::AngleRad)?,
                        Segment::Arc {
                            radius_m,
                            angle_rad,
                        } => {
                            fin(radius_m, arena_m, F::RadiusM)?;
                            at_least(radius_m, MIN_ARC_RADIUS_M, F::RadiusM)?;
                            fin(angle_rad, 100.0, F::AngleRad)?;
                        }
                        Segment::Translate { dx_m, dy_m } => {
                            if kind != RobotKind::Omni {
                                return Err(ProgramError::NeedsOmni { robot: kind });
                            }
                            fin(dx_m, arena_m, F::DxM)?;
                            fin(dy_m, arena_m, F::DyM)?;
                        }
                        Segment::SingleWheel { wheel, angle_rad } => {
                            if wheel as usize >= wheel_count {
                                return Err(ProgramError::NoSuchWheel {
                                    wheel,
                                    wheels: wheel_count.min(u8::MAX as usize) as u8,
                                });
                            }
                            fin(angle_rad, 1000.0, F::AngleRad)?;
                        }
                        Segment::Pause { duration_s } => {
                            fin(duration_s, 600.0, F::DurationS)?;
                            if duration_s < 0.0 {
                                return Err(ProgramError::NotPositive {
                                    field: F::DurationS,
                                    value: duration_s,
                                });
                            }
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The segments the board runs for it (the host forecasts its duration from the same).
    pub fn program(&self) -> Program {
        match self {
            ProgramSpec::Umbmark { side_m, dir } => Program::umbmark_square(*side_m, *dir),
            ProgramSpec::Omni { path, length_m, .. } => Program::omni_path(*path, *length_m),
            ProgramSpec::Custom(segs) => Program {
                segments: segs.clone(),
            },
            ProgramSpec::Circle {
                radius_m,
                dir,
                laps,
            } => Program::circle(*radius_m, *dir, *laps),
        }
    }

    /// The short description kept in a trial's header.
    pub fn kind(&self) -> ProgramKind {
        match self {
            ProgramSpec::Umbmark { side_m, dir } => ProgramKind::Umbmark {
                side_m: *side_m as f32,
                dir: *dir,
            },
            ProgramSpec::Omni { path, length_m, .. } => ProgramKind::Omni {
                path: *path,
                length_m: *length_m as f32,
            },
            ProgramSpec::Custom(s) => ProgramKind::Custom {
                segments: s.len() as u8,
            },
            ProgramSpec::Circle {
                radius_m,
                dir,
                laps,
            } => ProgramKind::Circle {
                radius_m: *radius_m as f32,
                dir: *dir,
                laps: *laps,
            },
        }
    }
}

/// A number of a program or drive request, named on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum ProgramField {
    /// A UMBmark side (m).
    SideM,
    /// An omni path length (m).
    LengthM,
    /// A straight segment (m).
    DistanceM,
    /// A turn or single-wheel angle (rad).
    AngleRad,
    /// A translation along body x (m).
    DxM,
    /// A translation along body y (m).
    DyM,
    /// A pause (s).
    DurationS,
    /// An arc's or a circle's radius (m).
    RadiusM,
    /// A circle's laps.
    Laps,
}

impl ProgramField {
    /// The field's name as in the program spec.
    pub fn as_str(self) -> &'static str {
        match self {
            ProgramField::SideM => "side_m",
            ProgramField::LengthM => "length_m",
            ProgramField::DistanceM => "distance_m",
            ProgramField::AngleRad => "angle_rad",
            ProgramField::DxM => "dx_m",
            ProgramField::DyM => "dy_m",
            ProgramField::DurationS => "duration_s",
            ProgramField::RadiusM => "radius_m",
            ProgramField::Laps => "laps",
        }
    }
}

/// Why a program or a drive was refused (structured: the host words it).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum ProgramError {
    /// Not finite, or `|value| > max`.
    OutOfRange {
        /// Which number.
        field: ProgramField,
        /// The value refused.
        value: f64,
        /// Largest allowed magnitude.
        max: f64,
    },
    /// Zero or negative where only positive makes sense (a pause: negative).
    NotPositive {
        /// Which number.
        field: ProgramField,
        /// The value refused.
        value: f64,
    },
    /// Omni paths and translate segments need an omni robot.
    NeedsOmni {
        /// The robot's kind.
        robot: RobotKind,
    },
    /// A custom program without segments.
    NoSegments,
    /// A single-wheel segment names a wheel the robot does not have.
    NoSuchWheel {
        /// The wheel index given (from 0).
        wheel: u8,
        /// Wheels of the robot.
        wheels: u8,
    },
    /// A drive twist not finite or beyond the board's limits.
    Twist {
        /// The twist refused (m/s, m/s, rad/s).
        twist: Twist<f32>,
        /// The board's speed limit (m/s).
        v_max: f64,
        /// The board's turn-rate limit (rad/s).
        omega_max: f64,
    },
    /// A host-link timeout shorter than the console's requests can keep alive.
    LinkTimeout {
        /// The timeout asked for (ms).
        ms: u16,
    },
    /// Below the least value that makes sense (an arc tighter than
    /// [`MIN_ARC_RADIUS_M`]).
    TooSmall {
        /// Which number.
        field: ProgramField,
        /// The value refused.
        value: f64,
        /// The least allowed.
        min: f64,
    },
}

impl fmt::Display for ProgramError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            ProgramError::OutOfRange { field, value, max } => {
                let w = field.as_str();
                write!(
                    f,
                    "{w} = {} must be finite and |{w}| <= {}",
                    Num(value),
                    Num(max)
                )
            }
            ProgramError::NotPositive {
                field: ProgramField::DurationS,
                value,
            } => write!(f, "duration_s = {} must not be negative", Num(value)),
            ProgramError::NotPositive { field, value } => {
                write!(f, "{} = {} must be positive", field.as_str(), Num(value))
            }
            ProgramError::NeedsOmni { robot } => write!(
                f,
                "omni paths and translate segments need an omni robot, not {}",
                robot.as_str()
            ),
            ProgramError::NoSegments => f.write_str("a custom program needs at least one segment"),
            ProgramError::TooSmall { field, value, min } => write!(
                f,
                "{} = {} must be at least {}",
                field.as_str(),
                Num(value),
                Num(min)
            ),
            ProgramError::NoSuchWheel { wheel, wheels } => {
                write!(f, "wheel {wheel} does not exist ({wheels} wheels)")
            }
            ProgramError::Twist {
                twist,
                v_max,
                omega_max,
            } => write!(
                f,
                "twist ({}, {}, {}) must be finite and within v_max {} m/s, omega_max {} rad/s",
                Num(twist.vx as f64),
                Num(twist.vy as f64),
                Num(twist.omega as f64),
                Num(v_max),
                Num(omega_max)
            ),
            ProgramError::LinkTimeout { ms } => write!(
                f,
                "link timeout {ms} ms is too short: 0 (off) or at least {MIN_LINK_TIMEOUT_MS} ms"
            ),
        }
    }
}
