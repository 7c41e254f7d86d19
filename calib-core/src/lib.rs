//! calib-core: the no_std heart of wheelcal, shared by the firmware and the host tools.
//!
//! Everything here is pure computation: no registers, no allocator, no I/O. The firmware
//! runs it at 1 kHz in f32; the host runs the same code in f64 against the simulator.
#![cfg_attr(not(feature = "std"), no_std)]

pub mod omni_cal;
pub mod stats;
pub mod umbmark;
