//! The verdict's rule: from the best plausible finding and what the fit left, the
//! answer (an effect, `none` or `unexplained`). Pure, so that every case of it can be
//! tested in numbers without a recording.

use crate::finding::{Finding, Verdict};

/// What the fit left, as [`decide`] weighs it.
#[derive(Debug, Clone, Copy)]
pub struct Outcome {
    /// Some counted stage started outside the noise.
    pub mismatch: bool,
    /// Share of the excess over noise the findings explain.
    pub explained_fraction: f64,
    /// The largest chi-square per residual a counted stage is left with.
    pub worst_final: f64,
    /// Identification of what the findings leave still finds a term that follows a
    /// quantity no catalogue physics follows ([`crate::identify::regressor_has_physics`]).
    pub left_outside_catalogue: bool,
    /// Share of the excess the top finding's family explains.
    pub family_share: f64,
    /// Identification of the nominal residual names the top finding's family (the
    /// residual depends on what that physics follows).
    pub family_identified: bool,
}

/// The verdict from the best plausible finding (`top`) and what the fit left. A finding
/// named by its signature is the answer. Otherwise the top finding's family must explain
/// at least [`crate::thresholds::MIN_EXPLAINED`] of the excess (issue 55: the best supported
/// explanation is the verdict, partial when a remainder is left); a far fit
/// ([`crate::thresholds::RESIDUAL_CHI2`]) that leaves something following a quantity no catalogue
/// physics follows is not (a floor mechanism with four free parameters can bend a heading
/// kick at every reversal most of the way, but what it leaves still follows the
/// reversals), nor one for a family identification did not name in the residual unless
/// it explains [`crate::thresholds::WELL_EXPLAINED`] of it (a slip limit bending a tilted floor's
/// steady drift 71 % of the way is not; a stepper's quanta, which no regressor follows,
/// at 95 % are).
pub fn decide(top: Option<&Finding>, o: &Outcome) -> Verdict {
    use crate::thresholds::{MIN_EXPLAINED, RESIDUAL_CHI2, WELL_EXPLAINED};
    let far = o.mismatch && o.worst_final > RESIDUAL_CHI2;
    match top {
        None if o.mismatch => Verdict::Unexplained,
        None => Verdict::None,
        Some(f) if f.signature.is_some() => Verdict::Effect(f.effect.clone()),
        Some(_) if o.mismatch && o.family_share < MIN_EXPLAINED => Verdict::Unexplained,
        Some(_) if far && o.left_outside_catalogue => Verdict::Unexplained,
        // Name by dependence, fit by mechanism: a fit that leaves the residual far
        // outside the noise is the answer only for a family whose dependence
        // identification found in the residual.
        Some(_) if far && !o.family_identified && o.family_share < WELL_EXPLAINED => {
            Verdict::Unexplained
        }
        Some(f) => Verdict::Effect(f.effect.clone()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::effects::Stage;
    use crate::finding::Fit;
    use crate::select::by_signature::partial;

    /// A fitted (not signature) finding.
    fn fitted(effect: &str) -> Finding {
        let mut f = partial(
            effect,
            "default",
            Stage::Ground,
            0.05,
            0.009,
            0.9,
            String::new(),
        );
        f.signature = None;
        f.fit = Fit::Full;
        f
    }

    fn outcome(explained_fraction: f64, worst_final: f64, left_outside: bool) -> Outcome {
        Outcome {
            mismatch: true,
            explained_fraction,
            worst_final,
            left_outside_catalogue: left_outside,
            family_share: explained_fraction,
            family_identified: true,
        }
    }

    /// The caster case in numbers: 96 % of the excess explained, 8.97 mm left against
    /// 1.07 mm noise (chi-square 70 per residual) and the remainder still follows the
    /// reversals: not the answer. The same fit with nothing outside the catalogue left
    /// (a slippery patch fitted by a region: 8.9 mm left, nothing identified) is.
    #[test]
    fn a_remainder_outside_the_catalogue_keeps_a_far_fit_from_the_verdict() {
        let f = fitted("floor_bumps");
        assert_eq!(
            decide(Some(&f), &outcome(0.96, 70.0, true)),
            Verdict::Unexplained
        );
        assert_eq!(
            decide(Some(&f), &outcome(0.96, 70.0, false)),
            Verdict::Effect("floor_bumps".into())
        );
        // Near the noise (chi-square under RESIDUAL_CHI2) a small remainder does not
        // overturn the finding, whatever it depends on.
        assert_eq!(
            decide(Some(&f), &outcome(0.99, 4.0, true)),
            Verdict::Effect("floor_bumps".into())
        );
        // A far fit whose family explains at least half, leaving nothing outside the
        // catalogue, is the verdict (its fit partial): issue 55's "motor lag, partial".
        assert_eq!(
            decide(Some(&f), &outcome(0.80, 70.0, false)),
            Verdict::Effect("floor_bumps".into())
        );
        // The family, not the sum of every finding, must explain half: 17 % of a
        // wheelbase beside 31 % of another effect is not a wheelbase verdict.
        let split = Outcome {
            family_share: 0.17,
            ..outcome(0.56, 4.0, false)
        };
        assert_eq!(decide(Some(&f), &split), Verdict::Unexplained);
        // A far fit of a family identification did not name needs WELL_EXPLAINED.
        let unnamed = Outcome {
            family_identified: false,
            ..outcome(0.71, 70.0, false)
        };
        assert_eq!(decide(Some(&f), &unnamed), Verdict::Unexplained);
        let nearly_all = Outcome {
            family_identified: false,
            ..outcome(0.96, 70.0, false)
        };
        assert_eq!(
            decide(Some(&f), &nearly_all),
            Verdict::Effect("floor_bumps".into())
        );
        // Under MIN_EXPLAINED (50 %) never, however close to the noise.
        assert_eq!(
            decide(Some(&f), &outcome(0.4, 1.5, false)),
            Verdict::Unexplained
        );
    }

    /// A signature names its effect even when the fit is far off; no finding is `none`
    /// on noise and `unexplained` on a mismatch.
    #[test]
    fn signatures_and_empty_findings_decide_as_before() {
        let mut f = fitted("missed_steps");
        f.signature = Some("12 jumps of whole electrical cycles".into());
        assert_eq!(
            decide(Some(&f), &outcome(0.3, 70.0, true)),
            Verdict::Effect("missed_steps".into())
        );
        assert_eq!(
            decide(None, &outcome(0.0, 70.0, true)),
            Verdict::Unexplained
        );
        let quiet = Outcome {
            mismatch: false,
            ..outcome(1.0, 1.0, false)
        };
        assert_eq!(decide(None, &quiet), Verdict::None);
    }
}
