//! Physical ranges of the catalogue's parameters. A finding outside its range is not a
//! property of the robot: it most likely stands in for something the catalogue lacks,
//! so it is listed `implausible` (with that guess) and never becomes the verdict.

use crate::finding::Finding;
use calibrate::{ALPHA_RANGE, BASE_RANGE, ED_RANGE, GAMMA_RANGE, RADIUS_RANGE};
use serde::Serialize;

/// A fitted parameter outside its physical range.
#[derive(Debug, Clone, Serialize)]
pub struct Implausible {
    /// Catalogue id of the finding.
    pub effect: String,
    /// The parameter's name.
    pub parameter: String,
    /// Its fitted value.
    pub value: f64,
    /// Its physical range (low, high).
    pub plausible: (f64, f64),
    /// What a value outside the range most likely stands in for.
    pub stands_for: String,
}

/// (range, what a value outside most likely stands for) of a catalogue parameter.
pub fn range(parameter: &str) -> Option<((f64, f64), &'static str)> {
    let around = |c: f64, h: f64| (c - h, c + h);
    if parameter.starts_with("radius_scale_") || parameter == "scale" {
        return Some((
            around(1.0, RADIUS_RANGE),
            "the mounting angles or positions of several wheels (diagnose tries one wheel at a time; `wheelcal calibrate` fits them all), a wrong counts per revolution, or slip",
        ));
    }
    if parameter.starts_with("alpha_offset_rad_") {
        return Some((around(0.0, ALPHA_RANGE), "rollers slipping sideways"));
    }
    if parameter == "roller_angle_offset_rad" {
        return Some((
            around(0.0, GAMMA_RANGE),
            "rollers slipping along their axles, or wheels mounted at other angles",
        ));
    }
    if parameter.starts_with("l_scale_") {
        return Some((around(1.0, BASE_RANGE), "scrub in rotation"));
    }
    match parameter {
        "ed" => Some((
            around(1.0, ED_RANGE),
            "slip on one side or a drift a one-direction run does not separate from wheel size",
        )),
        "eb" => Some((
            around(1.0, BASE_RANGE),
            "tyre scrub in turns or a wheel size error a one-direction run does not separate",
        )),
        _ => None,
    }
}

/// The implausible parameters of `findings`.
pub fn check(findings: &[Finding]) -> Vec<Implausible> {
    let mut out = Vec::new();
    for f in findings {
        for (p, v) in &f.parameters {
            if let Some(((lo, hi), why)) = range(p) {
                if *v < lo || *v > hi {
                    out.push(Implausible {
                        effect: f.effect.clone(),
                        parameter: p.clone(),
                        value: *v,
                        plausible: (lo, hi),
                        stands_for: why.to_string(),
                    });
                }
            }
        }
    }
    out
}

// Floor bumps must be localised in space ("bumps only where the residual is
// localised in space"); the test itself is `crate::localisation`.

/// Parameter name under which a `floor_bumps` finding's localisation is listed: the
/// significance (sigmas) of its own loss pattern beyond a uniform loss per wheel.
pub const LOCALISED_PARAMETER: &str = "localised_sigma";

/// What a `floor_bumps` finding whose loss is not localised most likely stands for.
pub const BUMPS_UNIFORM_STANDS_FOR: &str = "a wheel scale error or uniform slip: bumps spread evenly over the whole floor look like a smaller wheel (wheel_scale)";

/// The `floor_bumps` findings whose travel loss is not shown to be where their bumps are
/// (see [`crate::localisation`]); a recording too short to tell counts as not shown.
pub fn bumps_not_localised(
    ev: &crate::residuals::Evaluator,
    model: &crate::effects::Model,
    findings: &[Finding],
) -> Vec<Implausible> {
    findings
        .iter()
        .filter(|f| f.effect == crate::effects::Effect::FloorBumps.id())
        .filter_map(|f| {
            let z = crate::localisation::floor_bumps(ev, model, f).map_or(0.0, |l| l.sigma);
            (z < crate::localisation::LOCALISED_SIGMA).then(|| Implausible {
                effect: f.effect.clone(),
                parameter: LOCALISED_PARAMETER.to_string(),
                value: z,
                plausible: (crate::localisation::LOCALISED_SIGMA, f64::INFINITY),
                stands_for: BUMPS_UNIFORM_STANDS_FOR.to_string(),
            })
        })
        .collect()
}

/// The parameter name under which [`play_not_at_reversals`] lists backlash.
pub const AT_REVERSALS_PARAMETER: &str = "loss_at_restarts_over_reversals";
/// What backlash whose loss also follows starts without a reversal stands for.
pub const PLAY_ELSEWHERE_STANDS_FOR: &str =
    "a dead band or friction (travel lost at every start from rest, not only after reversals)";
/// Decision boundary of [`play_not_at_reversals`]: play loses travel after a reversal and
/// none at a start in the direction the wheel last moved (ratio 0); a dead band loses the
/// same at both (ratio 1). Half is the middle between the two, not a fitted number.
pub const PLAY_RESTART_SHARE: f64 = 0.5;
/// Fewest events of each kind [`play_not_at_reversals`] needs to judge.
const PLAY_MIN_EVENTS: usize = 3;
/// Window after an event over which the travel lost is read, s.
const PLAY_WINDOW_S: f64 = 0.5;

/// Backlash earns its place by its signature (issue 55 §3): in the nominal actuator
/// residual (encoder minus commanded travel), the travel lost in the half second after a
/// wheel starts from rest in the direction it last moved must be under
/// [`PLAY_RESTART_SHARE`] of that lost after it reverses. Listed (never the verdict) when it
/// is not; no judgement with fewer than three events of each kind.
pub fn play_not_at_reversals(
    ev: &crate::residuals::Evaluator,
    nominal: &crate::residuals::Eval,
    findings: &[Finding],
) -> Vec<Implausible> {
    if !findings
        .iter()
        .any(|f| f.effect == crate::effects::Effect::Backlash.id())
    {
        return Vec::new();
    }
    let p = ev.p;
    let (mut restart, mut reversal) = (Vec::new(), Vec::new());
    for (i, res) in &nominal.act {
        let Some(cmd) = p.wheels.get(*i).and_then(|w| w.cmd.as_ref()) else {
            continue;
        };
        let rows = &ev.act_rows;
        let top = rows
            .iter()
            .filter_map(|&r| cmd.get(r))
            .fold(0.0f64, |m, c| m.max(c.abs()));
        if top <= 0.0 {
            continue;
        }
        let moving = 0.05 * top;
        let (mut last_dir, mut was_moving) = (0.0f64, false);
        for (k, &r) in rows.iter().enumerate() {
            let c = cmd.get(r).copied().unwrap_or(0.0);
            let now = c.abs() > moving;
            let dir = c.signum();
            let event = now && (!was_moving || (last_dir != 0.0 && dir != last_dir));
            if event && last_dir != 0.0 {
                let t0 = p.t[r];
                let end = rows[k..]
                    .iter()
                    .position(|&q| p.t[q] >= t0 + PLAY_WINDOW_S)
                    .map(|j| k + j);
                if let (Some(e), Some(&a)) = (end, res.get(k)) {
                    if let Some(&b) = res.get(e) {
                        let lost = -(b - a) * dir;
                        if dir == last_dir {
                            restart.push(lost);
                        } else {
                            reversal.push(lost);
                        }
                    }
                }
            }
            if now {
                last_dir = dir;
            }
            was_moving = now;
        }
    }
    if restart.len() < PLAY_MIN_EVENTS || reversal.len() < PLAY_MIN_EVENTS {
        return Vec::new();
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (at_restart, at_reversal) = (mean(&restart), mean(&reversal));
    let ratio = if at_reversal > 0.0 {
        at_restart / at_reversal
    } else {
        f64::INFINITY
    };
    if ratio < PLAY_RESTART_SHARE {
        return Vec::new();
    }
    vec![Implausible {
        effect: crate::effects::Effect::Backlash.id().to_string(),
        parameter: AT_REVERSALS_PARAMETER.to_string(),
        value: ratio,
        plausible: (0.0, PLAY_RESTART_SHARE),
        stands_for: PLAY_ELSEWHERE_STANDS_FOR.to_string(),
    }]
}
