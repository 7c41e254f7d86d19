//! Per-wheel travel over short segments of time, three ways: what the encoder counted,
//! what the measured body motion asks of the wheel (nominal kinematics), and what was
//! commanded. The wiring and encoder-scale checks compare them.

use calib_core::correction::Corrections;
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::robot::Robot;
use fitkit::series::unwrap_angles;
use formats::recording::Recording;

/// Segments are about this long (s), as for the counts ratio.
pub const SEGMENT_S: f64 = 0.25;

/// Travel per segment and wheel (rad); NaN where a column is blank or absent.
pub(super) struct Segments {
    /// Encoder travel.
    pub enc: Vec<Vec<f64>>,
    /// Travel the measured body motion asks of the wheel.
    pub asked: Vec<Vec<f64>>,
    /// Commanded travel (the command held over each row).
    pub cmd: Vec<Vec<f64>>,
}

impl Segments {
    /// Sums over the segments where both series are finite: (sum a b, sum a a, sum b b,
    /// segments).
    pub fn dot(a: &[Vec<f64>], i: usize, b: &[Vec<f64>], j: usize) -> (f64, f64, f64, usize) {
        let (mut ab, mut aa, mut bb, mut n) = (0.0, 0.0, 0.0, 0);
        for (x, y) in a.iter().zip(b) {
            let (Some(&x), Some(&y)) = (x.get(i), y.get(j)) else {
                continue;
            };
            if x.is_finite() && y.is_finite() {
                ab += x * y;
                aa += x * x;
                bb += y * y;
                n += 1;
            }
        }
        (ab, aa, bb, n)
    }
}

/// A recording's pose rows with a finite time (row, x, y, theta), their headings
/// unwrapped, and the median interval between them (s): what the segment statistics walk.
/// `None` with fewer than 20 such rows or no positive median interval.
pub(super) type PoseTrack = (Vec<(usize, f64, f64, f64)>, Vec<f64>, f64);

/// See [`PoseTrack`].
pub(super) fn pose_track(rec: &Recording) -> Option<PoseTrack> {
    let rows: Vec<(usize, f64, f64, f64)> = rec
        .pose_rows()
        .filter(|r| r.0 < rec.t.len() && rec.t[r.0].is_finite())
        .collect();
    if rows.len() < 20 {
        return None;
    }
    let mut th: Vec<f64> = rows.iter().map(|r| r.3).collect();
    unwrap_angles(&mut th);
    let mut d: Vec<f64> = rows
        .windows(2)
        .map(|w| rec.t[w[1].0] - rec.t[w[0].0])
        .collect();
    let dt_med = super::odometry::median(&mut d);
    if dt_med.is_nan() || dt_med <= 0.0 {
        return None;
    }
    Some((rows, th, dt_med))
}

/// The segments of `rec`, between consecutive pose rows (steps across a gap longer than
/// 2.5 median pose intervals end a segment). `None` without enough poses.
pub(super) fn segments(robot: &Robot, rec: &Recording) -> Option<Segments> {
    let nw = robot.wheels.len();
    let rpc = robot.drive.rad_per_count().unwrap_or(f64::NAN);
    let kin = Kinematics::<f64>::new(robot, &Corrections::None).ok()?;
    if rec.wheels.len() != nw {
        return None;
    }
    let (rows, th, dt_med) = pose_track(rec)?;
    let mut out = Segments {
        enc: vec![],
        asked: vec![],
        cmd: vec![],
    };
    let (mut e, mut a, mut c) = (vec![0.0; nw], vec![0.0; nw], vec![0.0; nw]);
    let mut seg_t = 0.0;
    let flush = |e: &mut Vec<f64>, a: &mut Vec<f64>, c: &mut Vec<f64>, out: &mut Segments| {
        if a.iter().any(|x| *x != 0.0) || e.iter().any(|x| *x != 0.0 && x.is_finite()) {
            out.enc.push(e.clone());
            out.asked.push(a.clone());
            out.cmd.push(c.clone());
        }
        e.iter_mut().for_each(|x| *x = 0.0);
        a.iter_mut().for_each(|x| *x = 0.0);
        c.iter_mut().for_each(|x| *x = 0.0);
    };
    for j in 1..rows.len() {
        let (k0, k1) = (rows[j - 1].0, rows[j].0);
        let dt = rec.t[k1] - rec.t[k0];
        if !(dt > 0.0 && dt <= 2.5 * dt_med) {
            flush(&mut e, &mut a, &mut c, &mut out);
            seg_t = 0.0;
            continue;
        }
        let (dx, dy) = (rows[j].1 - rows[j - 1].1, rows[j].2 - rows[j - 1].2);
        let mid = 0.5 * (th[j] + th[j - 1]);
        let (cs, sn) = (mid.cos(), mid.sin());
        let tw = Twist::new(cs * dx + sn * dy, -sn * dx + cs * dy, th[j] - th[j - 1]);
        for i in 0..nw {
            let w = &rec.wheels[i];
            e[i] += match w
                .enc
                .as_ref()
                .and_then(|v| Some((*v.get(k0)?, *v.get(k1)?)))
            {
                Some((Some(p), Some(q))) => (q as f64 - p as f64) * rpc,
                _ => f64::NAN,
            };
            a[i] += kin.wheel_rate(i, &tw);
            c[i] += match &w.cmd {
                Some(v) => (k0..k1)
                    .map(|m| match v.get(m).copied().flatten() {
                        Some(x) => x * (rec.t[m + 1] - rec.t[m]),
                        None => f64::NAN,
                    })
                    .sum::<f64>(),
                None => f64::NAN,
            };
        }
        seg_t += dt;
        if seg_t >= SEGMENT_S {
            flush(&mut e, &mut a, &mut c, &mut out);
            seg_t = 0.0;
        }
    }
    Some(out)
}
