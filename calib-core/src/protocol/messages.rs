//! Requests, responses and the state a board reports.

#[allow(unused_imports)]
use super::*;

// Messages
// ---------------------------------------------------------------------------------------

/// What the host asks of a board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Request {
    /// Variant 0, frozen: the handshake.
    Hello {
        protocol_version: u16,
        schema: u32,
    },
    GetInfo,
    GetCorrections,
    /// Makes these the active corrections (validated; not persisted until saved).
    SetCorrections(Corrections),
    /// Persists the active corrections.
    SaveCorrections,
    /// Active corrections back to none (persist with SaveCorrections).
    ResetCorrections,
    GetParams,
    /// Replaces robot geometry, gains, limits and safety settings (validated; idle only).
    SetParams(Params),
    SaveParams,
    /// Active parameters back to the firmware's defaults (idle only).
    ResetParams,
    /// Drive at a body twist until the next Drive, or stop after `timeout_ms` (0 = the
    /// configured command timeout; longer values are capped by it).
    Drive {
        twist: Twist<f32>,
        timeout_ms: u16,
    },
    /// Run a motion program, logging a trial at `log_rate_hz` (0 = no log).
    RunProgram {
        program: ProgramSpec,
        log_rate_hz: u16,
    },
    /// Controlled stop (ramps to zero through the controllers).
    Stop,
    /// Immediate motor cut-off, latched until ClearFault.
    EStop,
    /// Clears a latched E-stop or fault.
    ClearFault,
    GetStatus,
    /// Unsolicited status frames every `period_ms` (0 = off).
    SetTelemetry {
        period_ms: u16,
    },
    ListTrials,
    /// Bytes `offset..offset+max_len` of a trial's records (resumable: ask again from the
    /// offset reached).
    ReadLog {
        trial: u16,
        offset: u32,
        max_len: u16,
    },
    ClearLogs,
}

/// A board's answer (or unsolicited telemetry).
// Messages are built once per frame and never moved in bulk; no_std has no Box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Response<'a> {
    /// Variant 0, frozen: the handshake answer; `compatible` is false on a mismatch.
    Hello {
        protocol_version: u16,
        schema: u32,
        firmware: String<FIRMWARE_LEN>,
        compatible: bool,
    },
    Ok,
    Info(Info),
    Corrections(Corrections),
    Params(Params),
    Status(Status),
    /// Unsolicited, every telemetry period.
    Telemetry(Status),
    Trials(Trials),
    #[serde(borrow)]
    LogChunk(LogChunk<'a>),
    /// The request was refused and nothing changed.
    Rejected(Rejection),
    /// A frame arrived damaged (sequence number unknown): resend the last request.
    Nack(FrameError),
}

/// Everything a board reports about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Info {
    pub firmware: String<FIRMWARE_LEN>,
    pub protocol_version: u16,
    pub schema: u32,
    pub robot_kind: RobotKind,
    pub drive: DriveType,
    pub wheel_count: u8,
    pub uptime_ms: u64,
    pub boot: BootReport,
    /// Bytes of trial-log RAM.
    pub log_capacity: u32,
    /// Bytes per log record for this robot.
    pub record_size: u16,
}

/// What the board found in flash at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BootReport {
    pub corrections: Stored,
    pub params: Stored,
}

/// State of one persisted item at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stored {
    /// Read, CRC and ranges good: in use.
    Loaded,
    /// Never saved: defaults in use.
    Missing,
    /// Present but failed CRC, decoding or validation: defaults in use.
    Invalid,
    /// The flash could not be read: defaults in use.
    StorageError,
}

/// Live state of a board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Status {
    pub uptime_ms: u64,
    pub mode: Mode,
    /// Why the motors last stopped.
    pub stop: StopReason,
    /// E-stop latched.
    pub estop: bool,
    /// Latched fault.
    pub fault: Option<Fault>,
    /// Odometry pose since the last program start (or boot).
    pub pose: Pose<f32>,
    /// Measured wheel rates, rad/s.
    pub wheel_rates: Vec<f32, MAX_WHEELS>,
    /// Commanded wheel rates, rad/s (corrections applied).
    pub wheel_cmds: Vec<f32, MAX_WHEELS>,
    /// Trial being recorded.
    pub trial: Option<u16>,
    /// Free bytes of the log ring.
    pub log_free: u32,
    /// Records dropped since boot because the log was full (see `firmware-app`'s log).
    pub dropped_records: u32,
    /// Trials evicted since boot to make room.
    pub evicted_trials: u32,
    /// Damaged frames received since boot.
    pub bad_frames: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    Idle,
    Drive,
    Program { segment: u8, segments: u8 },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StopReason {
    None,
    Request,
    EStop,
    CommandTimeout,
    Fault,
    ProgramDone,
}

/// A detected hardware fault (latched, motors off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// Commanded but the encoder did not move.
    Stall { wheel: u8 },
    /// The encoder moved implausibly far in one tick.
    CounterJump { wheel: u8, delta: i32 },
}

impl fmt::Display for Fault {
    /// Wheels numbered from 1, as in the robot file and the console's output.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Fault::Stall { wheel } => write!(
                f,
                "stall: wheel {} was commanded but its encoder did not move",
                *wheel as u16 + 1
            ),
            Fault::CounterJump { wheel, delta } => write!(
                f,
                "counter jump: wheel {}'s encoder moved {delta} counts in one tick",
                *wheel as u16 + 1
            ),
        }
    }
}

/// Why a request was refused; the board's state is unchanged. Structured (no text is
/// built on the board): the host words it with one `Display`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Rejection {
    ProtocolMismatch {
        board_version: u16,
        board_schema: u32,
    },
    InvalidCorrections(CorrectionFault),
    InvalidParams(ParamsFault),
    InvalidProgram(ProgramError),
    /// Not while a program or drive is under way.
    Busy,
    /// E-stop latched: send ClearFault first.
    EStopped,
    /// A fault is latched: send ClearFault first.
    Faulted(Fault),
    NoSuchTrial,
    /// The offset is past the trial's end.
    BadOffset {
        total: u32,
    },
    /// Flash write or read failed; the stored values are unchanged.
    Storage,
    /// The frame was intact but its body is not a request this firmware knows.
    Undecodable,
}

impl Rejection {
    pub fn corrections(e: &CorrectionError) -> Self {
        Rejection::InvalidCorrections(CorrectionFault::from(e))
    }
}

/// A correction factor, as named on the wire ([`CorrectionError`] names it with text).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum Factor {
    CL,
    CR,
    EB,
    FLat,
    FLon,
}

impl Factor {
    /// From the name `correction::check` was given (always one of the five; anything
    /// else reads as f_lat).
    pub fn from_name(name: &str) -> Factor {
        match name {
            "c_l" => Factor::CL,
            "c_r" => Factor::CR,
            "e_b" => Factor::EB,
            "f_lon" => Factor::FLon,
            _ => Factor::FLat,
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Factor::CL => "c_l",
            Factor::CR => "c_r",
            Factor::EB => "e_b",
            Factor::FLat => "f_lat",
            Factor::FLon => "f_lon",
        }
    }
}

/// Why corrections were refused, on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum CorrectionFault {
    NotFinite {
        factor: Factor,
        index: Option<u8>,
    },
    OutOfRange {
        factor: Factor,
        index: Option<u8>,
        value: f64,
    },
    WrongWheelCount {
        expected: u8,
        got: u8,
    },
    WrongKind {
        robot: RobotKind,
    },
    /// The corrected geometry cannot resolve a body twist.
    Singular,
}

impl From<&CorrectionError> for CorrectionFault {
    fn from(e: &CorrectionError) -> Self {
        let idx = |i: &Option<usize>| i.map(|i| i.min(u8::MAX as usize) as u8);
        let n = |v: usize| v.min(u8::MAX as usize) as u8;
        match e {
            CorrectionError::NotFinite { name, index } => CorrectionFault::NotFinite {
                factor: Factor::from_name(name),
                index: idx(index),
            },
            CorrectionError::OutOfRange { name, index, value } => CorrectionFault::OutOfRange {
                factor: Factor::from_name(name),
                index: idx(index),
                value: *value,
            },
            CorrectionError::WrongWheelCount { expected, got } => {
                CorrectionFault::WrongWheelCount {
                    expected: n(*expected),
                    got: n(*got),
                }
            }
            CorrectionError::WrongKind { robot } => CorrectionFault::WrongKind { robot: *robot },
        }
    }
}

impl fmt::Display for CorrectionFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = match *self {
            CorrectionFault::Singular => return f.write_str("the corrected geometry is singular"),
            CorrectionFault::NotFinite { factor, index } => CorrectionError::NotFinite {
                name: factor.as_str(),
                index: index.map(usize::from),
            },
            CorrectionFault::OutOfRange {
                factor,
                index,
                value,
            } => CorrectionError::OutOfRange {
                name: factor.as_str(),
                index: index.map(usize::from),
                value,
            },
            CorrectionFault::WrongWheelCount { expected, got } => {
                CorrectionError::WrongWheelCount {
                    expected: expected.into(),
                    got: got.into(),
                }
            }
            CorrectionFault::WrongKind { robot } => CorrectionError::WrongKind { robot },
        };
        CorrectionText(&e).fmt(f)
    }
}

/// Why parameters were refused, on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum ParamsFault {
    /// The robot description: wheel index (from 0) if a wheel is concerned.
    Robot {
        wheel: Option<u8>,
        field: crate::robot::Field,
        problem: crate::robot::Problem,
    },
    /// Setting [`SETTING_NAMES`]`[index]` is outside `[min, max]`.
    Setting {
        index: u8,
        min: f64,
        max: f64,
        value: f64,
    },
    /// The active corrections do not fit the new robot: reset them first.
    CorrectionsDoNotFit(CorrectionFault),
    /// The geometry cannot resolve a body twist.
    Singular,
}

impl From<&ParamsError> for ParamsFault {
    fn from(e: &ParamsError) -> Self {
        match e {
            ParamsError::Robot(r) => ParamsFault::Robot {
                wheel: r
                    .wheel
                    .as_ref()
                    .map(|(i, _)| (*i).min(u8::MAX as usize) as u8),
                field: r.field,
                problem: r.problem,
            },
            ParamsError::Setting {
                name,
                min,
                max,
                value,
            } => ParamsFault::Setting {
                index: SETTING_NAMES
                    .iter()
                    .position(|n| n == name)
                    .unwrap_or(u8::MAX as usize) as u8,
                min: *min,
                max: *max,
                value: *value,
            },
        }
    }
}

impl fmt::Display for ParamsFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamsFault::Robot {
                wheel,
                field,
                problem,
            } => {
                if let Some(i) = wheel {
                    write!(f, "wheel {}: ", *i as u16 + 1)?;
                }
                let e = RobotError {
                    wheel: None,
                    field: *field,
                    problem: *problem,
                };
                write!(f, "robot: {}", RobotText(&e))
            }
            ParamsFault::Setting {
                index,
                min,
                max,
                value,
            } => {
                match SETTING_NAMES.get(*index as usize) {
                    Some(n) => f.write_str(n)?,
                    None => write!(f, "setting #{index}")?,
                }
                write!(
                    f,
                    " = {} is outside [{}, {}]",
                    Num(*value),
                    Num(*min),
                    Num(*max)
                )
            }
            ParamsFault::CorrectionsDoNotFit(c) => write!(
                f,
                "the active corrections do not fit this robot ({c}): reset them first"
            ),
            ParamsFault::Singular => f.write_str("singular geometry"),
        }
    }
}

impl fmt::Display for Rejection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Rejection::ProtocolMismatch {
                board_version,
                board_schema,
            } => write!(
                f,
                "protocol mismatch: board speaks v{board_version} (schema {board_schema:08x}), host v{PROTOCOL_VERSION} (schema {SCHEMA_FINGERPRINT:08x})"
            ),
            Rejection::InvalidCorrections(r) => write!(f, "invalid corrections: {r}"),
            Rejection::InvalidParams(r) => write!(f, "invalid parameters: {r}"),
            Rejection::InvalidProgram(r) => write!(f, "invalid program: {r}"),
            Rejection::Busy => write!(f, "busy: stop the robot first"),
            Rejection::EStopped => write!(f, "E-stop latched: clear it first"),
            Rejection::Faulted(x) => write!(f, "fault latched ({x}): clear it first"),
            Rejection::NoSuchTrial => write!(f, "no such trial"),
            Rejection::BadOffset { total } => write!(f, "offset past the end ({total} bytes)"),
            Rejection::Storage => write!(f, "flash storage failed; stored values unchanged"),
            Rejection::Undecodable => write!(f, "request not understood by this firmware"),
        }
    }
}

// ---------------------------------------------------------------------------------------
