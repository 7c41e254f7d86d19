//! Which way the recordings turn. Whatever follows the turning direction (a tilted floor,
//! a caster, turn slip unequal left and right) goes into the geometry unseen when every
//! recording turns the same way: it changes sign with the direction, so one direction
//! cannot tell it from E_d and E_b, and its residuals look like the fit's noise. UMBmark
//! drives its square both ways for this reason. On the real squares of data/real the
//! clockwise and counter-clockwise E_d differ by 0.0039 (docs/calibrate.md).

use super::series::Series;

/// A turn is a run of heading change of one sign of at least this (rad, 17 degrees):
/// the counter-turns of the real runs (a controller's correction after a corner) reach
/// 0.22 rad over the OptiOdom sessions' 299 runs, in 0.5 s steps; the test paths turn a
/// quarter turn or more at a time.
pub const TURN_MIN_RAD: f64 = 0.3;
/// Headings are compared this far apart (s), so pose noise does not split a turn.
const STEP_S: f64 = 0.5;
/// The recordings turn one way when the other way's turns are under this share of all
/// turning (5 %: a set of twenty squares one way and one the other still counts as one
/// way; the real runs' single recordings measure exactly 0).
pub const ONE_WAY_SHARE: f64 = 0.05;

/// Turning of a set of recordings, in turns of at least [`TURN_MIN_RAD`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Turning {
    /// Counter-clockwise (left) turning, rad.
    pub left_rad: f64,
    /// Clockwise (right) turning, rad.
    pub right_rad: f64,
}

impl Turning {
    /// The measured turning of `series`.
    pub fn of(series: &[Series]) -> Turning {
        let mut t = Turning::default();
        for s in series {
            for turn in turns(s) {
                if turn > 0.0 {
                    t.left_rad += turn;
                } else {
                    t.right_rad -= turn;
                }
            }
        }
        t
    }

    /// `"clockwise"` or `"counter-clockwise"` when the recordings turn one way (the
    /// other way under [`ONE_WAY_SHARE`] of their turns), `None` when they turn both
    /// ways or not at all.
    pub fn one_way(&self) -> Option<&'static str> {
        let total = self.left_rad + self.right_rad;
        if total < TURN_MIN_RAD {
            return None;
        }
        if self.right_rad < ONE_WAY_SHARE * total {
            Some("counter-clockwise")
        } else if self.left_rad < ONE_WAY_SHARE * total {
            Some("clockwise")
        } else {
            None
        }
    }

    /// The other way's share of the turning.
    pub fn minority_share(&self) -> f64 {
        let total = self.left_rad + self.right_rad;
        if total > 0.0 {
            self.left_rad.min(self.right_rad) / total
        } else {
            0.0
        }
    }
}

/// The turns of one recording: its measured heading every [`STEP_S`], summed over runs of
/// one sign, the runs of at least [`TURN_MIN_RAD`] kept (signed, rad).
fn turns(s: &Series) -> Vec<f64> {
    let mut headings = Vec::new();
    let mut next_t = f64::NEG_INFINITY;
    for (i, &row) in s.pose_row.iter().enumerate() {
        let t = s.t.get(row).copied().unwrap_or(f64::NAN);
        if t >= next_t && s.pth[i].is_finite() {
            headings.push(s.pth[i]);
            next_t = t + STEP_S;
        }
    }
    let mut out = Vec::new();
    let mut run = 0.0f64;
    for w in headings.windows(2) {
        let d = wrap(w[1] - w[0]);
        if run != 0.0 && d != 0.0 && d.signum() != run.signum() {
            out.push(run);
            run = 0.0;
        }
        run += d;
    }
    out.push(run);
    out.retain(|r| r.abs() >= TURN_MIN_RAD);
    out
}

/// `a` wrapped into (-pi, pi].
fn wrap(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = a.rem_euclid(TAU);
    if w > PI {
        w - TAU
    } else {
        w
    }
}

/// The note of a calibration whose recordings all turn one way (`sense`), naming what
/// follows the direction and which parameters take it (`what`).
pub fn one_way_note(sense: &str, turning: &Turning, what: &str) -> String {
    format!(
        "every recording turns one way ({sense}; the other way {:.1} % of the turning): {what} are fitted from one turning direction, and whatever follows the turning direction (a tilted floor, a caster, turn slip unequal left and right) goes into them unseen, beyond their ±, which counts the fit's noise only; drive the path the other way as well (UMBmark drives its square both ways) and calibrate on both",
        turning.minority_share() * 100.0
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrap_keeps_angles_within_half_a_turn() {
        assert!((wrap(3.5) - (3.5 - std::f64::consts::TAU)).abs() < 1e-12);
        assert!((wrap(-0.2) + 0.2).abs() < 1e-12);
    }

    #[test]
    fn one_way_needs_the_other_way_under_its_share() {
        let t = |l, r| Turning {
            left_rad: l,
            right_rad: r,
        };
        assert_eq!(t(0.0, 6.3).one_way(), Some("clockwise"));
        assert_eq!(t(6.3, 0.2).one_way(), Some("counter-clockwise"));
        assert_eq!(t(6.3, 0.4).one_way(), None);
        assert_eq!(t(0.1, 0.1).one_way(), None);
    }
}
