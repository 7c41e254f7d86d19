//! The simplest adequate mechanism first: of one catalogue effect's mechanisms, one with
//! fewer parameters goes before a richer sibling whose BIC is not clearly lower, so that
//! each wheel its own value must beat one value for every wheel by more than noise.

use super::pool::Tried;
use crate::effects::Effect;

/// A mechanism with fewer parameters is preferred to a sibling whose BIC is lower by
/// less than this (the BIC's own "strong evidence" step, as [`BIC_THRESHOLD`](super::BIC_THRESHOLD)) ...
pub const SIMPLER_BIC_MARGIN: f64 = 10.0;
/// ... or by less than this share of the sibling's BIC gain: residuals that drift make
/// the BIC count small improvements as strong evidence in proportion to the gain (one
/// play for both wheels: -20,109; per-wheel play of 0.05096 and 0.05084 rad: -20,137).
pub const SIMPLER_BIC_SHARE: f64 = 0.05;

/// Of the mechanisms of one catalogue effect, one with fewer parameters whose BIC is
/// within [`SIMPLER_BIC_MARGIN`] or [`SIMPLER_BIC_SHARE`] of the best goes first: the
/// simplest adequate explanation (per-wheel play must beat one play for both wheels by
/// more than noise). `tried` is sorted by BIC change; the order between catalogue
/// effects is kept.
pub(super) fn prefer_simpler_mechanisms(tried: &mut Vec<Tried>, k: impl Fn(Effect) -> usize) {
    let scores: Vec<(Effect, usize, f64)> = tried.iter().map(|t| (t.0, k(t.0), t.4)).collect();
    let mut slots: Vec<Option<Tried>> = tried.drain(..).map(Some).collect();
    for i in simpler_first(&scores) {
        tried.extend(slots[i].take());
    }
}

/// The order [`prefer_simpler_mechanisms`] gives (indices into `scores`: effect,
/// parameter count, BIC change, sorted by BIC change).
fn simpler_first(scores: &[(Effect, usize, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..scores.len()).collect();
    for pos in 0..order.len() {
        let (e, k0, d0) = scores[order[pos]];
        if order[..pos].iter().any(|&i| scores[i].0.base() == e.base()) {
            continue;
        }
        let margin = SIMPLER_BIC_MARGIN.max(SIMPLER_BIC_SHARE * d0.abs());
        let simpler = (pos..order.len())
            .filter(|&j| {
                let (x, k, d) = scores[order[j]];
                x.base() == e.base() && k < k0 && d <= d0 + margin
            })
            .min_by_key(|&j| scores[order[j]].1);
        if let Some(j) = simpler {
            let i = order.remove(j);
            order.insert(pos, i);
        }
    }
    order
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One play for both wheels within 10 of per-wheel play goes first; 18 behind, it
    /// does not; 28 behind a gain of 20,137 (0.14 %), it does. Other catalogue effects
    /// keep their place.
    #[test]
    fn one_parameter_wins_unless_the_richer_mechanism_is_clearly_better() {
        let apply = |scores: &[(Effect, usize, f64)]| -> Vec<Effect> {
            simpler_first(scores)
                .into_iter()
                .map(|i| scores[i].0)
                .collect()
        };
        let close = [
            (Effect::BacklashPerWheel, 2, -108.0),
            (Effect::MotorLag, 1, -104.0),
            (Effect::Backlash, 1, -100.0),
        ];
        assert_eq!(
            apply(&close),
            vec![Effect::Backlash, Effect::BacklashPerWheel, Effect::MotorLag]
        );
        let clear = [
            (Effect::BacklashPerWheel, 2, -108.0),
            (Effect::MotorLag, 1, -104.0),
            (Effect::Backlash, 1, -90.0),
        ];
        assert_eq!(
            apply(&clear),
            vec![Effect::BacklashPerWheel, Effect::MotorLag, Effect::Backlash]
        );
        let large = [
            (Effect::BacklashPerWheel, 2, -20137.2),
            (Effect::Backlash, 1, -20108.8),
        ];
        assert_eq!(
            apply(&large),
            vec![Effect::Backlash, Effect::BacklashPerWheel]
        );
    }
}
