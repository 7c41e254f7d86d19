//! Floor features in world coordinates: cable strips ([Redundant omni]), low-friction
//! patches, a tilted floor.
//!
//! They are properties of the floor, not of the robot, so the same robot driven over a
//! different part of the floor meets them at different times: that is what makes them
//! locatable by position in a recording.

/// Parallel cables ([Redundant omni]: 5 mm cables every 30 mm) that each cost a wheel
/// `loss_m` of travel when it rolls over one.
///
/// The cables are the lines `n . p = offset_m + k * spacing_m` for every integer k, with
/// `n` the unit normal at `normal_rad` from world x: with the default normal 0 they are the
/// lines x = k * spacing_m across the whole floor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CableStrip {
    /// Distance between cables along the normal (m).
    pub spacing_m: f64,
    /// Travel a wheel loses crossing one cable (m).
    pub loss_m: f64,
    /// Direction of the cables' normal from world x (rad).
    pub normal_rad: f64,
    /// Position of cable 0 along the normal (m).
    pub offset_m: f64,
    /// Cables only where `start_m <= n . p <= end_m` (a strip); infinite by default.
    pub start_m: f64,
    /// Upper end of the strip along the normal (m).
    pub end_m: f64,
    /// Irregular spacing: cable k sits up to `jitter` spacings (< 0.5) off its regular
    /// place, by a fixed pseudo-random amount per cable (0 = regular).
    pub jitter: f64,
}

/// A fixed pseudo-random number in [-1, 1) for cable k (SplitMix64 of k): the same floor
/// every run, without a random stream.
fn cable_offset(k: i64) -> f64 {
    let mut z = (k as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

impl CableStrip {
    /// Cables across the whole floor, perpendicular to world x.
    pub fn new(spacing_m: f64, loss_m: f64) -> Self {
        CableStrip {
            spacing_m,
            loss_m,
            normal_rad: 0.0,
            offset_m: 0.0,
            start_m: f64::NEG_INFINITY,
            end_m: f64::INFINITY,
            jitter: 0.0,
        }
    }

    /// Unit normal of the cables.
    pub fn normal(&self) -> (f64, f64) {
        (self.normal_rad.cos(), self.normal_rad.sin())
    }

    /// Number of cables crossed between the normal coordinates `s0` and `s1`.
    pub fn crossings(&self, s0: f64, s1: f64) -> u32 {
        let (a, b) = (s0.min(s1).max(self.start_m), s0.max(s1).min(self.end_m));
        if a >= b {
            return 0;
        }
        if self.jitter > 0.0 {
            // Cable k sits at offset + (k + jitter * u_k) * spacing, |jitter| < 0.5: only
            // the neighbours of the regular range can move in or out of it.
            let k0 = ((a - self.offset_m) / self.spacing_m).floor() as i64 - 1;
            let k1 = ((b - self.offset_m) / self.spacing_m).floor() as i64 + 1;
            return (k0..=k1)
                .filter(|&k| {
                    let pos =
                        self.offset_m + (k as f64 + self.jitter * cable_offset(k)) * self.spacing_m;
                    a < pos && pos <= b
                })
                .count() as u32;
        }
        // Cable k sits at offset + k * spacing; count k with a < pos <= b.
        let ka = ((a - self.offset_m) / self.spacing_m).floor();
        let kb = ((b - self.offset_m) / self.spacing_m).floor();
        (kb - ka).max(0.0) as u32
    }
}

/// An axis-aligned rectangle of the floor where friction is `mu_scale` times the rest.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// Lower x bound (m).
    pub x_min: f64,
    /// Upper x bound (m).
    pub x_max: f64,
    /// Lower y bound (m).
    pub y_min: f64,
    /// Upper y bound (m).
    pub y_max: f64,
    /// Friction multiplier inside the patch.
    pub mu_scale: f64,
}

/// A floor tilted so the robot drifts downhill while it moves: a constant world-frame
/// drift velocity. Outside the diagnose catalogue on purpose (its "unexplained" control).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tilt {
    /// Drift speed while moving (m/s).
    pub drift_m_s: f64,
    /// Downhill direction from world x.
    pub direction_rad: f64,
}

/// The floor the robot drives on: flat unless features are added.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Surface {
    /// Cable strip, if any.
    pub cables: Option<CableStrip>,
    /// Low-friction patches.
    pub patches: Vec<Patch>,
    /// Tilt, if any.
    pub tilt: Option<Tilt>,
}

impl Surface {
    /// A flat, uniform floor.
    pub fn flat() -> Self {
        Surface::default()
    }

    /// Friction multiplier at a world point (patches may overlap: the lowest wins).
    pub fn mu_scale_at(&self, x: f64, y: f64) -> f64 {
        let mut s: f64 = 1.0;
        for p in &self.patches {
            if x >= p.x_min && x <= p.x_max && y >= p.y_min && y <= p.y_max {
                s = s.min(p.mu_scale);
            }
        }
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_cables_between_positions() {
        let c = CableStrip::new(0.03, 0.001);
        assert_eq!(c.crossings(0.001, 0.029), 0);
        assert_eq!(c.crossings(0.029, 0.031), 1);
        assert_eq!(c.crossings(0.031, 0.029), 1);
        // 1 m of travel from just past a cable crosses 33 cables (at 0.03 .. 0.99).
        assert_eq!(c.crossings(0.001, 1.001), 33);
        let mut s = c;
        s.start_m = 0.5;
        s.end_m = 0.7;
        assert_eq!(s.crossings(0.0, 1.0), 7); // 0.51 .. 0.69
                                              // Irregular: as many cables per metre on average, but not evenly spaced.
        let mut j = c;
        j.jitter = 0.4;
        assert!((j.crossings(0.0, 30.0) as i64 - 1000).abs() <= 1);
        // Cable positions to 1 mm over 3 m: gaps from 0.2 to 1.8 spacings occur.
        let pos: Vec<f64> = (0..3000)
            .filter(|&i| j.crossings(i as f64 * 1e-3, (i + 1) as f64 * 1e-3) > 0)
            .map(|i| i as f64 * 1e-3)
            .collect();
        let gaps: Vec<f64> = pos.windows(2).map(|w| w[1] - w[0]).collect();
        let (lo, hi) = gaps
            .iter()
            .fold((1.0f64, 0.0f64), |a, &g| (a.0.min(g), a.1.max(g)));
        assert!(lo < 0.5 * 0.03 && hi > 1.5 * 0.03, "{lo} {hi}");
    }
}
