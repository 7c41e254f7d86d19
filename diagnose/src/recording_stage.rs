//! The `recording` stage: artefacts of how a run was logged, not physics. Fitted as
//! recording parameters by [`crate::calibrate`] (`time_offset_s`: poses later than
//! encoders when positive; `clock_ratio`: pose clock over encoder clock) and removed
//! here before the physics is judged, so a late motion-capture stream is not diagnosed
//! as a slipping wheel.

use crate::calibrate::Nuisance;
use crate::replay::unwrap_angles;
use formats::recording::Recording;

/// The recording with its pose columns moved onto the encoders' clock: the pose written
/// at row k becomes the measured pose at the time that shows the robot at row k's encoder
/// time, t' = t0 + offset + ratio (t_k - t0), interpolated between measured samples.
/// Rows whose t' falls outside the measured poses lose their pose.
pub fn on_encoder_clock(rec: &Recording, nu: &Nuisance) -> Recording {
    let mut out = rec.clone();
    let rows: Vec<(usize, f64, f64, f64)> = rec.pose_rows().collect();
    if rows.len() < 2 || rec.t.is_empty() {
        return out;
    }
    let ts: Vec<f64> = rows.iter().map(|r| rec.t[r.0]).collect();
    let mut th: Vec<f64> = rows.iter().map(|r| r.3).collect();
    unwrap_angles(&mut th);
    let t0 = rec.t[0];
    for &(k, ..) in &rows {
        let tq = t0 + nu.time_offset_s + nu.clock_ratio * (rec.t[k] - t0);
        let j = ts.partition_point(|&v| v <= tq);
        if j == 0 || j >= ts.len() {
            // Outside the measured span (or exactly at its end).
            if (tq - ts[ts.len() - 1]).abs() < 1e-12 {
                continue;
            }
            out.x[k] = None;
            out.y[k] = None;
            out.theta[k] = None;
            continue;
        }
        let f = (tq - ts[j - 1]) / (ts[j] - ts[j - 1]);
        let l = |a: f64, b: f64| a + (b - a) * f;
        out.x[k] = Some(l(rows[j - 1].1, rows[j].1));
        out.y[k] = Some(l(rows[j - 1].2, rows[j].2));
        out.theta[k] = Some(l(th[j - 1], th[j]));
    }
    out
}
