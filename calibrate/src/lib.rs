//! Calibration from whole trajectories: the robot's geometry fitted to one or more
//! recordings with motion-capture ground truth (what OptiOdom does), not only to end
//! points as UMBmark does.
//!
//! Shared by all recordings: the geometry (differential drive: mean wheel scale, E_d,
//! E_b; any other wheel set: per wheel radius scale, mounting-angle offset and distance
//! scale). Per recording (nuisance): the start pose and the recording parameters
//! `time_offset_s` (poses later than encoders when positive) and `clock_ratio` (pose
//! clock over encoder clock).
//!
//! What the data cannot tell is said, not guessed: the covariance of the fit (with the
//! residuals' autocorrelation counted, since drift residuals are not independent
//! samples) gives correlations; pairs that move together are reported `not_separable`
//! with the recording that would separate them, and only their identifiable combination
//! is fitted. Every parameter has a plausible range; a value outside is listed
//! `implausible` with what it most likely stands in for.
//!
//! The modules, lowest first (each imports only those above it in this list):
//! `error` (why calibration cannot run), `params` (the parameters, their ranges and
//! models), `turn_law` (a two-sided robot's turn-radius law and turn ratio), `step` (the
//! per-geometry stepping), `series` (a recording reduced to what is replayed, its
//! dead-reckoned path, glitches and pose jumps), `evaluate` (the judge: given robot files'
//! dead reckoning of recordings they were not fitted to), `objective` (the residuals a fit
//! minimises), `sens` (the paths' sensitivities to the geometry), `pool` (threads),
//! `problem` (the joint problem), `solve` (the fit and its covariance), `events` (slips
//! and clock leads), `options` (what the caller chooses), `result` (what calibration
//! returns), `refusals` (what it will not answer), `choice` (which parameters to fit).
//! The held-out proxy on the real sessions is an evaluation harness, kept with the tests
//! (`tests/support/proxy.rs`). This file is the driver,
//! [`calibrate`], which runs them in order.

mod choice;
mod error;
mod evaluate;
mod events;
mod objective;
mod options;
mod params;
pub mod plots;
mod pool;
mod problem;
mod refusals;
mod result;
mod sens;
mod series;
mod solve;
mod spread;
mod step;
#[cfg(test)]
mod synth;
mod turn_law;
mod turning;

pub use choice::{
    CORR_LIMIT, LADDER_FOLDS, LADDER_TOLERANCE, MIN_ARC_SHARE, TURN_LAW_HOLDOUT_RATIO,
};
pub use error::CalibrateError;
pub use evaluate::{
    evaluate, same_wheels, Candidate, Evaluation, RecordingErrors, RobotSummary, Spread,
};
pub use events::{
    EVENT_GUARD_S, EVENT_MIN_RAD, EVENT_PER_TURN, EVENT_SIGMAS, EVENT_TRANSIENT_RAD, EVENT_WINDOW_S,
};
use objective::RES_UNIT_M;
pub use objective::{DR_HEADING_LEVER_M, HUBER_K};
pub use options::{CalOptions, CvBy, HOLDABLE, OMNI_HOLDABLE};
pub use params::{
    alike_priors, is_mecanum, ladder, param_specs, radius_range, robot_with, roller_specs,
    turn_law_specs, GeomKind, ParamSpec, ALIKE_ANGLE, ALIKE_SCALE, ALPHA_RANGE, BASE_RANGE,
    DIFF_EB_ARC_RANGE, EB_ARC_RANGE, EDGE_SHARE, ED_RANGE, GAMMA_RANGE, ICR_X_RANGE, MARKER_RANGE,
    MECANUM_MIN_GAMMA, MECANUM_RADIUS_RANGE, OMNI_RADIUS_RANGE, RADIUS_RANGE, SKID_EB_RANGE,
};
pub use refusals::{WORSE_FACTOR, WORSE_MARGIN_M};
pub use result::{
    BoardFactors, Calibration, Factors, FittedParam, GroupHeldout, Heldout, HeldoutMeans,
    HeldoutTable, Implausible, Inseparable, Inseparables, LawTest, PerRecording, PlacedForLog,
    WheelGeometry,
};
pub(crate) use series::Path;
pub use series::{
    board_dead_reckoned_poses, board_dead_reckoning_errors, dead_reckoned_poses,
    dead_reckoning_errors, dead_reckoning_rmse, dead_reckoning_rmse_law,
    fitted_dead_reckoning_rmse, Event, Nuisance, Series, Stamped, JUMP_MIN_M, JUMP_ONE_STEP,
    JUMP_SIGMAS, JUMP_WINDOW, MIN_POSES, NOISY_POSES_M, PART_SEP, PLAUSIBLE_CLOCK_DRIFT,
    PLAUSIBLE_TIME_OFFSET_S, SAMPLE_STEP_M,
};
pub use spread::MIN_SPREAD_GROUPS;
use turn_law::Turning;
pub use turn_law::{TurnLaw, ARC_RHO};

use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::robot::{Robot, RobotKind};
use choice::{choose_specs, fit_specs};
use events::{detect_events, robust_sigma};
use formats::recording::Recording;
use nalgebra::{DMatrix, SymmetricEigen};
use objective::position_rmse;
use options::Cfg;
use params::advice;
use pool::pool_map;
use problem::Problem;
use refusals::{check_inputs, refuse_bad_fit, refuse_broken_headings, refuse_unexplained};
use result::E_B_FOR;
use series::NUIS;
use solve::{
    aligned_rmse, correlations, covariance, noise_scale, nuisance_start, posterior_covariance,
    refs, reweighed, solve, solve_iter, OneStep, Solved,
};

/// Two parameters correlated above this whose uncertainty exceeds their value (and
/// [`MATERIAL_SHARE`] of the plausible half-range) are reported not separable too.
pub const WEAK_CORR: f64 = 0.5;
/// Share of a parameter's plausible half-range below which an uncertainty is immaterial:
/// a parameter fitted 0 ± 0.0002 is known, not lost.
pub const MATERIAL_SHARE: f64 = 0.1;

/// Fits the geometry of `robot` to `recordings` (name, recording, owned or borrowed)
/// jointly.
///
/// The phases, in order: the inputs checked and reduced to series (`Run::prepare`),
/// the start pose freed on noisy poses, the events found, the parameters chosen, the
/// joint fit (`Joint::fit`) and what it cannot tell (not separable pairs, implausible
/// values, unconstrained directions), the laws placed for a robot file, each recording's
/// errors, the held-out and cross-validated replays, the parameters with their spreads,
/// the firmware factors, and the result.
pub fn calibrate<R: std::borrow::Borrow<Recording>>(
    robot: &Robot,
    recordings: &[(String, R)],
    holdout: Option<&(String, Recording)>,
    opts: &CalOptions,
) -> Result<Calibration, CalibrateError> {
    let mut log = Log::default();
    let mut run = Run::prepare(robot, recordings, holdout, opts, &mut log)?;
    run.free_start_on_noisy_poses(&mut log);
    let events = run.find_events();
    let mut made = choice::Made::default();
    let specs = choose_specs(
        robot,
        &run.series,
        opts.marker_offset,
        run.cfg,
        &mut log.notes,
        &mut log.runs,
        &mut made,
    );
    let choice::Made { prefit, law_tests } = made;
    let mut fit = Joint::fit(&run, &specs, prefit, &mut log);
    let insep = fit.inseparable();
    fit.note_uncertainties(&mut log);
    let mut implausible = fit.within_plausible_ranges(&mut log);
    let after_res = fit.p.residuals(&fit.fitted.geom, &fit.fitted.nuis, false);
    let laws = fit.place_laws(&mut log)?;
    let unconstrained = fit.unconstrained();
    let per_recording = fit.per_recording(&after_res);
    refuse_unexplained(&per_recording, &run.shapes)?;
    refuse_bad_fit(&per_recording, &specs, &fit.fitted.geom, &fit.cov)?;
    let heldout = fit.heldout();
    let cv_by = opts.cv.or(opts.leave_one_out.then_some(CvBy::Run));
    let gn =
        (!run.cfg.free_start && run.cfg.huber.is_none()).then(|| OneStep::new(&fit.p, &fit.fitted));
    let leave_one_out = cv_by.map_or_else(Vec::new, |by| {
        fit.cross_validate(by, gn.as_ref(), &per_recording, &mut log)
    });
    let params = fit.params(gn.as_ref(), cv_by, &mut log.notes);
    implausible.extend(implausible_clocks(&per_recording));
    let factors = fit.factors(&laws, &mut log.notes);
    Ok(Calibration {
        robot: robot.name.to_string(),
        kind: robot.kind.as_str(),
        objective: objective_text(run.cfg),
        free_start: run.cfg.free_start,
        robust_loss: robust_loss_text(run.cfg),
        events,
        cv_by: cv_by.map(|c| c.name()),
        recordings: run.series.iter().map(|s| s.name.clone()).collect(),
        params,
        factors,
        joint_rmse_before_m: position_rmse(&fit.before_res),
        joint_rmse_after_m: position_rmse(&after_res),
        per_recording,
        heldout,
        leave_one_out: HeldoutTable(leave_one_out),
        correlations: fit.corr.clone(),
        inseparable: Inseparables(insep),
        unconstrained,
        implausible,
        notes: log.notes,
        turning_one_way: run.turning_one_way,
        model_runs: log.runs,
        fitted_robot: laws.fitted_robot,
        turn_law: laws.turn_law,
        law_tests,
        law_base_robot: laws.law_base_robot,
        placed_for_log: laws.placed_for_log,
    })
}

/// What a calibration says and counts as it goes: its notes (in the order the phases
/// write them) and its model runs.
#[derive(Default)]
struct Log {
    notes: Vec<String>,
    runs: usize,
}

/// The inputs as the fit sees them: the recordings reduced to series (split at pose
/// jumps, events marked once found), the held-out one, and the objective's settings.
struct Run<'a> {
    robot: &'a Robot,
    opts: &'a CalOptions,
    series: Vec<Series>,
    /// Each series' shape, kept for the refusals after the fit.
    shapes: Vec<(String, Option<series::Shape>)>,
    held: Option<Series>,
    turning_one_way: Option<&'static str>,
    cfg: Cfg,
}

impl<'a> Run<'a> {
    /// The inputs checked and reduced to series; broken input no geometry could make
    /// (headings in degrees, poses turning against the wheels) is refused before any fit,
    /// and recordings turning one way only are said to leave the geometry's sides open.
    fn prepare<R: std::borrow::Borrow<Recording>>(
        robot: &'a Robot,
        recordings: &[(String, R)],
        holdout: Option<&(String, Recording)>,
        opts: &'a CalOptions,
        log: &mut Log,
    ) -> Result<Self, CalibrateError> {
        if recordings.is_empty() {
            return Err(CalibrateError {
                recording: None,
                message: "no recording given".into(),
            });
        }
        if Kinematics::<f64>::new(robot, &Corrections::None).is_err() {
            return Err(CalibrateError {
                recording: None,
                message: "the robot's wheels cannot resolve the body twist".into(),
            });
        }
        check_inputs(robot, recordings, holdout, opts)?;
        let series = recordings
            .iter()
            .map(|(n, r)| Series::new(n, robot, r.borrow()))
            .collect::<Result<Vec<_>, _>>()?;
        let series: Vec<Series> = series
            .into_iter()
            .flat_map(|s| s.split_at_jumps(robot))
            .collect();
        // Broken input no geometry could make (headings in degrees, poses turning against
        // the wheels) is refused before any fit.
        let shapes: Vec<(String, Option<series::Shape>)> = series
            .iter()
            .map(|s| (s.name.clone(), series::shape(robot, s)))
            .collect();
        refuse_broken_headings(robot, &shapes)?;
        let held = holdout.map(|(n, r)| Series::new(n, robot, r)).transpose()?;
        let turning = turning::Turning::of(&series);
        let turning_one_way = turning.one_way();
        if let Some(sense) = turning_one_way {
            let what = match robot.kind {
                RobotKind::DiffDrive | RobotKind::SkidSteer => "E_d and E_b",
                _ => "the wheels' sizes and distances",
            };
            log.notes.push(turning::one_way_note(sense, &turning, what));
        }
        let cfg = Cfg {
            free_start: opts.free_start,
            huber: None,
            dr_lever: opts.heading_lever_m.unwrap_or(DR_HEADING_LEVER_M),
            known_law: (opts.turn_law.is_some() || opts.speed_law.is_some()).then(|| TurnLaw {
                arc_rel: opts.turn_law.unwrap_or(0.0),
                speed_rel: opts.speed_law.unwrap_or(0.0),
                ..TurnLaw::default()
            }),
            held: options::Held::of(&opts.hold),
        };
        Ok(Run {
            robot,
            opts,
            series,
            shapes,
            held,
            turning_one_way,
            cfg,
        })
    }

    /// SLAM-like poses: dead reckoning from one pose sample of centimetre noise tilts the
    /// whole recording (measured on the simulator: scale, E_d and E_b 8-11 sigma off), so
    /// the start pose is fitted from all samples instead.
    fn free_start_on_noisy_poses(&mut self, log: &mut Log) {
        let mut noise: Vec<f64> = self.series.iter().filter_map(|s| s.pose_noise_m).collect();
        noise.sort_by(|a, b| a.total_cmp(b));
        if let Some(&median_noise) = noise.get(noise.len() / 2) {
            if median_noise > NOISY_POSES_M && !self.cfg.free_start {
                self.cfg.free_start = true;
                log.notes.push(format!(
                    "the poses scatter {:.1} mm per sample (SLAM-like, above {:.0} mm): each recording's start pose and clocks are fitted (as --free-start), since dead reckoning from one noisy pose would tilt the whole recording",
                    median_noise * 1e3,
                    NOISY_POSES_M * 1e3
                ));
            }
        }
    }

    /// Events one geometry cannot explain (slips, motion capture leading the encoders,
    /// glitches): found on a first squared-loss fit, reported, and kept out of the fit
    /// (dead reckoning restarts from the measured pose after a slip; the samples inside an
    /// event are not compared). With `--robust`, Huber's scale is set here too.
    fn find_events(&mut self) -> Vec<Event> {
        let (robot, opts) = (self.robot, self.opts);
        let mut events: Vec<Event> = self
            .series
            .iter()
            .flat_map(|s| s.glitches.clone())
            .collect();
        if !self.cfg.free_start {
            let specs0 = self.cfg.unheld(param_specs(robot, opts.marker_offset));
            let f0 = fit_specs(robot, &specs0, &refs(&self.series), self.cfg, false).f;
            let r0 = robot_with(robot, &specs0, &f0.geom);
            for s in self.series.iter_mut() {
                events.extend(detect_events(&r0, s));
            }
            if opts.robust {
                // Huber's scale: HUBER_K robust sigmas (MAD) of the squared-loss residuals.
                let f1 = fit_specs(robot, &specs0, &refs(&self.series), self.cfg, false).f;
                let mut p1 = Problem::new(robot, &specs0, &self.series);
                self.cfg.apply(&mut p1);
                let r = p1.residuals(&f1.geom, &f1.nuis, false);
                let sigma = robust_sigma(&r);
                if sigma.is_finite() && sigma > 0.0 {
                    self.cfg.huber = Some(HUBER_K * sigma);
                }
            }
        }
        events
    }
}

/// The joint fit and what follows from it: the problem (over the run's series and the
/// chosen parameters), the nominal "before" and the fitted "after", and the covariance.
struct Joint<'r> {
    run: &'r Run<'r>,
    specs: &'r [ParamSpec],
    nominal: Vec<f64>,
    p: Problem<'r>,
    before_res: Vec<f64>,
    before_nuis: Vec<f64>,
    fitted: Solved,
    cov: DMatrix<f64>,
    corr: Vec<Vec<f64>>,
    /// The residuals' autocorrelation's inflation of the variance.
    inflation: f64,
}

/// Where the laws a robot file cannot express leave its constants: the fitted robot (E_b
/// and wheel size at the recordings' mean turn and speed, or `--e-b-for`'s), the robot
/// before them, and the shifts the factors take.
struct Laws {
    turn_law: TurnLaw,
    fitted_robot: Robot,
    law_base_robot: Robot,
    law_eb_shift: f64,
    law_scale: f64,
    placed_for_log: PlacedForLog,
}

impl<'r> Joint<'r> {
    /// The "before" (the nominal geometry) and the "after" (the joint fit of every
    /// recording), with the covariance every later phase reads.
    fn fit(
        run: &'r Run<'r>,
        specs: &'r [ParamSpec],
        prefit: Option<choice::Prefit>,
        log: &mut Log,
    ) -> Self {
        let (robot, series, cfg) = (run.robot, &run.series, run.cfg);
        let nominal: Vec<f64> = specs.iter().map(|s| s.nominal).collect();

        // Nominal geometry (nuisance fitted when free): the "before".
        let mut p = Problem::new(robot, specs, series);
        cfg.apply(&mut p);
        let before = solve(
            &p,
            &nominal,
            &nuisance_start(&refs(series), cfg.free_start),
            false,
        );
        let before_res = p.residuals(&nominal, &before.nuis, false);
        log.runs += before.evaluations;

        // Joint fit, the prior weighed by the nominal residuals first (directions the data
        // do not constrain must not wander off while the fit starts).
        // When choosing the model fitted it on all the recordings already (the same problem
        // and steps), that fit is taken over, its Jacobian at the solution by differences.
        p.prior_scale = noise_scale(&p, &before);
        // Only the nominal fit's nuisances are needed from here: its Jacobian (several MB on
        // a long recording, where diagnose's recording stage peaks) goes before the fits
        // below hold their own, as does the first fit's before the refit.
        // (A partial move would keep the other fields until the end of the scope: the
        // Jacobian is moved out and dropped by name.)
        let Solved {
            nuis: before_nuis,
            jac,
            ..
        } = before;
        drop(jac);
        let fitted = match prefit {
            Some(pre) => {
                debug_assert!(pre
                    .specs
                    .iter()
                    .map(|s| &s.name)
                    .eq(specs.iter().map(|s| &s.name)));
                p.prior_scale = pre.prior_scale;
                solve_iter(&p, &pre.f.geom, &pre.f.nuis, true, 0)
            }
            None => {
                p.differences_at_solution = false;
                let first = solve(&p, &nominal, &before_nuis, true);
                p.differences_at_solution = true;
                log.runs += first.evaluations;
                // Weigh the plausibility prior against the data's real information (MAP),
                // and refit.
                p.prior_scale = noise_scale(&p, &first);
                let Solved {
                    geom, nuis, jac, ..
                } = first;
                drop(jac);
                let f = solve(&p, &geom, &nuis, true);
                let (f, refits) = reweighed(&mut p, f);
                log.runs += refits;
                f
            }
        };
        log.runs += fitted.evaluations;
        let (cov, inflation) = covariance(&p, &fitted);
        let corr = correlations(&cov, specs.len());
        Joint {
            run,
            specs,
            nominal,
            p,
            before_res,
            before_nuis,
            fitted,
            cov,
            corr,
            inflation,
        }
    }

    /// Not separable pairs: correlated beyond [`CORR_LIMIT`], or beyond [`WEAK_CORR`] with
    /// a material uncertainty larger than their value; only the combination the data fix
    /// is fitted, and the recording that would separate them is advised.
    fn inseparable(&self) -> Vec<Inseparable> {
        let (specs, fitted, cov, corr) = (self.specs, &self.fitted, &self.cov, &self.corr);
        let g = specs.len();
        // Not separable pairs: fit only the combination the data fix.
        let mut insep = Vec::new();
        for a in 0..g {
            for b in a + 1..g {
                let c = corr[a][b];
                let (sa, sb) = (cov[(a, a)].sqrt(), cov[(b, b)].sqrt());
                let (da, db) = (
                    (fitted.geom[a] - specs[a].nominal).abs(),
                    (fitted.geom[b] - specs[b].nominal).abs(),
                );
                // "Uncertainty larger than the value" counts only when the uncertainty is material
                // against the plausible range: a parameter fitted 0 ± 0.0002 is known, not lost.
                let (ra, rb) = (
                    MATERIAL_SHARE * (specs[a].plausible.1 - specs[a].nominal),
                    MATERIAL_SHARE * (specs[b].plausible.1 - specs[b].nominal),
                );
                let weak = c.abs() > WEAK_CORR && (sa > da.max(ra) || sb > db.max(rb));
                if c.abs() > CORR_LIMIT || weak {
                    // Well-determined direction of the 2x2 block: the eigenvector with the
                    // smaller variance.
                    let blk =
                        nalgebra::Matrix2::new(cov[(a, a)], cov[(a, b)], cov[(a, b)], cov[(b, b)]);
                    let e = SymmetricEigen::new(blk);
                    let i_small = if e.eigenvalues[0] < e.eigenvalues[1] {
                        0
                    } else {
                        1
                    };
                    let good = e.eigenvectors.column(i_small);
                    let sgn = if good[0] < 0.0 { -1.0 } else { 1.0 };
                    insep.push(Inseparable {
                        params: [specs[a].name.clone(), specs[b].name.clone()],
                        correlation: c,
                        identifiable: [sgn * good[0], sgn * good[1]],
                        advice: advice(&specs[a], &specs[b]),
                    });
                }
            }
        }
        insep
    }

    /// What the uncertainties assume of the poses: motion capture is sub-millimetre, a
    /// SLAM trajectory centimetres, and the stated sigmas scale with it.
    fn note_uncertainties(&self, log: &mut Log) {
        let inflation = self.inflation;
        let noise: Vec<f64> = self
            .run
            .series
            .iter()
            .filter_map(|s| s.pose_noise_m)
            .collect();
        let pose_noise = if noise.is_empty() {
            String::new()
        } else {
            let mut v = noise.clone();
            v.sort_by(|a, b| a.total_cmp(b));
            format!(
                "; the poses scatter {:.1} mm per sample about the wheels' steps (median over the recordings), and the fit's residuals {:.1} mm RMS",
                1e3 * v[v.len() / 2],
                position_rmse(&self.p.residuals(&self.fitted.geom, &self.fitted.nuis, false)) * 1e3
            )
        };
        log.notes.push(format!(
            "uncertainties count the residuals' autocorrelation (variance x{inflation:.0}){pose_noise}"
        ));
    }

    /// What the data ask for outside the physical ranges is reported, and the geometry
    /// is refitted within them: an implausible value stands in for something else and
    /// must not be written to a robot.
    fn within_plausible_ranges(&mut self, log: &mut Log) -> Vec<Implausible> {
        let implausible: Vec<Implausible> = self
            .specs
            .iter()
            .zip(&self.fitted.geom)
            .filter(|(s, v)| **v < s.plausible.0 || **v > s.plausible.1)
            .map(|(s, v)| Implausible {
                name: s.name.clone(),
                value: *v,
                plausible: s.plausible,
                stands_for: s.stands_for.to_string(),
            })
            .collect();
        if !implausible.is_empty() {
            let unbounded = self
                .p
                .residuals(&self.fitted.geom, &self.fitted.nuis, false);
            log.notes.push(format!(
                "geometry fitted within the plausible ranges; unbounded it reaches {:.2} mm (fit RMSE) with the implausible values listed",
                position_rmse(&unbounded) * 1e3
            ));
            self.p.plausible_bounds = true;
            self.fitted = solve(&self.p, &self.fitted.geom, &self.fitted.nuis, true);
            log.runs += self.fitted.evaluations;
            (self.cov, _) = covariance(&self.p, &self.fitted);
            self.corr = correlations(&self.cov, self.specs.len());
        }
        implausible
    }

    /// A turn-radius law is more than a robot file or ROS 2's diff_drive_controller
    /// express: they get E_b at the recordings' mean turn, weighted by how much each row
    /// turns, or the constant closest to the law on the motion of `--e-b-for`; the board
    /// applies the law. A speed law likewise, with the wheel size.
    fn place_laws(&self, log: &mut Log) -> Result<Laws, CalibrateError> {
        let (robot, opts, series, specs) =
            (self.run.robot, self.run.opts, &self.run.series, self.specs);
        let (fitted, cfg, notes) = (&self.fitted, self.run.cfg, &mut log.notes);
        let mut fitted_robot = robot_with(robot, specs, &fitted.geom);
        // Applied only within the motion of the recordings fitted: beyond it the law holds
        // its edge's value (on the board too, `Corrections::DiffDriveLawsInRange`).
        // A law given (--turn-law, --speed-law, --laws-from) was fitted elsewhere: it is
        // applied as given, not bounded by these recordings.
        let turn_law = TurnLaw::of(specs, &fitted.geom, cfg.law());
        let turn_law = if cfg.known_law.is_some() {
            turn_law
        } else {
            turn_law.within(series::range_of(series))
        };
        let law_base_robot = fitted_robot.clone();
        let mut law_eb_shift = 0.0;
        let mut placed_for_log = PlacedForLog::default();
        // The "law is fitted" notes then say where the robot file's constant sits.
        let say_for_log = |notes: &mut Vec<String>, default: &str| {
            for n in notes
                .iter_mut()
                .filter(|n| n.contains(": the law is fitted"))
            {
                *n = n.replace(default, E_B_FOR);
            }
        };
        // A speed law likewise: they get the wheel size at the recordings' mean speed
        // (weighted by distance), or the constant closest to the law on `--e-b-for`'s motion.
        let mut law_scale = 1.0;
        if turn_law.speed_rel != 0.0 || turn_law.arc_rel != 0.0 {
            let t = Turning::of_all(series, robot);
            // `--e-b-for`'s log, read once for both laws.
            let motion = if opts.e_b_for.is_empty() {
                None
            } else {
                Some(e_b_motion(robot, &opts.e_b_for)?)
            };
            if turn_law.speed_rel != 0.0 && t.travel > 0.0 {
                let mean_speed = t.speed_term / t.travel;
                let for_log = motion
                    .as_ref()
                    .and_then(|m| turn_law::closest_constant_speed(&law_base_robot, &turn_law, m));
                if let (Some(v), Some(m)) = (for_log, &motion) {
                    placed_for_log.wheel_size = true;
                    say_for_log(notes, MEAN_SPEED);
                    notes.push(format!(
                        "robot file and ROS 2: wheel size {:+.3} % over standstill, the constant whose dead reckoning of --e-b-for's {} recording(s) stays closest to the speed law's (its size at {v:.3} m/s; {mean_speed:.3} m/s is the fitted recordings' mean speed)",
                        turn_law.speed_rel * v * 100.0,
                        m.len()
                    ));
                }
                law_scale = 1.0 + turn_law.speed_rel * for_log.unwrap_or(mean_speed);
                for w in fitted_robot.wheels.iter_mut() {
                    w.radius_m *= law_scale;
                }
            }
            let eb = specs
                .iter()
                .position(|s| s.kind == GeomKind::Eb)
                .map_or(1.0, |i| fitted.geom[i]);
            let mean_turn = (t.all > 0.0).then(|| t.arc_term / t.all);
            let share = match motion.as_ref().filter(|_| turn_law.arc_rel != 0.0) {
                None => mean_turn,
                Some(motion) => {
                    let share =
                        turn_law::closest_constant_share(&law_base_robot, &turn_law, motion);
                    if let Some(share) = share {
                        placed_for_log.e_b = true;
                        say_for_log(notes, MEAN_TURN);
                        notes.push(format!(
                            "robot file and ROS 2: E_b {:.6}, the constant whose dead reckoning of --e-b-for's {} recording(s) stays closest to the law's ({:.0} % of its widening; {:.0} % at the fitted recordings' mean turn)",
                            eb * (1.0 + turn_law.arc_rel * share),
                            motion.len(),
                            share * 100.0,
                            100.0 * mean_turn.unwrap_or(0.0)
                        ));
                    }
                    // A log that cannot be dead-reckoned leaves E_b at the mean turn.
                    share.or(mean_turn)
                }
            };
            if let Some(share) = share.filter(|_| turn_law.arc_rel != 0.0) {
                law_eb_shift = turn_law.arc_rel * eb * share;
                for w in fitted_robot.wheels.iter_mut() {
                    w.l_m *= (eb + law_eb_shift) / eb;
                }
            }
        }
        if !opts.e_b_for.is_empty() && turn_law.arc_rel == 0.0 && turn_law.speed_rel == 0.0 {
            notes.push(
                "--e-b-for: no turn or speed law was fitted or given, so one E_b serves every turn, one wheel size every speed, and the recordings given are not used"
                    .into(),
            );
        }
        Ok(Laws {
            turn_law,
            fitted_robot,
            law_base_robot,
            law_eb_shift,
            law_scale,
            placed_for_log,
        })
    }

    /// Unconstrained directions: eigenvectors of the correlation matrix with tiny
    /// eigenvalues.
    fn unconstrained(&self) -> Vec<Vec<(String, f64)>> {
        let (specs, corr) = (self.specs, &self.corr);
        let g = specs.len();
        let mut unconstrained = Vec::new();
        if g > 1 {
            let cm = DMatrix::from_fn(g, g, |i, j| corr[i][j]);
            let e = SymmetricEigen::new(cm);
            for k in 0..g {
                if e.eigenvalues[k] < 1e-2 {
                    let v = e.eigenvectors.column(k);
                    let mut dir: Vec<(String, f64)> = (0..g)
                        .filter(|&i| v[i].abs() > 0.1)
                        .map(|i| (specs[i].name.clone(), v[i]))
                        .collect();
                    if dir.first().is_some_and(|d| d.1 < 0.0) {
                        dir.iter_mut().for_each(|d| d.1 = -d.1);
                    }
                    unconstrained.push(dir);
                }
            }
        }
        unconstrained
    }

    /// Per recording: its dead reckoning and aligned errors (independent: in parallel,
    /// each thread taking the next recording, since the aligned fits' lengths vary), its
    /// share of the joint residuals and its nuisance.
    fn per_recording(&self, after_res: &[f64]) -> Vec<PerRecording> {
        let (robot, series, cfg, specs) =
            (self.run.robot, &self.run.series, self.run.cfg, self.specs);
        let (nominal, fitted, cov, before_res) =
            (&self.nominal, &self.fitted, &self.cov, &self.before_res);
        let (before_nuis, g) = (&self.before_nuis, specs.len());
        let replays = pool_map(series, |s| {
            let (ab, aa) = if cfg.free_start {
                (f64::NAN, f64::NAN)
            } else {
                (
                    aligned_rmse(robot, specs, nominal, s),
                    aligned_rmse(robot, specs, &fitted.geom, s),
                )
            };
            (
                dead_reckoning_rmse(robot, s).unwrap_or(f64::NAN),
                fitted_dead_reckoning_rmse(robot, specs, &fitted.geom, cfg.law(), s),
                ab,
                aa,
            )
        });
        let mut per_recording = Vec::new();
        let mut offs = (0, 0);
        for (i, s) in series.iter().enumerate() {
            let (dr_before, dr_after, ab, aa) = replays[i];
            let m = 3 * if cfg.free_start {
                s.pose_samples()
            } else {
                s.samples.len()
            };
            offs.1 = offs.0 + m;
            let (rb, ra) = (
                position_rmse(&before_res[offs.0..offs.1]),
                position_rmse(&after_res[offs.0..offs.1]),
            );
            let (nu, nu_nom, sig_t, sig_c) = if cfg.free_start {
                (
                    Nuisance::from(&fitted.nuis[i * NUIS..(i + 1) * NUIS]),
                    Nuisance::from(&before_nuis[i * NUIS..(i + 1) * NUIS]),
                    cov[(g + i * NUIS + 3, g + i * NUIS + 3)].max(0.0).sqrt(),
                    cov[(g + i * NUIS + 4, g + i * NUIS + 4)].max(0.0).sqrt(),
                )
            } else {
                let a = s.first_pose();
                (a, a, f64::NAN, f64::NAN)
            };
            let (ab, aa) = if cfg.free_start { (rb, ra) } else { (ab, aa) };
            per_recording.push(PerRecording {
                name: s.name.clone(),
                pose_samples: s.pose_samples(),
                compared_samples: m / 3,
                rmse_before_m: rb,
                rmse_after_m: ra,
                dead_reckoning_before_m: dr_before,
                dead_reckoning_after_m: dr_after,
                aligned_before_m: ab,
                aligned_after_m: aa,
                nuisance: nu,
                nuisance_nominal: nu_nom,
                time_offset_sigma_s: sig_t,
                clock_ratio_sigma: sig_c,
            });
            offs.0 = offs.1;
        }
        per_recording
    }

    /// The recording held out (`holdout`): dead-reckoned and aligned with the nominal and
    /// the fitted geometry.
    fn heldout(&self) -> Option<Heldout> {
        let (robot, specs, cfg) = (self.run.robot, self.specs, self.run.cfg);
        let (nominal, fitted) = (&self.nominal, &self.fitted);
        self.run.held.as_ref().map(|h| Heldout {
            name: h.name.clone(),
            group: None,
            rmse_before_m: dead_reckoning_rmse(robot, h).unwrap_or(f64::NAN),
            aligned_before_m: aligned_rmse(robot, specs, nominal, h),
            aligned_after_m: aligned_rmse(robot, specs, &fitted.geom, h),
            rmse_after_m: fitted_dead_reckoning_rmse(robot, specs, &fitted.geom, cfg.law(), h),
        })
    }

    /// Cross-validation: each group (run, session or path kind) held out in turn, the
    /// geometry refitted on the rest from the full solution (the same objective, loss,
    /// events and bounds), the held-out recordings dead-reckoned and aligned.
    fn cross_validate(
        &self,
        by: CvBy,
        gn: Option<&OneStep>,
        per_recording: &[PerRecording],
        log: &mut Log,
    ) -> Vec<Heldout> {
        let (robot, series, cfg, specs) =
            (self.run.robot, &self.run.series, self.run.cfg, self.specs);
        let (p, fitted) = (&self.p, &self.fitted);
        let mut leave_one_out = Vec::new();
        let groups: Vec<String> = series.iter().map(|s| by.group(&s.name)).collect();
        let mut distinct: Vec<String> = groups.clone();
        distinct.sort();
        distinct.dedup();
        if distinct.len() < 2 {
            log.notes.push(format!(
                "cross-validation by {} needs at least two groups, found {}",
                by.name(),
                distinct.len()
            ));
        }
        // Dead reckoning (squared loss): each fold is one Gauss-Newton step from the full
        // solution with the held-out recordings' rows taken out of the normal equations
        // (no refit: CV costs next to nothing). Otherwise a refit from the full solution.
        let t0 = std::time::Instant::now();
        // One-step folds: (recording, group, geometry without the group), replayed after.
        let mut stepped: Vec<(usize, &String, Vec<f64>)> = Vec::new();
        for (k, gname) in distinct.iter().enumerate().filter(|_| distinct.len() >= 2) {
            if let Some(one) = gn {
                let geom = one.without((0..series.len()).filter(|&j| &groups[j] == gname));
                for i in (0..series.len()).filter(|&j| &groups[j] == gname) {
                    stepped.push((i, gname, geom.clone()));
                }
                continue;
            }
            if t0.elapsed().as_secs_f64() > 2.0 {
                eprintln!(
                    "calibrate: cross-validation {}/{} ({:.1} s)",
                    k + 1,
                    distinct.len(),
                    t0.elapsed().as_secs_f64()
                );
            }
            let keep: Vec<usize> = (0..series.len()).filter(|&j| &groups[j] != gname).collect();
            let rest: Vec<&Series> = keep.iter().map(|&j| &series[j]).collect();
            let mut q = Problem::new(robot, specs, rest);
            cfg.apply(&mut q);
            q.priors = p.priors.clone();
            q.prior_scale = p.prior_scale;
            q.plausible_bounds = p.plausible_bounds;
            q.differences_at_solution = false;
            let nuis: Vec<f64> = if cfg.free_start {
                keep.iter()
                    .flat_map(|&j| fitted.nuis[j * NUIS..(j + 1) * NUIS].to_vec())
                    .collect()
            } else {
                vec![]
            };
            let f = solve(&q, &fitted.geom, &nuis, true);
            log.runs += f.evaluations;
            for i in (0..series.len()).filter(|&j| &groups[j] == gname) {
                leave_one_out.push(Heldout {
                    name: series[i].name.clone(),
                    group: Some(gname.clone()),
                    rmse_before_m: dead_reckoning_rmse(robot, &series[i]).unwrap_or(f64::NAN),
                    rmse_after_m: fitted_dead_reckoning_rmse(
                        robot,
                        specs,
                        &f.geom,
                        cfg.law(),
                        &series[i],
                    ),
                    aligned_before_m: per_recording[i].aligned_before_m,
                    aligned_after_m: aligned_rmse(robot, specs, &f.geom, &series[i]),
                });
            }
        }
        leave_one_out.extend(pool_map(&stepped, |(i, gname, geom)| {
            let s = &series[*i];
            Heldout {
                name: s.name.clone(),
                group: Some((*gname).clone()),
                rmse_before_m: per_recording[*i].dead_reckoning_before_m,
                rmse_after_m: fitted_dead_reckoning_rmse(robot, specs, geom, cfg.law(), s),
                aligned_before_m: per_recording[*i].aligned_before_m,
                aligned_after_m: aligned_rmse(robot, specs, geom, s),
            }
        }));
        leave_one_out
    }

    /// The fitted parameters with their uncertainties: the fit's, the spread between
    /// recordings (or the cross-validation's groups: what calibrating again on other runs
    /// would move each parameter by), and where the data alone leave a parameter free,
    /// its spread with the priors.
    fn params(
        &self,
        gn: Option<&OneStep>,
        cv_by: Option<CvBy>,
        notes: &mut Vec<String>,
    ) -> Vec<FittedParam> {
        let (specs, cov, fitted) = (self.specs, &self.cov, &self.fitted);
        // The spread between recordings (or the cross-validation's groups): what calibrating
        // again on other runs would move each parameter by.
        let names: Vec<&str> = self.run.series.iter().map(|s| s.name.as_str()).collect();
        let (spread_by, spread_by_name) = spread::spread_groups(&names, cv_by);
        let spread = gn.and_then(|one| spread::between_groups(one, &spread_by));
        if let Some(sp) = &spread {
            notes.push(spread::spread_note(specs, cov, sp, spread_by_name));
        }
        let mut params: Vec<FittedParam> = specs
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let fit = cov[(i, i)].max(0.0).sqrt();
                let between = spread.as_ref().map(|sp| sp.sigma[i]);
                FittedParam {
                    spec: s.clone(),
                    value: fitted.geom[i],
                    sigma: fit.max(between.unwrap_or(0.0)),
                    sigma_fit: fit,
                    sigma_between: between,
                    sigma_with_priors: None,
                }
            })
            .collect();
        // What the data alone leave free rests on the priors: its spread with them.
        if params.iter().any(FittedParam::sigma_exceeds_range) {
            let post = posterior_covariance(&self.p, fitted);
            for (i, q) in params.iter_mut().enumerate() {
                if q.sigma_exceeds_range() {
                    q.sigma_with_priors = Some(post[(i, i)].max(0.0).sqrt());
                }
            }
        }
        params
    }

    /// The firmware's factors: a left and a right side (whatever `--hold` left of scale, ed
    /// and eb) as c_L, c_R, E_b, with the board's laws; any other wheel set as per-wheel
    /// lateral factors, the geometry the factors cannot carry said in the notes.
    fn factors(&self, laws: &Laws, notes: &mut Vec<String>) -> Factors {
        let (robot, specs, fitted) = (self.run.robot, self.specs, &self.fitted);
        let (turn_law, fitted_robot) = (&laws.turn_law, &laws.fitted_robot);
        let (law_scale, law_eb_shift) = (laws.law_scale, laws.law_eb_shift);
        // A left and a right side (whatever `--hold` left of scale, ed and eb): c_L, c_R, E_b.
        let sides = robot.kind != RobotKind::Omni
            && specs
                .iter()
                .any(|s| matches!(s.kind, GeomKind::Scale | GeomKind::Ed | GeomKind::Eb));
        if sides {
            let scale_or = |k: GeomKind, or: f64| {
                specs
                    .iter()
                    .position(|s| s.kind == k)
                    .map_or(or, |i| fitted.geom[i])
            };
            let scale = |k: GeomKind| scale_or(k, 1.0);
            let (sc, ed, eb) = (
                scale(GeomKind::Scale),
                scale(GeomKind::Ed),
                scale(GeomKind::Eb),
            );
            // With a law: the constant factors at the recordings' mean turn and speed (as the
            // robot file); a differential drive's board applies the law itself, from a turn
            // in place and standstill.
            let (c_l, c_r) = calib_core::umbmark::wheel_factors(ed);
            let laws = calib_core::correction::DiffLaws {
                e_b_arc: if robot.kind == RobotKind::DiffDrive {
                    turn_law.arc_rel
                } else {
                    0.0
                },
                speed_rel: turn_law.speed_rel,
                // A negative "slip" puts the ground ahead of its wheels: poses stamped early,
                // the logger's offset, not the robot's (the note says so). The board reads its
                // own encoders and gets no such term.
                accel_slip_s: turn_law.accel_slip_s.max(0.0),
            };
            let board =
                (laws != calib_core::correction::DiffLaws::default()).then_some(BoardFactors {
                    c_l: sc * c_l,
                    c_r: sc * c_r,
                    e_b: eb,
                    laws,
                    range: turn_law.range.for_laws(&laws),
                });
            let sc = sc * law_scale;
            Factors::Diff {
                c_l: sc * c_l,
                c_r: sc * c_r,
                e_b: eb + law_eb_shift,
                board,
            }
        } else {
            if specs.iter().any(|s| {
                matches!(
                    s.kind,
                    GeomKind::Alpha(_)
                        | GeomKind::L(_)
                        | GeomKind::Gamma
                        | GeomKind::CentreX
                        | GeomKind::CentreY
                )
            }) {
                notes.push(
                    "wheel angle, position and roller angle have no firmware factor: `wheelcal apply` puts the fitted geometry on the board (`robot set`, the JSON's board_geometry) with factors of one; --write-robot and --write-board-robot write it for other tools"
                        .into(),
                );
            }
            let at = |k: GeomKind| specs.iter().position(|s| s.kind == k);
            if let (Some(ix), Some(iy)) = (at(GeomKind::CentreX), at(GeomKind::CentreY)) {
                let (x, y) = (fitted.geom[ix], fitted.geom[iy]);
                let distances: Vec<String> = fitted_robot
                    .wheels
                    .iter()
                    .map(|w| format!("{} {:.1} mm", w.name, w.l_m * 1e3))
                    .collect();
                notes.push(format!(
                    "the wheels are laid out about a point {:.1} mm from the one the odometry reports and motion capture tracks (x {:+.1} mm, y {:+.1} mm in the body frame): seen from the tracked point the wheels sit at {}",
                    x.hypot(y) * 1e3,
                    x * 1e3,
                    y * 1e3,
                    distances.join(", ")
                ));
            }
            if let Some(note) = sideways_note(robot, fitted_robot) {
                notes.push(note);
            }
            Factors::Wheels {
                f_lat: fitted_robot
                    .wheels
                    .iter()
                    .zip(&robot.wheels)
                    .map(|(f, n)| n.radius_m / f.radius_m)
                    .collect(),
                f_lon: 1.0,
                l_arc: turn_law.arc_rel,
            }
        }
    }
}

/// A recording's clocks the fit moved beyond the plausible: a time offset or clock
/// ratio no logger has stands in for a mis-stamped column or resampled ground truth.
fn implausible_clocks(per_recording: &[PerRecording]) -> Vec<Implausible> {
    let mut implausible = Vec::new();
    for pr in per_recording {
        let nu = pr.nuisance;
        if nu.time_offset_s.abs() > PLAUSIBLE_TIME_OFFSET_S {
            implausible.push(Implausible {
                name: format!("{}: time_offset_s", pr.name),
                value: nu.time_offset_s,
                plausible: (-PLAUSIBLE_TIME_OFFSET_S, PLAUSIBLE_TIME_OFFSET_S),
                stands_for:
                    "a t column that does not match the encoders (check the logger's clock)".into(),
            });
        }
        if (nu.clock_ratio - 1.0).abs() > PLAUSIBLE_CLOCK_DRIFT {
            implausible.push(Implausible {
                name: format!("{}: clock_ratio", pr.name),
                value: nu.clock_ratio,
                plausible: (1.0 - PLAUSIBLE_CLOCK_DRIFT, 1.0 + PLAUSIBLE_CLOCK_DRIFT),
                stands_for: "resampled or mis-stamped ground truth".into(),
            });
        }
    }
    implausible
}

/// The objective in words, for the result.
fn objective_text(cfg: Cfg) -> &'static str {
    if cfg.free_start {
        "aligned: start pose, time offset and clock ratio fitted per recording (--free-start)"
    } else {
        "dead reckoning from each recording's first measured pose, compared every 5 cm of travel (turns in place at the wheels' lever arm)"
    }
}

/// The robust loss in words, when `--robust` set one.
fn robust_loss_text(cfg: Cfg) -> Option<String> {
    cfg.huber.map(|c| {
        format!(
            "Huber, quadratic within {:.2} mm ({HUBER_K} robust sigmas of the squared-loss residuals), linear beyond",
            c * RES_UNIT_M * 1e3
        )
    })
}

/// When the fit moved the mecanum rollers' angle: how far a wheel turn carries the robot
/// sideways against along, relative to the nominal rollers (the body-frame lateral and
/// longitudinal gains, in words). A wheel whose rolling direction is at alpha + beta +
/// gamma carries the robot |tan(alpha + beta + gamma)| as far sideways as along per turn.
fn sideways_note(nominal: &Robot, fitted: &Robot) -> Option<String> {
    let (n, f) = nominal.wheels.iter().zip(&fitted.wheels).find(|(n, f)| {
        n.gamma_rad.abs() > 1f64.to_radians() && (f.gamma_rad - n.gamma_rad).abs() > 1e-6
    })?;
    let lean = |w: &calib_core::robot::Wheel| (w.alpha_rad + w.beta_rad + w.gamma_rad).tan().abs();
    let share = lean(f) / lean(n);
    Some(format!(
        "the rollers grip sideways otherwise than along: a wheel turn carries the robot {:.1} % as far sideways as along, relative to the nominal rollers (|gamma| {:.2} deg for {:.2} deg)",
        share * 100.0,
        f.gamma_rad.abs().to_degrees(),
        n.gamma_rad.abs().to_degrees()
    ))
}

/// Where a law's one E_b sits by default, in the notes' words.
const MEAN_TURN: &str = "at the recordings' mean turn";
/// Where a speed law's one wheel size sits by default, in the notes' words.
const MEAN_SPEED: &str = "at the recordings' mean speed";

/// `--e-b-for`'s recordings as series of their encoders alone (their poses, if any, are
/// not read: the closest constant E_b compares two dead reckonings).
fn e_b_motion(
    robot: &Robot,
    recordings: &[(String, Recording)],
) -> Result<Vec<Series>, CalibrateError> {
    recordings
        .iter()
        .map(|(name, rec)| {
            let mut r = rec.clone();
            for v in [&mut r.x, &mut r.y, &mut r.theta] {
                v.iter_mut().for_each(|c| *c = Some(0.0));
            }
            Series::new(name, robot, &r)
        })
        .collect()
}
