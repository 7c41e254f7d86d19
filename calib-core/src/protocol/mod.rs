//! The serial protocol between a board and the host: messages, framing and the trial-log
//! record layout, shared by the firmware, the virtual board and the console.
//!
//! # Framing
//! One frame on the wire is `COBS(seq u16 LE | postcard body | CRC-32/ISO-HDLC LE) 0x00`.
//! The CRC covers the sequence number and the body; COBS removes every zero byte so 0x00
//! only ever delimits frames, and a receiver that starts mid-stream or sees garbage
//! resynchronises at the next delimiter ([`FrameDecoder`]). A frame's unencoded content
//! (`seq | body | crc`) is at most [`MAX_PAYLOAD`] bytes, on the wire at most
//! [`MAX_WIRE`]. Responses echo the request's sequence number; unsolicited telemetry
//! frames carry the board's own counter and are told apart by their variant.
//!
//! # Handshake
//! [`Request::Hello`] and [`Response::Hello`] are variant 0 and their fields are frozen
//! across versions, so a host and a board of different versions can always tell each other
//! their [`PROTOCOL_VERSION`] and [`SCHEMA_FINGERPRINT`] and say so instead of misreading
//! the rest. After a Hello that did not match, the board rejects every other request with
//! [`Rejection::ProtocolMismatch`].
//!
//! # Using it from a host
//! - Send [`Request::Hello`] first; stop with the board's versions if `compatible` is false.
//! - Give every new request a new sequence number (wrapping). A board answers a repeated
//!   (sequence number, body) pair from its cache without acting again, so resending after
//!   a lost answer is safe; [`Response::Nack`] means the board saw a damaged frame: resend.
//! - Frames whose sequence number does not match the request outstanding are stale or
//!   telemetry ([`Response::Telemetry`]); skip them.
//! - Logs: [`Request::ListTrials`], then [`Request::ReadLog`] from offset 0 with
//!   `max_len` = [`MAX_LOG_CHUNK`], each next offset = offset + data length, until the
//!   offset reaches `total` of a finished trial. Decode the bytes with [`decode_blocks`]
//!   (compressed blocks of [`Record`]s, a key frame each; `record_size` in the trial's
//!   header is the size of one decoded record). A chunk may be shorter than asked (the
//!   ring's end); that is not the end of the trial.
//! - Saves ([`Request::SaveCorrections`], [`Request::SaveParams`]) answer only after the
//!   flash write: allow a few seconds (a sector erase takes up to 2 s).
//!
//! # Why not postcard-rpc
//! postcard-rpc (typed endpoints over a COBS serial transport) was considered. Its server
//! side is built around async dispatch tasks and its host client around tokio, while the
//! board's request handler here is a plain synchronous function `bytes in -> bytes out`
//! that must run identically on the UART, on a host pseudo-terminal and inside unit tests
//! without any executor; its endpoint keys are hashes of postcard-schema descriptions,
//! which would need `Schema` derives on calib-core types owned by other modules. The
//! framing here is ~150 lines, so owning it is cheaper than adapting to it.
//!
//! # Schema fingerprint
//! [`SCHEMA`] is a canonical text description of every message type; the fingerprint is
//! its CRC-32. A golden test (`tests::schema_golden`) serialises one sample of every
//! variant and compares the bytes' CRC with a recorded value, so changing a type without
//! updating [`SCHEMA`] (and thereby the fingerprint) breaks the build's tests.

use crate::control::PiGains;
use crate::correction::{CorrectionError, Corrections};
use crate::kinematics::Twist;
use crate::motion::{Direction, OmniPath, ProfileLimits, Segment, MAX_SEGMENTS};
use crate::odometry::Pose;
pub use crate::omni_cal::IdleWheels;
use crate::robot::{DriveType, Robot, RobotError, RobotKind, MAX_WHEELS};
use core::fmt::{self, Write as _};
use heapless::{String, Vec};
use serde::{Deserialize, Serialize};

mod frame;
mod log;
mod messages;
mod params;
#[cfg(test)]
mod tests;
mod text;

pub use frame::*;
pub use log::*;
pub use messages::*;
pub use params::*;
pub use text::*;

/// Bumped on any incompatible change of the messages or framing.
pub const PROTOCOL_VERSION: u16 = 2;

/// Canonical description of the message schema; its CRC-32 is [`SCHEMA_FINGERPRINT`].
/// Edit it whenever a message type changes (the golden test enforces this).
pub const SCHEMA: &str = "wheelcal-protocol v1;\
frame=cobs(seq:u16le,postcard(body),crc32-iso-hdlc:u32le),0x00;\
Request=Hello{protocol_version:u16,schema:u32}|GetInfo|GetCorrections|SetCorrections(Corrections)|\
SaveCorrections|ResetCorrections|GetParams|SetParams(Params)|SaveParams|ResetParams|\
Drive{twist:Twist<f32>,timeout_ms:u16}|RunProgram{program:ProgramSpec,log_rate_hz:u16}|Stop|EStop|\
ClearFault|GetStatus|SetTelemetry{period_ms:u16}|ListTrials|ReadLog{trial:u16,offset:u32,max_len:u16}|ClearLogs;\
Response=Hello{protocol_version:u16,schema:u32,firmware:String<24>,compatible:bool}|Ok|Info(Info)|\
Corrections(Corrections)|Params(Params)|Status(Status)|Telemetry(Status)|Trials(Trials)|LogChunk(LogChunk)|\
Rejected(Rejection)|Nack(FrameError);\
Corrections=None|DiffDrive{c_l:f64,c_r:f64,e_b:f64}|Omni{f_lat:Vec<f64,8>,f_lon:f64};\
Params{robot:Robot,gains:PiGains,limits:ProfileLimits,safety:Safety};\
Robot{name:String<32>,kind:RobotKind,drive:Drive,wheels:Vec<Wheel,8>,legs:Option<Legs>};\
Safety{command_timeout_ms:u16,stall_timeout_ms:u16,stall_min_rate:f32,max_jump_counts:u32,arena_m:f32};\
ProgramSpec=Umbmark{side_m:f64,dir:Direction}|Omni{path:OmniPath,length_m:f64,idle:IdleWheels}|Custom(Vec<Segment,32>);\
Info{firmware:String<24>,protocol_version:u16,schema:u32,robot_kind:RobotKind,drive:DriveType,wheel_count:u8,\
uptime_ms:u64,boot:BootReport,log_capacity:u32,record_size:u16};\
BootReport{corrections:Stored,params:Stored};Stored=Loaded|Missing|Invalid|StorageError;\
Status{uptime_ms:u64,mode:Mode,stop:StopReason,estop:bool,fault:Option<Fault>,pose:Pose<f32>,\
wheel_rates:Vec<f32,8>,wheel_cmds:Vec<f32,8>,trial:Option<u16>,log_free:u32,dropped_records:u32,\
evicted_trials:u32,bad_frames:u32};\
Mode=Idle|Drive|Program{segment:u8,segments:u8};\
StopReason=None|Request|EStop|CommandTimeout|Fault|ProgramDone;\
Fault=Stall{wheel:u8}|CounterJump{wheel:u8,delta:i32};\
Trials{trials:Vec<TrialInfo,8>,evicted:u32};\
TrialInfo{id:u16,program:ProgramKind,start_ms:u64,rate_hz:u16,wheel_count:u8,record_size:u16,\
records:u32,bytes:u32,dropped:u32,end:TrialEnd,corrections:Corrections};\
IdleWheels=Released|Held;\
ProgramKind=Drive|Umbmark{side_m:f32,dir:Direction}|Omni{path:OmniPath,length_m:f32}|Custom{segments:u8};\
TrialEnd=Running|Completed|Stopped|EStop|Fault|CommandTimeout;\
LogChunk{trial:u16,offset:u32,total:u32,data:bytes};\
Rejection=ProtocolMismatch{board_version:u16,board_schema:u32}|InvalidCorrections(CorrectionFault)|\
InvalidParams(ParamsFault)|InvalidProgram(ProgramError)|Busy|EStopped|Faulted(Fault)|NoSuchTrial|\
BadOffset{total:u32}|Storage|Undecodable;\
Factor=CL|CR|EB|FLat|FLon;\
CorrectionFault=NotFinite{factor:Factor,index:Option<u8>}|OutOfRange{factor:Factor,index:Option<u8>,value:f64}|\
WrongWheelCount{expected:u8,got:u8}|WrongKind{robot:RobotKind}|Singular;\
ParamsFault=Robot{wheel:Option<u8>,field:Field,problem:Problem}|Setting{index:u8,min:f64,max:f64,value:f64}|\
CorrectionsDoNotFit(CorrectionFault)|Singular;\
Field=Name|Kind|Wheels|RadiusM|AlphaDeg|LM|BetaDeg|GammaDeg|StepsPerRev|Microsteps|GearRatio|\
EncoderCountsPerRev|Legs;\
Problem=NotFinite|NotPositive(f64)|Negative(f64)|RollerParallelToAxle|DuplicateName|BadName|\
TooFewWheels(usize)|TooManyWheels(usize)|SingularJacobian|LegsMismatch|\
WrongWheelCount{kind:RobotKind,expected:usize,got:usize};\
ProgramError=OutOfRange{field:ProgramField,value:f64,max:f64}|NotPositive{field:ProgramField,value:f64}|\
NeedsOmni{robot:RobotKind}|NoSegments|NoSuchWheel{wheel:u8,wheels:u8}|\
Twist{twist:Twist<f32>,v_max:f64,omega_max:f64};\
ProgramField=SideM|LengthM|DistanceM|AngleRad|DxM|DyM|DurationS;\
FrameError=Cobs|TooShort|TooLong|Crc;\
Record=t_us:u32le,counts:i32le*n,cmd_rad_s:f32le*n,x:f32le,y:f32le,theta:f32le";

/// CRC-32 of [`SCHEMA`]: exchanged in the handshake.
pub const SCHEMA_FINGERPRINT: u32 = CRC32.checksum(SCHEMA.as_bytes());

/// Largest unencoded frame (seq + body + crc).
pub const MAX_PAYLOAD: usize = 1024;
/// Largest frame on the wire: COBS adds one byte per 254 plus one, and the delimiter.
pub const MAX_WIRE: usize = MAX_PAYLOAD + MAX_PAYLOAD / 254 + 2;
/// Largest log chunk: leaves room for the chunk's header inside [`MAX_PAYLOAD`].
pub const MAX_LOG_CHUNK: usize = 992;
/// Most trials a board keeps and lists.
pub const MAX_TRIALS: usize = 8;
/// Length of the firmware version text.
pub const FIRMWARE_LEN: usize = 24;
/// Length of a rejection's explanation.
pub const REASON_LEN: usize = 96;

const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);
const SEQ_LEN: usize = 2;
const CRC_LEN: usize = 4;
