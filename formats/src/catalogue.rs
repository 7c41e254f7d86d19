//! The effect catalogue's names, the one table the simulator (which makes the effects) and
//! diagnose (which names them) both read: an effect id or mechanism name written anywhere
//! else is a copy that can drift.
//!
//! An effect is what a recording shows (a wheel diameter mismatch, floor bumps...); a
//! mechanism is how it comes about (floor bumps from cables over the whole floor, or only
//! in a strip). `docs/formats.md` §4 lists them for users.

/// Left and right wheels of different diameters (Borenstein's E_d).
pub const WHEEL_DIAMETER_MISMATCH: &str = "wheel_diameter_mismatch";
/// Actual wheelbase unlike the nominal (Borenstein's E_b).
pub const WHEELBASE_ERROR: &str = "wheelbase_error";
/// The wheels' travel exceeds the body's when accelerating (traction).
pub const LONGITUDINAL_SLIP: &str = "longitudinal_slip";
/// The body slides sideways in turns.
pub const LATERAL_SLIP: &str = "lateral_slip";
/// Cables or seams that each cost a wheel some travel as it crosses.
pub const FLOOR_BUMPS: &str = "floor_bumps";
/// Play between motor and wheel, lost after each reversal.
pub const BACKLASH: &str = "backlash";
/// A stepper's rotor falling behind its steps.
pub const MISSED_STEPS: &str = "missed_steps";
/// The wheel rate lagging the command.
pub const MOTOR_LAG: &str = "motor_lag";
/// Friction that costs a DC wheel speed (a dead band, or a droop at every command).
pub const COULOMB_FRICTION: &str = "coulomb_friction";
/// Not in the catalogue: a control effect the simulator can make and diagnose must not
/// name as any of the above (a constant drift while moving).
pub const TILTED_FLOOR: &str = "tilted_floor";
/// Diagnose's one-parameter alternative to a diameter mismatch: every wheel's diameter off
/// by the same factor.
pub const WHEEL_SCALE: &str = "wheel_scale";

/// Diagnose's one-parameter alternative to every omni wheel's radius: one wheel mounted
/// at an angle off its nominal one.
pub const WHEEL_ANGLE_ERROR: &str = "wheel_angle_error";
/// Diagnose's one-parameter alternative to a wheelbase error of every wheel: one omni
/// wheel mounted nearer to or further from the centre.
pub const WHEEL_POSITION_ERROR: &str = "wheel_position_error";

/// The catalogue's effects in its order, then the control.
pub const EFFECT_IDS: [&str; 10] = [
    WHEEL_DIAMETER_MISMATCH,
    WHEELBASE_ERROR,
    LONGITUDINAL_SLIP,
    LATERAL_SLIP,
    FLOOR_BUMPS,
    BACKLASH,
    MISSED_STEPS,
    MOTOR_LAG,
    COULOMB_FRICTION,
    TILTED_FLOOR,
];

/// The mechanism of the geometry effects (they have no other).
pub const GEOMETRY: &str = "geometry";

/// A mechanism: (name in `mechanism:<name>`, its effect id).
pub type Mech = (&'static str, &'static str);

/// longitudinal_slip: per-wheel traction limit.
pub const MECH_WHEEL: Mech = ("wheel", LONGITUDINAL_SLIP);
/// longitudinal_slip: a bound on the body's linear acceleration.
pub const MECH_BODY: Mech = ("body", LONGITUDINAL_SLIP);
/// longitudinal_slip: slip proportional to the drive force.
pub const MECH_CREEP: Mech = ("creep", LONGITUDINAL_SLIP);
/// longitudinal_slip: each driven wheel its own traction limit (a payload off-centre, a
/// slipping hub; diagnose only).
pub const MECH_SLIP_PER_WHEEL: Mech = ("per_wheel", LONGITUDINAL_SLIP);
/// lateral_slip: v_y = -k v_x omega.
pub const MECH_LINEAR: Mech = ("linear", LATERAL_SLIP);
/// lateral_slip: slip speed saturating.
pub const MECH_SATURATING: Mech = ("saturating", LATERAL_SLIP);
/// floor_bumps: cables over the whole floor.
pub const MECH_WHOLE: Mech = ("whole", FLOOR_BUMPS);
/// floor_bumps: cables only in a strip or patch of the floor.
pub const MECH_REGION: Mech = ("region", FLOOR_BUMPS);
/// floor_bumps: irregular spacing.
pub const MECH_IRREGULAR: Mech = ("irregular", FLOOR_BUMPS);
/// backlash: the same play both ways.
pub const MECH_SYMMETRIC: Mech = ("symmetric", BACKLASH);
/// backlash: different loss on the two reversal directions.
pub const MECH_ASYMMETRIC: Mech = ("asymmetric", BACKLASH);
/// backlash: each wheel its own play.
pub const MECH_PER_WHEEL: Mech = ("per_wheel", BACKLASH);
/// missed_steps: rotor pull-out dynamics.
pub const MECH_PULL_OUT: Mech = ("pull_out", MISSED_STEPS);
/// missed_steps: random quanta of four full steps.
pub const MECH_QUANTA: Mech = ("quanta", MISSED_STEPS);
/// missed_steps: a full stall until the command rests.
pub const MECH_STALL: Mech = ("stall", MISSED_STEPS);
/// motor_lag: a first-order lag.
pub const MECH_FIRST_ORDER: Mech = ("first_order", MOTOR_LAG);
/// motor_lag: a transport delay.
pub const MECH_DELAY: Mech = ("delay", MOTOR_LAG);
/// motor_lag: a slew-rate limit.
pub const MECH_SLEW: Mech = ("slew", MOTOR_LAG);
/// coulomb_friction: a dead band around zero command.
pub const MECH_DEAD_BAND: Mech = ("dead_band", COULOMB_FRICTION);
/// coulomb_friction: a constant speed lost at every command (a velocity loop's finite gain).
pub const MECH_DROOP: Mech = ("droop", COULOMB_FRICTION);
/// motor_lag: each wheel's own first-order time constant.
pub const MECH_FIRST_ORDER_PER_WHEEL: Mech = ("first_order_per_wheel", MOTOR_LAG);
/// motor_lag: each wheel's own transport delay.
pub const MECH_DELAY_PER_WHEEL: Mech = ("delay_per_wheel", MOTOR_LAG);
/// motor_lag: each wheel's own acceleration limit (one weak motor).
pub const MECH_SLEW_PER_WHEEL: Mech = ("slew_per_wheel", MOTOR_LAG);
/// coulomb_friction: each wheel's own dead band.
pub const MECH_DEAD_BAND_PER_WHEEL: Mech = ("dead_band_per_wheel", COULOMB_FRICTION);

/// Every mechanism. The first listed for an effect is its default.
pub const MECHANISMS: [Mech; 24] = [
    MECH_WHEEL,
    MECH_BODY,
    MECH_CREEP,
    MECH_SLIP_PER_WHEEL,
    MECH_LINEAR,
    MECH_SATURATING,
    MECH_WHOLE,
    MECH_REGION,
    MECH_IRREGULAR,
    MECH_SYMMETRIC,
    MECH_ASYMMETRIC,
    MECH_PER_WHEEL,
    MECH_PULL_OUT,
    MECH_QUANTA,
    MECH_STALL,
    MECH_FIRST_ORDER,
    MECH_DELAY,
    MECH_SLEW,
    MECH_DEAD_BAND,
    MECH_DROOP,
    MECH_FIRST_ORDER_PER_WHEEL,
    MECH_DELAY_PER_WHEEL,
    MECH_SLEW_PER_WHEEL,
    MECH_DEAD_BAND_PER_WHEEL,
];

// Recording artefacts (diagnose's recording stage, docs/diagnose.md): how a run was
// logged, not physics. Reported under their own heading and removed before the physics.

/// The pose clock offset from the encoder clock.
pub const TIME_OFFSET: &str = "time_offset";
/// The pose clock running at another rate than the encoder clock.
pub const CLOCK_RATE: &str = "clock_rate";
/// Missing rows (gaps in `t`) and rows repeating the previous one whole.
pub const SAMPLE_GLITCH: &str = "sample_glitch";
/// Encoder counts per wheel revolution off by a simple fraction (a resolution or gear
/// ratio written wrong).
pub const COUNTS_PER_REV_ERROR: &str = "counts_per_rev_error";
/// One encoder counting a fraction off that is no simple ratio (against a stepper's
/// commands).
pub const ENCODER_SCALE: &str = "encoder_scale";
/// An encoder counting backwards.
pub const ENCODER_SIGN: &str = "encoder_sign";
/// Encoder columns holding another wheel's counts.
pub const WHEELS_SWAPPED: &str = "wheels_swapped";
/// Rows repeating the previous row's encoders (then catching up), or pose samples
/// repeating the previous pose, while the robot moves.
pub const STALE_SAMPLES: &str = "stale_samples";
/// The file's time going back (re-timed by the reader).
pub const TIME_BACKWARDS: &str = "time_backwards";
/// Written row times jittering by more than a logger's clock allows.
pub const TIME_JITTER: &str = "time_jitter";
/// The pose stream jumping: a single sample off (a marker swap) or the frame moved and
/// staying (a relocalisation).
pub const POSE_JUMP: &str = "pose_jump";

/// Every recording artefact id.
pub const RECORDING_IDS: [&str; 11] = [
    TIME_OFFSET,
    CLOCK_RATE,
    SAMPLE_GLITCH,
    COUNTS_PER_REV_ERROR,
    ENCODER_SCALE,
    ENCODER_SIGN,
    WHEELS_SWAPPED,
    STALE_SAMPLES,
    TIME_BACKWARDS,
    TIME_JITTER,
    POSE_JUMP,
];

/// The name of mechanism `name` of effect `id` as it appears in [`MECHANISMS`] (a
/// `&'static str` for callers that built the pair from input), if it is listed.
pub fn mechanism(id: &str, name: &str) -> Option<&'static str> {
    MECHANISMS
        .iter()
        .find(|(m, e)| *m == name && *e == id)
        .map(|(m, _)| *m)
}
