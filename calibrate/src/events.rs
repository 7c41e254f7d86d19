//! Events one geometry cannot explain, found in a first fit's dead reckoning
//! ([`detect_events`]): a slip (the heading discrepancy between odometry and motion
//! capture steps and stays) or a clock leading for a moment (it steps and comes back).
//! They are reported and kept out of the fit. The [`Event`] record is
//! [`series`](crate::series)'s, since reading a recording reports glitches and
//! pose jumps as events too.

use crate::objective::HUBER_K;
use crate::series::{Anchor, Event, Path, Series};
use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::robot::Robot;

/// Least heading step (rad) across [`EVENT_WINDOW_S`] reported as a slip.
pub const EVENT_MIN_RAD: f64 = 0.04;
/// ... and at least this many robust sigmas of the recording's discrepancies.
pub const EVENT_SIGMAS: f64 = 8.0;
/// Window over which encoders and motion capture are compared for events, s.
pub const EVENT_WINDOW_S: f64 = 3.0;
/// Time on either side of an event window whose mean discrepancy sets the step, s.
pub const EVENT_GUARD_S: f64 = 2.0;
/// A step must also exceed this fraction of the heading turned in its window (a geometry
/// error grows with the turn: 2 % is well beyond any fitted wheelbase's error).
pub const EVENT_PER_TURN: f64 = 0.02;
/// Least transient heading discrepancy (rad) reported as a clock leading for a moment
/// (0.1 s at 1 rad/s).
pub const EVENT_TRANSIENT_RAD: f64 = 0.08;
/// A slip's span within its window: the discrepancy has left the level before it by more
/// than this many sample-to-sample noise sigmas (or [`SLIP_BAND_SHARE`] of the step) and
/// not yet settled within as much of the level after it.
pub const SLIP_BAND_SIGMAS: f64 = 4.0;
/// ... or this share of the slip's step, when larger.
pub const SLIP_BAND_SHARE: f64 = 0.05;
/// Dead reckoning restarts after a slip from the heading the samples of this long after
/// it give, s (the odometry's turn over it taken off): their mean, not one sample's noise.
pub const ANCHOR_WINDOW_S: f64 = 0.25;

/// 1.4826 x the median absolute residual (a robust standard deviation).
pub(super) fn robust_sigma(r: &[f64]) -> f64 {
    let mut a: Vec<f64> = r
        .iter()
        .map(|v| v.abs())
        .filter(|v| v.is_finite())
        .collect();
    if a.is_empty() {
        return f64::NAN;
    }
    a.sort_by(|x, y| x.total_cmp(y));
    1.4826 * a[a.len() / 2]
}

/// Heading discrepancies (odometry minus motion capture) over [`EVENT_WINDOW_S`] that no
/// geometry explains: reported, and kept out of the fit (a slip restarts dead reckoning
/// from the measured pose after it; a clock lead's samples are not compared).
///
/// The phases: the discrepancy along the recording ([`Discrepancy::of`]); its step and
/// largest transient across each window, less what a geometry error makes of them
/// ([`Discrepancy::steps`]); the windows that stand out ([`Discrepancy::find`]); pairs
/// of opposite steps merged into clock leads ([`merge_opposite_steps`]); then the
/// events reported and a slip's samples kept out ([`Discrepancy::report`]).
pub(super) fn detect_events(robot: &Robot, s: &mut Series) -> Vec<Event> {
    let Ok(kin) = Kinematics::<f64>::new(robot, &Corrections::None) else {
        return vec![];
    };
    let mut path = Path::default();
    if !s.path(robot, &kin, &mut path) {
        return vec![];
    }
    let d = Discrepancy::of(s, &path);
    let steps = d.steps(s);
    let mut found = d.find(&steps);
    found.sort_by_key(|f| f.0);
    let merged = merge_opposite_steps(&d.t, &found);
    d.report(s, &path, &steps, merged)
}

/// One recording's heading discrepancy at its pose samples, and the windows the events
/// are looked for in.
struct Discrepancy {
    /// Per pose sample: its time (s).
    t: Vec<f64>,
    /// Per pose sample: the heading turned by odometry less that measured since the
    /// first (rad).
    e: Vec<f64>,
    /// Per pose sample: the measured distance driven since the first (m).
    dist: Vec<f64>,
    /// Per pose sample: the last sample of the window of [`EVENT_WINDOW_S`] from it.
    end: Vec<usize>,
    /// The times never decrease (samples are found by bisection).
    ordered: bool,
}

/// Per window, what the discrepancy does across it ([`Discrepancy::steps`]).
struct Steps {
    /// The step between the mean levels before and after the window, less what the
    /// regressed geometry error makes of it.
    step: Vec<f64>,
    /// The largest departure inside the window from the line between those levels.
    transient: Vec<f64>,
    /// The heading measured turned across the window (rad).
    turned: Vec<f64>,
    /// The geometry error regressed out: per radian turned and per metre driven.
    coef: (f64, f64),
}

impl Discrepancy {
    /// The discrepancy along `s` dead-reckoned as `path`, and each sample's window end.
    fn of(s: &Series, path: &Path) -> Discrepancy {
        let n = s.pose_row.len();
        let e: Vec<f64> = (0..n)
            .map(|j| (path.th[s.pose_row[j]] - path.th[s.pose_row[0]]) - (s.pth[j] - s.pth[0]))
            .collect();
        let t: Vec<f64> = (0..n).map(|j| s.t[s.pose_row[j]]).collect();
        // Window ends.
        let mut end = vec![n - 1; n];
        let mut k = 0;
        for (j, e_j) in end.iter_mut().enumerate() {
            k = k.max(j);
            while k + 1 < n && t[k] - t[j] < EVENT_WINDOW_S {
                k += 1;
            }
            *e_j = k;
        }
        let mut dist = vec![0.0; n];
        for j in 1..n {
            dist[j] = dist[j - 1] + (s.px[j] - s.px[j - 1]).hypot(s.py[j] - s.py[j - 1]);
        }
        let ordered = (1..n).all(|k| t[k - 1] <= t[k]);
        Discrepancy {
            t,
            e,
            dist,
            end,
            ordered,
        }
    }

    /// The first sample at or after `t0`: by bisection when the times never decrease
    /// (the same sample as the scan, which is quadratic in the samples over the
    /// recording).
    fn first_at(&self, t0: f64) -> usize {
        let (t, n) = (&self.t, self.t.len());
        if self.ordered && !t0.is_nan() {
            let (mut lo, mut hi) = (0, n);
            while lo < hi {
                let mid = (lo + hi) / 2;
                if t[mid] < t0 {
                    lo = mid + 1;
                } else {
                    hi = mid;
                }
            }
            lo.min(n - 1)
        } else {
            (0..n).find(|&k| t[k] >= t0).unwrap_or(n - 1)
        }
    }

    /// Per window, the step and the transient ([`Steps`]). The mean discrepancy over
    /// [`EVENT_GUARD_S`] before each window and after it: a slip is a step that stays;
    /// one clock leading the other for a moment is a transient inside the window that
    /// the means on either side do not see. What a geometry error makes of the same step
    /// (a wheelbase error grows with the heading turned, a diameter ratio with the
    /// distance driven) is regressed out (robustly, [`geometry_coef`]) before a step
    /// counts, so a geometry the event itself bent in the first fit does not hide it.
    fn steps(&self, s: &Series) -> Steps {
        let (t, e, end) = (&self.t, &self.e, &self.end);
        let n = t.len();
        let mut pre = vec![0.0; n + 1];
        for j in 0..n {
            pre[j + 1] = pre[j] + e[j];
        }
        let (mut pth_pre, mut dist_pre) = (vec![0.0; n + 1], vec![0.0; n + 1]);
        for j in 0..n {
            pth_pre[j + 1] = pth_pre[j] + s.pth[j];
            dist_pre[j + 1] = dist_pre[j] + self.dist[j];
        }
        let mean_of = |v: &[f64], a: usize, b: usize| (v[b + 1] - v[a]) / (b + 1 - a) as f64;
        let mut reg = vec![(0.0, 0.0); n];
        let mut step = vec![0.0; n];
        let mut transient = vec![0.0; n];
        let mut turned = vec![0.0; n];
        for j in 0..n {
            let b = end[j];
            let a0 = self.first_at(t[j] - EVENT_GUARD_S);
            let b1 = self.first_at(t[b] + EVENT_GUARD_S).max(b);
            let (m0, m1) = (mean_of(&pre, a0, j), mean_of(&pre, b, b1));
            step[j] = m1 - m0;
            reg[j] = (
                mean_of(&pth_pre, b, b1) - mean_of(&pth_pre, a0, j),
                mean_of(&dist_pre, b, b1) - mean_of(&dist_pre, a0, j),
            );
            transient[j] = (j..=b)
                .map(|k| {
                    e[k] - m0 - (m1 - m0) * (t[k] - t[j]) / (t[b] - t[j]).max(fitkit::MIN_DT_S)
                })
                .fold(0.0, |acc: f64, v| if v.abs() > acc.abs() { v } else { acc });
            turned[j] = (s.pth[b] - s.pth[j]).abs();
        }
        let coef = geometry_coef(&step, &reg);
        for j in 0..n {
            step[j] -= coef.0 * reg[j].0 + coef.1 * reg[j].1;
        }
        Steps {
            step,
            transient,
            turned,
            coef,
        }
    }

    /// The windows whose step (a slip: over [`EVENT_MIN_RAD`], [`EVENT_SIGMAS`] robust
    /// sigmas and [`EVENT_PER_TURN`] of the turn) or transient (a time lead: over
    /// [`EVENT_TRANSIENT_RAD`]) stands out, largest first, none overlapping another.
    fn find(&self, w: &Steps) -> Vec<Found> {
        let (n, end) = (self.t.len(), &self.end);
        let sigma = robust_sigma(&w.step);
        let thr = |j: usize| {
            EVENT_MIN_RAD
                .max(EVENT_SIGMAS * sigma)
                .max(EVENT_PER_TURN * w.turned[j])
        };
        let mut found: Vec<Found> = vec![];
        for (vals, kind, limit) in [
            (&w.step, "slip", None),
            (&w.transient, "time_lead", Some(EVENT_TRANSIENT_RAD)),
        ] {
            let mut used = vec![false; n];
            for f in &found {
                for u in used.iter_mut().take(f.1 + 1).skip(f.0) {
                    *u = true;
                }
            }
            loop {
                let best = (0..n)
                    .filter(|&j| !used[j])
                    .max_by(|&a, &b| vals[a].abs().total_cmp(&vals[b].abs()));
                let Some(j) = best.filter(|&j| vals[j].abs() > limit.unwrap_or_else(|| thr(j)))
                else {
                    break;
                };
                let (a, b) = (j, end[j]);
                for (u, w) in used.iter_mut().enumerate() {
                    if end[u] >= a && u <= b {
                        *w = true;
                    }
                }
                found.push((a, b, vals[j], kind));
            }
        }
        found
    }

    /// The events, in the order of their windows ([`coalesce`]d), with what is done
    /// about each: a slip keeps out of the fit only the samples where it happens
    /// ([`slip_span`]) and dead reckoning restarts after it (an [`Anchor`]); a time lead
    /// is reported only.
    fn report(&self, s: &mut Series, path: &Path, w: &Steps, merged: Vec<Found>) -> Vec<Event> {
        let (t, n) = (&self.t, self.t.len());
        // The discrepancy less what the regressed geometry error makes of it along the
        // recording, and its sample-to-sample noise: where within a slip's window it
        // moves.
        let e_geo: Vec<f64> = (0..n)
            .map(|j| self.e[j] - w.coef.0 * s.pth[j] - w.coef.1 * self.dist[j])
            .collect();
        let d: Vec<f64> = e_geo.windows(2).map(|w| w[1] - w[0]).collect();
        let noise = robust_sigma(&d) / std::f64::consts::SQRT_2;
        let mut out = vec![];
        let mut skip: Vec<(usize, usize)> = vec![];
        for (a, b, h, kind) in coalesce(merged) {
            let slip = kind == "slip";
            // A slip keeps out only the samples where it happens, not its whole window
            // (dropping 3 s of a square's data moved its wheel size by a sigma).
            let (a, b) = if slip {
                let a0 = self.first_at(t[a] - EVENT_GUARD_S).min(a);
                let b1 = self.first_at(t[b] + EVENT_GUARD_S).max(b);
                slip_span(&e_geo, (a0, a), (b, b1), noise)
            } else {
                (a, b)
            };
            out.push(Event {
                recording: s.name.clone(),
                kind,
                t_s: t[a] - s.t[0],
                duration_s: t[b] - t[a],
                heading_rad: h,
                position_m: 0.0,
                handled: if slip {
                    format!("dead reckoning restarts from the measured pose after it (its heading averaged over the next {ANCHOR_WINDOW_S} s)")
                } else {
                    "reported only: the heading it leads by is given back when the turn ends".into()
                },
            });
            if slip {
                skip.push((a, b));
            }
            if slip && !s.anchors.iter().any(|x| x.sample == b) {
                // The heading dead reckoning restarts from: the measured heading at b less
                // the odometry's turn since, averaged over the samples of the next
                // ANCHOR_WINDOW_S (one sample's noise would tilt the rest of the
                // recording).
                let (mut sum, mut m) = (0.0, 0usize);
                for k in (b..n).take_while(|&k| t[k] - t[b] <= ANCHOR_WINDOW_S) {
                    sum += s.pth[k] - (path.th[s.pose_row[k]] - path.th[s.pose_row[b]]);
                    m += 1;
                }
                s.anchors.push(Anchor {
                    sample: b,
                    pose: [s.px[b], s.py[b], sum / m.max(1) as f64],
                });
            }
        }
        s.anchors.sort_by_key(|x| x.sample);
        s.samples
            .retain(|&j| !skip.iter().any(|&(a, b)| j > a && j < b));
        out
    }
}

/// The geometry error in the windows' steps: Huber-weighted least squares of `step` on
/// the two regressors `reg` (the heading turned, the distance driven), a few passes.
fn geometry_coef(step: &[f64], reg: &[(f64, f64)]) -> (f64, f64) {
    let n = step.len();
    let mut coef = (0.0, 0.0);
    for _ in 0..5 {
        let res: Vec<f64> = (0..n)
            .map(|j| step[j] - coef.0 * reg[j].0 - coef.1 * reg[j].1)
            .collect();
        let c = HUBER_K * robust_sigma(&res).max(1e-6);
        let (mut a11, mut a12, mut a22, mut b1, mut b2) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for j in 0..n {
            let w = if res[j].abs() <= c {
                1.0
            } else {
                c / res[j].abs()
            };
            let (x, y) = reg[j];
            a11 += w * x * x;
            a12 += w * x * y;
            a22 += w * y * y;
            b1 += w * x * step[j];
            b2 += w * y * step[j];
        }
        let det = a11 * a22 - a12 * a12;
        if det.abs() < 1e-12 * (a11 * a22).max(1e-300) {
            break;
        }
        coef = ((a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det);
    }
    coef
}

/// Two steps of opposite sign that undo each other within a few seconds: a clock leading
/// the other through a turn, not a slip; they become one `time_lead` (with the
/// transients between them, which belong to the same turn). `found` sorted by first
/// sample; `t` the samples' times.
fn merge_opposite_steps(t: &[f64], found: &[Found]) -> Vec<Found> {
    let mut merged: Vec<Found> = vec![];
    let mut i = 0;
    while i < found.len() {
        let f = found[i];
        if f.3 == "slip" {
            let next = (i + 1..found.len()).find(|&j| found[j].3 == "slip");
            if let Some(j) = next {
                let g = found[j];
                if t[g.0] - t[f.1] < 2.0 * EVENT_WINDOW_S
                    && f.2 * g.2 < 0.0
                    && (f.2 + g.2).abs() < 0.3 * f.2.abs().max(g.2.abs())
                {
                    let h = found[i..=j].iter().map(|x| x.2).fold(0.0, |acc: f64, v| {
                        if v.abs() > acc.abs() {
                            v
                        } else {
                            acc
                        }
                    });
                    merged.push((f.0, g.1.max(f.1), h, "time_lead"));
                    i = j + 1;
                    continue;
                }
            }
        }
        merged.push(f);
        i += 1;
    }
    merged
}

/// Where a slip found in the window `(before.1, after.0)` happens: the last sample of the
/// window still within the band of the discrepancy's mean level over `before`, and the
/// first from which it stays within the band of the level over `after` (the band:
/// [`SLIP_BAND_SIGMAS`] x `noise`, or [`SLIP_BAND_SHARE`] of the step). The whole window
/// when the levels are not finite or the span would be empty.
fn slip_span(
    e: &[f64],
    before: (usize, usize),
    after: (usize, usize),
    noise: f64,
) -> (usize, usize) {
    let (a, b) = (before.1, after.0);
    let level = |(i, j): (usize, usize)| e[i..=j].iter().sum::<f64>() / (j + 1 - i) as f64;
    let (m0, m1) = (level(before), level(after));
    let band = (SLIP_BAND_SIGMAS * noise).max(SLIP_BAND_SHARE * (m1 - m0).abs());
    if !band.is_finite() || !m0.is_finite() || !m1.is_finite() || b <= a + 1 {
        return (a, b);
    }
    let start = (a..=b)
        .find(|&k| (e[k] - m0).abs() > band)
        .map_or(a, |k| k.saturating_sub(1).max(a));
    let end = (a..=b)
        .rev()
        .find(|&k| (e[k] - m1).abs() > band)
        .map_or(b, |k| (k + 1).min(b));
    if start < end {
        (start, end)
    } else {
        (a, b)
    }
}

/// A found event: first and last sample of its window, its heading, its kind.
type Found = (usize, usize, f64, &'static str);

/// One report per stretch of time: a `time_lead` whose window starts before the previous
/// `time_lead`'s ends (a transient and a pair of opposite steps over the same turn) joins
/// it, with the union of their windows and the larger heading. A slip keeps its own window
/// (dead reckoning restarts after it). `events` sorted by their first sample.
fn coalesce(events: Vec<Found>) -> Vec<Found> {
    let mut out: Vec<Found> = Vec::with_capacity(events.len());
    for ev in events {
        if let Some(last) = out.last_mut() {
            if ev.3 == "time_lead" && last.3 == "time_lead" && ev.0 <= last.1 {
                last.1 = last.1.max(ev.1);
                if ev.2.abs() > last.2.abs() {
                    last.2 = ev.2;
                }
                continue;
            }
        }
        out.push(ev);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;
    use calib_core::odometry::Pose;
    use rand::SeedableRng;
    use rand_chacha::ChaCha8Rng;
    use rand_distr::{Distribution, Normal};

    /// 10,000 Gaussian residuals of sigma 3 mm, 1 % of them replaced by gross outliers
    /// (+-1 m, which alone put the RMS over 30 sigma), and non-finite values that are
    /// skipped. 1.4826 x the median |r| estimates sigma with a standard error of 1.17
    /// sigma / sqrt(n) = 1.2 %; the outliers move the median |r| to the 0.5 / 0.99
    /// quantile of |Z|, +0.9 %. Within 5 %: the bias plus over three standard errors.
    #[test]
    fn robust_sigma_ignores_gross_outliers() {
        let sigma = 0.003;
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let normal = Normal::new(0.0, sigma).unwrap();
        let mut r: Vec<f64> = (0..10_000).map(|_| normal.sample(&mut rng)).collect();
        for (i, v) in r.iter_mut().enumerate().filter(|(i, _)| i % 100 == 7) {
            *v = if i % 200 == 7 { 1.0 } else { -1.0 };
        }
        let rms = (r.iter().map(|v| v * v).sum::<f64>() / r.len() as f64).sqrt();
        assert!(rms > 30.0 * sigma, "the outliers are gross: rms {rms}");
        r.extend([f64::NAN, f64::INFINITY, f64::NEG_INFINITY]);
        let s = robust_sigma(&r);
        assert!((s / sigma - 1.0).abs() < 0.05, "robust sigma {s}");
        assert!(robust_sigma(&[]).is_nan());
        assert!(robust_sigma(&[f64::NAN]).is_nan());
    }

    /// A noise-free differential-drive recording (40 s at 50 Hz, poses dead-reckoned from
    /// the encoders with the robot itself), and the same with a slip planted at 20 s: the
    /// poses after it turned by 0.1 rad about the pose there (motion capture and odometry
    /// part for good). Clean, the heading discrepancy is rounding (1e-15 rad) against a
    /// 0.04 rad threshold: no event. With the slip: a `slip` found in a 3 s window that
    /// holds 20 s and reported where it happens, from the sample at 20 s to the next (one
    /// 50 Hz step; its span: [`slip_span`]), its size the planted step with the sign of
    /// odometry minus motion capture. The
    /// robust regression of the steps on the turned heading and the distance cannot take
    /// the step: the rows it shows in have Huber weights about 1e-5 against the others' 1,
    /// so 1 % is loose. Dead reckoning restarts at the span's end, from the heading
    /// measured there (averaged over [`ANCHOR_WINDOW_S`] with the odometry's turn taken
    /// off: noise-free, the measured heading to 1e-9 rad), and no sample inside the span
    /// is compared. The windows beside it see the same step in part (as a transient
    /// against their linear ramp, or through a guard interval reaching over it) and may
    /// report it again, smaller: every event stays within a window and a guard of 20 s.
    #[test]
    fn detect_events_finds_a_planted_slip_at_its_time_and_nothing_on_a_clean_run() {
        let robot = synth::robot("mobolab");
        let (rate, slip_t, slip) = (50.0, 20.0, 0.1f64);
        let clean = synth::recording(
            &robot,
            2000,
            rate,
            Pose::new(0.5, -0.3, 0.4),
            synth::wander(&robot),
        );
        let mut s = Series::new("clean", &robot, &clean).unwrap();
        assert!(detect_events(&robot, &mut s).is_empty());
        assert_eq!(s.anchors.iter().map(|a| a.sample).collect::<Vec<_>>(), [0]);

        let mut slipped = clean.clone();
        let k0 = (slip_t * rate) as usize;
        let (x0, y0) = (clean.x[k0].unwrap(), clean.y[k0].unwrap());
        let (sn, c) = slip.sin_cos();
        for k in k0 + 1..clean.len() {
            let (dx, dy) = (clean.x[k].unwrap() - x0, clean.y[k].unwrap() - y0);
            slipped.x[k] = Some(x0 + c * dx - sn * dy);
            slipped.y[k] = Some(y0 + sn * dx + c * dy);
            slipped.theta[k] = Some(clean.theta[k].unwrap() + slip);
        }
        let mut s = Series::new("slipped", &robot, &slipped).unwrap();
        let events = detect_events(&robot, &mut s);
        let near = EVENT_WINDOW_S + EVENT_GUARD_S;
        assert!(
            events.iter().all(|e| e.recording == "slipped"
                && e.t_s > slip_t - near
                && e.t_s + e.duration_s < slip_t + near),
            "{events:?}"
        );
        let full: Vec<&Event> = events
            .iter()
            .filter(|e| (e.heading_rad + slip).abs() < 0.01 * slip)
            .collect();
        assert_eq!(full.len(), 1, "{events:?}");
        let e = full[0];
        assert_eq!(e.kind, "slip");
        assert!(e.t_s > slip_t - EVENT_WINDOW_S && e.t_s <= slip_t, "{e:?}");
        assert!(e.duration_s <= 1.0 / rate + 1e-9, "{e:?}");
        // Its span's end is an anchor, and no sample inside the span is compared.
        let at = |j: usize| s.t[s.pose_row[j]] - s.t[0];
        let anchor = *s
            .anchors
            .iter()
            .find(|a| (at(a.sample) - (e.t_s + e.duration_s)).abs() < 1e-9)
            .expect("an anchor at the slip's end");
        let b = anchor.sample;
        assert!(at(b) > slip_t);
        assert!((anchor.pose[2] - s.pth[b]).abs() < 1e-9, "{anchor:?}");
        assert!(!s
            .samples
            .iter()
            .any(|&j| at(j) > e.t_s && at(j) < e.t_s + e.duration_s));
    }

    /// Overlapping or touching time leads become one (the union of the windows, the
    /// larger heading: exact), apart ones and slips stay as they are.
    #[test]
    fn overlapping_time_leads_are_one_event() {
        let found = vec![
            (0, 10, -0.06, "slip"),
            (245, 306, -0.107, "time_lead"),
            (249, 412, 0.145, "time_lead"),
            (412, 420, 0.02, "time_lead"),
            (590, 756, 0.095, "time_lead"),
            (700, 720, 0.3, "slip"),
        ];
        assert_eq!(
            coalesce(found),
            vec![
                (0, 10, -0.06, "slip"),
                (245, 420, 0.145, "time_lead"),
                (590, 756, 0.095, "time_lead"),
                (700, 720, 0.3, "slip"),
            ]
        );
    }
}
