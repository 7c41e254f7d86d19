//! Quadrature encoders as a board reads them: a count that is the floor of the shaft angle
//! in counts, held in a 16-bit hardware counter that wraps.
//!
//! Counts are per *wheel* revolution as the robot file says; an encoder on the motor shaft
//! (before the gear and its backlash) is expressed the same way, with the motor angle
//! divided by the gear ratio, which is why the robot file allows fractional counts.

use std::f64::consts::TAU;

/// One encoder.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Encoder {
    counts_per_rad: f64,
    /// Raw counter value at angle 0 (counters power up anywhere).
    raw_offset: u16,
}

impl Encoder {
    /// `counts_per_wheel_rev` from the robot file (0: no encoder, reads 0).
    pub fn new(counts_per_wheel_rev: f64, raw_offset: u16) -> Self {
        Encoder {
            counts_per_rad: counts_per_wheel_rev / TAU,
            raw_offset,
        }
    }

    /// Cumulative signed count for a shaft angle in wheel radians.
    pub fn count(&self, wheel_angle_rad: f64) -> i64 {
        // A hair of tolerance so an angle that should sit exactly on an edge (n counts
        // times the count width) is not read one low because of rounding in the product.
        (wheel_angle_rad * self.counts_per_rad + 1e-9).floor() as i64
    }

    /// What the 16-bit hardware counter shows.
    pub fn raw(&self, wheel_angle_rad: f64) -> u16 {
        self.raw_offset
            .wrapping_add(self.count(wheel_angle_rad) as u16)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use calib_core::encoder::{CounterExtender, CounterWidth};

    #[test]
    fn one_wheel_revolution_is_1920_counts() {
        let e = Encoder::new(1920.0, 65000);
        assert_eq!(e.count(TAU), 1920);
        assert_eq!(e.count(-TAU), -1920);
        assert_eq!(e.count(TAU * 0.5 / 1920.0), 0);
        // Ten revolutions through the 16-bit wrap, read back with calib-core's extender.
        let mut ext = CounterExtender::new(CounterWidth::Bits16, e.raw(0.0) as u32);
        for k in 1..=10_000 {
            ext.update(e.raw(k as f64 * 10.0 * TAU / 10_000.0) as u32);
        }
        assert_eq!(ext.position(), 19_200);
    }
}
