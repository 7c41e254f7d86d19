//! A priority-ceiling mutex: locking raises BASEPRI to the control executor's priority
//! instead of masking every interrupt.
//!
//! The application is shared by the control task (interrupt executor at [`CEILING`]) and
//! the link tasks (thread mode). While a link task holds the lock, the control executor's
//! interrupt cannot run, so the two never touch the application at once; interrupts more
//! urgent than the ceiling (the stepper's compare interrupt, the UART, USB, the time
//! driver) stay live, so a long answer (up to ~1 KiB encoded with CRC and COBS) cannot
//! delay a step edge.
//! A critical-section mutex masked them all for the whole tick, request or telemetry.

use cortex_m::register::{basepri, basepri_max};
use embassy_stm32::interrupt::Priority;
use embassy_sync::blocking_mutex::raw::RawMutex;

/// Priority of the control executor's interrupt: the ceiling of every lock.
pub const CEILING: Priority = Priority::P6;

/// Raw mutex for data shared only by code running at or below [`CEILING`] (thread mode
/// and the control executor); never lock it from a more urgent interrupt.
pub struct CeilingRawMutex(());

// SAFETY: every user runs at a priority no more urgent than CEILING (see the type's
// documentation); with BASEPRI at CEILING none of them can preempt the holder, so no
// two of them are inside `lock` at once. The tasks run on one core.
unsafe impl RawMutex for CeilingRawMutex {
    const INIT: Self = CeilingRawMutex(());

    fn lock<R>(&self, f: impl FnOnce() -> R) -> R {
        let old = basepri::read();
        // basepri_max only ever raises the mask: a caller already at the ceiling keeps it.
        basepri_max::write(CEILING as u8);
        let r = f();
        // SAFETY: restores the mask that was in force when the lock was taken (lowering
        // BASEPRI may let a pending interrupt run, which is what it was waiting for).
        unsafe { basepri::write(old) };
        r
    }
}
