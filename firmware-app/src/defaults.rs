//! What a board runs with when its flash holds nothing valid.

use calib_core::control::PiGains;
use calib_core::motion::ProfileLimits;
use calib_core::protocol::{Params, Safety};
use calib_core::robot::{Drive, DriveType, Robot, RobotKind, Wheel, DEFAULT_COUNTS_PER_REV};
use core::f64::consts::{FRAC_PI_2, PI};

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
        robot: robot(drive),
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

/// The default robot, written out rather than built by `presets::diff_drive`, whose
/// `expect` would pull core's float formatting (~10 KiB) into the firmware; a test checks
/// it equals the preset and passes validation.
fn robot(drive: Drive) -> Robot {
    let wheel = |name: &str, alpha: f64, beta: f64| Wheel {
        name: heapless::String::try_from(name).unwrap_or_default(),
        radius_m: 0.05,
        alpha_rad: alpha,
        l_m: 0.20,
        beta_rad: beta,
        gamma_rad: 0.0,
        driven: true,
    };
    let mut wheels = heapless::Vec::new();
    let _ = wheels.push(wheel("left", FRAC_PI_2, 0.0));
    let _ = wheels.push(wheel("right", -FRAC_PI_2, PI));
    Robot {
        name: heapless::String::try_from("default").unwrap_or_default(),
        kind: RobotKind::DiffDrive,
        drive,
        wheels,
        legs: None,
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn default_robot_is_the_valid_preset() {
        let p = super::params();
        let preset = calib_core::robot::presets::diff_drive("default", 0.05, 0.40, p.robot.drive);
        assert_eq!(p.robot, preset);
        assert_eq!(p.validate(), Ok(()));
    }
}
