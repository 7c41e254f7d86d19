//! Noise statistics of residual series: how correlated neighbouring residuals are, and
//! what that does to the variance of their mean.

/// Lag-1 autocorrelation pooled over `series` (pairs never straddle two series), in
/// [0, `cap`]: an AR(1) residual's mean has [`ar1_inflation`] times the variance of
/// independent samples, so it discounts their count.
pub fn lag1_autocorrelation<'a>(series: impl IntoIterator<Item = &'a [f64]>, cap: f64) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for s in series {
        for w in s.windows(2) {
            num += w[0] * w[1];
            den += w[0] * w[0];
        }
    }
    if den > 0.0 {
        (num / den).clamp(0.0, cap)
    } else {
        0.0
    }
}

/// Variance inflation of a mean of AR(1) samples with lag-1 correlation `rho`.
pub fn ar1_inflation(rho: f64) -> f64 {
    (1.0 + rho) / (1.0 - rho)
}
