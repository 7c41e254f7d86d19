//! What calibrate refuses to answer: inputs it cannot fit ([`check_inputs`]: a held-out
//! recording that is also fitted, a turn law or a marker offset on a drive without one,
//! `--hold` names the robot's models lack), broken input no geometry could make
//! ([`refuse_broken_headings`]: headings in degrees, poses turning against the wheels;
//! [`refuse_unexplained`]: wheels that do not describe the poses' motion) and a fit that
//! would be confident and wrong ([`refuse_bad_fit`]: a recording made several times
//! worse than nominal, an uncertainty zero or infinite).

use crate::error::CalibrateError;
use crate::options::CalOptions;
use crate::params::{GeomKind, ParamSpec, BASE_RANGE, DIFF_EB_ARC_RANGE, OMNI_RADIUS_RANGE};
use crate::result::PerRecording;
use crate::series::Shape;
use calib_core::robot::{Robot, RobotKind};
use formats::recording::Recording;
use nalgebra::DMatrix;

/// A fit that makes a recording more than this many times worse than nominal (plus
/// [`WORSE_MARGIN_M`]) is refused, naming the recording.
pub const WORSE_FACTOR: f64 = 3.0;
/// See [`WORSE_FACTOR`], m.
pub const WORSE_MARGIN_M: f64 = 0.01;

/// The share of the poses' spread the wheels must explain: 1 - (aligned residual /
/// spread)^2, the aligned residual the fitted geometry's dead reckoning leaves with each
/// recording's start pose and clocks fitted, the spread the RMS distance of the measured
/// positions from their mean (an R^2 of positions, free of units and of the recording's
/// size). Below it the wheels do not describe the motion and no geometry is fitted.
///
/// Where 3/4 comes from: it refuses when the residual exceeds half the spread. Good
/// recordings leave far less: the six real OptiOdom squares and the omni3 square at most
/// 0.008 of their spread (diff-square-run-04), the 299 real session recordings fitted
/// alone at most 0.084 (omni4-square-080920201810-run-03: 99.3 % explained) and fitted
/// by session at most 0.057; the broken inputs of issue 52 leave 0.91 (left and right
/// encoders swapped), 1.12 (rover4, two columns swapped), 1.69 and 2.0 (theta in
/// degrees, mobolab and omni3): about the whole spread, explaining nothing. Half the
/// spread sits 6 times above the worst good recording and nearly 2 times under the best
/// broken one. A residual under [`WORSE_MARGIN_M`] (the centimetre [`refuse_bad_fit`]
/// allows) is not judged: a turn in place spreads its poses a millimetre (the Ivanjko
/// sessions: 0.6-1.3 mm spread, 1-2 mm residual, at the poses' noise), and no share of
/// that means anything.
pub const MIN_EXPLAINED: f64 = 0.75;

/// The largest ratio of the measured turn to the nominal wheels' turn any plausible
/// geometry makes: wheels up to 10 % larger ([`OMNI_RADIUS_RANGE`], the widest radius
/// range) on a separation or wheel distance up to 8 % shorter ([`BASE_RANGE`]), 1.20. A
/// skid-steer robot turns less than its wheels (E_b 1..3), never more.
pub const MAX_TURN_RATIO: f64 = (1.0 + OMNI_RADIUS_RANGE) / (1.0 - BASE_RANGE);

/// The turn ratio from which headings look like degrees: the geometric mean of
/// [`MAX_TURN_RATIO`] (1.20) and 180/pi (57.3, what degrees read as radians give),
/// about 8.3: halfway, on a log scale, between the most a plausible geometry turns and
/// degrees. The real recordings judged ([`MIN_HEADING_SPREAD`]) measure 0.955-1.131; a
/// skid-steer robot in degrees still gives 57.3/3 = 19 or more (rover4 in degrees
/// measured 35.8, mobolab and omni3 57.3).
pub fn degrees_ratio() -> f64 {
    (MAX_TURN_RATIO * 180.0 / std::f64::consts::PI).sqrt()
}

/// Headings are judged only when the measured heading varies at least this much about
/// its mean (RMS, in the file's units: degrees only make it larger): below it a run is
/// straight and its heading's variation the poses' noise and drift. Of the 306 real
/// recordings (the OptiOdom squares, omni3 square and the 299 session runs) 22 straight
/// runs vary 0.004-0.015 rad and are not judged; every other varies 0.93 rad or more.
pub const MIN_HEADING_SPREAD: f64 = 0.1;

/// Broken headings, before any fit, where the measured heading varies at least
/// [`MIN_HEADING_SPREAD`]: the wheels' heading must explain [`MIN_EXPLAINED`] of the
/// measured heading's variance (correlation squared; the 284 real recordings judged:
/// 0.999 and over; rover4 with two encoder columns swapped: the wheels do not turn at
/// all), with a positive slope (poses turning against the wheels: left and right
/// encoders swapped, or wheels counting backwards; mobolab swapped: -1.00), under
/// [`degrees_ratio`] (theta in degrees).
pub(super) fn refuse_broken_headings(
    robot: &Robot,
    shapes: &[(String, Option<Shape>)],
) -> Result<(), CalibrateError> {
    for (name, sh) in shapes {
        let Some(sh) = sh else { continue };
        if sh.heading_spread.is_nan() || sh.heading_spread < MIN_HEADING_SPREAD {
            continue;
        }
        let refuse = |message: String| {
            Err(CalibrateError {
                recording: Some(name.clone()),
                message,
            })
        };
        let follow = if sh.heading_follow.is_finite() {
            sh.heading_follow
        } else {
            0.0
        };
        if follow.powi(2) < MIN_EXPLAINED {
            return refuse(format!(
                "the wheels' heading does not follow the poses' (correlation {follow:.2}; the poses' heading varies {:.2} in its units about its mean): {}; no factors",
                sh.heading_spread,
                swapped_wheels(robot)
            ));
        }
        if sh.heading_ratio < 0.0 {
            return refuse(format!(
                "the poses turn against the wheels (turn ratio {:.2}): {}; no factors",
                sh.heading_ratio,
                swapped_sides(robot)
            ));
        }
        if sh.heading_ratio >= degrees_ratio() {
            return refuse(format!(
                "theta looks like degrees: the measured heading turns {:.1} times as far as the wheels (a plausible geometry turns at most {MAX_TURN_RATIO:.2} times, degrees read as radians 57.3 times); write theta in radians (docs/formats.md §2); no factors",
                sh.heading_ratio
            ));
        }
    }
    Ok(())
}

/// The likely cause of a turn against the wheels, in the robot's words.
fn swapped_sides(robot: &Robot) -> &'static str {
    match robot.kind {
        RobotKind::DiffDrive | RobotKind::SkidSteer => {
            "the left and right encoder columns look swapped (or the wheels count backwards)"
        }
        _ => "encoder columns look swapped, or the wheels count backwards",
    }
}

/// The likely cause of wheels whose turn does not follow the poses'.
fn swapped_wheels(robot: &Robot) -> &'static str {
    match robot.kind {
        RobotKind::SkidSteer => {
            "encoder columns look swapped between the sides (a side's wheels cancel), or one counts backwards"
        }
        _ => "encoder columns look swapped, or one counts backwards, or the poses are another robot's",
    }
}

/// Refuses a fit whose wheels do not describe a recording's motion: less than
/// [`MIN_EXPLAINED`] of the poses' spread explained by the fitted geometry with the
/// start pose and clocks fitted (after [`refuse_broken_headings`], which names the
/// causes a heading shows).
pub(super) fn refuse_unexplained(
    per: &[PerRecording],
    shapes: &[(String, Option<Shape>)],
) -> Result<(), CalibrateError> {
    for (r, (_, sh)) in per.iter().zip(shapes) {
        let Some(sh) = sh else { continue };
        let res = r.aligned_after_m;
        if !res.is_finite() || res < WORSE_MARGIN_M || sh.spread_m.is_nan() || sh.spread_m <= 0.0 {
            continue;
        }
        let explained = 1.0 - (res / sh.spread_m).powi(2);
        if explained >= MIN_EXPLAINED {
            continue;
        }
        let cause = "encoder columns swapped, counts in other units than the robot file's (encoder_counts_per_rev, gear_ratio), or another robot's recording";
        return Err(CalibrateError {
            recording: Some(r.name.clone()),
            message: format!(
                "the wheels do not describe this recording's motion: the fitted geometry leaves {:.0} mm RMS (start pose and clocks fitted) against the poses' {:.0} mm spread about their mean, {:.0} % explained (at least {:.0} % needed): {cause}; no factors",
                res * 1e3,
                sh.spread_m * 1e3,
                (explained * 100.0).max(-999.0),
                MIN_EXPLAINED * 100.0
            ),
        });
    }
    Ok(())
}

/// Inputs `calibrate` refuses before fitting: a held-out recording that is also fitted,
/// a marker offset on a drive without one.
pub(super) fn check_inputs<R: std::borrow::Borrow<Recording>>(
    robot: &Robot,
    recordings: &[(String, R)],
    holdout: Option<&(String, Recording)>,
    opts: &CalOptions,
) -> Result<(), CalibrateError> {
    if let Some((hn, hr)) = holdout {
        if let Some((n, _)) = recordings.iter().find(|(_, r)| {
            let r: &Recording = r.borrow();
            r.t == hr.t && r.x == hr.x && r.y == hr.y && r.theta == hr.theta && r.len() == hr.len()
        }) {
            return Err(CalibrateError {
                recording: Some(hn.clone()),
                message: format!(
                    "the held-out recording is also fitted (as {n}): a held-out error needs a recording the fit did not see"
                ),
            });
        }
    }
    if let Some(law) = opts.turn_law {
        if !matches!(robot.kind, RobotKind::DiffDrive | RobotKind::Omni) {
            return Err(CalibrateError {
                recording: None,
                message: format!(
                    "a known turn law (--turn-law) is for differential drives and omni robots; a {} robot's law is fitted from its recordings",
                    robot.kind.as_str()
                ),
            });
        }
        if !law.is_finite() || law.abs() > DIFF_EB_ARC_RANGE {
            return Err(CalibrateError {
                recording: None,
                message: format!(
                    "--turn-law {law} is outside the plausible -{r}..{r} (eb_arc / eb, an omni robot's l_arc: the separation or wheel distance on arcs over that of a turn in place, minus 1)",
                    r = DIFF_EB_ARC_RANGE
                ),
            });
        }
    }
    if let Some(law) = opts.speed_law {
        if robot.kind != RobotKind::DiffDrive {
            return Err(CalibrateError {
                recording: None,
                message: "a known speed law (--speed-law) is for differential drives".into(),
            });
        }
        let r = calib_core::correction::SPEED_REL_MAX;
        if !law.is_finite() || law.abs() > r {
            return Err(CalibrateError {
                recording: None,
                message: format!(
                    "--speed-law {law} is outside the -{r}..{r} per m/s a board applies (speed_rel: how much further a wheel rolls per m/s of its speed)"
                ),
            });
        }
    }
    if !opts.hold.is_empty() {
        hold_refusal(robot, opts)?;
    }
    if !opts.e_b_for.is_empty()
        && !matches!(robot.kind, RobotKind::DiffDrive | RobotKind::SkidSteer)
    {
        return Err(CalibrateError {
            recording: Some(opts.e_b_for[0].0.clone()),
            message: "--e-b-for places a turn law's one E_b for the robot file; only differential-drive and skid-steer robots have one".into(),
        });
    }
    if opts.marker_offset && robot.kind != RobotKind::Omni {
        return Err(CalibrateError {
            recording: None,
            message: "a marker offset is fitted for omni robots only: a differential drive's marker offset is not separable from its wheelbase and start heading (drop --marker-offset)".into(),
        });
    }
    Ok(())
}

/// Refuses a fit that makes a recording clearly worse than nominal, or whose
/// uncertainties are zero or infinite: the answer would be confident and wrong.
pub(super) fn refuse_bad_fit(
    per: &[PerRecording],
    specs: &[ParamSpec],
    geom: &[f64],
    cov: &DMatrix<f64>,
) -> Result<(), CalibrateError> {
    for r in per {
        // One shared geometry need not help every recording (a run whose errors cancelled
        // with the nominal geometry gets worse: a note says so); several times worse is a
        // recording the geometry cannot explain (a glitch, another robot, other units).
        let limit = WORSE_FACTOR * r.rmse_before_m + WORSE_MARGIN_M;
        if r.rmse_after_m > limit || r.rmse_after_m.is_nan() {
            return Err(CalibrateError {
                recording: Some(r.name.clone()),
                message: format!(
                    "the fitted geometry makes this recording worse than nominal ({:.2} -> {:.2} mm): the recordings disagree: another robot's recording among them (or one in other units, or with swapped columns), or an error no geometry explains; fit it apart or leave it out",
                    r.rmse_before_m * 1e3,
                    r.rmse_after_m * 1e3
                ),
            });
        }
    }
    for (i, sp) in specs.iter().enumerate() {
        let sg = cov[(i, i)].sqrt();
        if !geom[i].is_finite() || !sg.is_finite() || sg <= 0.0 {
            return Err(CalibrateError {
                recording: per.first().map(|r| r.name.clone()).filter(|_| per.len() == 1),
                message: format!(
                    "{} = {} with uncertainty {sg}: the recordings do not determine it (do the encoders move?)",
                    sp.name, geom[i]
                ),
            });
        }
    }
    Ok(())
}

/// `--hold`: names of the robot kind's list ([`HOLDABLE`] for a differential drive or
/// skid-steer robot, [`OMNI_HOLDABLE`] for an omni robot), each a family the robot's
/// models have, and something left to fit.
fn hold_refusal(robot: &Robot, opts: &CalOptions) -> Result<(), CalibrateError> {
    use crate::options::Held;
    use crate::options::{HOLDABLE, OMNI_HOLDABLE};
    use crate::params::ladder;
    let refuse = |message: String| {
        Err(CalibrateError {
            recording: None,
            message,
        })
    };
    let omni = robot.kind == RobotKind::Omni;
    let names: &[&str] = if omni { &OMNI_HOLDABLE } else { &HOLDABLE };
    let kind = if omni {
        "an omni robot"
    } else {
        "a differential-drive or skid-steer robot"
    };
    if let Some(bad) = opts.hold.iter().find(|h| !names.contains(&h.as_str())) {
        return refuse(format!(
            "--hold {bad}: not a parameter that can be held on {kind} (one of {})",
            names.join(", ")
        ));
    }
    if !omni {
        if HOLDABLE.iter().all(|n| opts.hold.iter().any(|h| h == n)) {
            return refuse(format!(
                "--hold {}: every parameter held leaves nothing to fit",
                HOLDABLE.join(" --hold ")
            ));
        }
        return Ok(());
    }
    let rungs = ladder(robot, opts.marker_offset);
    for h in &opts.hold {
        let one = Held::of(std::slice::from_ref(h));
        if !rungs.iter().flat_map(|r| &r.1).any(|s| one.holds(s)) {
            return refuse(format!(
                "--hold {h}: this robot's models have no such parameter (its ladder: {})",
                rungs.iter().map(|r| r.0).collect::<Vec<_>>().join("; ")
            ));
        }
    }
    let held = Held::of(&opts.hold);
    if rungs
        .iter()
        .flat_map(|r| &r.1)
        .filter(|s| !matches!(s.kind, GeomKind::MarkerX | GeomKind::MarkerY))
        .all(|s| held.holds(s))
    {
        return refuse(format!(
            "--hold {}: every family of this robot's models held leaves nothing to fit",
            opts.hold.join(" --hold ")
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::param_specs;
    use crate::series::Nuisance;
    use crate::synth;

    fn per(name: &str, before: f64, after: f64) -> PerRecording {
        let nu = Nuisance {
            x0_m: 0.0,
            y0_m: 0.0,
            theta0_rad: 0.0,
            time_offset_s: 0.0,
            clock_ratio: 1.0,
        };
        PerRecording {
            name: name.into(),
            pose_samples: 100,
            compared_samples: 50,
            rmse_before_m: before,
            rmse_after_m: after,
            aligned_before_m: f64::NAN,
            aligned_after_m: f64::NAN,
            dead_reckoning_before_m: f64::NAN,
            dead_reckoning_after_m: f64::NAN,
            nuisance: nu,
            nuisance_nominal: nu,
            time_offset_sigma_s: f64::NAN,
            clock_ratio_sigma: f64::NAN,
        }
    }

    /// A recording may get worse with the shared geometry up to WORSE_FACTOR x nominal +
    /// WORSE_MARGIN_M: 3 x 4 mm + 10 mm = 22 mm. 21.9 mm passes, 22.1 mm is refused,
    /// naming the recording and both figures; so is a NaN. An uncertainty of zero is
    /// refused naming the parameter (and the recording, when there is only one).
    #[test]
    fn refuse_bad_fit_draws_the_line_at_three_times_nominal_plus_a_centimetre() {
        let specs = param_specs(&synth::robot("mobolab"), false);
        let geom = [1.0, 1.0, 1.0];
        let cov = DMatrix::<f64>::identity(3, 3) * 1e-6;
        let ok = [per("a", 0.004, 0.003), per("b", 0.004, 0.0219)];
        assert_eq!(refuse_bad_fit(&ok, &specs, &geom, &cov), Ok(()));
        let worse = [per("a", 0.004, 0.003), per("b", 0.004, 0.0221)];
        let e = refuse_bad_fit(&worse, &specs, &geom, &cov).unwrap_err();
        assert_eq!(e.recording.as_deref(), Some("b"));
        assert!(e.message.contains("(4.00 -> 22.10 mm)"), "{e}");
        let nan = [per("c", 0.004, f64::NAN)];
        assert!(refuse_bad_fit(&nan, &specs, &geom, &cov).is_err());
        let mut flat = cov.clone();
        flat[(2, 2)] = 0.0;
        let e = refuse_bad_fit(&ok[..1], &specs, &geom, &flat).unwrap_err();
        assert_eq!(e.recording.as_deref(), Some("a"));
        assert!(e.message.starts_with("eb = 1 with uncertainty 0"), "{e}");
        assert_eq!(
            refuse_bad_fit(&ok, &specs, &geom, &flat)
                .unwrap_err()
                .recording,
            None
        );
    }

    fn shape(spread: f64, ratio: f64, follow: f64) -> (String, Option<Shape>) {
        (
            "r".into(),
            Some(Shape {
                spread_m: 0.5,
                heading_spread: spread,
                heading_ratio: ratio,
                heading_follow: follow,
            }),
        )
    }

    /// The heading checks: degrees from 8.3 (the log-midpoint of 1.20 and 57.3), a
    /// negative slope, a correlation under sqrt(3/4); a heading varying under 0.1 is not
    /// judged.
    #[test]
    fn broken_headings_are_told_apart() {
        let robot = synth::robot("mobolab");
        assert!((MAX_TURN_RATIO - 1.1 / 0.92).abs() < 1e-12);
        assert!(
            (degrees_ratio() - 8.277).abs() < 1e-3,
            "{}",
            degrees_ratio()
        );
        let ok = |sh| refuse_broken_headings(&robot, &[sh]).is_ok();
        let says = |sh, w: &str| {
            let e = refuse_broken_headings(&robot, &[sh]).unwrap_err();
            assert!(e.message.contains(w), "{e}");
        };
        assert!(ok(shape(1.0, 1.13, 0.999)));
        assert!(ok(shape(1.0, 0.33, 0.999)));
        assert!(ok(shape(1.0, 8.2, 0.999)));
        says(shape(1.0, 8.3, 0.999), "theta looks like degrees");
        says(shape(57.0, 57.3, 0.999), "theta looks like degrees");
        says(
            shape(1.0, -1.0, -0.999),
            "left and right encoder columns look swapped",
        );
        says(shape(1.0, 0.0, f64::NAN), "does not follow");
        says(shape(1.0, 0.9, 0.86), "does not follow");
        assert!(ok(shape(1.0, 0.9, 0.87)));
        assert!(ok(shape(0.099, -1.0, -0.999)));
    }

    /// The wheels must explain 3/4 of the poses' spread: a residual of half the spread
    /// passes, a little more is refused; under a centimetre nothing is judged.
    #[test]
    fn unexplained_motion_is_refused_at_half_the_spread() {
        let mut p = per("r", 0.004, 0.004);
        let sh = [shape(1.0, 1.0, 1.0)];
        p.aligned_after_m = 0.249;
        assert!(refuse_unexplained(std::slice::from_ref(&p), &sh).is_ok());
        p.aligned_after_m = 0.251;
        let e = refuse_unexplained(std::slice::from_ref(&p), &sh).unwrap_err();
        assert!(e.message.contains("75 % needed"), "{e}");
        let tiny = [(
            "r".to_string(),
            Some(Shape {
                spread_m: 0.001,
                ..sh[0].1.unwrap()
            }),
        )];
        p.aligned_after_m = 0.009;
        assert!(refuse_unexplained(std::slice::from_ref(&p), &tiny).is_ok());
    }
}
