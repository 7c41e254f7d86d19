//! Quadrature encoders: extending a wrapping hardware counter into a position that never
//! wraps, and counts into wheel angle.
//!
//! A 16-bit timer in QEI mode wraps every 65 536 counts. Reading it every control tick and
//! adding the signed difference (taken modulo 2^16) loses nothing as long as the wheel
//! moves fewer than 32 767 counts between two reads: with 1920 counts per wheel revolution
//! at 1 kHz that is 17 wheel revolutions per millisecond, ~1000 times faster than any
//! wheel here turns. The extended position is an i64: at 1 MHz of counts it would take
//! 292 000 years to overflow.

use serde::{Deserialize, Serialize};

/// Width of the hardware counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum CounterWidth {
    /// 16-bit timer (wraps every 65 536 counts).
    Bits16,
    /// 32-bit timer.
    Bits32,
}

impl CounterWidth {
    fn bits(self) -> u32 {
        match self {
            CounterWidth::Bits16 => 16,
            CounterWidth::Bits32 => 32,
        }
    }

    /// Largest movement between two reads that is still counted correctly.
    pub fn max_delta(self) -> i64 {
        (1i64 << (self.bits() - 1)) - 1
    }
}

/// Turns successive raw counter readings into a continuous 64-bit count.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CounterExtender {
    width: CounterWidth,
    last_raw: u32,
    position: i64,
}

impl CounterExtender {
    /// Starts at position 0 from the counter's current raw value.
    pub fn new(width: CounterWidth, raw: u32) -> Self {
        CounterExtender {
            width,
            last_raw: raw,
            position: 0,
        }
    }

    /// Feeds a new raw reading; returns the signed movement since the last one.
    pub fn update(&mut self, raw: u32) -> i64 {
        let delta = match self.width {
            CounterWidth::Bits16 => (raw as u16).wrapping_sub(self.last_raw as u16) as i16 as i64,
            CounterWidth::Bits32 => raw.wrapping_sub(self.last_raw) as i32 as i64,
        };
        self.last_raw = raw;
        self.position += delta;
        delta
    }

    /// Continuous count since construction.
    pub fn position(&self) -> i64 {
        self.position
    }
}

/// Wheel angle in radians for a count, given counts per wheel revolution (may be
/// fractional: a motor-side encoder times the gear ratio).
pub fn counts_to_rad(counts: i64, counts_per_rev: f64) -> f64 {
    counts as f64 * core::f64::consts::TAU / counts_per_rev
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        /// Any sequence of movements below the limit is tracked exactly through wraps.
        #[test]
        fn wrap_16_never_loses_counts(start in any::<u16>(), steps in proptest::collection::vec(-32767i64..=32767, 1..400)) {
            let mut truth: i64 = 0;
            let mut raw = start as i64;
            let mut ext = CounterExtender::new(CounterWidth::Bits16, start as u32);
            for s in steps {
                truth += s;
                raw = (raw + s).rem_euclid(65536);
                ext.update(raw as u32);
                prop_assert_eq!(ext.position(), truth);
            }
        }

        #[test]
        fn wrap_32_never_loses_counts(start in any::<u32>(), steps in proptest::collection::vec(-(i32::MAX as i64)..=(i32::MAX as i64), 1..200)) {
            let mut truth: i64 = 0;
            let mut raw = start as i64;
            let mut ext = CounterExtender::new(CounterWidth::Bits32, start);
            for s in steps {
                truth += s;
                raw = (raw + s).rem_euclid(1i64 << 32);
                ext.update(raw as u32);
                prop_assert_eq!(ext.position(), truth);
            }
        }
    }

    #[test]
    fn wrap_limit_is_half_range() {
        assert_eq!(CounterWidth::Bits16.max_delta(), 32767);
        // One more than the limit is read as a reversal: documented, and why the control
        // loop reads every tick.
        let mut e = CounterExtender::new(CounterWidth::Bits16, 0);
        assert_eq!(e.update(32768), -32768);
    }

    #[test]
    fn counts_to_angle() {
        assert!((counts_to_rad(1920, 1920.0) - core::f64::consts::TAU).abs() < 1e-15);
        // Motor-side 64 cpr x 43.7 gear (shared/real) = 2796.8 counts per wheel rev.
        assert!(
            (counts_to_rad(-2797, 2796.8) + core::f64::consts::TAU * 2797.0 / 2796.8).abs() < 1e-12
        );
    }
}
