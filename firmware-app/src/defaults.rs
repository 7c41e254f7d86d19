//! What a board runs with when its flash holds nothing valid.

use calib_core::control::PiGains;
use calib_core::motion::ProfileLimits;
use calib_core::protocol::{Params, Safety};
use calib_core::robot::{presets, Drive, DriveType, DEFAULT_COUNTS_PER_REV};

/// A DC differential drive with 50 mm wheels, 0.40 m wheelbase and 480-ppr encoders; the
/// host uploads the real robot with SetParams.
pub fn params() -> Params {
    let drive = Drive {
        kind: DriveType::Dc,
        steps_per_rev: 200,
        microsteps: 1,
        gear_ratio: 1.0,
        encoder_counts_per_rev: DEFAULT_COUNTS_PER_REV,
    };
    Params {
        robot: presets::diff_drive("default", 0.05, 0.40, drive),
        gains: gains(),
        limits: ProfileLimits::default(),
        safety: Safety::default(),
    }
}

/// Gains for a motor reaching ~20 rad/s at the wheel at full duty: feed-forward does most
/// of the work, the PI removes load and friction.
pub fn gains() -> PiGains {
    PiGains {
        kp: 0.05,
        ki: 2.0,
        kff: 1.0 / 20.0,
        kstatic: 0.0,
        out_max: 1.0,
    }
}
