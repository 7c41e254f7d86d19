//! Robot parameters, safety settings and motion programs, with their validation.

#[allow(unused_imports)]
use super::*;

/// Robot geometry and the settings that go with it, persisted together.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
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
            ParamsError::Robot(e) => write!(f, "robot: {}", RobotText(e)),
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
        let ranges: [(&'static str, f64, f64, f64); 14] = [
            ("gains.kp", g.kp as f64, 0.0, 100.0),
            ("gains.ki", g.ki as f64, 0.0, 1000.0),
            ("gains.kff", g.kff as f64, 0.0, 100.0),
            ("gains.kstatic", g.kstatic as f64, 0.0, 1.0),
            ("gains.out_max", g.out_max as f64, 0.01, 1.0),
            ("limits.v_max", l.v_max, 1e-3, 5.0),
            ("limits.a_max", l.a_max, 1e-3, 20.0),
            ("limits.omega_max", l.omega_max, 1e-3, 20.0),
            ("limits.alpha_max", l.alpha_max, 1e-3, 100.0),
            (
                "safety.command_timeout_ms",
                s.command_timeout_ms as f64,
                10.0,
                10_000.0,
            ),
            (
                "safety.stall_timeout_ms",
                s.stall_timeout_ms as f64,
                5.0,
                5_000.0,
            ),
            ("safety.stall_min_rate", s.stall_min_rate as f64, 0.0, 100.0),
            (
                "safety.max_jump_counts",
                s.max_jump_counts as f64,
                1.0,
                32_767.0,
            ),
            ("safety.arena_m", s.arena_m as f64, 0.5, 1000.0),
        ];
        for (name, value, min, max) in ranges {
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ProgramSpec {
    /// Borenstein's square.
    Umbmark {
        /// Side length (m).
        side_m: f64,
        /// Turning sense.
        dir: Direction,
    },
    /// 001's straight omni paths.
    Omni {
        /// Which path.
        path: OmniPath,
        /// Commanded length (m).
        length_m: f64,
        /// What the wheels the path does not drive do: released (drive cut) or held at
        /// zero speed by their velocity loops (001 does both, one per path).
        idle: IdleWheels,
    },
    /// Up to [`MAX_SEGMENTS`] segments.
    Custom(Vec<Segment, MAX_SEGMENTS>),
}

impl ProgramSpec {
    /// Checks every number is finite and within reach before anything moves: sides and
    /// path lengths positive and at most `arena_m` (the board's [`Safety::arena_m`]),
    /// custom straights and translations within the arena, turns of at most 100 rad,
    /// pauses of at most 10 min, and that wheel indices exist. The board refuses a program
    /// that fails, and the console runs the same check before sending.
    pub fn validate(
        &self,
        wheel_count: usize,
        kind: RobotKind,
        arena_m: f64,
    ) -> Result<(), Reason> {
        let fin = |v: f64, max: f64, what: &str| -> Result<(), Reason> {
            if v.is_finite() && v.abs() <= max {
                Ok(())
            } else {
                Err(reason(&format_args!(
                    "{what} = {} must be finite and |{what}| <= {}",
                    Num(v),
                    Num(max)
                )))
            }
        };
        match self {
            ProgramSpec::Umbmark { side_m, .. } => {
                fin(*side_m, arena_m, "side_m")?;
                if *side_m <= 0.0 {
                    return Err(reason(&"side_m must be positive"));
                }
            }
            ProgramSpec::Omni { length_m, .. } => {
                if kind != RobotKind::Omni {
                    return Err(reason(&"omni paths need an omni robot"));
                }
                fin(*length_m, arena_m, "length_m")?;
                if *length_m <= 0.0 {
                    return Err(reason(&"length_m must be positive"));
                }
            }
            ProgramSpec::Custom(segs) => {
                if segs.is_empty() {
                    return Err(reason(&"a custom program needs at least one segment"));
                }
                for s in segs {
                    match *s {
                        Segment::Straight { distance_m } => fin(distance_m, arena_m, "distance_m")?,
                        Segment::Turn { angle_rad } => fin(angle_rad, 100.0, "angle_rad")?,
                        Segment::Translate { dx_m, dy_m } => {
                            if kind != RobotKind::Omni {
                                return Err(reason(&"translate segments need an omni robot"));
                            }
                            fin(dx_m, arena_m, "dx_m")?;
                            fin(dy_m, arena_m, "dy_m")?;
                        }
                        Segment::SingleWheel { wheel, angle_rad } => {
                            if wheel as usize >= wheel_count {
                                return Err(reason(&format_args!(
                                    "wheel {wheel} does not exist ({wheel_count} wheels)"
                                )));
                            }
                            fin(angle_rad, 1000.0, "angle_rad")?;
                        }
                        Segment::Pause { duration_s } => {
                            fin(duration_s, 600.0, "duration_s")?;
                            if duration_s < 0.0 {
                                return Err(reason(&"duration_s must not be negative"));
                            }
                        }
                    }
                }
            }
        }
        Ok(())
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
        }
    }
}
