//! Matching the pose stream to the joint stream by time. Each joint instant gets the pose
//! interpolated linearly between the two pose samples around it (heading unwrapped), the
//! exact sample when the stamps coincide, and nothing before the first pose, after the
//! last, or inside a gap longer than the allowed one: never extrapolated, never bridged
//! over a stretch the pose sensor lost the robot.

use crate::poses::PoseSeries;

/// The pose at each of the sorted instants `t_ns`, `None` where there is none to
/// interpolate from.
pub fn poses_at(p: &PoseSeries, t_ns: &[i64], max_gap_ns: i64) -> Vec<Option<(f64, f64, f64)>> {
    let s = &p.stamps_ns;
    let mut out = Vec::with_capacity(t_ns.len());
    let mut i = 0; // first pose sample with stamp >= t
    for &t in t_ns {
        while i < s.len() && s[i] < t {
            i += 1;
        }
        let v = if i < s.len() && s[i] == t {
            Some((p.x[i], p.y[i], p.yaw[i]))
        } else if i == 0 || i == s.len() || s[i] - s[i - 1] > max_gap_ns {
            None
        } else {
            let (a, b) = (i - 1, i);
            let w = (t - s[a]) as f64 / (s[b] - s[a]) as f64;
            let lerp = |u: &[f64]| u[a] + (u[b] - u[a]) * w;
            Some((lerp(&p.x), lerp(&p.y), lerp(&p.yaw)))
        };
        out.push(v);
    }
    out
}

/// Poses re-expressed in the frame of the first one (the robot's start frame: it starts
/// at x = y = theta = 0, x along its heading), headings kept continuous.
pub fn to_start_frame(poses: &mut [Option<(f64, f64, f64)>]) {
    let Some((x0, y0, th0)) = poses.iter().flatten().next().copied() else {
        return;
    };
    let (c, s) = (th0.cos(), th0.sin());
    for (x, y, th) in poses.iter_mut().flatten() {
        let (dx, dy) = (*x - x0, *y - y0);
        // `+ 0.0` writes the start's -0.0 as 0.
        *x = c * dx + s * dy + 0.0;
        *y = -s * dx + c * dy + 0.0;
        *th = *th - th0 + 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series() -> PoseSeries {
        PoseSeries {
            stamps_ns: vec![100, 200, 1_000],
            x: vec![0.0, 1.0, 2.0],
            y: vec![0.0, -1.0, 0.0],
            yaw: vec![3.0, 3.4, 3.5],
            ..PoseSeries::default()
        }
    }

    #[test]
    fn interpolates_inside_and_never_extrapolates() {
        let p = poses_at(&series(), &[50, 100, 150, 200, 600, 1_000, 1_001], 500);
        assert_eq!(p[0], None, "before the first pose");
        assert_eq!(
            p[1],
            Some((0.0, 0.0, 3.0)),
            "a coinciding stamp is the sample itself"
        );
        let (x, y, th) = p[2].unwrap();
        assert!((x - 0.5).abs() < 1e-15 && (y + 0.5).abs() < 1e-15 && (th - 3.2).abs() < 1e-15);
        assert_eq!(p[3], Some((1.0, -1.0, 3.4)));
        assert_eq!(p[4], None, "a gap of 800 ns > 500 is not bridged");
        assert_eq!(p[5], Some((2.0, 0.0, 3.5)));
        assert_eq!(p[6], None, "after the last pose");
    }

    #[test]
    fn start_frame_puts_the_first_pose_at_the_origin() {
        let mut p = vec![
            None,
            Some((1.0, 2.0, std::f64::consts::FRAC_PI_2)),
            Some((1.0, 3.0, 2.0)),
        ];
        to_start_frame(&mut p);
        assert_eq!(p[0], None);
        assert_eq!(p[1], Some((0.0, 0.0, 0.0)));
        // One metre along world +y is one metre straight ahead of a robot facing +y.
        let (x, y, th) = p[2].unwrap();
        assert!((x - 1.0).abs() < 1e-15 && y.abs() < 1e-15);
        assert!((th - (2.0 - std::f64::consts::FRAC_PI_2)).abs() < 1e-15);
    }
}
