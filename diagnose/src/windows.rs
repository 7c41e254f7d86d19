//! Locates the time windows where the residual leaves the noise band, per stage and axis,
//! and describes what the robot was doing in them.
//!
//! The test statistic is the residual's change over a short lag, in the body frame: white
//! noise of sigma changes by sigma * sqrt(2) whatever the lag, while a model error makes
//! the residual walk away while it acts. Windows far beyond the noise (5 sigma) are kept,
//! so a noise-only recording yields essentially none.

use crate::effects::Stage;
use crate::residuals::{Eval, Evaluator};
use serde::Serialize;
use std::collections::BTreeMap;

/// Threshold in noise standard deviations of the lagged increment.
pub const SIGMA_BAND: f64 = 5.0;
/// Lag of the increment, seconds.
pub const LAG_S: f64 = 0.5;

/// Residual direction.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    /// Along the body's x axis (actuator stage: along the wheel's rolling direction).
    Longitudinal,
    /// Along the body's y axis.
    Lateral,
    /// The heading.
    Heading,
}

impl Axis {
    /// The axis' name in reports.
    pub fn as_str(self) -> &'static str {
        match self {
            Axis::Longitudinal => "longitudinal",
            Axis::Lateral => "lateral",
            Axis::Heading => "heading",
        }
    }
}

/// A stretch of time where the model leaves the noise band.
#[derive(Debug, Clone, Serialize)]
pub struct Window {
    /// Start of the window, s.
    pub t_start_s: f64,
    /// End of the window, s.
    pub t_end_s: f64,
    /// The stage whose residual leaves the band.
    pub stage: Stage,
    /// The direction in which it leaves.
    pub axis: Axis,
    /// The wheel whose rolling direction carries most of the mismatch (actuator stage:
    /// the wheel compared).
    pub wheel: Option<String>,
    /// Largest lagged increment, in noise sigmas.
    pub peak_sigma: f64,
    /// True when the fitted model stays inside the noise band here.
    pub explained_by_fit: bool,
    /// What the robot was doing (window means of absolute values, or counts).
    pub signals: BTreeMap<String, f64>,
    /// The signal most unusual in this window compared with the whole recording.
    pub related_signal: Option<String>,
}

/// Per-row motion signals from the measured poses and nominal odometry.
pub struct Signals {
    /// Signal names, the unit in the name where there is one (`speed_m_s`, `reversals`).
    pub names: Vec<&'static str>,
    /// `[signal][row]`
    pub values: Vec<Vec<f64>>,
    /// Per signal: mean of |value| over the recording and the spread of |value| about it
    /// (computed once: every window compares its stretch with them).
    pub abs_stats: Vec<(f64, f64)>,
}

/// Computes the signals windows are related to, per row (from the nominal odometry
/// increments, which are smoother than the pose samples).
pub fn signals(ev: &Evaluator) -> Signals {
    let p = ev.p;
    let n = p.rows();
    let path = ev.path_per_row(&crate::effects::Model::default());
    let mut speed = vec![0.0; n];
    let mut omega = vec![0.0; n];
    for k in 0..n.saturating_sub(1) {
        let dt = (p.t[k + 1] - p.t[k]).max(fitkit::MIN_DT_S);
        let s = &path.step[k];
        speed[k] = s.vx / dt;
        omega[k] = s.omega / dt;
    }
    if n >= 2 {
        speed[n - 1] = speed[n - 2];
        omega[n - 1] = omega[n - 2];
    }
    // Smooth over ~0.1 s so that encoder quantisation does not dominate accelerations.
    let smooth = |v: &[f64]| -> Vec<f64> {
        let dt = if n > 1 {
            (p.t[n - 1] - p.t[0]) / (n - 1) as f64
        } else {
            1.0
        };
        let h = ((0.05 / dt.max(fitkit::MIN_DT_S)) as usize).clamp(0, 50);
        let mut pre = vec![0.0; n + 1];
        for k in 0..n {
            pre[k + 1] = pre[k] + v[k];
        }
        (0..n)
            .map(|k| {
                let (a, b) = (k.saturating_sub(h), (k + h + 1).min(n));
                (pre[b] - pre[a]) / (b - a) as f64
            })
            .collect()
    };
    let speed = smooth(&speed);
    let omega = smooth(&omega);
    let mut accel = vec![0.0; n];
    for k in 1..n {
        accel[k] = (speed[k] - speed[k - 1]) / (p.t[k] - p.t[k - 1]).max(fitkit::MIN_DT_S);
    }
    let accel = smooth(&accel);
    let centripetal: Vec<f64> = speed.iter().zip(&omega).map(|(v, w)| v * w).collect();
    let mut distance = vec![0.0; n];
    let mut reversals = vec![0.0; n];
    for k in 1..n {
        distance[k] = distance[k - 1] + path.step[k - 1].vx.hypot(path.step[k - 1].vy);
        let flip = speed[k].signum() != speed[k - 1].signum()
            && speed[k].abs() > 1e-3
            && speed[k - 1].abs() > 1e-3;
        reversals[k] = if flip { 1.0 } else { 0.0 };
    }
    let mut names = vec![
        "speed_m_s",
        "accel_m_s2",
        "turn_rate_rad_s",
        "centripetal_m_s2",
        "distance_m",
        "reversals",
    ];
    let mut values = vec![speed, accel, omega, centripetal, distance, reversals];
    if let Some((f, r)) = &p.legs {
        names.push("leg_front_rad");
        names.push("leg_rear_rad");
        values.push(f.clone());
        values.push(r.clone());
    }
    // Measured position, held between pose samples.
    let mut px = vec![0.0; n];
    let mut py = vec![0.0; n];
    let (mut lx, mut ly, mut j) = (
        p.poses.x.first().copied().unwrap_or(0.0),
        p.poses.y.first().copied().unwrap_or(0.0),
        0,
    );
    for k in 0..n {
        while j < p.poses.len() && p.poses.row[j] <= k {
            lx = p.poses.x[j];
            ly = p.poses.y[j];
            j += 1;
        }
        px[k] = lx;
        py[k] = ly;
    }
    names.push("x_m");
    names.push("y_m");
    values.push(px);
    values.push(py);
    let abs_stats = values
        .iter()
        .map(|v| {
            let all = v.iter().map(|x| x.abs()).sum::<f64>() / v.len().max(1) as f64;
            let spread = (v.iter().map(|x| (x.abs() - all).powi(2)).sum::<f64>()
                / v.len().max(1) as f64)
                .sqrt()
                .max(1e-12);
            (all, spread)
        })
        .collect();
    Signals {
        names,
        values,
        abs_stats,
    }
}

/// Intervals (row indices into the sample series) where |increment over lag| > band.
fn flagged(series: &[f64], sigma: f64, lag: usize) -> Vec<(usize, usize, f64)> {
    let mut out: Vec<(usize, usize, f64)> = Vec::new();
    if series.len() <= lag || sigma <= 0.0 {
        return out;
    }
    let band = SIGMA_BAND * sigma * 2f64.sqrt();
    for k in 0..series.len() - lag {
        let d = (series[k + lag] - series[k]).abs();
        if d > band {
            let z = d / (sigma * 2f64.sqrt());
            match out.last_mut() {
                Some(last) if k <= last.1 => {
                    last.1 = k + lag;
                    last.2 = last.2.max(z);
                }
                _ => out.push((k, k + lag, z)),
            }
        }
    }
    out
}

/// Body-frame residual series (longitudinal, lateral) as the cumulative sum of rotated
/// increments, so that lagged differences are in the body frame of each instant.
fn body_frame(ev: &Evaluator, e: &Eval) -> (Vec<f64>, Vec<f64>) {
    let th = &ev.p.poses.theta;
    let n = e.ex.len();
    let mut lon = vec![0.0; n];
    let mut lat = vec![0.0; n];
    for k in 1..n {
        let (dx, dy) = (e.ex[k] - e.ex[k - 1], e.ey[k] - e.ey[k - 1]);
        let (s, c) = th[k - 1].sin_cos();
        lon[k] = lon[k - 1] + c * dx + s * dy;
        lat[k] = lat[k - 1] - s * dx + c * dy;
    }
    (lon, lat)
}

fn lag_samples(times: &[f64]) -> usize {
    if times.len() < 2 {
        return 1;
    }
    let dt = (times[times.len() - 1] - times[0]) / (times.len() - 1) as f64;
    ((LAG_S / dt.max(fitkit::MIN_DT_S)).round() as usize).max(1)
}

/// Finds the windows of the nominal residual and marks those the fit explains.
pub fn locate(ev: &Evaluator, nominal: &Eval, fitted: &Eval, sig: &Signals) -> Vec<Window> {
    let p = ev.p;
    let mut out = Vec::new();
    // Ground stage.
    let pose_t: Vec<f64> = p.poses.row.iter().map(|&r| p.t[r]).collect();
    if pose_t.len() >= 3 {
        let lag = lag_samples(&pose_t);
        let (lon0, lat0) = body_frame(ev, nominal);
        let (lon1, lat1) = body_frame(ev, fitted);
        let sp = ev.noise.pose_sigma_m;
        let sh = ev.noise.heading_sigma_rad;
        for (axis, s0, s1, sigma) in [
            (Axis::Longitudinal, &lon0, &lon1, sp),
            (Axis::Lateral, &lat0, &lat1, sp),
            (Axis::Heading, &nominal.eth, &fitted.eth, sh),
        ] {
            let after = flagged(s1, sigma, lag);
            for (a, b, z) in flagged(s0, sigma, lag) {
                let (ra, rb) = (p.poses.row[a], p.poses.row[b]);
                let explained = !after.iter().any(|&(c, d, _)| c <= b && d >= a);
                let wheel = ground_wheel(ev, nominal, a, b, axis);
                let peaks = peak_rows(s0, &p.poses.row, a, b);
                let (signals, related) = describe(sig, ra, rb, &peaks);
                out.push(Window {
                    t_start_s: pose_t[a],
                    t_end_s: pose_t[b],
                    stage: Stage::Ground,
                    axis,
                    wheel,
                    peak_sigma: z,
                    explained_by_fit: explained,
                    signals,
                    related_signal: related,
                });
            }
        }
    }
    // Actuator stage, per wheel.
    let act_t: Vec<f64> = ev.act_rows.iter().map(|&r| p.t[r]).collect();
    if act_t.len() >= 3 {
        let lag = lag_samples(&act_t).min(act_t.len() - 1);
        for ((i, e0), (_, e1)) in nominal.act.iter().zip(&fitted.act) {
            let after = flagged(e1, ev.noise.actuator_sigma_m, lag);
            for (a, b, z) in flagged(e0, ev.noise.actuator_sigma_m, lag) {
                let (ra, rb) = (ev.act_rows[a], ev.act_rows[b]);
                let explained = !after.iter().any(|&(c, d, _)| c <= b && d >= a);
                let peaks = peak_rows(e0, &ev.act_rows, a, b);
                let (signals, related) = describe(sig, ra, rb, &peaks);
                out.push(Window {
                    t_start_s: act_t[a],
                    t_end_s: act_t[b],
                    stage: Stage::Actuator,
                    axis: Axis::Longitudinal,
                    wheel: Some(p.wheels[*i].name.clone()),
                    peak_sigma: z,
                    explained_by_fit: explained,
                    signals,
                    related_signal: related,
                });
            }
        }
    }
    out.sort_by(|a, b| a.t_start_s.total_cmp(&b.t_start_s));
    out
}

/// Most windows a report lists (the strongest, in time order); the count of all is kept.
pub const MAX_LISTED: usize = 200;
/// Windows of the same stage, axis and wheel closer than this are one window (s).
pub const MERGE_GAP_S: f64 = 0.5;

/// Windows merged (same stage, axis and wheel, overlapping or under [`MERGE_GAP_S`]
/// apart: the stronger one's description, the union of the times) and bounded to the
/// [`MAX_LISTED`] strongest, in time order; with the number of merged windows. A long
/// recording with a residual out of the noise everywhere listed thousands (480 KB of a
/// 458 KB report at 120,000 rows), which tells a reader no more than the strongest.
pub fn bounded(mut ws: Vec<Window>) -> (Vec<Window>, usize) {
    ws.sort_by(|a, b| {
        (a.stage as u8, a.axis as u8, &a.wheel)
            .cmp(&(b.stage as u8, b.axis as u8, &b.wheel))
            .then(a.t_start_s.total_cmp(&b.t_start_s))
    });
    let mut merged: Vec<Window> = Vec::with_capacity(ws.len());
    for w in ws {
        if let Some(last) = merged.last_mut() {
            if last.stage == w.stage
                && last.axis == w.axis
                && last.wheel == w.wheel
                && w.t_start_s <= last.t_end_s + MERGE_GAP_S
            {
                let (start, end) = (last.t_start_s, last.t_end_s.max(w.t_end_s));
                let explained = last.explained_by_fit && w.explained_by_fit;
                if w.peak_sigma > last.peak_sigma {
                    *last = w;
                }
                last.t_start_s = start;
                last.t_end_s = end;
                last.explained_by_fit = explained;
                continue;
            }
        }
        merged.push(w);
    }
    let total = merged.len();
    if merged.len() > MAX_LISTED {
        merged.sort_by(|a, b| b.peak_sigma.total_cmp(&a.peak_sigma));
        merged.truncate(MAX_LISTED);
    }
    merged.sort_by(|a, b| a.t_start_s.total_cmp(&b.t_start_s));
    (merged, total)
}

/// The wheel whose rolling constraint the window's body residual loads most.
fn ground_wheel(ev: &Evaluator, e: &Eval, a: usize, b: usize, axis: Axis) -> Option<String> {
    let robot = &ev.p.robot;
    let th = ev.p.poses.theta[a];
    let (s, c) = th.sin_cos();
    let (dx, dy) = (e.ex[b] - e.ex[a], e.ey[b] - e.ey[a]);
    let d = match axis {
        Axis::Longitudinal => [c * dx + s * dy, 0.0, 0.0],
        Axis::Lateral => [0.0, -s * dx + c * dy, 0.0],
        Axis::Heading => [0.0, 0.0, e.eth[b] - e.eth[a]],
    };
    robot
        .wheels
        .iter()
        .map(|w| {
            let r = w.rolling_row();
            let v = (r[0] * d[0] + r[1] * d[1] + r[2] * d[2]) / w.radius_m;
            (w.name.to_string(), v.abs())
        })
        .filter(|(_, v)| *v > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(n, _)| n)
}

/// Rows where the residual changes most within samples a..=b (steps of at least half
/// the window's largest): what the robot does there is what relates to the residual, not
/// what it does on average including rest.
fn peak_rows(series: &[f64], rows: &[usize], a: usize, b: usize) -> Vec<usize> {
    let b = b
        .min(series.len().saturating_sub(1))
        .min(rows.len().saturating_sub(1));
    if b <= a {
        return Vec::new();
    }
    let steps: Vec<f64> = (a..b).map(|k| (series[k + 1] - series[k]).abs()).collect();
    let top = steps.iter().cloned().fold(0.0, f64::max);
    if top <= 0.0 {
        return Vec::new();
    }
    let mut out: Vec<usize> = Vec::new();
    for (j, d) in steps.iter().enumerate() {
        if *d >= 0.5 * top {
            // The rows spanned by the step (samples may be several rows apart).
            out.extend(rows[a + j]..=rows[a + j + 1]);
        }
    }
    out.sort_unstable();
    out.dedup();
    out
}

/// Signal values over rows a..=b (mean absolute values at the residual's peaks `peaks`
/// when given, else over the window) and the most unusual one (largest difference from
/// the whole-recording mean in units of its spread).
fn describe(
    sig: &Signals,
    a: usize,
    b: usize,
    peaks: &[usize],
) -> (BTreeMap<String, f64>, Option<String>) {
    let mut map = BTreeMap::new();
    let mut best: Option<(&str, f64)> = None;
    for ((name, v), &(all, spread)) in sig.names.iter().zip(&sig.values).zip(&sig.abs_stats) {
        if v.is_empty() {
            continue;
        }
        let b = b.min(v.len() - 1);
        let a = a.min(b);
        let abs_mean = |s: &[f64]| s.iter().map(|x| x.abs()).sum::<f64>() / s.len().max(1) as f64;
        let value = match *name {
            "distance_m" => v[b] - v[a],
            "reversals" => v[a..=b].iter().sum(),
            "x_m" | "y_m" | "leg_front_rad" | "leg_rear_rad" => {
                v[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
            }
            _ if !peaks.is_empty() => {
                let at: Vec<f64> = peaks
                    .iter()
                    .filter(|&&k| k < v.len())
                    .map(|&k| v[k])
                    .collect();
                abs_mean(&at)
            }
            _ => abs_mean(&v[a..=b]),
        };
        map.insert(name.to_string(), value);
        if matches!(*name, "x_m" | "y_m" | "distance_m") {
            continue;
        }
        let inside = if *name == "reversals" {
            value / (b - a + 1) as f64
        } else {
            value
        };
        let z = (inside - all) / spread;
        if z > 0.5 && best.is_none_or(|bst| z > bst.1) {
            best = Some((name, z));
        }
    }
    (map, best.map(|b| b.0.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(t0: f64, t1: f64, z: f64, wheel: &str) -> Window {
        Window {
            t_start_s: t0,
            t_end_s: t1,
            stage: Stage::Actuator,
            axis: Axis::Longitudinal,
            wheel: Some(wheel.into()),
            peak_sigma: z,
            explained_by_fit: true,
            signals: BTreeMap::new(),
            related_signal: None,
        }
    }

    /// Neighbours of one wheel merge (the stronger one's peak, the union of times); other
    /// wheels stay apart; beyond MAX_LISTED the strongest are listed and all counted.
    #[test]
    fn windows_merge_and_are_bounded() {
        let (m, n) = bounded(vec![
            w(0.0, 1.0, 3.0, "a"),
            w(1.2, 2.0, 5.0, "a"),
            w(1.1, 1.5, 4.0, "b"),
            w(9.0, 9.5, 2.0, "a"),
        ]);
        assert_eq!(n, 3);
        assert_eq!(
            (m[0].t_start_s, m[0].t_end_s, m[0].peak_sigma),
            (0.0, 2.0, 5.0)
        );
        assert_eq!(m[1].wheel.as_deref(), Some("b"));
        let many: Vec<Window> = (0..1000)
            .map(|k| w(k as f64, k as f64 + 0.2, k as f64, "a"))
            .collect();
        let (m, n) = bounded(many);
        assert_eq!((m.len(), n), (MAX_LISTED, 1000));
        assert_eq!(m[0].peak_sigma, (1000 - MAX_LISTED) as f64);
    }

    #[test]
    fn peaks_are_where_the_residual_steps() {
        // A residual flat except for a 1 mm step between samples 5 and 6 (rows 10..12) and
        // a 0.3 mm one (below half the largest) between 8 and 9.
        let mut s = vec![0.0; 12];
        for (k, v) in s.iter_mut().enumerate() {
            *v = if k >= 9 {
                1.3e-3
            } else if k >= 6 {
                1e-3
            } else {
                0.0
            };
        }
        let rows: Vec<usize> = (0..12).map(|k| 2 * k).collect();
        assert_eq!(peak_rows(&s, &rows, 0, 11), vec![10, 11, 12]);
        assert!(peak_rows(&s, &rows, 0, 4).is_empty());
    }
}
