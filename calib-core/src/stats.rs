//! Descriptive statistics and normal-distribution probabilities used to judge calibration
//! runs ([Measuring errors] sec. 7, [Redundant omni] sec. IV).
//!
//! Everything is f64 and allocation-free. Functions come in two flavours: on `&[f64]`, and
//! `*_by` on any slice with a projection, so callers can summarise e.g. the x errors of a
//! `&[Run]` without copying them into a buffer (there is no allocator on the firmware).

use core::f64::consts::{FRAC_PI_2, PI, SQRT_2};
use core::fmt;

/// Why a statistic could not be computed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StatsError {
    /// The statistic needs more samples than were given.
    TooFewSamples {
        /// Samples needed.
        need: usize,
        /// Samples given.
        got: usize,
    },
    /// A sample or parameter was NaN or infinite.
    NonFinite,
    /// All samples are equal, so a shape statistic (skewness, kurtosis) is undefined.
    ZeroSpread,
    /// A parameter is outside its domain; the text names it and the requirement.
    InvalidParameter(&'static str),
}

impl fmt::Display for StatsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StatsError::TooFewSamples { need, got } => {
                write!(f, "need at least {need} samples, got {got}")
            }
            StatsError::NonFinite => write!(f, "a sample or parameter is NaN or infinite"),
            StatsError::ZeroSpread => write!(
                f,
                "all samples are equal: skewness/kurtosis are undefined (measure more precisely or add runs)"
            ),
            StatsError::InvalidParameter(what) => write!(f, "invalid parameter: {what}"),
        }
    }
}

impl core::error::Error for StatsError {}

fn check_finite(v: f64) -> Result<f64, StatsError> {
    if v.is_finite() {
        Ok(v)
    } else {
        Err(StatsError::NonFinite)
    }
}

/// Arithmetic mean of `f(item)` over `items`.
pub fn mean_by<T>(items: &[T], f: impl Fn(&T) -> f64) -> Result<f64, StatsError> {
    if items.is_empty() {
        return Err(StatsError::TooFewSamples { need: 1, got: 0 });
    }
    let mut sum = 0.0;
    for it in items {
        sum += check_finite(f(it))?;
    }
    Ok(sum / items.len() as f64)
}

/// Arithmetic mean.
pub fn mean(xs: &[f64]) -> Result<f64, StatsError> {
    mean_by(xs, |x| *x)
}

/// Central moments m2, m3, m4 (divided by n) about the mean; two passes for accuracy.
fn central_moments_by<T>(
    items: &[T],
    f: &impl Fn(&T) -> f64,
) -> Result<(f64, f64, f64, f64), StatsError> {
    let m = mean_by(items, f)?;
    let (mut s2, mut s3, mut s4) = (0.0, 0.0, 0.0);
    for it in items {
        let d = f(it) - m;
        let d2 = d * d;
        s2 += d2;
        s3 += d2 * d;
        s4 += d2 * d2;
    }
    let n = items.len() as f64;
    Ok((m, s2 / n, s3 / n, s4 / n))
}

/// Sample standard deviation with Bessel's correction (divides by n - 1), the usual
/// estimate of the spread of repeated runs.
pub fn sample_std_dev_by<T>(items: &[T], f: impl Fn(&T) -> f64) -> Result<f64, StatsError> {
    let n = items.len();
    if n < 2 {
        return Err(StatsError::TooFewSamples { need: 2, got: n });
    }
    let (_, m2, _, _) = central_moments_by(items, &f)?;
    Ok(libm::sqrt(m2 * n as f64 / (n as f64 - 1.0)))
}

/// Sample standard deviation (n - 1).
pub fn sample_std_dev(xs: &[f64]) -> Result<f64, StatsError> {
    sample_std_dev_by(xs, |x| *x)
}

/// Adjusted Fisher-Pearson sample skewness G1 = sqrt(n(n-1))/(n-2) * m3/m2^1.5, the
/// definition of Excel's SKEW and SPSS, which [Redundant omni]'s Table II most likely used.
pub fn skewness_by<T>(items: &[T], f: impl Fn(&T) -> f64) -> Result<f64, StatsError> {
    let n = items.len();
    if n < 3 {
        return Err(StatsError::TooFewSamples { need: 3, got: n });
    }
    let (_, m2, m3, _) = central_moments_by(items, &f)?;
    if m2 <= 0.0 {
        return Err(StatsError::ZeroSpread);
    }
    let nf = n as f64;
    let g1 = m3 / (m2 * libm::sqrt(m2));
    Ok(libm::sqrt(nf * (nf - 1.0)) / (nf - 2.0) * g1)
}

/// Adjusted Fisher-Pearson sample skewness G1 (see [`skewness_by`]).
pub fn skewness(xs: &[f64]) -> Result<f64, StatsError> {
    skewness_by(xs, |x| *x)
}

/// Sample excess kurtosis G2 = ((n+1) g2 + 6)(n-1)/((n-2)(n-3)) with g2 = m4/m2^2 - 3, the
/// definition of Excel's KURT and SPSS (0 for a normal distribution).
pub fn excess_kurtosis_by<T>(items: &[T], f: impl Fn(&T) -> f64) -> Result<f64, StatsError> {
    let n = items.len();
    if n < 4 {
        return Err(StatsError::TooFewSamples { need: 4, got: n });
    }
    let (_, m2, _, m4) = central_moments_by(items, &f)?;
    if m2 <= 0.0 {
        return Err(StatsError::ZeroSpread);
    }
    let nf = n as f64;
    let g2 = m4 / (m2 * m2) - 3.0;
    Ok(((nf + 1.0) * g2 + 6.0) * (nf - 1.0) / ((nf - 2.0) * (nf - 3.0)))
}

/// Sample excess kurtosis G2 (see [`excess_kurtosis_by`]).
pub fn excess_kurtosis(xs: &[f64]) -> Result<f64, StatsError> {
    excess_kurtosis_by(xs, |x| *x)
}

fn check_sigma(sigma: f64) -> Result<(), StatsError> {
    check_finite(sigma)?;
    if sigma < 0.0 {
        return Err(StatsError::InvalidParameter(
            "standard deviation must be >= 0",
        ));
    }
    Ok(())
}

/// Normal probability density ([Measuring errors] eq. 18), used to draw the error
/// distribution curves.
pub fn normal_pdf(x: f64, mean: f64, sigma: f64) -> Result<f64, StatsError> {
    check_finite(x)?;
    check_finite(mean)?;
    check_finite(sigma)?;
    if sigma <= 0.0 {
        return Err(StatsError::InvalidParameter(
            "standard deviation must be > 0 for a density",
        ));
    }
    let z = (x - mean) / sigma;
    Ok(libm::exp(-0.5 * z * z) / (sigma * libm::sqrt(2.0 * PI)))
}

/// Standard normal cumulative distribution Phi(z), via erfc so that the lower tail keeps
/// its relative accuracy.
pub fn std_normal_cdf(z: f64) -> f64 {
    0.5 * libm::erfc(-z / SQRT_2)
}

/// Normal cumulative distribution P(X <= x); sigma = 0 is a point mass at the mean.
pub fn normal_cdf(x: f64, mean: f64, sigma: f64) -> Result<f64, StatsError> {
    check_finite(mean)?;
    check_sigma(sigma)?;
    if x.is_nan() {
        return Err(StatsError::NonFinite);
    }
    if sigma == 0.0 {
        return Ok(if x >= mean { 1.0 } else { 0.0 });
    }
    Ok(std_normal_cdf((x - mean) / sigma))
}

/// Probability that a normal variable lies in the zone [a, b] ([Measuring errors] Fig. 25:
/// zones between zero, the smallest and the largest observed error). `a`/`b` may be
/// -inf/+inf.
pub fn normal_probability_between(
    mean: f64,
    sigma: f64,
    a: f64,
    b: f64,
) -> Result<f64, StatsError> {
    if a.is_nan() || b.is_nan() {
        return Err(StatsError::NonFinite);
    }
    if a > b {
        return Err(StatsError::InvalidParameter("zone must have a <= b"));
    }
    check_finite(mean)?;
    check_sigma(sigma)?;
    if sigma == 0.0 {
        return Ok(if a <= mean && mean <= b { 1.0 } else { 0.0 });
    }
    // Subtract in the tail where both cdf values are small, to avoid cancellation.
    let za = (a - mean) / sigma;
    let zb = (b - mean) / sigma;
    let p = if za > 0.0 {
        std_normal_cdf(-za) - std_normal_cdf(-zb)
    } else {
        std_normal_cdf(zb) - std_normal_cdf(za)
    };
    Ok(p.clamp(0.0, 1.0))
}

/// Probability that a 2-D normal end point with independent axes (standard deviations
/// `sigma_x`, `sigma_y`) lies within `radius` of its centre ([Measuring errors] Fig. 24:
/// "within 3 cm of the centre of gravity").
///
/// In polar coordinates the radial integral is closed-form; substituting
/// tan(phi) = (s_min/s_max) tan(t) then turns the angular integral into
/// P = (2/pi) int_0^{pi/2} [1 - exp(-R^2 / (2 (s_max^2 cos^2 t + s_min^2 sin^2 t)))] dt,
/// a bounded, smooth integrand that stays well-behaved for very unequal sigmas. It is
/// even and pi-periodic, so the trapezoidal rule converges spectrally; the step is halved
/// until two estimates agree to 1e-12. Equal sigmas give the Rayleigh cdf exactly.
pub fn probability_within_radius(
    sigma_x: f64,
    sigma_y: f64,
    radius: f64,
) -> Result<f64, StatsError> {
    check_sigma(sigma_x)?;
    check_sigma(sigma_y)?;
    check_finite(radius)?;
    if radius < 0.0 {
        return Err(StatsError::InvalidParameter("radius must be >= 0"));
    }
    if radius == 0.0 {
        return Ok(0.0);
    }
    let (smax, smin) = if sigma_x >= sigma_y {
        (sigma_x, sigma_y)
    } else {
        (sigma_y, sigma_x)
    };
    if smax == 0.0 {
        return Ok(1.0);
    }
    // Work in units of s_max so the exponent is O(R/s) whatever the physical scale.
    let r2 = (radius / smax) * (radius / smax);
    let k2 = (smin / smax) * (smin / smax);
    let g = |t: f64| {
        let c = libm::cos(t);
        let s = libm::sin(t);
        let d = c * c + k2 * s * s;
        if d <= 0.0 {
            1.0
        } else {
            -libm::expm1(-0.5 * r2 / d)
        }
    };
    let mut m = 8usize;
    let h0 = FRAC_PI_2 / m as f64;
    let mut sum = 0.5 * (g(0.0) + g(FRAC_PI_2));
    for i in 1..m {
        sum += g(i as f64 * h0);
    }
    let mut estimate = 2.0 / PI * sum * h0;
    // 2^22 intervals resolve the width-(s_min/s_max) feature near t = pi/2 down to
    // ratios of ~1e-6; below that its whole weight (< 1e-6) is within the tolerance.
    while m < (1 << 22) {
        let h = FRAC_PI_2 / (2 * m) as f64;
        for i in 0..m {
            sum += g((2 * i + 1) as f64 * h);
        }
        m *= 2;
        let next = 2.0 / PI * sum * h;
        let converged = m >= 64 && libm::fabs(next - estimate) <= 1e-12;
        estimate = next;
        if converged {
            break;
        }
    }
    Ok(estimate.clamp(0.0, 1.0))
}

/// Mean radial error ([Redundant omni] eq. 7): mean distance of the end points from the target.
pub fn mean_radial_error_by<T>(
    items: &[T],
    f: impl Fn(&T) -> (f64, f64),
) -> Result<f64, StatsError> {
    mean_by(items, |it| {
        let (x, y) = f(it);
        libm::hypot(x, y)
    })
}

/// Mean radial error ([Redundant omni] eq. 7) of (x, y) error pairs.
pub fn mean_radial_error(points: &[(f64, f64)]) -> Result<f64, StatsError> {
    mean_radial_error_by(points, |p| *p)
}

/// Mean error improvement index ([Redundant omni] eq. 8), in percent:
/// 100 (before - after) / before.
pub fn improvement_index_percent(before: f64, after: f64) -> Result<f64, StatsError> {
    check_finite(before)?;
    check_finite(after)?;
    if before <= 0.0 {
        return Err(StatsError::InvalidParameter(
            "error before calibration must be > 0",
        ));
    }
    if after < 0.0 {
        return Err(StatsError::InvalidParameter(
            "error after calibration must be >= 0",
        ));
    }
    Ok((before - after) / before * 100.0)
}

/// [Measuring errors] eq. 19: P_e = (e_BC - e_AC) / e_BC, the relative decrease of the
/// maximum error before (BC) and after (AC) calibration. Returned as a fraction exactly as
/// eq. 19 is written (the paper's text calls it a percentage: multiply by 100 to print it
/// so).
pub fn error_decrease_pe(max_error_before: f64, max_error_after: f64) -> Result<f64, StatsError> {
    improvement_index_percent(max_error_before, max_error_after).map(|p| p / 100.0)
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;

    // Textbook set: mean 5, population variance 4. Hand computation: sum of squared
    // deviations 32 -> s = sqrt(32/7); cubed 42 -> m3 = 5.25, g1 = 5.25/8 = 0.65625,
    // G1 = sqrt(56)/6 * g1; fourth 356 -> m4 = 44.5, g2 = 44.5/16 - 3 = -0.21875,
    // G2 = (9 g2 + 6) * 7 / 30 = 0.940625. Tolerance 1e-12: exact inputs, a handful of
    // f64 operations.
    const DATA: [f64; 8] = [2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0];

    #[test]
    fn moments_of_a_known_set() {
        assert!((mean(&DATA).unwrap() - 5.0).abs() < 1e-12);
        assert!((sample_std_dev(&DATA).unwrap() - libm::sqrt(32.0 / 7.0)).abs() < 1e-12);
        let g1 = libm::sqrt(56.0) / 6.0 * 0.65625;
        assert!((skewness(&DATA).unwrap() - g1).abs() < 1e-12);
        assert!((skewness(&DATA).unwrap() - 0.818_487_553_356_799_6).abs() < 1e-12);
        assert!((excess_kurtosis(&DATA).unwrap() - 0.940_625).abs() < 1e-12);
        // Mirrored data flips the skewness, keeps the kurtosis.
        let mirrored = DATA.map(|x| -x);
        assert!((skewness(&mirrored).unwrap() + g1).abs() < 1e-12);
        assert!((excess_kurtosis(&mirrored).unwrap() - 0.940_625).abs() < 1e-12);
    }

    #[test]
    fn projection_variants_agree() {
        let pairs: [(f64, f64); 8] = DATA.map(|x| (x, 0.0));
        assert_eq!(mean_by(&pairs, |p| p.0), mean(&DATA));
        assert_eq!(sample_std_dev_by(&pairs, |p| p.0), sample_std_dev(&DATA));
    }

    #[test]
    fn moment_errors() {
        assert_eq!(
            mean(&[]),
            Err(StatsError::TooFewSamples { need: 1, got: 0 })
        );
        assert_eq!(
            sample_std_dev(&[1.0]),
            Err(StatsError::TooFewSamples { need: 2, got: 1 })
        );
        assert_eq!(
            skewness(&[1.0, 2.0]),
            Err(StatsError::TooFewSamples { need: 3, got: 2 })
        );
        assert_eq!(
            excess_kurtosis(&[1.0, 2.0, 3.0]),
            Err(StatsError::TooFewSamples { need: 4, got: 3 })
        );
        assert_eq!(skewness(&[3.0; 5]), Err(StatsError::ZeroSpread));
        assert_eq!(excess_kurtosis(&[3.0; 5]), Err(StatsError::ZeroSpread));
        assert_eq!(mean(&[1.0, f64::NAN]), Err(StatsError::NonFinite));
        assert_eq!(
            sample_std_dev(&[1.0, f64::INFINITY]),
            Err(StatsError::NonFinite)
        );
        let msg = std::format!("{}", StatsError::TooFewSamples { need: 2, got: 1 });
        assert_eq!(msg, "need at least 2 samples, got 1");
    }

    #[test]
    fn erf_and_normal_cdf_match_tables() {
        // Abramowitz & Stegun table 7.1 values, 10 digits: tolerance 1e-10.
        assert!((libm::erf(0.5) - 0.520_499_877_8).abs() < 1e-10);
        assert!((libm::erf(1.0) - 0.842_700_792_9).abs() < 1e-10);
        assert!((libm::erf(2.0) - 0.995_322_265_0).abs() < 1e-10);
        // Phi(1.96) = 0.9750021 (7 digits quoted): tolerance 1e-7.
        assert!((std_normal_cdf(1.96) - 0.975_002_1).abs() < 1e-7);
        assert!((normal_cdf(1.96, 0.0, 1.0).unwrap() - 0.975_002_1).abs() < 1e-7);
        assert!((std_normal_cdf(0.0) - 0.5).abs() < 1e-15);
        // Shift/scale invariance: P(X <= mu + 2 sigma) = Phi(2) = (1 + erf(sqrt 2))/2.
        let phi2 = 0.5 * (1.0 + libm::erf(SQRT_2));
        assert!((normal_cdf(13.0, 5.0, 4.0).unwrap() - phi2).abs() < 1e-15);
        // Lower tail keeps relative accuracy: Phi(-10) = 7.619853e-24.
        assert!((std_normal_cdf(-10.0) / 7.619_853_024_160_527e-24 - 1.0).abs() < 1e-9);
        assert_eq!(normal_cdf(4.0, 5.0, 0.0).unwrap(), 0.0);
        assert!(normal_cdf(0.0, 0.0, -1.0).is_err());
        assert!(normal_cdf(f64::NAN, 0.0, 1.0).is_err());
    }

    #[test]
    fn normal_pdf_values() {
        // 1/sqrt(2 pi) = 0.3989422804014327; at one sigma times exp(-1/2).
        assert!((normal_pdf(0.0, 0.0, 1.0).unwrap() - 0.398_942_280_401_432_7).abs() < 1e-15);
        let v = normal_pdf(3.0, 1.0, 2.0).unwrap();
        assert!((v - 0.398_942_280_401_432_7 * libm::exp(-0.5) / 2.0).abs() < 1e-15);
        assert!(normal_pdf(0.0, 0.0, 0.0).is_err());
        assert!(normal_pdf(f64::NAN, 0.0, 1.0).is_err());
    }

    #[test]
    fn zone_probabilities() {
        // 95 % two-sided interval: P(|Z| < 1.959964) = 0.95 (tolerance 1e-6: 7 digits).
        let p = normal_probability_between(0.0, 1.0, -1.959_964, 1.959_964).unwrap();
        assert!((p - 0.95).abs() < 1e-6);
        // Zones tile the line: below, between, above sum to 1 exactly up to rounding.
        let (m, s) = (0.05, 0.012);
        let lo = normal_probability_between(m, s, f64::NEG_INFINITY, 0.04).unwrap();
        let mid = normal_probability_between(m, s, 0.04, 0.07).unwrap();
        let hi = normal_probability_between(m, s, 0.07, f64::INFINITY).unwrap();
        assert!((lo + mid + hi - 1.0).abs() < 1e-14);
        // Far upper tail computed without cancellation: P(Z in [8, 9]) = Q(8) - Q(9).
        let t = normal_probability_between(0.0, 1.0, 8.0, 9.0).unwrap();
        assert!((t / (6.220_960_574_271_785e-16 - 1.128_588_405_953_840_5e-19) - 1.0).abs() < 1e-9);
        assert!(normal_probability_between(0.0, 1.0, 1.0, 0.0).is_err());
        assert!(normal_probability_between(0.0, 1.0, f64::NAN, 0.0).is_err());
        assert_eq!(
            normal_probability_between(0.0, 0.0, -1.0, 1.0).unwrap(),
            1.0
        );
    }

    #[test]
    fn within_radius_equal_sigmas_is_rayleigh() {
        // Rayleigh cdf 1 - exp(-R^2/(2 sigma^2)); required accuracy 1e-6, we ask 1e-12
        // since the trapezoid of a constant integrand is exact.
        for &(s, r) in &[(0.01, 0.03), (1.0, 0.1), (2.0, 5.0), (0.5, 1e-4)] {
            let p = probability_within_radius(s, s, r).unwrap();
            let exact = -libm::expm1(-r * r / (2.0 * s * s));
            assert!((p - exact).abs() < 1e-12, "s={s} r={r} p={p} exact={exact}");
        }
    }

    /// Brute-force reference: composite Simpson in Cartesian coordinates over the disc,
    /// integrating x exactly via erf for each y (so only a 1-D Simpson is needed).
    fn reference_within_radius(sx: f64, sy: f64, r: f64) -> f64 {
        let n = 20_000; // even; Simpson error ~ h^4 f'''' which is << 1e-9 here
        let h = 2.0 * r / n as f64;
        let f = |y: f64| {
            let half = libm::sqrt((r * r - y * y).max(0.0));
            normal_pdf(y, 0.0, sy).unwrap() * libm::erf(half / (sx * SQRT_2))
        };
        let mut sum = f(-r) + f(r);
        for i in 1..n {
            let y = -r + i as f64 * h;
            sum += if i % 2 == 1 { 4.0 } else { 2.0 } * f(y);
        }
        sum * h / 3.0
    }

    #[test]
    fn within_radius_unequal_sigmas_matches_cartesian_reference() {
        // The reference's integrand has a sqrt singularity in its derivative at y = +-R,
        // which limits Simpson to ~h^1.5 accuracy: with h = 1e-4 R that is ~1e-7, below
        // the 1e-6 the brief asks for, so that is the tolerance.
        for &(sx, sy, r) in &[(1.0, 2.0, 1.5), (0.02, 0.005, 0.03), (3.0, 0.1, 0.2)] {
            let p = probability_within_radius(sx, sy, r).unwrap();
            let reference = reference_within_radius(sx, sy, r);
            assert!(
                (p - reference).abs() < 1e-6,
                "{sx} {sy} {r}: {p} vs {reference}"
            );
            // The argument order must not matter.
            let q = probability_within_radius(sy, sx, r).unwrap();
            assert!((p - q).abs() < 1e-12);
        }
    }

    #[test]
    fn within_radius_limits() {
        // Degenerate axis: 1-D P(|X| < R) = erf(R/(sigma sqrt 2)); P(|Z|<1) = 0.682689.
        let p = probability_within_radius(1.0, 0.0, 1.0).unwrap();
        assert!((p - 0.682_689_492_137_085_9).abs() < 1e-12);
        // Nearly degenerate (ratio 1e-6): the 2-D formula tends to the same limit; the
        // minor axis changes it by O(sy/R) = 1e-6 at most, hence the 1e-6 tolerance.
        let p = probability_within_radius(1.0, 1e-6, 1.0).unwrap();
        assert!((p - 0.682_689_492_137_085_9).abs() < 1e-6);
        assert_eq!(probability_within_radius(0.0, 0.0, 0.1).unwrap(), 1.0);
        assert_eq!(probability_within_radius(1.0, 1.0, 0.0).unwrap(), 0.0);
        assert!((probability_within_radius(1.0, 3.0, 100.0).unwrap() - 1.0).abs() < 1e-12);
        assert!(probability_within_radius(-1.0, 1.0, 1.0).is_err());
        assert!(probability_within_radius(1.0, 1.0, -1.0).is_err());
        assert!(probability_within_radius(f64::NAN, 1.0, 1.0).is_err());
    }

    #[test]
    fn radial_error_and_improvement() {
        // 3-4-5 and 5-12-13 triangles: mean of 5 and 13 is 9.
        let pts = [(3.0, 4.0), (-5.0, 12.0)];
        assert!((mean_radial_error(&pts).unwrap() - 9.0).abs() < 1e-12);
        assert!(mean_radial_error(&[]).is_err());
        // [Redundant omni] Table II: 91.72 -> 15.43 is quoted as an 80 % improvement (eq. 8
        // gives 83.18 %, which the paper rounds down to "at least 80 %").
        let imp = improvement_index_percent(91.72, 15.43).unwrap();
        assert!((imp - 83.177_060_619_276_1).abs() < 1e-9);
        assert!(imp >= 80.0);
        assert!(improvement_index_percent(0.0, 1.0).is_err());
        assert!(improvement_index_percent(1.0, f64::NAN).is_err());
        // [Measuring errors] eq. 19 with Table 1 Case I: (97.15 - 8.54)/97.15 = 0.912095.
        let pe = error_decrease_pe(97.15, 8.54).unwrap();
        assert!((pe - 88.61 / 97.15).abs() < 1e-12);
        assert!(error_decrease_pe(-1.0, 0.0).is_err());
        // [Measuring errors] Table 1's "Improvement" column (11, 10, 5) is NOT eq. 19: it
        // is the ratio E_max,sys before/after, truncated (97.15/8.54 = 11.4,
        // 101.42/9.43 = 10.8, 33.39/6.23 = 5.4), while eq. 19 gives 0.91, 0.91, 0.81.
        for (before, after, column) in [
            (97.15, 8.54, 11.0),
            (101.42, 9.43, 10.0),
            (33.39, 6.23, 5.0),
        ] {
            assert_eq!(libm::floor(before / after), column);
            let pe = error_decrease_pe(before, after).unwrap();
            assert!((0.8..0.92).contains(&pe), "{pe}");
        }
    }
}
