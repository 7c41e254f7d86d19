//! Sensor noise models: an external "vision" pose sensor (camera, motion capture) and an
//! IMU gyro's yaw rate.

use crate::error::check_range;
use crate::SimError;
use calib_core::odometry::Pose;
use rand::Rng;
use rand_distr::StandardNormal;

/// External pose measurement of the body origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct VisionConfig {
    /// Samples per second (30 Hz: a camera).
    pub rate_hz: f64,
    /// Standard deviation of x and y, m.
    pub sigma_xy_m: f64,
    /// Standard deviation of theta, rad.
    pub sigma_theta_rad: f64,
}

impl Default for VisionConfig {
    fn default() -> Self {
        VisionConfig {
            rate_hz: 30.0,
            sigma_xy_m: 0.001,
            sigma_theta_rad: 0.002,
        }
    }
}

impl VisionConfig {
    /// Checks every setting is finite and in range.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("vision.rate_hz", self.rate_hz, 1e-3, 1e6)?;
        check_range("vision.sigma_xy_m", self.sigma_xy_m, 0.0, 10.0)?;
        check_range("vision.sigma_theta_rad", self.sigma_theta_rad, 0.0, 10.0)
    }

    /// A noisy measurement of `truth`.
    pub fn measure<R: Rng>(&self, truth: &Pose<f64>, rng: &mut R) -> Pose<f64> {
        let n = |rng: &mut R| rng.sample::<f64, _>(StandardNormal);
        Pose::new(
            truth.x + self.sigma_xy_m * n(rng),
            truth.y + self.sigma_xy_m * n(rng),
            truth.theta + self.sigma_theta_rad * n(rng),
        )
    }
}

/// Gyro yaw rate: truth + constant bias + white noise.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImuConfig {
    /// Constant bias (rad/s).
    pub bias_rad_s: f64,
    /// Standard deviation per sample, rad/s.
    pub sigma_rad_s: f64,
}

impl Default for ImuConfig {
    fn default() -> Self {
        // An MPU-6050 class gyro ([Korayem et al.]): a few mrad/s of bias and noise per sample.
        ImuConfig {
            bias_rad_s: 0.003,
            sigma_rad_s: 0.005,
        }
    }
}

impl ImuConfig {
    /// Checks every setting is finite and in range.
    pub fn validate(&self) -> Result<(), SimError> {
        check_range("imu.bias_rad_s", self.bias_rad_s, -10.0, 10.0)?;
        check_range("imu.sigma_rad_s", self.sigma_rad_s, 0.0, 10.0)
    }

    /// A noisy measurement of `true_rate` (rad/s).
    pub fn measure<R: Rng>(&self, true_rate: f64, rng: &mut R) -> f64 {
        true_rate + self.bias_rad_s + self.sigma_rad_s * rng.sample::<f64, _>(StandardNormal)
    }
}
