//! Requests, responses and the state a board reports.

#[allow(unused_imports)]
use super::*;

// Messages
// ---------------------------------------------------------------------------------------

/// What the host asks of a board.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Request {
    /// Variant 0, frozen: the handshake.
    Hello {
        /// The host's [`PROTOCOL_VERSION`].
        protocol_version: u16,
        /// The host's [`SCHEMA_FINGERPRINT`].
        schema: u32,
    },
    /// Asks for [`Info`].
    GetInfo,
    /// Asks for the active corrections.
    GetCorrections,
    /// Makes these the active corrections (validated; not persisted until saved).
    SetCorrections(Corrections),
    /// Persists the active corrections.
    SaveCorrections,
    /// Active corrections back to none (persist with SaveCorrections).
    ResetCorrections,
    /// Asks for the active parameters.
    GetParams,
    /// Replaces robot geometry, gains, limits and safety settings (validated; idle only).
    SetParams(Params),
    /// Persists the active parameters.
    SaveParams,
    /// Active parameters back to the firmware's defaults (idle only).
    ResetParams,
    /// Drive at a body twist until the next Drive, or stop after `timeout_ms` (0 = the
    /// configured command timeout; longer values are capped by it).
    Drive {
        /// Body twist (m/s, m/s, rad/s).
        twist: Twist<f32>,
        /// Command timeout (ms); 0 = the configured one.
        timeout_ms: u16,
    },
    /// Run a motion program, logging a trial at `log_rate_hz` (0 = no log).
    RunProgram {
        /// The program.
        program: ProgramSpec,
        /// Log rate (Hz); 0 = no log.
        log_rate_hz: u16,
        /// Host-link failsafe: the program is cut ([`StopReason::LinkLost`]) when no valid
        /// request has arrived for this long, so a host that froze, crashed or lost its
        /// cable cannot leave the robot driving. 0 turns it off (an explicit choice, e.g.
        /// a program started with `--no-wait`); otherwise at least
        /// [`MIN_LINK_TIMEOUT_MS`].
        link_timeout_ms: u16,
    },
    /// Controlled stop (ramps to zero through the controllers).
    Stop,
    /// Immediate motor cut-off, latched until ClearFault.
    EStop,
    /// Clears a latched E-stop or fault.
    ClearFault,
    /// Asks for [`Status`].
    GetStatus,
    /// Unsolicited status frames every `period_ms` (0 = off).
    SetTelemetry {
        /// Telemetry period (ms); 0 = off.
        period_ms: u16,
    },
    /// Asks for the trial list.
    ListTrials,
    /// Bytes `offset..offset+max_len` of a trial's records (resumable: ask again from the
    /// offset reached).
    ReadLog {
        /// Trial id.
        trial: u16,
        /// First byte wanted (from the start of the trial's records).
        offset: u32,
        /// Most bytes wanted (the board sends at most [`MAX_LOG_CHUNK`]).
        max_len: u16,
    },
    /// Deletes every stored trial.
    ClearLogs,
}

/// A board's answer (or unsolicited telemetry).
// Messages are built once per frame and never moved in bulk; no_std has no Box.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Response<'a> {
    /// Variant 0, frozen: the handshake answer; `compatible` is false on a mismatch.
    Hello {
        /// The board's [`PROTOCOL_VERSION`].
        protocol_version: u16,
        /// The board's [`SCHEMA_FINGERPRINT`].
        schema: u32,
        /// Firmware version text.
        firmware: String<FIRMWARE_LEN>,
        /// Whether the host's version and schema match the board's.
        compatible: bool,
    },
    /// Done (for requests with nothing to return).
    Ok,
    /// Answer to [`Request::GetInfo`].
    Info(Info),
    /// Answer to [`Request::GetCorrections`].
    Corrections(Corrections),
    /// Answer to [`Request::GetParams`].
    Params(Params),
    /// Answer to [`Request::GetStatus`].
    Status(Status),
    /// Unsolicited, every telemetry period.
    Telemetry(Status),
    /// Answer to [`Request::ListTrials`].
    Trials(Trials),
    #[serde(borrow)]
    /// Answer to [`Request::ReadLog`].
    LogChunk(LogChunk<'a>),
    /// The request was refused and nothing changed.
    Rejected(Rejection),
    /// A frame arrived damaged (sequence number unknown): resend the last request.
    Nack(FrameError),
}

/// Everything a board reports about itself.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Info {
    /// Firmware version text.
    pub firmware: String<FIRMWARE_LEN>,
    /// The board's [`PROTOCOL_VERSION`].
    pub protocol_version: u16,
    /// The board's [`SCHEMA_FINGERPRINT`].
    pub schema: u32,
    /// Kind of the configured robot.
    pub robot_kind: RobotKind,
    /// How its wheels are driven.
    pub drive: DriveType,
    /// Wheels of the configured robot.
    pub wheel_count: u8,
    /// Time since boot (ms).
    pub uptime_ms: u64,
    /// What was found in flash at boot.
    pub boot: BootReport,
    /// Bytes of trial-log RAM.
    pub log_capacity: u32,
    /// Bytes per log record for this robot.
    pub record_size: u16,
}

/// What the board found in flash at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct BootReport {
    /// State of the stored corrections.
    pub corrections: Stored,
    /// State of the stored parameters.
    pub params: Stored,
}

/// State of one persisted item at boot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
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
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Status {
    /// Time since boot (ms).
    pub uptime_ms: u64,
    /// What the board is doing.
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

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
/// What the board is doing.
pub enum Mode {
    /// No drive or program under way (the twist ramps down to zero).
    Idle,
    /// Driving by twist commands ([`Request::Drive`]).
    Drive,
    /// Running a program.
    Program {
        /// Index of the segment under way (0-based).
        segment: u8,
        /// Segments in the program.
        segments: u8,
    },
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
/// Why the motors last stopped.
pub enum StopReason {
    /// Not stopped since boot or the last program start.
    None,
    /// [`Request::Stop`].
    Request,
    /// [`Request::EStop`].
    EStop,
    /// No new twist command within the command timeout.
    CommandTimeout,
    /// A fault was detected (see [`Fault`]).
    Fault,
    /// The program ran to its end.
    ProgramDone,
    /// No request from the host within the program's link timeout (the host-link
    /// failsafe of [`Request::RunProgram`]).
    LinkLost,
}

/// A detected hardware fault (latched, motors off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// Commanded but the encoder did not move.
    Stall {
        /// Wheel index (0-based).
        wheel: u8,
    },
    /// The encoder moved implausibly far in one tick.
    CounterJump {
        /// Wheel index (0-based).
        wheel: u8,
        /// The movement seen in one tick (counts).
        delta: i32,
    },
    /// A value on the way to a motor was not a finite number (NaN or infinite). Nothing
    /// is written to the motor then and every wheel stops: a NaN that reached the
    /// velocity loop used to come out as full reverse duty (`NaN.max(-1.0)` is -1.0).
    NonFinite {
        /// Wheel index (0-based).
        wheel: u8,
        /// Which value it was.
        value: ControlValue,
    },
}

/// The per-wheel values of the control path that lead to a motor register, each checked
/// finite every tick before anything is written.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ControlValue {
    /// The wheel's commanded rate (from the kinematics or a program), rad/s.
    Command,
    /// The wheel's measured rate (from the encoder), rad/s.
    Rate,
    /// A DC wheel's signed PWM duty (becomes a timer compare value and a direction pin).
    Duty,
    /// A stepper wheel's step rate (becomes a timer half period and a direction pin).
    StepRate,
}

impl ControlValue {
    /// Every value that is checked, in the order of the control path.
    pub const ALL: [ControlValue; 4] = [
        ControlValue::Command,
        ControlValue::Rate,
        ControlValue::Duty,
        ControlValue::StepRate,
    ];

    /// The value's name in messages.
    pub fn as_str(self) -> &'static str {
        match self {
            ControlValue::Command => "commanded rate",
            ControlValue::Rate => "measured rate",
            ControlValue::Duty => "PWM duty",
            ControlValue::StepRate => "step rate",
        }
    }
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
            Fault::NonFinite { wheel, value } => write!(
                f,
                "not a number: wheel {}'s {} was not finite; nothing was written to the \
                 motor and every wheel was stopped",
                *wheel as u16 + 1,
                value.as_str()
            ),
        }
    }
}

/// Why a request was refused; the board's state is unchanged. Structured (no text is
/// built on the board): the host words it with one `Display`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Rejection {
    /// The host's version or schema did not match at [`Request::Hello`].
    ProtocolMismatch {
        /// The board's [`PROTOCOL_VERSION`].
        board_version: u16,
        /// The board's [`SCHEMA_FINGERPRINT`].
        board_schema: u32,
    },
    /// The corrections failed validation.
    InvalidCorrections(CorrectionFault),
    /// The parameters failed validation.
    InvalidParams(ParamsFault),
    /// The program failed validation.
    InvalidProgram(ProgramError),
    /// Not while a program or drive is under way.
    Busy,
    /// E-stop latched: send ClearFault first.
    EStopped,
    /// A fault is latched: send ClearFault first.
    Faulted(Fault),
    /// No trial with that id is stored.
    NoSuchTrial,
    /// The offset is past the trial's end.
    BadOffset {
        /// The trial's length so far (bytes).
        total: u32,
    },
    /// Flash write or read failed; the stored values are unchanged.
    Storage,
    /// The frame was intact but its body is not a request this firmware knows.
    Undecodable,
}

impl Rejection {
    /// [`Rejection::InvalidCorrections`] worded from a correction error.
    pub fn corrections(e: &CorrectionError) -> Self {
        Rejection::InvalidCorrections(CorrectionFault::from(e))
    }
}

/// A correction factor, as named on the wire ([`CorrectionError`] names it with text).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Factor {
    /// c_L, the left wheel factor.
    CL,
    /// c_R, the right wheel factor.
    CR,
    /// E_b, the wheelbase factor.
    EB,
    /// A lateral factor of F_lat.
    FLat,
    /// F_lon, the longitudinal factor.
    FLon,
    /// A turn law's e_b_arc.
    EBArc,
    /// A speed law's speed_rel (protocol v6, last on the wire).
    SpeedRel,
    /// An acceleration law's accel_slip_s (protocol v6, last on the wire).
    AccelSlip,
    /// An omni robot's turn law l_arc (protocol v8, last on the wire).
    LArc,
}

impl Factor {
    /// From the name `correction::check` was given (always one of the nine; anything
    /// else reads as f_lat).
    pub fn from_name(name: &str) -> Factor {
        match name {
            "c_l" => Factor::CL,
            "c_r" => Factor::CR,
            "e_b" => Factor::EB,
            "f_lon" => Factor::FLon,
            "e_b_arc" => Factor::EBArc,
            "speed_rel" => Factor::SpeedRel,
            "accel_slip_s" => Factor::AccelSlip,
            "l_arc" => Factor::LArc,
            _ => Factor::FLat,
        }
    }

    /// The factor's name as the console and the robot files write it.
    pub fn as_str(self) -> &'static str {
        match self {
            Factor::CL => "c_l",
            Factor::CR => "c_r",
            Factor::EB => "e_b",
            Factor::FLat => "f_lat",
            Factor::FLon => "f_lon",
            Factor::EBArc => "e_b_arc",
            Factor::SpeedRel => "speed_rel",
            Factor::AccelSlip => "accel_slip_s",
            Factor::LArc => "l_arc",
        }
    }
}

/// Why corrections were refused, on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum CorrectionFault {
    /// A factor is NaN or infinite.
    NotFinite {
        /// Which factor.
        factor: Factor,
        /// Its wheel index (from 0) for per-wheel factors.
        index: Option<u8>,
    },
    /// A factor outside [0.5, max].
    OutOfRange {
        /// Which factor.
        factor: Factor,
        /// Its wheel index (from 0) for per-wheel factors.
        index: Option<u8>,
        /// The value refused.
        value: f64,
        /// The upper bound that applied (2.0; 3.0 for a skid-steer robot's E_b).
        max: f64,
    },
    /// Per-wheel factors for another number of wheels.
    WrongWheelCount {
        /// Wheels of the robot.
        expected: u8,
        /// Factors given.
        got: u8,
    },
    /// Factors of another drive kind (differential vs omni).
    WrongKind {
        /// The robot's kind.
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
            CorrectionError::OutOfRange {
                name,
                index,
                value,
                max,
            } => CorrectionFault::OutOfRange {
                factor: Factor::from_name(name),
                index: idx(index),
                value: *value,
                max: *max,
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
                max,
            } => CorrectionError::OutOfRange {
                name: factor.as_str(),
                index: index.map(usize::from),
                value,
                max,
            },
            CorrectionFault::WrongWheelCount { expected, got } => {
                CorrectionError::WrongWheelCount {
                    expected: expected.into(),
                    got: got.into(),
                }
            }
            CorrectionFault::WrongKind { robot } => CorrectionError::WrongKind { robot },
        };
        e.fmt(f)
    }
}

/// Why parameters were refused, on the wire.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum ParamsFault {
    /// The robot description: wheel index (from 0) if a wheel is concerned.
    Robot {
        /// Wheel index (from 0), if a wheel is concerned.
        wheel: Option<u8>,
        /// The field at fault.
        field: crate::robot::Field,
        /// What is wrong with it.
        problem: crate::robot::Problem,
    },
    /// Setting [`SETTING_NAMES`]`[index]` is outside `[min, max]`.
    Setting {
        /// Index into [`SETTING_NAMES`].
        index: u8,
        /// Smallest allowed value.
        min: f64,
        /// Largest allowed value.
        max: f64,
        /// The value refused.
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
                write!(f, "robot: {e}")
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
