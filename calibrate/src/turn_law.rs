//! How a robot with a left and a right side turns: the turn-radius law ([`TurnLaw`]: the
//! separation widening from a turn in place to a wide arc, the ICRs' longitudinal
//! offset), each row's turn ratio rho ([`turn_ratio`]: 1 in place, 0 straight) and the
//! sides' stepping the law is applied through ([`Sides`]). Separate from the recording
//! because the stepping ([`step`](crate::step)) and the sensitivities need the
//! same law at every geometry.

use crate::params::{GeomKind, ParamSpec};
use calib_core::correction::{Corrections, LawRange};
use calib_core::kinematics::Kinematics;
use calib_core::robot::{Robot, RobotKind};
use serde::Serialize;

/// A turn-radius law (zero when the separation does not depend on the turn).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct TurnLaw {
    /// eb_arc / eb: relative growth of the separation from a turn in place to a wide arc.
    pub arc_rel: f64,
    /// Longitudinal ICR offset, m.
    pub icr_x_m: f64,
    /// Differential drive: growth of the wheels' effective size per m/s of their speed
    /// (0: the size does not depend on speed).
    pub speed_rel: f64,
    /// Differential drive: the ground's lag behind each side's speed, s (slip in
    /// proportion to acceleration: the ground moves at v - accel_slip_s dv/dt).
    pub accel_slip_s: f64,
    /// The motion the law was fitted on (the recordings' turn ratios, fastest side and
    /// largest change of speed): beyond it each term is held at its edge's value, as the
    /// board holds it. Unbounded while fitting (the recordings' own range changes
    /// nothing on them) and when no law is kept (then absent from the JSON).
    #[serde(skip_serializing_if = "LawRange::is_unbounded")]
    pub range: LawRange,
}

impl TurnLaw {
    /// The law in `values` (in `specs` order); each term the specs do not fit is
    /// `known`'s ([`CalOptions::turn_law`](crate::CalOptions::turn_law) and
    /// [`CalOptions::speed_law`](crate::CalOptions::speed_law), else 0).
    pub fn of(specs: &[ParamSpec], values: &[f64], known: TurnLaw) -> TurnLaw {
        let get = |k: GeomKind| specs.iter().position(|s| s.kind == k).map(|i| values[i]);
        let eb = get(GeomKind::Eb).unwrap_or(1.0);
        TurnLaw {
            arc_rel: get(GeomKind::EbArc).map_or(known.arc_rel, |a| a / eb),
            icr_x_m: get(GeomKind::IcrX).unwrap_or(known.icr_x_m),
            speed_rel: get(GeomKind::SpeedRel).unwrap_or(known.speed_rel),
            accel_slip_s: get(GeomKind::AccelSlip).unwrap_or(known.accel_slip_s),
            range: known.range,
        }
    }

    /// Any term at all (the range aside).
    pub fn has_terms(&self) -> bool {
        self.arc_rel != 0.0
            || self.icr_x_m != 0.0
            || self.speed_rel != 0.0
            || self.accel_slip_s != 0.0
    }

    /// The law applied only within `range` (unchanged without a term).
    pub fn within(self, range: LawRange) -> TurnLaw {
        if self.has_terms() {
            TurnLaw { range, ..self }
        } else {
            self
        }
    }
}

/// Time either side over which a recording's turn ratio rho is smoothed (s): one encoder
/// count makes a row's own ratio noisy at low speed (20 rows at 200 rows/s, 2 at 20).
const RHO_HALF_WINDOW_S: f64 = 0.1;

/// The median step between consecutive times, when positive.
pub(crate) fn median_step(t: &[f64]) -> Option<f64> {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    if d.is_empty() {
        return None;
    }
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, |a, b| a.total_cmp(b));
    (*m > 0.0).then_some(*m)
}

/// How a robot's sides move over one increment, from the counts at nominal radii,
/// smoothed as rho is ([`turn_ratio`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct SideMotion {
    /// The left and right sides' speeds, |v| (m/s).
    pub(crate) speed: [f64; 2],
    /// The change of each side's signed speed over the increment (m/s).
    pub(crate) dv: [f64; 2],
    /// The left and right sides' signed speeds (m/s) now and at the next increment: `dv`
    /// is their difference, and held within a law's speeds ([`Sides::step`]) it is the
    /// difference of the held speeds.
    pub(crate) v: [f64; 2],
    pub(crate) next: [f64; 2],
}

/// Per increment, rho = |d_r - d_l| / (|d_r| + |d_l|) of the sides' travel (nominal
/// radii), and the sides' motion ([`SideMotion`]: speeds d / dt and their change), both
/// smoothed over [`RHO_HALF_WINDOW_S`] either side (in rows at the median row step).
pub(super) fn turn_ratio(
    robot: &Robot,
    inc: &[Vec<f64>],
    t: &[f64],
) -> (Vec<f64>, Vec<SideMotion>) {
    let m = inc.len();
    let half = median_step(t).map_or(1, |dt| ((RHO_HALF_WINDOW_S / dt).round() as usize).max(1));
    let sides = Sides::new(robot);
    let (mut pl, mut pr) = (vec![0.0; m + 1], vec![0.0; m + 1]);
    for k in 0..m {
        let (l, r) = sides.travel(&inc[k]);
        pl[k + 1] = pl[k] + l;
        pr[k + 1] = pr[k] + r;
    }
    let (rho, v): (Vec<f64>, Vec<[f64; 2]>) = (0..m)
        .map(|k| {
            let (a, b) = (k.saturating_sub(half), (k + half + 1).min(m));
            let (dl, dr) = (pl[b] - pl[a], pr[b] - pr[a]);
            let den = dl.abs() + dr.abs();
            let rho = if den > 0.0 {
                (dr - dl).abs() / den
            } else {
                0.0
            };
            let dt = t[b.min(t.len() - 1)] - t[a];
            let v = if dt > 0.0 {
                [dl / dt, dr / dt]
            } else {
                [0.0; 2]
            };
            (rho, v)
        })
        .unzip();
    let motion = (0..m)
        .map(|k| {
            let next = v.get(k + 1).copied().unwrap_or(v[k]);
            SideMotion {
                speed: [v[k][0].abs(), v[k][1].abs()],
                dv: [next[0] - v[k][0], next[1] - v[k][1]],
                v: v[k],
                next,
            }
        })
        .collect();
    (rho, motion)
}

/// An omni robot's turn ratio per increment: rho = |omega| L / max(|v|, |omega| L) of
/// the nominal twist ([`calib_core::kinematics::turn_ratio`], L the wheels' mean
/// distance from the centre), each component summed over [`RHO_HALF_WINDOW_S`] either
/// side as [`turn_ratio`] sums the sides' travel. `None` when the nominal kinematics do
/// not solve.
pub(super) fn omni_turn_ratio(robot: &Robot, inc: &[Vec<f64>], t: &[f64]) -> Option<Vec<f64>> {
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    let lever = robot.mean_wheel_distance_m();
    let m = inc.len();
    let half = median_step(t).map_or(1, |dt| ((RHO_HALF_WINDOW_S / dt).round() as usize).max(1));
    let mut sum = vec![[0.0f64; 3]; m + 1];
    for k in 0..m {
        let tw = kin.forward(&inc[k]);
        sum[k + 1] = [sum[k][0] + tw.vx, sum[k][1] + tw.vy, sum[k][2] + tw.omega];
    }
    Some(
        (0..m)
            .map(|k| {
                let (a, b) = (sum[k.saturating_sub(half)], sum[(k + half + 1).min(m)]);
                calib_core::kinematics::turn_ratio(
                    (b[0] - a[0]).hypot(b[1] - a[1]),
                    (b[2] - a[2]) * lever,
                )
            })
            .collect(),
    )
}

/// A robot's sides as the stepping needs them, computed once per geometry (the wheels'
/// sides and the mean half separation take trigonometry): [`Sides::travel`] and
/// [`Sides::step`] give the same values, to the bit, as computing them per row.
#[derive(Debug, Clone)]
pub(crate) struct Sides {
    /// Per wheel: on the left side, and its radius (m).
    wheels: Vec<(bool, f64)>,
    /// Left and right wheel counts, at least 1.
    counts: (f64, f64),
    /// Mean |y| of the wheels (half the separation, E_b applied), m.
    half: f64,
    /// A skid-steer robot (the law's shape differs).
    skid: bool,
}

impl Sides {
    pub(crate) fn new(robot: &Robot) -> Sides {
        let wheels: Vec<(bool, f64)> = robot
            .wheels
            .iter()
            .map(|w| (w.is_left(), w.radius_m))
            .collect();
        let nl = wheels.iter().filter(|w| w.0).count() as f64;
        let nr = wheels.len() as f64 - nl;
        let half = robot
            .wheels
            .iter()
            .map(|w| w.position().1.abs())
            .sum::<f64>()
            / robot.wheels.len().max(1) as f64;
        Sides {
            wheels,
            counts: (f64::max(nl, 1.0), f64::max(nr, 1.0)),
            half,
            skid: robot.kind == RobotKind::SkidSteer,
        }
    }

    /// Share of the law's widening at turn ratio `rho`: a differential drive's turn slip
    /// ([`calib_core::kinematics::turn_law_share`]); a skid-steer robot's moving ICRs
    /// (1 - rho)^2, as measured on the simulator's independent tyres.
    #[inline]
    pub(crate) fn law_share(&self, rho: f64) -> f64 {
        if self.skid {
            (1.0 - rho).powi(2)
        } else {
            calib_core::kinematics::turn_law_share(rho)
        }
    }

    /// Mean travel of the left and the right wheels over one increment (m).
    #[inline]
    pub(crate) fn travel(&self, inc: &[f64]) -> (f64, f64) {
        let (mut l, mut r) = (0.0, 0.0);
        for (&(left, radius), d) in self.wheels.iter().zip(inc) {
            if left {
                l += radius * d;
            } else {
                r += radius * d;
            }
        }
        (l / self.counts.0, r / self.counts.1)
    }

    /// One step of a robot driven by its sides (skid-steer, or a differential drive with
    /// a law): each side's mean travel (grown by the speed law at the side's speed, less
    /// the acceleration law's lag times its change of speed), the separation (E_b
    /// applied) widened by the turn law at this turn ratio, the sideways speed of the ICR
    /// offset.
    #[inline]
    pub(crate) fn step(
        &self,
        law: &TurnLaw,
        rho: f64,
        side: SideMotion,
        inc: &[f64],
    ) -> calib_core::kinematics::Twist<f64> {
        let (mut l, mut r) = self.travel(inc);
        // Within the law's range: beyond it each term holds its edge's value.
        let g = &law.range;
        if law.speed_rel != 0.0 {
            let top = g.speed_max_m_s as f64;
            l *= 1.0 + law.speed_rel * side.speed[0].min(top);
            r *= 1.0 + law.speed_rel * side.speed[1].min(top);
        }
        if law.accel_slip_s != 0.0 {
            // The lag stops growing beyond the fitted speeds (the changes of the held
            // speeds: from rest to rest it still cancels).
            let top = g.speed_max_m_s as f64;
            let dv = |i: usize| {
                if top == f64::INFINITY {
                    side.dv[i]
                } else {
                    side.next[i].clamp(-top, top) - side.v[i].clamp(-top, top)
                }
            };
            l -= law.accel_slip_s * dv(0);
            r -= law.accel_slip_s * dv(1);
        }
        let rho = rho.clamp(g.rho_min as f64, g.rho_max as f64);
        let half = self.half * (1.0 + law.arc_rel * self.law_share(rho));
        let dth = (r - l) / (2.0 * half);
        calib_core::kinematics::Twist::new(0.5 * (l + r), -law.icr_x_m * dth, dth)
    }
}

/// How a recording turns: the side-travel difference |d_r - d_l| summed over all rows, over
/// the rows on arcs ([`ARC_RHO`]), and weighted by (1 - rho)^2 (what averages the E_b law
/// over the recording's turning).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Turning {
    pub(crate) all: f64,
    pub(crate) arcs: f64,
    pub(crate) arc_term: f64,
    /// The sides' travel |d_l| + |d_r|, m.
    pub(crate) travel: f64,
    /// The sides' travel weighted by their speed, sum |d| |v| (m^2/s): over `travel`,
    /// the recording's mean speed by distance.
    pub(crate) speed_term: f64,
}

impl Turning {
    /// The sums over every recording of `series` ([`Series::turning`](crate::Series)).
    pub(crate) fn of_all(series: &[crate::Series], robot: &Robot) -> Turning {
        series.iter().fold(Turning::default(), |a, s| {
            let t = s.turning(robot);
            Turning {
                all: a.all + t.all,
                arcs: a.arcs + t.arcs,
                arc_term: a.arc_term + t.arc_term,
                travel: a.travel + t.travel,
                speed_term: a.speed_term + t.speed_term,
            }
        })
    }
}

/// How far along a turn law's widening (0: a turn in place, 1: arcs) the one constant
/// E_b sits whose dead reckoning of `motion` stays closest to the law's own: the mean
/// squared position gap over every row, minimised by golden-section search on [0, 1].
/// No ground truth enters, so `motion` may be any log of the robot's driving. `base` has
/// the separation of a turn in place
/// ([`Calibration::law_base_robot`](crate::Calibration::law_base_robot)); the
/// law's other terms (a speed law) are kept on both sides.
pub(crate) fn closest_constant_share(
    base: &Robot,
    law: &TurnLaw,
    motion: &[crate::Series],
) -> Option<f64> {
    let constant = TurnLaw {
        arc_rel: 0.0,
        ..*law
    };
    closest_constant(base, law, motion, &constant, (0.0, 1.0), |r, share| {
        for w in r.wheels.iter_mut() {
            w.l_m *= 1.0 + law.arc_rel * share;
        }
    })
}

/// The speed law's counterpart of [`closest_constant_share`]: the speed (m/s, from 0 to
/// the fastest side's speed in `motion`) at which the law's wheel size, 1 + speed_rel v
/// times `base`'s (the size at standstill), dead-reckons `motion` closest to the law's
/// own. The law's other terms (a turn law) are kept on both sides.
pub(crate) fn closest_constant_speed(
    base: &Robot,
    law: &TurnLaw,
    motion: &[crate::Series],
) -> Option<f64> {
    let fastest = motion
        .iter()
        .flat_map(|s| s.motion.iter().flatten())
        .flat_map(|m| m.speed)
        .fold(0.0, f64::max);
    let constant = TurnLaw {
        speed_rel: 0.0,
        ..*law
    };
    closest_constant(base, law, motion, &constant, (0.0, fastest), |r, v| {
        for w in r.wheels.iter_mut() {
            w.radius_m *= 1.0 + law.speed_rel * v;
        }
    })
}

/// The value in `range` whose robot (`base` changed by `apply`), dead-reckoning `motion`
/// under `constant`, stays closest to `base` under `law`: the mean squared position gap
/// over every row, one smooth valley, minimised by golden-section search (the ends
/// themselves compared too). None when `motion` cannot be dead-reckoned.
fn closest_constant(
    base: &Robot,
    law: &TurnLaw,
    motion: &[crate::Series],
    constant: &TurnLaw,
    range: (f64, f64),
    apply: impl Fn(&mut Robot, f64),
) -> Option<f64> {
    use calib_core::correction::Corrections;
    use calib_core::kinematics::Kinematics;
    let kin = Kinematics::<f64>::new(base, &Corrections::None).ok()?;
    let mut target = Vec::new();
    for s in motion {
        let mut p = crate::Path::default();
        s.path_with(base, &kin, law, &mut p).then_some(())?;
        target.push(p);
    }
    let mut p = crate::Path::default();
    let mut gap = |x: f64| -> f64 {
        let mut r = base.clone();
        apply(&mut r, x);
        let Ok(kin) = Kinematics::<f64>::new(&r, &Corrections::None) else {
            return f64::INFINITY;
        };
        let (mut acc, mut n) = (0.0, 0usize);
        for (s, t) in motion.iter().zip(&target) {
            if !s.path_with(&r, &kin, constant, &mut p) {
                return f64::INFINITY;
            }
            for k in 0..t.x.len() {
                acc += (p.x[k] - t.x[k]).powi(2) + (p.y[k] - t.y[k]).powi(2);
            }
            n += t.x.len();
        }
        acc / n.max(1) as f64
    };
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = range;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (gap(c), gap(d));
    for _ in 0..40 {
        if fc <= fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = gap(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = gap(d);
        }
    }
    let (x, best) = if fc <= fd { (c, fc) } else { (d, fd) };
    [(range.0, gap(range.0)), (range.1, gap(range.1)), (x, best)]
        .into_iter()
        .min_by(|p, q| p.1.total_cmp(&q.1))
        .map(|p| p.0)
}

/// Turn ratios that count as arcs (rho = 1 is a turn in place, 0 a straight line).
pub const ARC_RHO: (f64, f64) = (0.1, 0.8);

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth;

    /// A 200 Hz clock (5 ms) whose stamps jitter: every third stamp late by 1.5 ms (steps
    /// 5, 6.5, 3.5 ms in turn), one row dropped (an 11.5 ms step) and one stamp repeated
    /// (a zero step). A third of the steps are exactly nominal and they hold the middle of
    /// the sorted steps, so the median is 5 ms; differences of times below 1 s carry
    /// rounding of about 1e-16 s, hence 1e-12.
    #[test]
    fn median_step_of_a_jittered_clock_is_the_nominal_step() {
        let (dt, late) = (0.005, 0.0015);
        let mut t: Vec<f64> = (0..60)
            .map(|k| k as f64 * dt + if k % 3 == 2 { late } else { 0.0 })
            .collect();
        t.remove(31);
        t.insert(40, t[39]);
        let m = median_step(&t).unwrap();
        assert!((m - dt).abs() < 1e-12, "median step {m}");
        // No step, or a clock that does not advance: no step to give.
        assert_eq!(median_step(&[1.0]), None);
        assert_eq!(median_step(&[2.0; 9]), None);
    }

    /// rho = |d_r - d_l| / (|d_r| + |d_l|) over the window (10 rows either side at 100
    /// Hz): straight rows are 0 and rows in place 1, exactly; a window of s straight rows
    /// (d_l = d_r = d) and p rows in place (d_l = -d, d_r = d), s >= p, gives
    /// 2 p d / (2 s d) = p / s; standing still, 0. Sums of equal increments round at
    /// 1e-16, hence 1e-12. Each side's speed is its travel over the window's time,
    /// r d / 0.01 s straight and in place alike (1e-9: the window's time is a difference
    /// of stamps); standing still, no motion.
    #[test]
    fn turn_ratio_is_zero_straight_one_in_place_and_the_window_share_between() {
        let robot = synth::robot("mobolab");
        let t: Vec<f64> = (0..101).map(|k| k as f64 * 0.01).collect();
        let d = 0.02; // rad per row
        let side = |w: &calib_core::robot::Wheel| if w.is_left() { -1.0 } else { 1.0 };
        // Rows 0..50 straight, 50..90 in place, 90..100 standing still.
        let inc: Vec<Vec<f64>> = (0..100)
            .map(|k| {
                robot
                    .wheels
                    .iter()
                    .map(|w| match k {
                        0..=49 => d,
                        50..=89 => side(w) * d,
                        _ => 0.0,
                    })
                    .collect()
            })
            .collect();
        let (rho, motion) = turn_ratio(&robot, &inc, &t);
        let speed: Vec<[f64; 2]> = motion.iter().map(|m| m.speed).collect();
        assert_eq!(rho.len(), 100);
        // Every wheel turns d per 10 ms row, straight or in place: each side at r d / 0.01 s.
        let v = robot.wheels[0].radius_m * d / 0.01;
        for k in (10..40).chain(60..80) {
            for side in speed[k] {
                assert!(
                    (side - v).abs() < 1e-9 * v,
                    "row {k}: {:?} against {v}",
                    speed[k]
                );
            }
        }
        assert!(
            rho[..40].iter().all(|&r| r == 0.0),
            "straight: {:?}",
            &rho[..40]
        );
        assert!(
            rho[60..80].iter().all(|&r| r == 1.0),
            "in place: {:?}",
            &rho[60..80]
        );
        // Row 45's window is rows 35..=55: 15 straight, 6 in place.
        assert!((rho[45] - 6.0 / 15.0).abs() < 1e-12, "rho {}", rho[45]);
        // Row 99's window is rows 89..=99: 1 in place, 10 still (the turn only).
        assert_eq!(rho[99], 1.0);
        let still: Vec<Vec<f64>> = vec![vec![0.0; 2]; 100];
        let (rho, motion) = turn_ratio(&robot, &still, &t);
        assert!(rho.iter().all(|&r| r == 0.0));
        assert!(motion
            .iter()
            .all(|m| m.speed == [0.0; 2] && m.dv == [0.0; 2]));
    }

    /// 20 s of `robot` with its left wheels at `left` rad/s and its right ones at
    /// `right`, from the origin (synthetic, noise-free).
    fn steady(robot: &Robot, left: f64, right: f64) -> crate::Series {
        let start = calib_core::odometry::Pose::new(0.0, 0.0, 0.0);
        let rec = synth::recording(robot, 1000, 50.0, start, |_| {
            robot
                .wheels
                .iter()
                .map(|w| if w.is_left() { left } else { right })
                .collect()
        });
        crate::Series::new("steady", robot, &rec).unwrap()
    }

    /// On a steady arc the law's separation is constant, E_b (1 + arc_rel (1 - rho^2)),
    /// so the constant closest to it is that share, 1 - rho^2 (rho = |d_r - d_l| /
    /// (|d_r| + |d_l|)): wheel rates 4 and 5.3 rad/s give rho 1.3 / 9.3 and a share of
    /// 0.980, rates 1 and 5 give rho 4 / 6 and 0.556. The law's turn ratio is smoothed
    /// over 0.1 s, so the first rows of a 20 s run see less of the turn: 1e-4 (measured
    /// 1e-5; the golden-section search itself narrows to 1e-8).
    /// Standing still, every constant dead-reckons alike and the in-place end (0) is
    /// kept.
    #[test]
    fn the_closest_constant_on_a_steady_arc_is_its_share_of_the_law() {
        let robot = synth::robot("mobolab");
        let law = TurnLaw {
            arc_rel: 0.04,
            ..TurnLaw::default()
        };
        let arc = |left: f64, right: f64| steady(&robot, left, right);
        for (left, right) in [(4.0, 5.3), (1.0, 5.0)] {
            let rho: f64 = (right - left) / (right + left);
            let share = closest_constant_share(&robot, &law, &[arc(left, right)]).unwrap();
            println!(
                "rates {left}, {right}: share {share:.5}, 1 - rho^2 {:.5}",
                1.0 - rho * rho
            );
            assert!(
                (share - (1.0 - rho * rho)).abs() < 1e-4,
                "rates {left}, {right}: share {share} against {}",
                1.0 - rho * rho
            );
        }
        let still = closest_constant_share(&robot, &law, &[arc(0.0, 0.0)]).unwrap();
        assert_eq!(still, 0.0);
    }

    /// The speed law's counterpart: on a straight run at one speed the law's wheel size
    /// is constant, 1 + speed_rel v, so the closest constant is the law's at that speed
    /// (wheel rates 5 rad/s on mobolab's 0.05 m wheels: 0.25 m/s; 2 rad/s: 0.1 m/s), to
    /// 1e-4 m/s as above. On an arc whose sides run at different speeds (4 and 5.3 rad/s)
    /// no constant keeps both the forward speed and the turn rate: the closest lies
    /// between the speed whose size keeps the one (0.237 m/s) and the other (0.465 m/s).
    /// Standing still, the lower end (0) is kept.
    #[test]
    fn the_closest_constant_wheel_size_on_a_steady_run_is_the_laws_at_its_speed() {
        let robot = synth::robot("mobolab");
        let law = TurnLaw {
            speed_rel: 0.1,
            ..TurnLaw::default()
        };
        let run = |left: f64, right: f64| steady(&robot, left, right);
        let r = robot.wheels[0].radius_m;
        for rate in [5.0, 2.0] {
            let v = closest_constant_speed(&robot, &law, &[run(rate, rate)]).unwrap();
            println!("rate {rate}: speed {v:.6} m/s, wheel {:.6} m/s", r * rate);
            assert!(
                (v - r * rate).abs() < 1e-4,
                "rate {rate}: {v} against {}",
                r * rate
            );
        }
        // Sides at 4 and 5.3 rad/s: the law grows each side by its own speed, so the
        // size that keeps the forward speed (the sides' mean) and the size that keeps the
        // turn rate (their difference) differ; the closest constant lies between them.
        let (vl, vr) = (4.0 * r, 5.3 * r);
        let grow = |v: f64| 1.0 + 0.1 * v;
        let forward = ((grow(vl) * vl + grow(vr) * vr) / (vl + vr) - 1.0) / 0.1;
        let turn = ((grow(vr) * vr - grow(vl) * vl) / (vr - vl) - 1.0) / 0.1;
        let v = closest_constant_speed(&robot, &law, &[run(4.0, 5.3)]).unwrap();
        println!("rates 4, 5.3: speed {v:.6} m/s, forward {forward:.4}, turn {turn:.4}");
        assert!(v > forward && v < turn, "{v}");
        let still = closest_constant_speed(&robot, &law, &[run(0.0, 0.0)]).unwrap();
        assert_eq!(still, 0.0);
    }
}
