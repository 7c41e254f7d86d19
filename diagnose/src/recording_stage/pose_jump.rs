//! `pose_jump`: the pose stream jumping where the wheels say the body did not. Each pose
//! step is compared with the step the wheels give (nominal kinematics, turned into the
//! world by the measured heading): the innovation. A single sample off (a marker swap) is
//! an innovation and its opposite on the next step: the sample is blanked. A jump of the
//! pose frame that stays (a SLAM relocalisation) is one innovation whose offset persists
//! over the samples after it: the poses after it are re-aligned, either as a rigid move
//! of the frame (positions turn with the heading) or as a translation with a heading
//! offset, whichever makes the later steps agree with the wheels.

use super::artefact::{Artefact, Event, MAX_EVENTS};
use super::odometry::{body_steps, quantum, quantum_sd, robust_sd};
use calib_core::robot::Robot;
use fitkit::series::unwrap_angles;
use formats::recording::Recording;
use std::collections::BTreeMap;

/// An innovation is a candidate jump beyond this many of its robust sigmas (per x, y,
/// theta). On the controls (docs/diagnose.md) the largest is below half of it.
pub const JUMP_Z: f64 = 10.0;
/// Samples on each side over which a jump's persistence and size are measured.
pub const JUMP_WINDOW: usize = 10;

struct Innov {
    q: [Vec<f64>; 3],
    /// Per step, the wheels' displacement in the world frame (by the measured heading).
    odo: Vec<(f64, f64)>,
}

type PoseRow = (usize, f64, f64, f64);
/// The pose rows, the innovations, which steps are usable, the robust sigmas.
type Innovations = (Vec<PoseRow>, Innov, Vec<bool>, Vec<f64>);

/// The pose rows, the innovations of each pose step against the wheels' step, which steps
/// are usable (no gap), and the innovations' robust sigmas (x, y, theta).
#[allow(clippy::needless_range_loop)] // x, y, theta and the steps indexed alike
fn innovations(robot: &Robot, rec: &Recording) -> Option<Innovations> {
    let steps = body_steps(robot, rec)?;
    let rows: Vec<PoseRow> = rec.pose_rows().collect();
    let m = rows.len();
    if m < 4 * JUMP_WINDOW {
        return None;
    }
    let mut th: Vec<f64> = rows.iter().map(|r| r.3).collect();
    unwrap_angles(&mut th);
    // Each channel's noise is at least its quantisation's (see `odometry::quantum`).
    let xs: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let ys: Vec<f64> = rows.iter().map(|r| r.2).collect();
    let floor = [
        quantum_sd(quantum(&xs)).max(1e-9),
        quantum_sd(quantum(&ys)).max(1e-9),
        quantum_sd(quantum(&th)).max(1e-9),
    ];
    let mut d: Vec<f64> = rows
        .windows(2)
        .map(|w| rec.t[w[1].0] - rec.t[w[0].0])
        .collect();
    let dt_med = super::odometry::median(&mut d);
    if dt_med.is_nan() || dt_med <= 0.0 {
        return None;
    }
    // Innovations per pose step j (from sample j - 1 to j).
    let mut inn = Innov {
        q: [vec![0.0; m], vec![0.0; m], vec![0.0; m]],
        odo: vec![(0.0, 0.0); m],
    };
    let mut usable = vec![false; m];
    let mut vel = vec![[f64::NAN; 3]; m];
    for j in 1..m {
        let (k0, k1) = (rows[j - 1].0, rows[j].0);
        let dt = rec.t[k1] - rec.t[k0];
        if !(dt > 0.0 && dt <= 2.5 * dt_med) {
            continue;
        }
        let (mut x, mut y, mut h) = (0.0, 0.0, th[j - 1]);
        for s in steps.get(k0 + 1..=k1).unwrap_or(&[]) {
            let mid = h + 0.5 * s.omega;
            x += mid.cos() * s.vx - mid.sin() * s.vy;
            y += mid.sin() * s.vx + mid.cos() * s.vy;
            h += s.omega;
        }
        inn.q[0][j] = rows[j].1 - rows[j - 1].1 - x;
        inn.q[1][j] = rows[j].2 - rows[j - 1].2 - y;
        inn.q[2][j] = th[j] - th[j - 1] - (h - th[j - 1]);
        inn.odo[j] = (x, y);
        vel[j] = [x / dt, y / dt, (h - th[j - 1]) / dt];
        usable[j] = true;
    }
    // Poses late by tau against the wheels make each innovation follow the change of
    // velocity, q_j = -tau (v(t_j) - v(t_j-1)): a robot that starts turning at once
    // (the real squares, 44 ms late) would look like a heading jump. Tau is fitted
    // (innovations beyond JUMP_Z left out, channels weighted by their robust sigma) and
    // taken out; the clock stage fits the offset properly afterwards.
    let s0: Vec<f64> = (0..3)
        .map(|c| {
            let v: Vec<f64> = (0..m).filter(|&j| usable[j]).map(|j| inn.q[c][j]).collect();
            robust_sd(&v).max(floor[c])
        })
        .collect();
    let dv = |j: usize, c: usize| -> f64 {
        if j == 0 || j + 1 >= m {
            return f64::NAN;
        }
        0.5 * (vel[j + 1][c] - vel[j - 1][c])
    };
    let (mut num, mut den) = (0.0, 0.0);
    for j in 1..m {
        if !usable[j] || (0..3).any(|c| inn.q[c][j].abs() / s0[c] > JUMP_Z) {
            continue;
        }
        for c in 0..3 {
            let d = dv(j, c);
            if d.is_finite() {
                let w = 1.0 / (s0[c] * s0[c]);
                num += w * inn.q[c][j] * d;
                den += w * d * d;
            }
        }
    }
    let tau = if den > 0.0 {
        (-num / den).clamp(-0.5, 0.5)
    } else {
        0.0
    };
    if tau.is_finite() && tau != 0.0 {
        for j in 1..m {
            for c in 0..3 {
                let d = dv(j, c);
                if usable[j] && d.is_finite() {
                    inn.q[c][j] += tau * d;
                }
            }
        }
    }
    let s: Vec<f64> = (0..3)
        .map(|c| {
            let v: Vec<f64> = (0..m).filter(|&j| usable[j]).map(|j| inn.q[c][j]).collect();
            robust_sd(&v).max(floor[c])
        })
        .collect();
    Some((rows, inn, usable, s))
}

/// The largest pose innovation in its robust sigmas (the statistic [`JUMP_Z`] bounds).
pub(super) fn largest_innovation_z(robot: &Robot, rec: &Recording) -> f64 {
    let Some((rows, inn, usable, s)) = innovations(robot, rec) else {
        return f64::NAN;
    };
    (0..rows.len())
        .filter(|&j| usable[j])
        .map(|j| (0..3).map(|c| inn.q[c][j].abs() / s[c]).fold(0.0, f64::max))
        .fold(0.0, f64::max)
}

/// Finds single-sample and permanent pose jumps; blanks the first, re-aligns after the
/// second.
#[allow(clippy::needless_range_loop)] // x, y, theta and the steps indexed alike
pub(super) fn pose_jumps(robot: &Robot, rec: &mut Recording) -> Option<Artefact> {
    let (rows, mut inn, usable, s) = innovations(robot, rec)?;
    let m = rows.len();
    let z = |q: &[Vec<f64>; 3], j: usize| -> f64 {
        (0..3).map(|c| q[c][j].abs() / s[c]).fold(0.0, f64::max)
    };
    let mut a = Artefact::new("pose_jump");
    let mut blank = vec![];
    // (sample index of the first pose after the jump, dx, dy, dtheta, rho)
    let mut jumps: Vec<(usize, f64, f64, f64, f64)> = vec![];
    let mut j = 2;
    while j + 1 < m {
        if !(usable[j] && z(&inn.q, j) > JUMP_Z) {
            j += 1;
            continue;
        }
        // A single sample off: this step's innovation and the next's cancel.
        let back = (0..3)
            .map(|c| (inn.q[c][j] + inn.q[c][j + 1]).abs() / s[c])
            .fold(0.0, f64::max);
        if usable[j + 1] && z(&inn.q, j + 1) > JUMP_Z && back < 0.5 * z(&inn.q, j) {
            blank.push(rows[j].0);
            let mut size = BTreeMap::new();
            size.insert("dx_m".to_string(), inn.q[0][j]);
            size.insert("dy_m".to_string(), inn.q[1][j]);
            size.insert("dtheta_rad".to_string(), inn.q[2][j]);
            size.insert("single_sample".to_string(), 1.0);
            a.events.push(Event {
                at_s: rec.t[rows[j].0],
                size,
            });
            for c in 0..3 {
                inn.q[c][j + 1] += inn.q[c][j];
                inn.q[c][j] = 0.0;
            }
            j += 2;
            continue;
        }
        // A jump that stays: the poses after it keep the offset (mean over the window
        // after it, against the window before it, of the summed innovations).
        let lo = j.saturating_sub(JUMP_WINDOW).max(1);
        let hi = (j + JUMP_WINDOW).min(m);
        let mut stays = true;
        let mut size3 = [0.0; 3];
        for c in 0..3 {
            let mut r = 0.0;
            let (mut before, mut nb) = (0.0f64, 0.0f64);
            let (mut after, mut na) = (0.0f64, 0.0f64);
            for u in lo..hi {
                r += inn.q[c][u];
                if u < j {
                    before += r;
                    nb += 1.0;
                } else {
                    after += r;
                    na += 1.0;
                }
            }
            // The level before includes steps up to j - 1; subtract the jump's own
            // innovation to compare the levels.
            let step = after / na.max(1.0) - before / nb.max(1.0);
            size3[c] = step;
            let q = inn.q[c][j];
            if q.abs() / s[c] > 0.5 * JUMP_Z && (step - q).abs() > 0.5 * q.abs() {
                stays = false;
            }
        }
        if !stays {
            j += 1;
            continue;
        }
        let phi = size3[2];
        // Rigid (positions turn with the heading) or a translation with a heading offset:
        // whichever makes the steps after the jump agree with the wheels.
        let end = (j + 3 * JUMP_WINDOW).min(m);
        let (mut rx, mut ry, mut tx, mut ty) = (0.0, 0.0, 0.0, 0.0);
        let (c, sn) = (phi.cos(), phi.sin());
        for u in j + 1..end {
            if !usable[u] {
                continue;
            }
            let (ox, oy) = inn.odo[u];
            rx += inn.q[0][u];
            ry += inn.q[1][u];
            // Wheels' steps turned back by phi: the heading after the jump is phi off.
            let (px, py) = (c * ox + sn * oy, -sn * ox + c * oy);
            tx += inn.q[0][u] + ox - px;
            ty += inn.q[1][u] + oy - py;
        }
        let rho = if tx.hypot(ty) < rx.hypot(ry) {
            0.0
        } else {
            phi
        };
        // The frame's move p' = R(rho) p + d, from where the robot would have been seen.
        let (ax, ay) = (rows[j].1, rows[j].2);
        let (cx, cy) = (ax - size3[0], ay - size3[1]);
        let (cr, sr) = (rho.cos(), rho.sin());
        let (dx, dy) = (ax - (cr * cx - sr * cy), ay - (sr * cx + cr * cy));
        jumps.push((j, dx, dy, phi, rho));
        let mut size = BTreeMap::new();
        size.insert("dx_m".to_string(), dx);
        size.insert("dy_m".to_string(), dy);
        size.insert("dtheta_rad".to_string(), phi);
        size.insert("jump_m".to_string(), size3[0].hypot(size3[1]));
        size.insert("rigid".to_string(), f64::from(u8::from(rho != 0.0)));
        a.events.push(Event {
            at_s: rec.t[rows[j].0],
            size,
        });
        j += JUMP_WINDOW;
    }
    if a.events.is_empty() {
        return None;
    }
    // Re-align after each jump, the last first (each was measured in the frame before
    // it).
    for &(j, dx, dy, phi, rho) in jumps.iter().rev() {
        let (cr, sr) = (rho.cos(), rho.sin());
        for r in &rows[j..] {
            let k = r.0;
            if let (Some(x), Some(y), Some(t)) = (rec.x[k], rec.y[k], rec.theta[k]) {
                let (ux, uy) = (x - dx, y - dy);
                rec.x[k] = Some(cr * ux + sr * uy);
                rec.y[k] = Some(-sr * ux + cr * uy);
                rec.theta[k] = Some(t - phi);
            }
        }
    }
    for k in blank {
        rec.x[k] = None;
        rec.y[k] = None;
        rec.theta[k] = None;
    }
    let singles = a
        .events
        .iter()
        .filter(|e| e.size.contains_key("single_sample"))
        .count();
    a.parameters
        .insert("single_sample_jumps".into(), singles as f64);
    a.parameters
        .insert("frame_jumps".into(), (a.events.len() - singles) as f64);
    a.events.truncate(MAX_EVENTS);
    a.removed = true;
    a.notes.push(
        "single samples off blanked; the poses after a jump of the frame re-aligned to the frame before it".into(),
    );
    Some(a)
}
