//! Diagnose: finds where a model of the robot and a recording of it part, names the
//! physics the model left out, fits it and shows the fit improve.
//!
//! The pipeline, in layers (each module imports only those below it;
//! `host-tests/tests/layering.rs` checks the crates without a module circle):
//!
//! 1. Recording (`recording_stage`): logging artefacts (sample glitches, counts per
//!    revolution, clocks) are found, reported and removed before any physics is judged.
//! 2. Replay per stage (`replay`, `actuator` with its `variants`, `ground` with its
//!    `variants`): commands -> wheel motion (against the encoders) and wheel motion ->
//!    body motion (against the measured poses, and against the encoders of free wheels,
//!    which roll with the body).
//! 3. Residuals (`residuals`): nuisances (start pose, encoder offsets) solved for every
//!    evaluation; noise levels; folds of time for held-out checks.
//! 4. Identification (`identify`): what the nominal residual depends on, over a library
//!    of physical regressors, by sparse regression held out on blocks of time.
//! 5. Fits and selection (`effects`, `fit`, `select`, `signature`, `localisation`):
//!    catalogue effects fitted as augmentations of the model, their other mechanisms only
//!    where identification or the default's score asks; greedy forward selection by
//!    information criterion and held-out error; the verdict is decided once, there.
//! 6. Findings and report (`finding`, `plausibility`, `windows`, `report`, `plots`):
//!    RMSE before and after, parameters with uncertainty, windows, plots.
//!
//! The entry point is [`diagnose`]; the console's `wheelcal diagnose` is a thin wrapper.

pub mod actuator;
pub mod drift;
pub mod effects;
pub mod finding;
pub mod ground;
pub mod identify;
pub mod localisation;
pub mod multi;
pub mod plausibility;
pub mod plots;
pub mod recording_stage;
pub mod replay;
pub mod report;
pub mod residuals;
pub mod select;
pub mod signature;
pub mod thresholds;
pub mod windows;

pub use effects::{Effect, Model, Stage};
pub use finding::{Finding, Verdict};
pub use report::{write_robot, Report};
pub use windows::{Axis, Window};

use calib_core::robot::Robot;
use formats::recording::Recording;
use residuals::Evaluator;
use std::collections::BTreeMap;
use std::fmt;

/// Verdict when no effect is needed.
pub const VERDICT_NONE: &str = "none";
/// Verdict when the data leave the noise band and no catalogue effect explains it.
pub const VERDICT_UNEXPLAINED: &str = "unexplained";
pub use thresholds::{MIN_EXPLAINED, MISMATCH_CHI2, RESIDUAL_CHI2, WELL_EXPLAINED};

/// Tuning of a diagnosis.
#[derive(Debug, Clone)]
pub struct Options {
    /// Most effects to combine.
    pub max_effects: usize,
    /// Rows faster than this (per second) are merged first (`formats::decimate`); `None`
    /// diagnoses every row.
    pub max_row_rate_hz: Option<f64>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_effects: select::MAX_EFFECTS,
            max_row_rate_hz: Some(formats::decimate::DEFAULT_MAX_ROW_RATE_HZ),
        }
    }
}

/// Why a recording cannot be diagnosed (it parsed, but holds too little to compare).
#[derive(Debug, Clone, PartialEq)]
pub enum DiagnoseError {
    /// Too few rows or pose samples to estimate noise and fit anything.
    NotEnoughData(String),
    /// The robot's kinematics cannot be built.
    Geometry(String),
}

impl fmt::Display for DiagnoseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            DiagnoseError::NotEnoughData(s) => write!(f, "not enough data to diagnose: {s}"),
            DiagnoseError::Geometry(s) => write!(f, "robot geometry: {s}"),
        }
    }
}

impl std::error::Error for DiagnoseError {}

/// Least pose samples for the ground stage to say anything (start pose takes 3 numbers).
pub const MIN_POSE_SAMPLES: usize = 8;

/// Diagnoses a recording of `robot` (a copy of it is corrected and replayed; use
/// [`diagnose_owned`] to hand the recording over and keep one copy in memory).
pub fn diagnose(
    robot: &Robot,
    recording: &Recording,
    options: &Options,
) -> Result<Report, DiagnoseError> {
    diagnose_owned(robot, recording.clone(), options)
}

/// Diagnoses a recording of `robot`, taking it over: its logging artefacts are removed in
/// place, and it is dropped once replayed (memory is then bounded by the replay's
/// columns, not the file's).
pub fn diagnose_owned(
    robot: &Robot,
    recording: Recording,
    options: &Options,
) -> Result<Report, DiagnoseError> {
    check_input(robot, &recording)?;
    let (prepared, recorded, notes) = prepare(robot, recording, options)?;
    let ev = Evaluator::new(&prepared);
    let mut run = Diagnosis {
        robot,
        ev: &ev,
        notes,
    };
    // Identification of the nominal residual: what it depends on, before any fit. The
    // selection fits the other mechanisms of the effects it names.
    let nominal_eval = ev.evaluate(&Model::default(), residuals::Fold::All);
    let identification = run.identify(&nominal_eval);
    let sel = select::select(
        &ev,
        options.max_effects,
        &identify::named_effects(&identification),
    );
    let windows = run.windows(&sel);
    let mut findings = run.findings(&sel);
    // Verdict: the finding explaining the largest share of the excess over noise, with
    // signatures naming effects no mechanism fits fully. Identification of what the
    // findings leave: the verdict weighs it, the report says it.
    let left = run.identify(&sel.final_eval);
    let decided = select::verdict(&ev, &sel, &mut findings, &left, &identification);
    run.note_wander(&decided.verdict, &sel);
    let separability = run.note_separability(recorded.geometry.as_ref(), &findings);
    let depends_on = depends_on(&decided.verdict, &left, &identification);
    Ok(run.report(
        &sel,
        Found {
            findings,
            decided,
            windows,
            identification,
            depends_on,
            separability,
        },
        recorded.artefacts,
    ))
}

/// Refuses a recording that cannot be compared with `robot` at all.
fn check_input(robot: &Robot, recording: &Recording) -> Result<(), DiagnoseError> {
    if recording.len() < 3 {
        return Err(DiagnoseError::NotEnoughData(format!(
            "{} rows (need at least 3)",
            recording.len()
        )));
    }
    if recording.wheels.len() != robot.wheels.len() {
        return Err(DiagnoseError::Geometry(format!(
            "the recording has {} wheels, the robot {}",
            recording.wheels.len(),
            robot.wheels.len()
        )));
    }
    if calib_core::Kinematics::<f64>::new(robot, &calib_core::Corrections::None).is_err() {
        return Err(DiagnoseError::Geometry(
            "the wheels cannot resolve the body twist".into(),
        ));
    }
    Ok(())
}

/// What the recording stage found, kept for the report.
struct Recorded {
    /// The logging artefacts found (and removed where they could be).
    artefacts: Vec<recording_stage::Artefact>,
    /// The whole-geometry fit of the recording stage.
    geometry: Option<calibrate::Calibration>,
}

/// Merges fast rows, finds and removes the recording's logging artefacts and prepares
/// the replay; the recording is dropped once replayed. Returns the replay, what the
/// recording stage found and the notes so far.
fn prepare(
    robot: &Robot,
    recording: Recording,
    options: &Options,
) -> Result<(replay::Prepared, Recorded, Vec<String>), DiagnoseError> {
    // Fast rows merged first: the replays' cost and memory follow the rows kept.
    let recording = match options.max_row_rate_hz {
        Some(rate) if rate.is_finite() && rate > 0.0 => recording.decimated(rate).0,
        _ => recording,
    };
    let decimation = recording.merged;
    // Recording artefacts first: found, reported apart and removed before the physics.
    let stage = recording_stage::analyse(robot, recording);
    let recording_stage::RecordingStage {
        artefacts,
        corrected,
        geometry,
    } = stage;
    let prepared = replay::Prepared::new(robot, &corrected);
    let mut notes = corrected.notes.clone();
    notes.extend(decimation.map(|d| d.note()));
    drop(corrected);
    if prepared.poses.len() < MIN_POSE_SAMPLES && !prepared.has_actuator_stage() {
        return Err(DiagnoseError::NotEnoughData(format!(
            "{} pose samples and no wheel with both a command and an encoder (need {} pose samples or an actuator stage)",
            prepared.poses.len(),
            MIN_POSE_SAMPLES
        )));
    }
    if prepared.wheels.iter().all(|w| w.enc_rad.is_none()) {
        notes.push("no encoders: the ground stage is driven by the commands".into());
    }
    if !prepared.has_commands() {
        notes.push("no commands: actuator effects cannot be tested".into());
    }
    Ok((
        prepared,
        Recorded {
            artefacts,
            geometry,
        },
        notes,
    ))
}

/// A diagnosis under way: the robot, the evaluator of the prepared recording, and the
/// notes each phase adds.
struct Diagnosis<'a> {
    robot: &'a Robot,
    ev: &'a Evaluator<'a>,
    notes: Vec<String>,
}

/// What the diagnosis found, for the report.
struct Found {
    /// The findings, ordered by the verdict.
    findings: Vec<Finding>,
    /// The verdict.
    decided: select::Decided,
    /// Windows where the recording departs, as listed, and how many were found.
    windows: (Vec<Window>, usize),
    /// Identification of the nominal residual.
    identification: Vec<identify::Term>,
    /// What the residual depends on, as the report says it.
    depends_on: Vec<String>,
    /// Geometry this recording cannot separate.
    separability: report::Separability,
}

impl Diagnosis<'_> {
    /// What residuals `e` depend on: identification of both stages.
    fn identify(&self, e: &residuals::Eval) -> Vec<identify::Term> {
        let mut terms = identify::ground(self.ev.p, e);
        terms.extend(identify::actuator(self.ev, e));
        terms
    }

    /// Where the recording departs from the nominal and the fitted model, as listed
    /// (and how many were found).
    fn windows(&self, sel: &select::Selection) -> (Vec<Window>, usize) {
        let sig = windows::signals(self.ev);
        windows::bounded(windows::locate(
            self.ev,
            &sel.nominal_eval,
            &sel.final_eval,
            &sig,
        ))
    }

    /// Findings, best first (selection order).
    fn findings(&mut self, sel: &select::Selection) -> Vec<Finding> {
        sel.steps.iter().map(|st| self.finding(sel, st)).collect()
    }

    /// The finding of one selection step. A parameter the fit pushed to the bound
    /// nearest "no effect" is left out and noted.
    fn finding(&mut self, sel: &select::Selection, st: &select::Step) -> Finding {
        let (robot, ev) = (self.robot, self.ev);
        let e = st.effect;
        let vals = sel.model.get(e).unwrap_or(&[]);
        let sig_vals = sel
            .sigma
            .iter()
            .find(|(x, _)| *x == e)
            .map(|(_, s)| s.clone())
            .unwrap_or_default();
        let names = select::named(robot, e, vals);
        let specs = e.params(robot);
        let mut parameters = BTreeMap::new();
        let mut uncertainties = BTreeMap::new();
        let mut at_edge = Vec::new();
        for (j, (n, v)) in names.into_iter().enumerate() {
            // A parameter the fit pushed to the bound nearest "no effect" is not a
            // measurement: said as no effect, not reported at the range's edge.
            if let Some(spec) = specs.get(j).filter(|s| s.at_null_edge(v)) {
                at_edge.push(format!(
                    "{n} (its range's bound {})",
                    spec.null_bound().unwrap_or(v)
                ));
                continue;
            }
            parameters.insert(n.clone(), v);
            let s = sig_vals.get(j).copied().filter(|s| s.is_finite());
            uncertainties.insert(n, s);
        }
        if !at_edge.is_empty() {
            self.notes.push(format!(
                "{} ({}): no effect fitted for {}; not reported",
                e.id(),
                e.mechanism(),
                at_edge.join(", ")
            ));
        }
        let stage = select::evidence_stage(ev, e);
        let (b, a) = match stage {
            Stage::Ground => (st.before.ground_rmse(), st.after.ground_rmse()),
            Stage::Actuator => (st.before.actuator_rmse(), st.after.actuator_rmse()),
        };
        Finding {
            effect: e.id().to_string(),
            stage: e.stage(),
            rmse_stage: stage,
            parameters,
            uncertainties,
            rmse_before_m: b,
            rmse_after_m: a,
            delta_bic: st.delta_bic,
            heldout_ratio: st.heldout_ratio,
            mechanism: e.mechanism().to_string(),
            fit: finding::Fit::Full,
            explained_share: 0.0,
            signature: None,
            residual_left_m: None,
            implausible_sign: false,
        }
    }

    /// An unexplained ground residual whose changes follow none of the motion is what a
    /// wandering pose reference leaves: said, not decided (one recording cannot tell it
    /// from physics that random-walks the pose, docs/diagnose.md "Reference wander").
    fn note_wander(&mut self, verdict: &Verdict, sel: &select::Selection) {
        if *verdict != Verdict::Unexplained {
            return;
        }
        let Some(w) = reference_wander(self.ev.p, &sel.nominal_eval) else {
            return;
        };
        self.notes.push(format!(
            "the ground residual ({:.2} mm against {:.2} mm of white noise) wanders as a drifting pose reference would: its changes follow none of the motion (likelihood ratio {:.1} < {:.1}, spread {:.1} < {:.1}, body-frame shape {:.1} < {:.1} over {} windows of {:.1} s; {:.2} mm/sqrt(s)); if the capture frame or localiser may drift, check it before the robot",
            sel.nominal.ground_rmse() * 1e3,
            self.ev.noise.pose_sigma_m * 1e3,
            w.statistic,
            drift::CHI2_7_Q99,
            w.spread,
            drift::CHI2_4_Q99,
            w.body_shape,
            drift::CHI2_2_Q99,
            w.windows,
            w.window_s,
            w.rate_m_per_sqrt_s * 1e3,
        ));
    }

    /// Geometry this recording cannot separate (from the whole-geometry fit of the
    /// recording stage), said next to any finding that names one side of it.
    fn note_separability(
        &mut self,
        geometry: Option<&calibrate::Calibration>,
        findings: &[Finding],
    ) -> report::Separability {
        let separability =
            report::Separability(geometry.map(|c| c.inseparable.clone()).unwrap_or_default());
        if let Some(f) = findings
            .iter()
            .find(|f| f.parameters.keys().any(|p| separability.0.involves(p)))
        {
            self.notes.push(format!(
                "{} is one of several geometry explanations this recording cannot tell apart (not_separable)",
                f.effect
            ));
        }
        separability
    }

    /// The report of the diagnosis.
    fn report(
        self,
        sel: &select::Selection,
        found: Found,
        artefacts: Vec<recording_stage::Artefact>,
    ) -> Report {
        let (ev, p) = (self.ev, self.ev.p);
        let Found {
            findings,
            decided,
            windows: (windows, windows_total),
            identification,
            depends_on,
            separability,
        } = found;
        let rmse_stage = findings.first().map_or(Stage::Ground, |f| f.rmse_stage);
        let plot = plot_data(ev, sel);
        let n_act = sel.nominal.n_act;
        Report {
            robot: self.robot.name.to_string(),
            rows: p.rows(),
            pose_samples: p.poses.len(),
            duration_s: p.t.last().unwrap_or(&0.0) - p.t.first().unwrap_or(&0.0),
            verdict: decided.verdict,
            fit: decided.fit,
            findings,
            windows,
            heading_rmse_nominal_rad: (sel.nominal.heading / sel.nominal.n_pose.max(1) as f64)
                .sqrt(),
            heading_rmse_final_rad: (sel.final_rss.heading / sel.final_rss.n_pose.max(1) as f64)
                .sqrt(),
            noise: ev.noise,
            explained_fraction: decided.explained_fraction,
            rmse_stage,
            rmse: report::Rmses {
                ground: report::StageRmse {
                    before_m: sel.nominal.ground_rmse(),
                    after_m: sel.final_rss.ground_rmse(),
                },
                actuator: (n_act > 0).then(|| report::StageRmse {
                    before_m: sel.nominal.actuator_rmse(),
                    after_m: sel.final_rss.actuator_rmse(),
                }),
            },
            start_pose: [
                sel.final_eval.start.0,
                sel.final_eval.start.1,
                sel.final_eval.start.2,
            ],
            candidates: sel.candidates.clone(),
            notes: self.notes,
            model_runs_ground: ev.runs.get().0,
            model_runs_actuator: ev.runs.get().1,
            model: sel.model.clone(),
            plot,
            recording_artefacts: artefacts,
            implausible: decided.implausible,
            separability,
            identification,
            depends_on,
            windows_total,
        }
    }
}

/// What the report says the residual depends on: what the findings leave (`left`),
/// or, for an unexplained verdict with nothing identified in what is left, what the
/// nominal residual depends on.
fn depends_on(
    verdict: &Verdict,
    left: &[identify::Term],
    nominal: &[identify::Term],
) -> Vec<String> {
    if !left.is_empty() || *verdict != Verdict::Unexplained {
        left.iter().map(|t| t.depends_on.clone()).collect()
    } else {
        nominal.iter().map(|t| t.depends_on.clone()).collect()
    }
}

/// The wander test ([`drift::test`]) on the nominal ground residual, when it says the
/// ground stage is a wandering reference (its changes follow none of the motion, and
/// none jumps).
fn reference_wander(p: &replay::Prepared, nominal: &residuals::Eval) -> Option<drift::Wander> {
    let ps = &p.poses;
    let t: Vec<f64> = ps.row.iter().map(|&r| p.t[r]).collect();
    drift::test(
        &t,
        (&ps.x, &ps.y, &ps.theta),
        (&nominal.ex, &nominal.ey, &nominal.eth),
    )
    .filter(|w| w.is_wander())
}

fn plot_data(ev: &Evaluator, sel: &select::Selection) -> report::PlotData {
    let p = ev.p;
    let ps = &p.poses;
    let (n, f) = (&sel.nominal_eval, &sel.final_eval);
    let pts = |e: &residuals::Eval| -> Vec<(f64, f64)> {
        (0..ps.len())
            .map(|k| (ps.x[k] - e.ex[k], ps.y[k] - e.ey[k]))
            .collect()
    };
    let norm = |e: &residuals::Eval| -> Vec<f64> {
        e.ex.iter().zip(&e.ey).map(|(x, y)| x.hypot(*y)).collect()
    };
    report::PlotData {
        pose_t: ps.row.iter().map(|&r| p.t[r]).collect(),
        measured: (0..ps.len()).map(|k| (ps.x[k], ps.y[k])).collect(),
        nominal: pts(n),
        fitted: pts(f),
        err_nominal: norm(n),
        err_fitted: norm(f),
        heading_nominal: n.eth.clone(),
        heading_fitted: f.eth.clone(),
        act_t: ev.act_rows.iter().map(|&r| p.t[r]).collect(),
        act: n
            .act
            .iter()
            .zip(&f.act)
            .map(|((i, a), (_, b))| (p.wheels[*i].name.clone(), a.clone(), b.clone()))
            .collect(),
    }
}
