//! What the recording stage reports: an artefact with its parameters, gaps and events.
//! A leaf module: the checks beside it build these.

use serde::Serialize;
use std::collections::BTreeMap;
use std::fmt;

/// One artefact found in the recording.
#[derive(Debug, Clone, Serialize)]
pub struct Artefact {
    /// One of [`super::RECORDING_IDS`].
    pub id: &'static str,
    /// Fitted values or counts by name (`time_offset_s`, `clock_ratio`,
    /// `counts_ratio_<wheel>`, `missing_samples`, `duplicated_samples`).
    pub parameters: BTreeMap<String, f64>,
    /// Uncertainty per fitted parameter: one sigma for the clocks and for a raw counts
    /// ratio (`counts_ratio_raw_<wheel>`, from the scatter of its segments); the snapped
    /// fraction `counts_ratio_<wheel>` has none.
    pub uncertainties: BTreeMap<String, f64>,
    /// The gaps in `t`, one interval each with its count of missing samples (a list of
    /// every missing sample grew without bound on a jump in `t`).
    pub gaps: Vec<Gap>,
    /// Times of the duplicated rows (s).
    pub duplicated_at_s: Vec<f64>,
    /// Each place the fault shows, with its time and size (at most [`MAX_EVENTS`]; the
    /// parameters count them all).
    pub events: Vec<Event>,
    /// Whether the physics stages saw the recording with this artefact removed.
    pub removed: bool,
    /// What was concluded per wheel, and what the data cannot tell (a counts ratio far
    /// from 1 that no single simple fraction explains is reported here, not removed).
    pub notes: Vec<String>,
}

impl Artefact {
    /// An artefact of `id` with nothing found yet.
    pub(super) fn new(id: &'static str) -> Self {
        Artefact {
            id,
            parameters: BTreeMap::new(),
            uncertainties: BTreeMap::new(),
            gaps: vec![],
            duplicated_at_s: vec![],
            events: vec![],
            removed: false,
            notes: vec![],
        }
    }
}

impl fmt::Display for Artefact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.id)?;
        for (k, v) in &self.parameters {
            match self.uncertainties.get(k) {
                Some(s) => write!(f, " {k} = {v:.5} ± {s:.2e}")?,
                None => write!(f, " {k} = {v:.5}")?,
            }
        }
        let times = |v: &[f64]| {
            let mut s: Vec<String> = v.iter().take(8).map(|t| format!("{t:.3}")).collect();
            if v.len() > 8 {
                s.push(format!("... ({} in all)", v.len()));
            }
            s.join(", ")
        };
        if !self.gaps.is_empty() {
            let mut s: Vec<String> = self
                .gaps
                .iter()
                .take(8)
                .map(|g| format!("{:.3}-{:.3} s ({})", g.after_s, g.before_s, g.missing))
                .collect();
            if self.gaps.len() > 8 {
                s.push(format!("... ({} gaps in all)", self.gaps.len()));
            }
            write!(f, " missing samples in {}", s.join(", "))?;
        }
        if !self.duplicated_at_s.is_empty() {
            write!(
                f,
                " duplicated samples at {} s",
                times(&self.duplicated_at_s)
            )?;
        }
        if !self.events.is_empty() {
            let mut s: Vec<String> = self
                .events
                .iter()
                .take(8)
                .map(|e| {
                    let size: Vec<String> =
                        e.size.iter().map(|(k, v)| format!("{k} {v:.4}")).collect();
                    if size.is_empty() {
                        format!("{:.3} s", e.at_s)
                    } else {
                        format!("{:.3} s ({})", e.at_s, size.join(", "))
                    }
                })
                .collect();
            if self.events.len() > 8 {
                s.push(format!("... ({} listed)", self.events.len()));
            }
            write!(f, " at {}", s.join("; "))?;
        }
        if self.removed {
            write!(f, " (removed before the physics)")?;
        }
        for n in &self.notes {
            write!(f, "; {n}")?;
        }
        Ok(())
    }
}

/// Most events listed per artefact (the parameters count them all).
pub const MAX_EVENTS: usize = 1000;

/// One place a recording artefact shows: its time and its size by name.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Event {
    /// Time (s), as written in the file.
    pub at_s: f64,
    /// Sizes by name (`back_s`, `dx_m`, `dy_m`, `dtheta_rad`, `rows`).
    pub size: BTreeMap<String, f64>,
}

/// One gap in `t`: rows missing between two consecutive rows.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Gap {
    /// Time of the last row before the gap (s).
    pub after_s: f64,
    /// Time of the first row after the gap (s).
    pub before_s: f64,
    /// Samples missing at the median row interval (a float: a jump in `t` of 1e300 s
    /// misses more samples than any integer counts).
    pub missing: f64,
}
