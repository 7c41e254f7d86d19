//! The firmware's hardware-independent application: everything between the registers and
//! the host that does not touch a register.
//!
//! The embassy glue (`src/` of the root package) and the host's virtual board both drive
//! the same [`App`]: they call [`App::tick`] at [`TICK_HZ`] with an [`EncoderSource`] and a
//! [`WheelDriver`], feed received bytes through a [`Server`], and persist what the server
//! asks them to through a [`Store`] on any `NorFlash`. Nothing here blocks, allocates or
//! panics on input.
#![cfg_attr(not(test), no_std)]
// Requests, replies and motion states are moved a few times per request, never per tick,
// and there is no allocator to box them.
#![allow(clippy::large_enum_variant)]

pub mod app;
pub mod defaults;
pub mod hal;
pub mod links;
pub mod log;
pub mod server;
pub mod storage;
pub mod wheel;

pub use app::{App, Handled, PersistItem, TICK_HZ};
pub use hal::{ByteStream, EncoderSource, WheelDriver};
pub use links::{SaveQueue, TelemetryRoute};
pub use log::TrialLog;
pub use server::{Server, Step};
pub use storage::{Loaded, Store, StoreError};

/// Firmware version reported in the handshake.
pub const FIRMWARE_VERSION: &str = concat!("wheelcal-fw ", env!("CARGO_PKG_VERSION"));
