//! calib-core: the no_std heart of wheelcal, shared by the firmware and the host tools.
//!
//! Everything here is pure computation: no registers, no allocator, no I/O. The firmware
//! runs it at 1 kHz in f32; the host runs the same code in f64 against the simulator.
#![no_std]

#[cfg(test)]
#[macro_use]
extern crate std;

pub mod circle_test;
pub mod correction;
pub mod kinematics;
pub mod linalg;
pub mod num;
pub mod omni_cal;
pub mod omni_circle_test;
pub mod protocol;
pub mod robot;
pub mod stats;
pub mod umbmark;

pub use correction::Corrections;
pub use kinematics::{Kinematics, Twist};
pub use robot::{Robot, RobotKind};
pub mod motion;
pub mod odometry;
pub use odometry::{Odometry, Pose};
pub mod control;
pub mod diff_laws;
pub mod encoder;
pub mod omni_laws;
pub mod stepper;
