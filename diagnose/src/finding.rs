//! What a diagnosis found: each effect with its fit ([`Finding`], [`Fit`]) and the
//! conclusion ([`Verdict`]). Below the selection and the report, which both use them.

use crate::effects::Stage;
use serde::{Serialize, Serializer};
use std::collections::BTreeMap;
use std::fmt;

/// How far a finding's mechanism explains its effect.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Fit {
    /// The mechanism's model explains the effect.
    Full,
    /// The effect was named from its signature in the residuals and no mechanism fits it
    /// fully.
    Partial,
}

impl fmt::Display for Fit {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Fit::Full => "full",
            Fit::Partial => "partial",
        })
    }
}

/// One named effect with its fitted parameters.
#[derive(Debug, Clone, Serialize)]
pub struct Finding {
    /// Catalogue id.
    pub effect: String,
    /// The stage the effect acts on.
    pub stage: Stage,
    /// Fitted parameter values by name (the unit in the name where there is one:
    /// `tau_s`, `backlash_rad`; `ed` and `mu` are dimensionless).
    pub parameters: BTreeMap<String, f64>,
    /// One standard deviation per parameter (from the Jacobian); `null` when the data
    /// do not constrain it.
    pub uncertainties: BTreeMap<String, Option<f64>>,
    /// The stage whose data the RMSEs below are measured on: the effect's own stage, or
    /// the ground stage for an actuator effect on wheels without encoders.
    pub rmse_stage: Stage,
    /// RMSE of `rmse_stage` before and after adding it (ground: position error;
    /// actuator: wheel-surface error, encoder angle times radius).
    pub rmse_before_m: f64,
    /// RMSE of `rmse_stage` with the effect added, m.
    pub rmse_after_m: f64,
    /// Information-criterion change when added (negative favours the effect).
    pub delta_bic: f64,
    /// Held-out sum of squares with the effect over without it.
    pub heldout_ratio: f64,
    /// The mechanism that fitted best, e.g. `wheel`, `body`, `creep`.
    pub mechanism: String,
    /// How far the mechanism's model explains the effect.
    pub fit: Fit,
    /// Share of the excess over noise this finding explains (0..1); findings are
    /// ordered by it.
    pub explained_share: f64,
    /// What the signature test saw (e.g. steps of one electrical cycle at high
    /// commanded acceleration), if the effect has one.
    pub signature: Option<String>,
    /// RMSE of `rmse_stage` still left after the fit, beyond the noise (partial fits).
    pub residual_left_m: Option<f64>,
    /// A parameter has a non-physical sign (negative slip, loss or delay).
    pub implausible_sign: bool,
}

/// What the diagnosis concludes. In the JSON and the summary: the effect's catalogue id,
/// `none` or `unexplained`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Verdict {
    /// The recording stays within its noise of the nominal model.
    None,
    /// The recording leaves the noise and no finding explains enough of it.
    Unexplained,
    /// The finding explaining the largest share of the excess, by its effect id.
    Effect(String),
}

impl Verdict {
    /// The verdict as the JSON writes it.
    pub fn as_str(&self) -> &str {
        match self {
            Verdict::None => crate::VERDICT_NONE,
            Verdict::Unexplained => crate::VERDICT_UNEXPLAINED,
            Verdict::Effect(id) => id,
        }
    }
}

impl fmt::Display for Verdict {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for Verdict {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.as_str())
    }
}

/// Tests and callers compare a verdict with an effect id.
impl PartialEq<&str> for Verdict {
    fn eq(&self, other: &&str) -> bool {
        self.as_str() == *other
    }
}

impl PartialEq<str> for Verdict {
    fn eq(&self, other: &str) -> bool {
        self.as_str() == other
    }
}
