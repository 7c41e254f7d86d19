//! Signatures: before any parametric fit, what each effect does to the
//! residuals, looked for directly. A clear signature names an effect even when no
//! mechanism fits it fully (the finding then says `"fit": "partial"`), and a residual with
//! no signature of drift at all is noise, however coloured.
//!
//! - Noise: a stationary residual (motion-capture noise correlated over a second, jittered
//!   sample times) changes by as much over 8 s as over 2 s; a model error keeps growing.
//! - `missed_steps`: the wheel residual jumps by whole electrical cycles (four full steps)
//!   where the commanded acceleration is high.
//! - `floor_bumps` in a region: measured travel falls short of the wheels' in proportion to
//!   distance, inside one stretch of the floor only (chord lengths: heading drift does not
//!   enter).

use crate::effects::Model;
use crate::residuals::{Eval, Evaluator};

/// Lags (s) of the stationarity test and the largest variance ratio still called noise.
const LAG_SHORT_S: f64 = 2.0;
const LAG_LONG_S: f64 = 8.0;
/// Largest [`drift_ratio`] (long-lag over short-lag variance) still called noise.
pub const STATIONARY_RATIO: f64 = 2.0;

/// Variance of the residual's change over the long lag over that over the short lag.
/// `None` when the series is too short to tell.
pub fn drift_ratio(t: &[f64], e: &[f64]) -> Option<f64> {
    let n = t.len().min(e.len());
    if n < 10 {
        return None;
    }
    let span = t[n - 1] - t[0];
    if span < 3.0 * LAG_LONG_S {
        return None;
    }
    let var_at = |lag: f64| -> f64 {
        let (mut s, mut c, mut j) = (0.0, 0usize, 0usize);
        for i in 0..n {
            while j < n && t[j] < t[i] + lag {
                j += 1;
            }
            if j >= n {
                break;
            }
            let d = e[j] - e[i];
            s += d * d;
            c += 1;
        }
        s / c.max(1) as f64
    };
    let short = var_at(LAG_SHORT_S);
    (short > 0.0).then(|| var_at(LAG_LONG_S) / short)
}

/// True when every residual series of a stage is stationary (noise, not drift).
pub fn stage_is_noise(ev: &Evaluator, e: &Eval, ground: bool) -> bool {
    let p = ev.p;
    if ground {
        let t: Vec<f64> = p.poses.row.iter().map(|&r| p.t[r]).collect();
        let mut any = false;
        for s in [&e.ex, &e.ey, &e.eth] {
            match drift_ratio(&t, s) {
                Some(r) if r < STATIONARY_RATIO => any = true,
                Some(_) => return false,
                None => return false,
            }
        }
        any
    } else {
        let t: Vec<f64> = ev.act_rows.iter().map(|&r| p.t[r]).collect();
        let mut any = false;
        for (_, s) in &e.act {
            match drift_ratio(&t, s) {
                Some(r) if r < STATIONARY_RATIO => any = true,
                _ => return false,
            }
        }
        any
    }
}

/// What a stepper's wheel residual shows.
#[derive(Debug, Clone, PartialEq)]
pub struct StepSignature {
    /// Jumps of at least half an electrical cycle.
    pub jumps: usize,
    /// Share of them within two rows of a high commanded acceleration.
    pub at_high_accel: f64,
    /// Mean distance of the jump sizes from whole cycles (0 = exact multiples).
    pub off_cycle: f64,
}

impl StepSignature {
    /// Whether the jumps name missed steps: at least 5, at least 80 % of them at high
    /// commanded acceleration, and within a quarter cycle of whole cycles on average.
    pub fn clear(&self) -> bool {
        self.jumps >= 5 && self.at_high_accel >= 0.8 && self.off_cycle < 0.25
    }
}

/// Looks for steps of one electrical cycle in the actuator residual of `e`.
pub fn stepper_steps(ev: &Evaluator, e: &Eval) -> Option<StepSignature> {
    let p = ev.p;
    let d = &p.robot.drive;
    if d.kind != calib_core::robot::DriveType::Stepper || d.steps_per_rev == 0 {
        return None;
    }
    let cycle_rad = 4.0 * std::f64::consts::TAU / (d.steps_per_rev as f64 * d.gear_ratio);
    let rows = &ev.act_rows;
    let (mut jumps, mut hits, mut off) = (0usize, 0usize, 0.0);
    for (i, s) in &e.act {
        let w = &p.wheels[*i];
        let Some(cmd) = &w.cmd else { continue };
        let cycle_m = cycle_rad * w.radius_m;
        // |commanded acceleration| per row, and its high level (95th percentile / 2).
        let acc: Vec<f64> = (0..p.rows())
            .map(|k| {
                let k1 = (k + 1).min(p.rows() - 1);
                let dt = (p.t[k1] - p.t[k]).max(fitkit::MIN_DT_S);
                ((cmd[k1] - cmd[k]) / dt).abs()
            })
            .collect();
        let mut sorted = acc.clone();
        sorted.sort_by(|a, b| a.total_cmp(b));
        let high = 0.5 * sorted[((sorted.len() - 1) as f64 * 0.95) as usize];
        if high <= 0.0 {
            continue;
        }
        for k in 0..s.len().saturating_sub(1) {
            let dj = s[k + 1] - s[k];
            if dj.abs() < 0.5 * cycle_m {
                continue;
            }
            jumps += 1;
            let q = dj.abs() / cycle_m;
            off += (q - q.round()).abs();
            let (r0, r1) = (
                rows[k].saturating_sub(2),
                (rows[k + 1] + 2).min(p.rows() - 1),
            );
            if acc[r0..=r1].iter().any(|&a| a >= high) {
                hits += 1;
            }
        }
    }
    Some(StepSignature {
        jumps,
        at_high_accel: hits as f64 / jumps.max(1) as f64,
        off_cycle: off / jumps.max(1) as f64,
    })
}

/// Travel lost inside a stretch of world x.
#[derive(Debug, Clone, PartialEq)]
pub struct RegionSignature {
    /// Start of the stretch, world x, m.
    pub start_m: f64,
    /// End of the stretch, world x, m.
    pub end_m: f64,
    /// Travel lost per metre inside (chord lengths), and its significance in noise sigmas.
    pub loss_per_m: f64,
    /// Significance of `loss_per_m`, in noise sigmas.
    pub sigma: f64,
    /// Loss per metre outside the region.
    pub outside_per_m: f64,
}

impl RegionSignature {
    /// Whether the stretch names floor bumps in a region: loss over 8 sigmas and over
    /// 3 mm per metre, with less than 30 % of that outside.
    pub fn clear(&self) -> bool {
        self.sigma > 8.0
            && self.loss_per_m > 0.003
            && self.outside_per_m.abs() < 0.3 * self.loss_per_m
    }
}

/// Per driven wheel with an encoder, compares the travel its encoder reports with the
/// travel its contact made according to the measured poses (body motion over ~0.3 s
/// segments, through the wheel's rolling row), binned by the wheel's world x, and returns
/// the stretch with the most significant loss. Measured heading enters directly, so the
/// heading drift a bump makes in dead reckoning does not blur the signature.
pub fn region_loss(ev: &Evaluator, model: &Model) -> Option<RegionSignature> {
    let p = ev.p;
    // The contact travel the model predicts (the final model: slip it found is not a
    // floor), against what the measured poses say.
    let path = ev.path_per_row(model);
    let ps = &p.poses;
    if ps.len() < 40 {
        return None;
    }
    let dur = p.t[ps.row[ps.len() - 1]] - p.t[ps.row[0]];
    let step = ((0.3 * ps.len() as f64 / dur.max(fitkit::MIN_DT_S)).round() as usize).max(1);
    // (world x of the wheel, deficit m, wheel travel m)
    let mut seg: Vec<(f64, f64, f64)> = Vec::new();
    for (i, w) in p.robot.wheels.iter().enumerate() {
        let Some(enc) = &p.wheels[i].enc_rad else {
            continue;
        };
        if !w.driven {
            continue;
        }
        let row = w.rolling_row();
        let (bx, by) = w.position();
        let r = w.radius_m * w.gamma_rad.cos();
        let mut j = 0;
        while j + step < ps.len() {
            let (a, b) = (j, j + step);
            j = b;
            // Segments across a gap in the pose stream are not straight enough to resolve
            // through one mid heading.
            if p.t[ps.row[b]] - p.t[ps.row[a]] > 0.6 {
                continue;
            }
            let th = 0.5 * (ps.theta[a] + ps.theta[b]);
            let (sn, cs) = th.sin_cos();
            let (dx, dy) = (ps.x[b] - ps.x[a], ps.y[b] - ps.y[a]);
            let d = [
                cs * dx + sn * dy,
                -sn * dx + cs * dy,
                ps.theta[b] - ps.theta[a],
            ];
            let implied = row[0] * d[0] + row[1] * d[1] + row[2] * d[2];
            let (mut mx, mut my, mut mw) = (0.0, 0.0, 0.0);
            for st in &path.step[ps.row[a]..ps.row[b].min(path.step.len())] {
                mx += st.vx;
                my += st.vy;
                mw += st.omega;
            }
            let travel = row[0] * mx + row[1] * my + row[2] * mw;
            if travel.abs() < 1e-4 || r <= 0.0 {
                continue;
            }
            // Cruise only: slip in launches and stops loses travel wherever the robot
            // happens to accelerate, which is not a property of the floor.
            let (ra, rb) = (ps.row[a], ps.row[b]);
            let rm = (ra + rb) / 2;
            let v1 = (enc[rm] - enc[ra]) / (p.t[rm] - p.t[ra]).max(fitkit::MIN_DT_S);
            let v2 = (enc[rb] - enc[rm]) / (p.t[rb] - p.t[rm]).max(fitkit::MIN_DT_S);
            if (v2 - v1).abs() > 0.2 * v1.abs().max(v2.abs()) {
                continue;
            }
            let wx = 0.5 * (ps.x[a] + ps.x[b]) + cs * bx - sn * by;
            seg.push((wx, (travel - implied) * travel.signum(), travel.abs()));
        }
    }
    if seg.len() < 40 {
        return None;
    }
    // Noise of one segment's deficit, robustly (the region is a minority of segments).
    let mut dev: Vec<f64> = seg.iter().map(|s| s.1).collect();
    dev.sort_by(|a, b| a.total_cmp(b));
    let med = dev[dev.len() / 2];
    let mut mad: Vec<f64> = dev.iter().map(|d| (d - med).abs()).collect();
    mad.sort_by(|a, b| a.total_cmp(b));
    let sigma = (1.4826 * mad[mad.len() / 2]).max(1e-6);
    let (lo, hi) = seg
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), s| {
            (l.min(s.0), h.max(s.0))
        });
    let bin = 0.05;
    let nb = (((hi - lo) / bin).ceil() as usize).clamp(1, 400);
    let mut loss = vec![0.0; nb];
    let mut dist = vec![0.0; nb];
    let mut count = vec![0usize; nb];
    for (x, l, d) in &seg {
        let b = (((x - lo) / bin) as usize).min(nb - 1);
        loss[b] += l;
        dist[b] += d;
        count[b] += 1;
    }
    let (tl, td, tc): (f64, f64, usize) = (loss.iter().sum(), dist.iter().sum(), seg.len());
    let mut best: Option<(f64, usize, usize)> = None;
    for i in 0..nb {
        let (mut l, mut d, mut c) = (0.0, 0.0, 0usize);
        for k in i..nb {
            l += loss[k];
            d += dist[k];
            c += count[k];
            // A region is wider than a few segments (one bad segment is not a floor).
            if c < 10 || k - i < 3 || tc - c < 10 || d <= 0.0 {
                continue;
            }
            let z = l / (sigma * (c as f64).sqrt());
            let out_d = td - d;
            let out_rate = if out_d > 0.0 { (tl - l) / out_d } else { 0.0 };
            // Contrast with the outside: a uniform loss (or a diameter error) is not a region.
            let score = z - ((tl - l) / (sigma * ((tc - c) as f64).sqrt())).abs();
            if l / d > 2.0 * out_rate.abs() && best.is_none_or(|b| score > b.0) {
                best = Some((score, i, k));
            }
        }
    }
    let (_, i, k) = best?;
    let (l, d, c): (f64, f64, usize) = (
        loss[i..=k].iter().sum(),
        dist[i..=k].iter().sum(),
        count[i..=k].iter().sum(),
    );
    let out_d = td - d;
    Some(RegionSignature {
        start_m: lo + i as f64 * bin,
        end_m: lo + (k + 1) as f64 * bin,
        loss_per_m: l / d,
        sigma: l / (sigma * (c as f64).sqrt()),
        outside_per_m: if out_d > 0.0 { (tl - l) / out_d } else { 0.0 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    #[test]
    fn drift_ratio_tells_noise_from_drift() {
        // 60 s at 30 Hz. White noise: the change over 8 s and over 2 s both have variance
        // 2 sigma^2 (ratio 1). AR(1) with rho 0.97 (correlation ~1.1 s): 2 sigma^2 (1 -
        // rho^240) / (2 sigma^2 (1 - rho^60)) = 1.19. A random walk: 8 / 2 = 4. A linear
        // drift: (8 / 2)^2 = 16.
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let n = Normal::new(0.0, 1.0).unwrap();
        let t: Vec<f64> = (0..1800).map(|k| k as f64 / 30.0).collect();
        let white: Vec<f64> = t.iter().map(|_| n.sample(&mut rng)).collect();
        let mut ar = vec![0.0; t.len()];
        let mut walk = vec![0.0; t.len()];
        for k in 1..t.len() {
            ar[k] = 0.97 * ar[k - 1] + (1.0f64 - 0.97 * 0.97).sqrt() * n.sample(&mut rng);
            walk[k] = walk[k - 1] + n.sample(&mut rng);
        }
        let line: Vec<f64> = t.iter().map(|x| 0.01 * x).collect();
        let r = |s: &[f64]| drift_ratio(&t, s).unwrap();
        assert!((r(&white) - 1.0).abs() < 0.15, "{}", r(&white));
        assert!((r(&ar) - 1.19).abs() < 0.4, "{}", r(&ar));
        assert!(r(&ar) < STATIONARY_RATIO);
        assert!((r(&walk) - 4.0).abs() < 1.5, "{}", r(&walk));
        assert!((r(&line) - 16.0).abs() < 0.5, "{}", r(&line));
    }
}
