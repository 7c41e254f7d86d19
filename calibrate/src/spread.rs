//! How far calibrating again on other runs would move each parameter: the spread between
//! recordings (delete-one-group jackknife), beside the fit's own uncertainty.
//!
//! The fit's sigma comes from its residuals (their autocorrelation counted). It knows
//! nothing of what differs from one run to the next: the motion, and with it how any
//! physics the model leaves out leans on each parameter. On a simulated robot whose
//! wheelbase is 4 % wider on arcs, eight calibrations on three runs each found turn laws
//! 0.0024 apart where each fit said ± 0.00024 (`calibrate_sim.rs`,
//! `reported_uncertainty_is_the_spread_between_calibrations`). The jackknife measures that
//! spread from the recordings at hand: each group left out in turn (one Gauss-Newton step
//! from the full solution, as cross-validation's folds), the variance
//! (G - 1) / G x sum (theta_g - mean)^2.

use super::options::CvBy;
use super::params::ParamSpec;
use super::solve::OneStep;
use nalgebra::DMatrix;

/// Fewer groups than this leave the spread unmeasured (two values give no spread worth
/// the name).
pub const MIN_SPREAD_GROUPS: usize = 3;

/// The between-groups standard deviation of every geometry parameter.
pub(super) struct Spread {
    /// One per parameter, in the fit's order.
    pub sigma: Vec<f64>,
    /// How many groups were left out in turn.
    pub groups: usize,
}

/// The jackknife over `groups` (one label per recording of `one`'s problem).
pub(super) fn between_groups(one: &OneStep, groups: &[String]) -> Option<Spread> {
    let mut distinct: Vec<&String> = groups.iter().collect();
    distinct.sort();
    distinct.dedup();
    if distinct.len() < MIN_SPREAD_GROUPS {
        return None;
    }
    let fits: Vec<Vec<f64>> = distinct
        .iter()
        .map(|d| one.without((0..groups.len()).filter(|&j| &groups[j] == *d)))
        .collect();
    Some(Spread {
        sigma: jackknife_sigmas(&fits),
        groups: fits.len(),
    })
}

/// Delete-one jackknife standard deviations of the columns of `fits` (one row per group
/// left out).
fn jackknife_sigmas(fits: &[Vec<f64>]) -> Vec<f64> {
    let k = fits.len() as f64;
    let g = fits.first().map_or(0, Vec::len);
    (0..g)
        .map(|a| {
            let mean = fits.iter().map(|f| f[a]).sum::<f64>() / k;
            ((k - 1.0) / k * fits.iter().map(|f| (f[a] - mean).powi(2)).sum::<f64>()).sqrt()
        })
        .collect()
}

/// The groups the spread is measured over: cross-validation's when it has enough, else
/// the recordings (the parts of one split at a pose jump together).
pub(super) fn spread_groups(names: &[&str], cv_by: Option<CvBy>) -> (Vec<String>, &'static str) {
    if let Some(by) = cv_by {
        let g: Vec<String> = names.iter().map(|n| by.group(n)).collect();
        let mut d = g.clone();
        d.sort();
        d.dedup();
        if d.len() >= MIN_SPREAD_GROUPS {
            return (g, by.name());
        }
    }
    (names.iter().map(|n| CvBy::Run.group(n)).collect(), "run")
}

/// The report's note: what the ± figures are, and where the spread is the larger.
pub(super) fn spread_note(
    specs: &[ParamSpec],
    cov: &DMatrix<f64>,
    spread: &Spread,
    by: &str,
) -> String {
    let larger: Vec<String> = specs
        .iter()
        .enumerate()
        .filter_map(|(i, s)| {
            let fit = cov[(i, i)].max(0.0).sqrt();
            (spread.sigma[i] > fit).then(|| {
                format!(
                    "{} ({:.1} times the fit's own)",
                    s.name,
                    spread.sigma[i] / fit.max(1e-300)
                )
            })
        })
        .collect();
    let what = if by == "run" { "recordings" } else { "groups" };
    let unit = if by == "run" {
        String::new()
    } else {
        format!(" (by {by})")
    };
    format!(
        "uncertainties (±): the larger of the fit's own (its residuals, their autocorrelation counted) and the spread between the {} {what}{unit} (each left out in turn: what calibrating again on other runs would move a parameter by); {}",
        spread.groups,
        if larger.is_empty() {
            "the fit's own is the larger for every parameter".to_string()
        } else {
            format!("the spread is the larger for {}", larger.join(", "))
        }
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three groups whose estimates are 1, 2 and 3: mean 2, variance 2/3 x 2 = 4/3.
    #[test]
    fn the_jackknife_of_three_values() {
        let s = jackknife_sigmas(&[vec![1.0, 5.0], vec![2.0, 5.0], vec![3.0, 5.0]]);
        assert!((s[0] - (4.0f64 / 3.0).sqrt()).abs() < 1e-12, "{s:?}");
        assert_eq!(s[1], 0.0);
    }

    /// Cross-validation's groups when there are three or more; else the recordings, a
    /// recording's parts (split at a pose jump) in one group.
    #[test]
    fn the_spread_is_over_the_cv_groups_or_the_recordings() {
        let names = ["a-run-01", "a-run-02", "b-run-01", "b-run-02"];
        let (g, by) = spread_groups(&names, Some(CvBy::Session));
        assert_eq!(by, "run");
        assert_eq!(g.len(), 4);
        let names = ["a-run-01", "b-run-01", "c-run-01", "c-run-02"];
        let (g, by) = spread_groups(&names, Some(CvBy::Session));
        assert_eq!((by, g[2].as_str(), g[3].as_str()), ("session", "c", "c"));
    }
}
