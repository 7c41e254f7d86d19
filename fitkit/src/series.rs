//! Series helpers the fits share: headings unwrapped, blank cells held.

use std::f64::consts::{PI, TAU};

/// Unwraps a heading series so consecutive samples differ by less than pi.
pub fn unwrap_angles(theta: &mut [f64]) {
    let mut offset = 0.0;
    for i in 1..theta.len() {
        let raw_prev = theta[i - 1] - offset;
        let d = theta[i] - raw_prev;
        if d > PI {
            offset -= TAU * ((d + PI) / TAU).floor();
        } else if d < -PI {
            offset += TAU * ((-d + PI) / TAU).floor();
        }
        theta[i] += offset;
    }
}

/// Holds the last measured value over blank cells (and the first one before it);
/// `None` when the column has no value at all.
pub fn fill<T: Copy>(cells: &[Option<T>]) -> Option<Vec<T>> {
    let first = cells.iter().find_map(|c| *c)?;
    let mut last = first;
    Some(
        cells
            .iter()
            .map(|c| {
                if let Some(v) = c {
                    last = *v;
                }
                last
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unwrap_handles_wrapped_and_multi_turn() {
        let mut th = vec![3.0, -3.0, -2.0, 3.1, -3.1];
        unwrap_angles(&mut th);
        assert!((th[1] - (TAU - 3.0)).abs() < 1e-12);
        assert!((th[2] - (TAU - 2.0)).abs() < 1e-12);
        // -2 -> 3.1 is a step of 5.1 > pi: taken as -1.18.
        assert!((th[3] - (3.1)).abs() < 1e-12);
        assert!((th[4] - (TAU - 3.1)).abs() < 1e-12);
    }
}
