//! `encoder_scale`: one encoder counting a fraction off that is no simple ratio (a
//! disc of another resolution, counts x 0.97), told from physics only where the evidence
//! separates them: an open-loop stepper robot, whose wheels turn as commanded unless
//! steps are missed. There the encoder's travel over the commanded travel is its scale,
//! and the poses must agree with the commands (a wheel of another size, or missed steps,
//! make the poses disagree with the commands instead). On a DC robot a wheel's encoder
//! scale against the poses is indistinguishable from its diameter: left to the physics.

use super::artefact::{Artefact, Event};
use super::segments::Segments;
use calib_core::robot::{DriveType, Robot};
use formats::recording::Recording;
use std::collections::BTreeMap;

/// Smallest scale error reported (relative). On the stepper controls (docs/diagnose.md)
/// the encoder's travel over the commanded travel departs from 1 by at most a few 1e-4
/// (whole counts, merged rows); 0.5 % is ten times that.
pub const SCALE_MIN: f64 = 0.005;
/// ... and at least this many of its own sigmas (from the segments' scatter).
pub const SCALE_SIGMAS: f64 = 4.0;
/// The poses must agree with the commands: their travel over the commanded travel
/// departs from 1 by less than this fraction of the encoder's departure.
pub const POSES_AGREE: f64 = 0.5;

/// Per wheel with an encoder and a command on a stepper robot: (encoder over commanded
/// travel, its sigma, pose-asked over commanded travel).
pub(super) fn stepper_scales(robot: &Robot, segs: &Segments) -> Vec<Option<(f64, f64, f64)>> {
    let nw = robot.wheels.len();
    if robot.drive.kind != DriveType::Stepper {
        return vec![None; nw];
    }
    (0..nw)
        .map(|i| {
            let (ec, cc, _, n) = Segments::dot(&segs.cmd, i, &segs.enc, i);
            let (ac, cc2, _, n2) = Segments::dot(&segs.cmd, i, &segs.asked, i);
            if n < 8 || n2 < 8 || cc.is_nan() || cc <= 0.0 || cc2.is_nan() || cc2 <= 0.0 {
                return None;
            }
            let k = ec / cc;
            let kp = ac / cc2;
            // Sigma from the segments' scatter about the fit.
            let w: Vec<f64> = segs
                .cmd
                .iter()
                .zip(&segs.enc)
                .filter_map(|(c, e)| {
                    let (c, e) = (*c.get(i)?, *e.get(i)?);
                    (c.is_finite() && e.is_finite()).then_some(c * (e - k * c))
                })
                .collect();
            let rho = fitkit::noise::lag1_autocorrelation([w.as_slice()], 0.9);
            let ss: f64 = w.iter().map(|v| v * v).sum();
            let sigma = ss.sqrt() / cc * fitkit::noise::ar1_inflation(rho).sqrt();
            (k.is_finite() && kp.is_finite() && sigma.is_finite()).then_some((k, sigma, kp))
        })
        .collect()
}

/// Finds and removes per-wheel encoder scales on a stepper robot.
pub(super) fn encoder_scale(
    robot: &Robot,
    rec: &mut Recording,
    segs: &Segments,
) -> Option<Artefact> {
    let mut a = Artefact::new("encoder_scale");
    let scales = stepper_scales(robot, segs);
    for (i, s) in scales.iter().enumerate() {
        let Some((k, sigma, kp)) = *s else { continue };
        let off = k - 1.0;
        if !(off.abs() > SCALE_MIN
            && off.abs() > SCALE_SIGMAS * sigma
            && (kp - 1.0).abs() < POSES_AGREE * off.abs()
            && k > 0.0)
        {
            continue;
        }
        let name = &robot.wheels[i].name;
        a.parameters.insert(format!("encoder_scale_{name}"), k);
        a.uncertainties
            .insert(format!("encoder_scale_{name}"), sigma);
        a.notes.push(format!(
            "{name}: the encoder counts {k:.4} of the commanded travel while the poses show {kp:.4} of it (a stepper turns as commanded): the encoder's scale, not the wheel"
        ));
        if let Some(e) = rec.wheels[i].enc.as_mut() {
            for c in e.iter_mut().flatten() {
                let v = (*c as f64 / k).round();
                if v.is_finite() && v.abs() < 9e15 {
                    *c = v as i64;
                }
            }
        }
    }
    if a.parameters.is_empty() {
        return None;
    }
    a.removed = true;
    a.events.push(Event {
        at_s: rec.t.first().copied().unwrap_or(0.0),
        size: BTreeMap::new(),
    });
    Some(a)
}
