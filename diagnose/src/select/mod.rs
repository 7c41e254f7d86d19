//! Greedy forward selection of catalogue effects, and the verdict.
//!
//! Each round fits every remaining effect on top of the model so far, takes the one with
//! the best information criterion, and keeps it only if it also predicts held-out data
//! (fit on alternate time blocks, validated on the others) and improves the fit by a
//! practically visible amount. The chosen effects are then refitted jointly.
//!
//! The BIC's sample count is discounted by the residuals' lag-1 autocorrelation: odometry
//! residuals drift, and counting every sample of a drift as independent evidence would
//! let any effect that bends the drift a little look significant.
//!
//! One module per concept, each importing only those before it in this list:
//! - `criteria`: what a candidate is measured by (evidence stage, chi-square per
//!   residual, the discounted BIC) and the thresholds it must pass;
//! - `region`, `fit`: fitting effects' parameters (the region mechanism's starts and
//!   bounds, the grid, the zoom, the local optimiser);
//! - `pool`, `heldout`: fitting a round's candidates over the cores; the held-out check;
//! - `per_wheel`, `gate`, `simpler`, `accept`: choosing among them (which mechanisms a
//!   round fits, the simplest adequate first, whether one joins the model);
//! - `rounds`: the selection itself, a short driver over the round's phases;
//! - `decide`, `by_signature`, `verdict`: the verdict, its rule and the findings
//!   signatures name.

mod accept;
mod by_signature;
mod criteria;
mod decide;
mod fit;
mod gate;
mod heldout;
mod per_wheel;
mod pool;
mod region;
mod rounds;
mod simpler;
mod verdict;

pub use criteria::{evidence_stage, named, BIC_THRESHOLD, HELDOUT_MIN_GAIN, RMSE_MIN_GAIN};
pub use decide::{decide, Outcome};
pub use gate::{settled, variant_worth_fitting, DefaultScore, FAR_FROM_NOISE, VARIANT_SHARE};
pub use per_wheel::PER_WHEEL_HELDOUT_SHARE;
pub use rounds::{select, Candidate, Selection, Step, MAX_EFFECTS};
pub use simpler::{SIMPLER_BIC_MARGIN, SIMPLER_BIC_SHARE};
pub use verdict::{verdict, Decided};
