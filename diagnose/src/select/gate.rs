//! Which mechanisms a round fits. Every catalogue effect's default mechanism is fitted;
//! its other mechanisms only when the data lean towards that effect at all, its stage is
//! left outside the noise, or identification names it; the grid-searched defaults of
//! round 0 wait a round when another default already brings their stage back to the
//! noise. This keeps the larger catalogue's cost near the old one's.

use super::criteria::{evidence_stage, stage_chi2, BIC_THRESHOLD};
use super::per_wheel::one_value_form;
use super::pool::{Fitted, Todo};
use crate::effects::{Effect, Stage};
use crate::residuals::{Evaluator, Fold};

/// A default mechanism whose BIC gain is at least this share of the best default's in
/// its stage has its other mechanisms fitted too. One far behind the best is unlikely to
/// become the round's choice by changing mechanism, and is tried again next round.
pub const VARIANT_SHARE: f64 = 0.01;

/// A stage whose chi-square per residual is above this many times
/// [`crate::thresholds::MISMATCH_CHI2`] is far from its noise.
pub const FAR_FROM_NOISE: f64 = 10.0;

/// Whether a default fitted this round brings `stage` from far above its noise
/// ([`FAR_FROM_NOISE`]) back to it ([`crate::thresholds::MISMATCH_CHI2`]): a grid-searched competitor
/// could then at best fit as well, and is tried next round on top of it.
pub fn settled(
    stage: Stage,
    defaults: &[DefaultScore],
    base_chi2: impl Fn(Stage) -> Option<f64>,
) -> bool {
    base_chi2(stage).is_some_and(|c| c > FAR_FROM_NOISE * crate::thresholds::MISMATCH_CHI2)
        && defaults.iter().any(|x| {
            x.stage == stage
                && x.delta_bic < BIC_THRESHOLD
                && x.chi2_left
                    .is_some_and(|c| c <= crate::thresholds::MISMATCH_CHI2)
        })
}

/// A default mechanism's fit in this round: its BIC change and the chi-square per
/// residual it leaves in its evidence stage.
#[derive(Debug, Clone, Copy)]
pub struct DefaultScore {
    /// The catalogue effect (its default mechanism).
    pub effect: Effect,
    /// Its evidence stage.
    pub stage: Stage,
    /// BIC change when added (negative favours it).
    pub delta_bic: f64,
    /// Chi-square per residual of the stage with it added.
    pub chi2_left: Option<f64>,
}

/// Whether the other mechanism `variant` (evidence stage `stage`) is worth fitting this
/// round: identification names its family; or its default lowers the BIC by at least
/// [`VARIANT_SHARE`] of the most any default of its stage does; or its stage leaves the
/// noise (`base_chi2` above [`crate::thresholds::MISMATCH_CHI2`]) and no default of that stage
/// brings it back.
pub fn variant_worth_fitting(
    variant: Effect,
    stage: Stage,
    defaults: &[DefaultScore],
    base_chi2: impl Fn(Stage) -> Option<f64>,
    identified: &[Effect],
) -> bool {
    let same: Vec<&DefaultScore> = defaults.iter().filter(|x| x.stage == stage).collect();
    let best = same.iter().map(|x| x.delta_bic).fold(0.0, f64::min);
    let leans = same.iter().any(|x| {
        x.effect == variant.base() && x.delta_bic < 0.0 && x.delta_bic <= VARIANT_SHARE * best
    });
    let mismatch_left = base_chi2(stage).is_some_and(|c| c > crate::thresholds::MISMATCH_CHI2)
        && same.iter().all(|x| {
            x.chi2_left
                .is_none_or(|c| c > crate::thresholds::MISMATCH_CHI2)
        });
    leans || mismatch_left || identified.contains(&variant.base())
}

/// What a round has fitted when it decides which other mechanisms to fit
/// ([`Gate::wants`]).
pub(super) struct Gate<'a, 'e> {
    /// The run's evaluator.
    pub ev: &'a Evaluator<'e>,
    /// The catalogue effects identification of the nominal residual names.
    pub identified: &'a [Effect],
    /// The defaults fitted this round, scored.
    pub scored: &'a [DefaultScore],
    /// Chi-square per residual of each stage of the round's model.
    pub base_chi2: &'a dyn Fn(Stage) -> Option<f64>,
    /// The grid-searched defaults left for the next round ([`settled`]).
    pub deferred: &'a [Todo],
    /// The defaults fitted this round (the grid-searched ones apart).
    pub defaults: &'a [Todo],
    /// The grid-searched defaults fitted this round.
    pub searched: &'a [Todo],
    /// Every fit so far this round (carried over or new).
    pub fitted: &'a [Fitted],
}

impl Gate<'_, '_> {
    /// Whether the other mechanism `e` is fitted this round.
    pub fn wants(&self, e: &Effect) -> bool {
        let (ev, base_chi2, deferred, fitted) =
            (self.ev, self.base_chi2, self.deferred, self.fitted);
        // Traction per wheel is tried only when identification shows a heading
        // error that follows acceleration: otherwise its two or more limits take
        // the place of a diameter mismatch (on the real ccw square 04 they fit
        // 0.071 and 0.045 g and beat ed by 525 in BIC).
        if *e == Effect::SlipPerWheel {
            return self.identified.contains(e);
        }
        // An actuator mechanism per wheel is tried only when no mechanism fitted
        // so far (this round's or carried over) brings the actuator stage back
        // into the noise: each wheel its own value is for what one value leaves
        // (and costs a run per wheel and start: +65 % actuator runs on the
        // 120k-row bench when tried always).
        if e.stage() == Stage::Actuator
            && one_value_form(*e).is_some()
            && *e != Effect::BacklashPerWheel
        {
            let out = |c: Option<f64>| c.is_none_or(|c| c > crate::thresholds::MISMATCH_CHI2);
            return !deferred.iter().any(|(d, _)| *d == e.base())
                && base_chi2(Stage::Actuator)
                    .is_some_and(|c| c > crate::thresholds::MISMATCH_CHI2)
                && fitted
                    .iter()
                    .filter(|f| f.0.stage() == Stage::Actuator)
                    .all(|f| out(stage_chi2(ev, &ev.rss(&f.3, Fold::All), Stage::Actuator)));
        }
        !deferred.iter().any(|(d, _)| *d == e.base())
            && (variant_worth_fitting(
                *e,
                evidence_stage(ev, *e),
                self.scored,
                base_chi2,
                self.identified,
            ) || !self
                .defaults
                .iter()
                .chain(self.searched)
                .any(|(d, _)| *d == e.base())
                && !fitted.iter().any(|f| f.0 == e.base()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn score(effect: Effect, stage: Stage, delta_bic: f64, chi2_left: f64) -> DefaultScore {
        DefaultScore {
            effect,
            stage,
            delta_bic,
            chi2_left: Some(chi2_left),
        }
    }

    /// A diameter mismatch that explains the ground stage: floor bumps lean a little
    /// (-138 against -523,000), so their region mechanism waits; the stage is back in
    /// the noise, so no other ground mechanism is needed this round.
    #[test]
    fn a_dominant_default_spares_the_far_behind_variants() {
        let d = [
            score(
                Effect::WheelDiameterMismatch,
                Stage::Ground,
                -523_000.0,
                1.1,
            ),
            score(Effect::FloorBumps, Stage::Ground, -138.0, 900.0),
            score(Effect::LongitudinalSlip, Stage::Ground, -313.0, 900.0),
        ];
        let chi2 = |_: Stage| Some(950.0);
        for v in [Effect::BumpsRegion, Effect::SlipBody, Effect::SlipCreep] {
            assert!(
                !variant_worth_fitting(v, Stage::Ground, &d, chi2, &[]),
                "{v:?}"
            );
        }
        // ... unless identification names the family.
        assert!(variant_worth_fitting(
            Effect::BumpsRegion,
            Stage::Ground,
            &d,
            chi2,
            &[Effect::FloorBumps]
        ));
    }

    /// Body-bound slip: the wheel mechanism leans weakly (-6 against the best -24.5 of the
    /// ground stage); its variants are fitted. Actuator scores do not set the ground bar.
    #[test]
    fn a_leaning_default_within_its_stage_opens_its_variants() {
        let d = [
            score(Effect::LateralSlip, Stage::Ground, -24.5, 40.0),
            score(Effect::LongitudinalSlip, Stage::Ground, -6.0, 45.0),
            score(Effect::MotorLag, Stage::Actuator, -1571.8, 1.0),
        ];
        let chi2 = |s: Stage| Some(if s == Stage::Ground { 50.0 } else { 1.0 });
        assert!(variant_worth_fitting(
            Effect::SlipBody,
            Stage::Ground,
            &d,
            chi2,
            &[]
        ));
        // The stage is out of the noise and no default brings it back: every ground
        // variant is tried, region bumps included.
        assert!(variant_worth_fitting(
            Effect::BumpsRegion,
            Stage::Ground,
            &d,
            chi2,
            &[]
        ));
        // The actuator stage is in the noise and backlash does not lean: not tried.
        assert!(!variant_worth_fitting(
            Effect::BacklashAsymmetric,
            Stage::Actuator,
            &d,
            chi2,
            &[]
        ));
    }

    /// Round 0 shaped as the 120k-row bench's (its BIC changes; the chi-squares per
    /// residual made up): the four radii bring the ground stage from 50 to 1.4 (a
    /// mismatch is 2): floor bumps and traction slip wait for round 1. Not when the stage
    /// started within ten mismatches of the noise (a concealed effect), nor when the best
    /// default leaves it at 2.5, nor for a stage that only another stage's default
    /// settled.
    #[test]
    fn a_default_that_brings_its_stage_back_to_the_noise_settles_round_0() {
        let d = [
            score(
                Effect::WheelDiameterMismatch,
                Stage::Ground,
                -522_532.0,
                1.4,
            ),
            score(Effect::WheelbaseError, Stage::Ground, -45.5, 48.0),
            score(Effect::MotorLag, Stage::Actuator, -118_758.0, 1.2),
        ];
        let far = |_: Stage| Some(50.0);
        assert!(settled(Stage::Ground, &d, far));
        let near = |_: Stage| Some(15.0);
        assert!(!settled(Stage::Ground, &d, near));
        let mut short = d;
        short[0].chi2_left = Some(2.5);
        assert!(!settled(Stage::Ground, &short, far));
        let actuator_only = [d[1], d[2]];
        assert!(!settled(Stage::Ground, &actuator_only, far));
        assert!(settled(Stage::Actuator, &actuator_only, far));
    }
}
