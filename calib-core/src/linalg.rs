//! The few small numeric helpers several modules need: one 3x3 inverse with one
//! singularity rule, and sin(u)/u for exact-arc integration.

/// A 3x3 matrix, row-major.
pub type Mat3 = [[f64; 3]; 3];

/// Determinant of a 3x3 matrix.
pub fn det3(m: &Mat3) -> f64 {
    m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
        - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
}

/// Relative size below which a determinant counts as zero: |det| <= this times the product
/// of the diagonal. The matrices inverted here are normal matrices (positive diagonal), so
/// the ratio measures conditioning independent of units.
pub const SINGULAR_RATIO: f64 = 1e-9;

/// Inverse of a normal matrix (positive diagonal) by the adjugate, or `None` when it is
/// singular by [`SINGULAR_RATIO`], has a non-positive diagonal product or is not finite.
pub fn inverse3(m: &Mat3) -> Option<Mat3> {
    let det = det3(m);
    let scale = m[0][0] * m[1][1] * m[2][2];
    if !det.is_finite() || scale.is_nan() || scale <= 0.0 || det.abs() <= SINGULAR_RATIO * scale {
        return None;
    }
    let c =
        |r0: usize, c0: usize, r1: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let adj = [
        [c(1, 1, 2, 2), -c(0, 1, 2, 2), c(0, 1, 1, 2)],
        [-c(1, 0, 2, 2), c(0, 0, 2, 2), -c(0, 0, 1, 2)],
        [c(1, 0, 2, 1), -c(0, 0, 2, 1), c(0, 0, 1, 1)],
    ];
    let mut out = [[0.0; 3]; 3];
    for a in 0..3 {
        for b in 0..3 {
            out[a][b] = adj[a][b] / det;
        }
    }
    Some(out)
}

/// sin(u)/u, accurate near 0 (the chord of an arc turning by 2u is its length times this).
pub fn sinc(u: f64) -> f64 {
    if libm::fabs(u) < 1e-4 {
        let u2 = u * u;
        1.0 - u2 / 6.0 + u2 * u2 / 120.0
    } else {
        libm::sin(u) / u
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_times_matrix_is_identity() {
        let m = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]];
        let inv = inverse3(&m).expect("well conditioned");
        for (i, row) in m.iter().enumerate() {
            for (j, want_col) in [0usize, 1, 2].into_iter().enumerate() {
                let p: f64 = (0..3).map(|k| row[k] * inv[k][want_col]).sum();
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((p - want).abs() < 1e-14, "({i},{j}) = {p}");
            }
        }
    }

    #[test]
    fn singular_and_degenerate_matrices_are_refused() {
        // Rank 2: third row = first + second.
        let m = [[1.0, 2.0, 3.0], [0.5, 1.0, 0.0], [1.5, 3.0, 3.0]];
        assert!(inverse3(&m).is_none());
        assert!(inverse3(&[[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
        assert!(inverse3(&[[0.0; 3]; 3]).is_none());
    }

    #[test]
    fn sinc_series_meets_the_closed_form() {
        // Either side of the switch at 1e-4 the two forms agree to rounding.
        for u in [9.9e-5, 1.01e-4, -1e-4, 0.3] {
            assert!((sinc(u) - libm::sin(u) / u).abs() < 1e-15, "u = {u}");
        }
        assert_eq!(sinc(0.0), 1.0);
    }
}
