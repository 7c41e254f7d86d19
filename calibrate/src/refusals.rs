//! What calibrate refuses to answer: inputs it cannot fit ([`check_inputs`]: a held-out
//! recording that is also fitted, a turn law or a marker offset on a drive without one,
//! `--hold` names the robot's models lack) and a fit that would be confident and wrong
//! ([`refuse_bad_fit`]: a recording made several times worse than nominal, an
//! uncertainty zero or infinite).

use crate::error::CalibrateError;
use crate::options::CalOptions;
use crate::params::{GeomKind, ParamSpec, DIFF_EB_ARC_RANGE};
use crate::result::PerRecording;
use calib_core::robot::{Robot, RobotKind};
use formats::recording::Recording;
use nalgebra::DMatrix;

/// A fit that makes a recording more than this many times worse than nominal (plus
/// [`WORSE_MARGIN_M`]) is refused, naming the recording.
pub const WORSE_FACTOR: f64 = 3.0;
/// See [`WORSE_FACTOR`], m.
pub const WORSE_MARGIN_M: f64 = 0.01;

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
                    "the fitted geometry makes this recording worse than nominal ({:.2} -> {:.2} mm): the recordings disagree, or this one holds an error no geometry explains; fit it apart or leave it out",
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
}
