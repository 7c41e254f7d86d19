//! Turns a parsed recording into the dense series the models replay: wheel angles from
//! encoder counts, commands held over each sample interval, pose samples with the heading
//! unwrapped, leg angles and the normal-load share on the driven wheels.
//!
//! Blank cells are filled by holding the last value (a blank means "not measured at this
//! instant", formats.md §2), so every series has one value per row.

use calib_core::robot::{Robot, RobotKind};
use fitkit::series::{fill, unwrap_angles};
use formats::recording::Recording;

/// Standard gravity, m/s^2, for the traction limit mu * g.
pub const G: f64 = 9.80665;

/// One wheel's measured series.
#[derive(Debug, Clone)]
pub struct WheelData {
    /// The wheel's name in the robot file.
    pub name: String,
    /// Nominal wheel radius, m.
    pub radius_m: f64,
    /// Whether a motor drives the wheel (otherwise it rolls freely with the body).
    pub driven: bool,
    /// Encoder angle in rad relative to the first count, one per row.
    pub enc_rad: Option<Vec<f64>>,
    /// Commanded rate in rad/s, held from its row to the next.
    pub cmd: Option<Vec<f64>>,
    /// Radians per encoder count (quantisation step), when encoders exist.
    pub rad_per_count: f64,
}

/// Measured poses (rows with x, y and theta), heading unwrapped.
#[derive(Debug, Clone, Default)]
pub struct PoseSamples {
    /// Recording row of each sample.
    pub row: Vec<usize>,
    /// Measured x, m.
    pub x: Vec<f64>,
    /// Measured y, m.
    pub y: Vec<f64>,
    /// Measured heading, rad, unwrapped.
    pub theta: Vec<f64>,
}

impl PoseSamples {
    /// Number of pose samples.
    pub fn len(&self) -> usize {
        self.row.len()
    }

    /// Whether the recording has no pose sample.
    pub fn is_empty(&self) -> bool {
        self.row.is_empty()
    }
}

/// A recording in the form the models need.
#[derive(Debug, Clone)]
pub struct Prepared {
    /// The nominal robot.
    pub robot: Robot,
    /// Time of each row, s.
    pub t: Vec<f64>,
    /// Per-wheel series, in the robot file's wheel order.
    pub wheels: Vec<WheelData>,
    /// The rows with a measured pose.
    pub poses: PoseSamples,
    /// Leg angles per row (wheeled-legged robots).
    pub legs: Option<(Vec<f64>, Vec<f64>)>,
    /// Share of the weight on driven wheels per row (1 for robots whose wheels all drive).
    pub driven_share: Vec<f64>,
    /// Measured pose, lightly smoothed and interpolated to every row (held before the
    /// first and after the last sample): where the robot is on the floor, for
    /// floor-fixed effects.
    pub pose_at_row: Vec<(f64, f64, f64)>,
    /// Cosine and sine of that pose's heading.
    pub heading_cs_at_row: Vec<(f64, f64)>,
    /// Rows the ground stage integrates between: every pose row, the first and
    /// the last, and enough others that no step is longer than 1 / [`GROUND_RATE_HZ`].
    /// Encoder counts are cumulative, so a coarser step loses no odometry; rows between
    /// are interpolated.
    pub ground_rows: Vec<usize>,
    /// The rows were merged (`formats::decimate`): each command is the mean over its
    /// interval, so commands are read as held, never as samples of a ramp.
    pub commands_are_means: bool,
}

/// Most ground-stage steps per second (100-200 rows/s lose no odometry).
pub const GROUND_RATE_HZ: f64 = 50.0;

/// The rows [`Prepared::ground_rows`] keeps.
pub fn ground_rows(t: &[f64], pose_rows: &[usize], rate_hz: f64) -> Vec<usize> {
    let n = t.len();
    let mut out = Vec::new();
    let mut poses = pose_rows.iter().peekable();
    let min_dt = 1.0 / rate_hz - 1e-9;
    for k in 0..n {
        let pose = poses.peek().is_some_and(|&&r| r == k);
        if pose {
            poses.next();
        }
        let far = out.last().is_none_or(|&l: &usize| t[k] - t[l] >= min_dt);
        if k == 0 || k + 1 == n || pose || far {
            out.push(k);
        }
    }
    out
}

impl Prepared {
    /// Builds the dense series. Never fails on a recording calib-core accepted.
    pub fn new(robot: &Robot, rec: &Recording) -> Prepared {
        let rad_per_count = robot.drive.rad_per_count().unwrap_or(0.0);
        let wheels = robot
            .wheels
            .iter()
            .enumerate()
            .map(|(i, w)| {
                let series = rec.wheels.get(i);
                let enc_rad = if rad_per_count > 0.0 {
                    series
                        .and_then(|s| s.enc.as_ref())
                        .and_then(|e| fill(e))
                        .map(|counts| {
                            let c0 = counts[0];
                            counts
                                .iter()
                                .map(|c| (c - c0) as f64 * rad_per_count)
                                .collect()
                        })
                } else {
                    None
                };
                let cmd = series.and_then(|s| s.cmd.as_ref()).and_then(|c| fill(c));
                WheelData {
                    name: w.name.to_string(),
                    radius_m: w.radius_m,
                    driven: w.driven,
                    enc_rad,
                    cmd,
                    rad_per_count,
                }
            })
            .collect();
        let mut poses = PoseSamples::default();
        for (i, x, y, th) in rec.pose_rows() {
            poses.row.push(i);
            poses.x.push(x);
            poses.y.push(y);
            poses.theta.push(th);
        }
        unwrap_angles(&mut poses.theta);
        let legs = if robot.kind == RobotKind::WheeledLegged {
            let half_pi = std::f64::consts::FRAC_PI_2;
            let f = rec
                .leg_front
                .as_ref()
                .and_then(|v| fill(v))
                .unwrap_or_else(|| vec![half_pi; rec.len()]);
            let r = rec
                .leg_rear
                .as_ref()
                .and_then(|v| fill(v))
                .unwrap_or_else(|| vec![half_pi; rec.len()]);
            Some((f, r))
        } else {
            None
        };
        let driven_share = driven_share(robot, legs.as_ref(), rec.len());
        let pose_at_row = interpolate_poses(&rec.t, &poses);
        let heading_cs_at_row = pose_at_row
            .iter()
            .map(|p| {
                let (s, c) = p.2.sin_cos();
                (c, s)
            })
            .collect();
        Prepared {
            ground_rows: ground_rows(&rec.t, &poses.row, GROUND_RATE_HZ),
            pose_at_row,
            heading_cs_at_row,
            robot: robot.clone(),
            t: rec.t.clone(),
            wheels,
            poses,
            legs,
            driven_share,
            commands_are_means: rec.merged.is_some(),
        }
    }

    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.t.len()
    }

    /// Leg angles (front, rear) at row `k`, rad, on wheeled-legged robots; they move the
    /// wheel contacts along x.
    pub fn leg_angles(&self, k: usize) -> Option<(f64, f64)> {
        self.legs.as_ref().map(|(f, r)| (f[k], r[k]))
    }

    /// Median row interval, s.
    pub fn row_dt_s(&self) -> f64 {
        let mut d: Vec<f64> = self.t.windows(2).map(|w| w[1] - w[0]).collect();
        if d.is_empty() {
            return 0.0;
        }
        d.sort_by(|a, b| a.total_cmp(b));
        d[d.len() / 2]
    }

    /// True when at least one wheel has both a command and an encoder.
    pub fn has_actuator_stage(&self) -> bool {
        self.wheels
            .iter()
            .any(|w| w.cmd.is_some() && w.enc_rad.is_some())
    }

    /// True when some wheel has a command (actuator effects can act on something).
    pub fn has_commands(&self) -> bool {
        self.wheels.iter().any(|w| w.cmd.is_some())
    }
}

fn interpolate_poses(t: &[f64], ps: &PoseSamples) -> Vec<(f64, f64, f64)> {
    let n = t.len();
    if ps.is_empty() {
        return vec![(0.0, 0.0, 0.0); n];
    }
    // Smooth over five samples: vision noise would otherwise make a wheel standing on a
    // cable line seem to cross it back and forth.
    let m = ps.len();
    let avg = |v: &[f64], j: usize| -> f64 {
        let (a, b) = (j.saturating_sub(2), (j + 3).min(m));
        v[a..b].iter().sum::<f64>() / (b - a) as f64
    };
    let sx: Vec<f64> = (0..m).map(|j| avg(&ps.x, j)).collect();
    let sy: Vec<f64> = (0..m).map(|j| avg(&ps.y, j)).collect();
    let sth: Vec<f64> = (0..m).map(|j| avg(&ps.theta, j)).collect();
    let ps = &PoseSamples {
        row: ps.row.clone(),
        x: sx,
        y: sy,
        theta: sth,
    };
    let mut out = Vec::with_capacity(n);
    let mut j = 0;
    for k in 0..n {
        while j + 1 < ps.len() && ps.row[j + 1] <= k {
            j += 1;
        }
        let (r0, r1) = (ps.row[j], ps.row[(j + 1).min(ps.len() - 1)]);
        if k <= r0 || r1 <= r0 {
            out.push((ps.x[j], ps.y[j], ps.theta[j]));
        } else {
            let j1 = j + 1;
            let f = (t[k] - t[r0]) / (t[r1] - t[r0]);
            let lerp = |a: f64, b: f64| a + (b - a) * f;
            out.push((
                lerp(ps.x[j], ps.x[j1]),
                lerp(ps.y[j], ps.y[j1]),
                lerp(ps.theta[j], ps.theta[j1]),
            ));
        }
    }
    out
}

/// Share of the weight carried by driven wheels. Wheeled-legged: by moment balance from
/// the leg angles (front pair driven); otherwise each wheel carries an equal share.
fn driven_share(robot: &Robot, legs: Option<&(Vec<f64>, Vec<f64>)>, n: usize) -> Vec<f64> {
    let driven = robot.wheels.iter().filter(|w| w.driven).count();
    let equal = driven as f64 / robot.wheels.len().max(1) as f64;
    match (legs, &robot.legs) {
        (Some((f, r)), Some(geom)) => {
            // Which pair is driven: the wheels ahead of the origin or behind it.
            let front_driven = robot
                .wheels
                .iter()
                .filter(|w| w.position().0 > 0.0)
                .any(|w| w.driven);
            let rear_driven = robot
                .wheels
                .iter()
                .filter(|w| w.position().0 <= 0.0)
                .any(|w| w.driven);
            (0..n)
                .map(|k| {
                    let front = geom.front_load_share(f[k], r[k]).unwrap_or(0.5);
                    match (front_driven, rear_driven) {
                        (true, true) => 1.0,
                        (true, false) => front,
                        (false, true) => 1.0 - front,
                        (false, false) => 0.0,
                    }
                })
                .collect()
        }
        _ => vec![equal; n],
    }
}
