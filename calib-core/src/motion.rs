//! Motion programs: segments with trapezoidal velocity profiles, and the papers' test
//! paths (UMBmark square, [Redundant omni]'s omni paths 4W-1 and 4W-2).
//!
//! The runner hands out, per control tick, the *average* twist over that tick
//! (displacement / dt), so the commanded displacements of a segment add up to its exact
//! length whatever the tick: a square commanded this way closes to rounding error.

use crate::kinematics::Twist;
use heapless::Vec;
use serde::{Deserialize, Serialize};

/// Most segments in one program (a custom list from the host).
pub const MAX_SEGMENTS: usize = 32;

/// Turning sense of a square: cw turns right at the corners, ccw left.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Clockwise seen from above: right turns at the corners.
    Cw,
    /// Counter-clockwise seen from above: left turns at the corners.
    Ccw,
}

impl Direction {
    /// Lower-case name as used in files and on the command line (`cw`, `ccw`).
    pub fn as_str(self) -> &'static str {
        match self {
            Direction::Cw => "cw",
            Direction::Ccw => "ccw",
        }
    }
}

/// [Redundant omni]'s straight test paths of the 4-wheel omni robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, postcard_schema::Schema)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum OmniPath {
    /// Along body +x: wheels 1 and 3 turn, 2 and 4 stand still.
    W1,
    /// Along body +y: wheels 2 and 4 turn.
    W2,
}

impl OmniPath {
    /// The paper's name of the path (`4W-1`, `4W-2`).
    pub fn as_str(self) -> &'static str {
        match self {
            OmniPath::W1 => "4W-1",
            OmniPath::W2 => "4W-2",
        }
    }

    /// Unit direction of travel in the body frame.
    pub fn direction(self) -> (f64, f64) {
        match self {
            OmniPath::W1 => (1.0, 0.0),
            OmniPath::W2 => (0.0, 1.0),
        }
    }
}

/// One piece of a motion program.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub enum Segment {
    /// Drive along body x.
    Straight {
        /// Signed distance (m); negative drives backwards.
        distance_m: f64,
    },
    /// Turn in place (positive = counter-clockwise).
    Turn {
        /// Signed heading change (rad).
        angle_rad: f64,
    },
    /// Omni: translate without turning by (dx, dy) in the body frame.
    Translate {
        /// Displacement along body x (m).
        dx_m: f64,
        /// Displacement along body y (m).
        dy_m: f64,
    },
    /// Turn one wheel by an angle, the others held.
    SingleWheel {
        /// Index of the wheel that turns (0-based, robot's wheel order).
        wheel: u8,
        /// Signed wheel rotation (rad).
        angle_rad: f64,
    },
    /// Stand still.
    Pause {
        /// How long to stand still (s).
        duration_s: f64,
    },
    /// Drive forward along body x on an arc of constant radius: the arcs a turn-radius
    /// law (tyre scrub, skid-steer ICRs) needs to be seen, which squares lack.
    Arc {
        /// Radius of the arc (m, positive).
        radius_m: f64,
        /// Signed heading change (rad, positive = counter-clockwise, to the left).
        angle_rad: f64,
    },
}

/// Speed and acceleration limits for the profiles.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, postcard_schema::Schema)]
pub struct ProfileLimits {
    /// m/s along a path.
    pub v_max: f64,
    /// m/s^2.
    pub a_max: f64,
    /// rad/s for turns and single-wheel moves.
    pub omega_max: f64,
    /// rad/s^2.
    pub alpha_max: f64,
}

impl Default for ProfileLimits {
    fn default() -> Self {
        ProfileLimits {
            v_max: 0.3,
            a_max: 0.3,
            omega_max: 1.0,
            alpha_max: 2.0,
        }
    }
}

/// A trapezoidal (or triangular, when too short to cruise) profile over a distance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Trapezoid {
    distance: f64,
    v_peak: f64,
    accel: f64,
    t_ramp: f64,
    t_cruise: f64,
}

impl Trapezoid {
    /// A profile covering |distance| with speed and acceleration limits (> 0).
    pub fn new(distance: f64, v_max: f64, a_max: f64) -> Self {
        let d = distance.abs();
        let v_max = v_max.abs().max(1e-9);
        let a_max = a_max.abs().max(1e-9);
        let (v_peak, t_ramp, t_cruise) = if d * a_max >= v_max * v_max {
            (v_max, v_max / a_max, (d - v_max * v_max / a_max) / v_max)
        } else {
            let v = libm::sqrt(d * a_max);
            (v, v / a_max, 0.0)
        };
        Trapezoid {
            distance,
            v_peak,
            accel: a_max,
            t_ramp,
            t_cruise,
        }
    }

    /// Total time of the profile (s).
    pub fn duration(&self) -> f64 {
        2.0 * self.t_ramp + self.t_cruise
    }

    /// Peak speed reached.
    pub fn peak_speed(&self) -> f64 {
        self.v_peak
    }

    /// Signed position at time t (clamped to the ends).
    pub fn position(&self, t: f64) -> f64 {
        let d = self.distance.abs();
        let p = if t <= 0.0 {
            0.0
        } else if t < self.t_ramp {
            0.5 * self.accel * t * t
        } else if t < self.t_ramp + self.t_cruise {
            0.5 * self.accel * self.t_ramp * self.t_ramp + self.v_peak * (t - self.t_ramp)
        } else if t < self.duration() {
            let r = self.duration() - t;
            d - 0.5 * self.accel * r * r
        } else {
            d
        };
        p.copysign(self.distance)
    }

    /// Signed speed at time t.
    pub fn velocity(&self, t: f64) -> f64 {
        let v = if t <= 0.0 || t >= self.duration() {
            0.0
        } else if t < self.t_ramp {
            self.accel * t
        } else if t < self.t_ramp + self.t_cruise {
            self.v_peak
        } else {
            self.accel * (self.duration() - t)
        };
        v.copysign(self.distance)
    }
}

/// What a program asks of the wheels during one tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setpoint {
    /// Average body twist over the tick.
    Body(Twist<f64>),
    /// Average rate of one wheel over the tick; the others stand still.
    Wheel {
        /// Index of the wheel that turns (0-based).
        index: u8,
        /// Wheel rate (rad/s).
        rate: f64,
    },
}

/// A list of segments.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, postcard_schema::Schema)]
pub struct Program {
    /// The segments in execution order (at most [`MAX_SEGMENTS`]).
    pub segments: Vec<Segment, MAX_SEGMENTS>,
}

impl Program {
    /// A program of these segments, or `None` if there are more than [`MAX_SEGMENTS`].
    pub fn from_segments(segments: &[Segment]) -> Option<Self> {
        Vec::from_slice(segments)
            .ok()
            .map(|segments| Program { segments })
    }

    /// Borenstein's UMBmark square: four legs of `side_m`, turning 90 deg at each corner,
    /// ending back at the start with the start heading.
    pub fn umbmark_square(side_m: f64, dir: Direction) -> Self {
        let turn = match dir {
            Direction::Ccw => core::f64::consts::FRAC_PI_2,
            Direction::Cw => -core::f64::consts::FRAC_PI_2,
        };
        let mut segments = Vec::new();
        for _ in 0..4 {
            let _ = segments.push(Segment::Straight { distance_m: side_m });
            let _ = segments.push(Segment::Turn { angle_rad: turn });
        }
        Program { segments }
    }

    /// A circle of `radius_m`, `laps` times round, driven forward from rest to rest:
    /// arcs of one radius for calibrating the separation on arcs against the squares'
    /// turns in place.
    pub fn circle(radius_m: f64, dir: Direction, laps: u8) -> Self {
        let sign = match dir {
            Direction::Ccw => 1.0,
            Direction::Cw => -1.0,
        };
        let mut segments = Vec::new();
        let _ = segments.push(Segment::Arc {
            radius_m,
            angle_rad: sign * core::f64::consts::TAU * f64::from(laps),
        });
        Program { segments }
    }

    /// [Redundant omni]'s straight omni test path of length `length_m`.
    pub fn omni_path(path: OmniPath, length_m: f64) -> Self {
        let (ux, uy) = path.direction();
        let mut segments = Vec::new();
        let _ = segments.push(Segment::Translate {
            dx_m: ux * length_m,
            dy_m: uy * length_m,
        });
        Program { segments }
    }

    /// Total duration under `limits`.
    pub fn duration(&self, limits: &ProfileLimits) -> f64 {
        self.segments
            .iter()
            .map(|s| profile_of(s, limits).0.duration())
            .sum()
    }

    /// A runner that steps through the program tick by tick.
    pub fn runner(&self, limits: ProfileLimits) -> ProgramRunner {
        ProgramRunner {
            program: self.clone(),
            limits,
            index: 0,
            t: 0.0,
            profile: None,
        }
    }
}

/// The profile of a segment and the unit "direction" it scales.
fn profile_of(s: &Segment, l: &ProfileLimits) -> (Trapezoid, Twist<f64>) {
    match *s {
        Segment::Straight { distance_m } => (
            Trapezoid::new(distance_m, l.v_max, l.a_max),
            Twist::new(1.0, 0.0, 0.0),
        ),
        Segment::Turn { angle_rad } => (
            Trapezoid::new(angle_rad, l.omega_max, l.alpha_max),
            Twist::new(0.0, 0.0, 1.0),
        ),
        Segment::Arc {
            radius_m,
            angle_rad,
        } => {
            // Along the arc's length, within both the speed and the turn-rate limits.
            let r = radius_m.max(0.0);
            let sign = if angle_rad < 0.0 { -1.0 } else { 1.0 };
            let omega = if r > 0.0 { sign / r } else { 0.0 };
            (
                Trapezoid::new(
                    r * libm::fabs(angle_rad),
                    l.v_max.min(l.omega_max * r),
                    l.a_max.min(l.alpha_max * r),
                ),
                Twist::new(1.0, 0.0, omega),
            )
        }
        Segment::Translate { dx_m, dy_m } => {
            let d = libm::sqrt(dx_m * dx_m + dy_m * dy_m);
            let u = if d > 0.0 {
                Twist::new(dx_m / d, dy_m / d, 0.0)
            } else {
                Twist::zero()
            };
            (Trapezoid::new(d, l.v_max, l.a_max), u)
        }
        Segment::SingleWheel { angle_rad, .. } => (
            Trapezoid::new(angle_rad, l.omega_max * 5.0, l.alpha_max * 5.0),
            Twist::zero(),
        ),
        Segment::Pause { duration_s } => {
            // A zero-distance profile with the pause's duration.
            (
                Trapezoid {
                    distance: 0.0,
                    v_peak: 0.0,
                    accel: 1.0,
                    t_ramp: 0.0,
                    t_cruise: duration_s.max(0.0),
                },
                Twist::zero(),
            )
        }
    }
}

/// Steps a program: call [`ProgramRunner::setpoint`] once per control tick.
#[derive(Debug, Clone, PartialEq)]
pub struct ProgramRunner {
    program: Program,
    limits: ProfileLimits,
    index: usize,
    t: f64,
    profile: Option<(Trapezoid, Twist<f64>)>,
}

impl ProgramRunner {
    /// Index of the segment under way (== number of segments when finished).
    pub fn segment_index(&self) -> usize {
        self.index
    }

    /// Whether every segment has been run.
    pub fn is_finished(&self) -> bool {
        self.index >= self.program.segments.len()
    }

    /// The setpoint for the next tick of length `dt`, or `None` when the program is done.
    pub fn setpoint(&mut self, dt: f64) -> Option<Setpoint> {
        loop {
            let seg = *self.program.segments.get(self.index)?;
            let (prof, unit) = *self
                .profile
                .get_or_insert_with(|| profile_of(&seg, &self.limits));
            if self.t >= prof.duration() {
                self.index += 1;
                self.t = 0.0;
                self.profile = None;
                continue;
            }
            let (p0, p1) = (prof.position(self.t), prof.position(self.t + dt));
            self.t += dt;
            let rate = (p1 - p0) / dt;
            return Some(match seg {
                Segment::SingleWheel { wheel, .. } => Setpoint::Wheel { index: wheel, rate },
                _ => Setpoint::Body(unit.scale(rate)),
            });
        }
    }

    /// Like [`Self::setpoint`] but only for body-twist programs (single-wheel ticks give a
    /// zero twist).
    pub fn twist_at_tick(&mut self, dt: f64) -> Option<Twist<f64>> {
        self.setpoint(dt).map(|s| match s {
            Setpoint::Body(t) => t,
            Setpoint::Wheel { .. } => Twist::zero(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trapezoid_reaches_the_distance() {
        let p = Trapezoid::new(4.0, 0.4, 0.5);
        // ramp 0.8 s covering 0.16 m each, cruise 3.68 m at 0.4 m/s = 9.2 s.
        assert!((p.duration() - (2.0 * 0.8 + 9.2)).abs() < 1e-12);
        assert!((p.position(p.duration()) - 4.0).abs() < 1e-12);
        assert!((p.velocity(5.0) - 0.4).abs() < 1e-12);
        // Triangular: 0.1 m at a = 0.5 peaks at sqrt(0.05) m/s.
        let t = Trapezoid::new(-0.1, 0.4, 0.5);
        assert!((t.peak_speed() - 0.05f64.sqrt()).abs() < 1e-12);
        assert!((t.position(10.0) + 0.1).abs() < 1e-15);
    }

    #[test]
    fn tick_displacements_sum_to_segment() {
        let prog = Program::umbmark_square(4.0, Direction::Cw);
        let mut r = prog.runner(ProfileLimits::default());
        let (mut dist, mut turn) = (0.0, 0.0);
        let dt = 1e-3;
        while let Some(t) = r.twist_at_tick(dt) {
            dist += t.vx * dt;
            turn += t.omega * dt;
        }
        assert!((dist - 16.0).abs() < 1e-9, "{dist}");
        assert!((turn + core::f64::consts::TAU).abs() < 1e-9, "{turn}");
        assert!(r.is_finished());
    }

    /// Integrates a program's twists tick by tick along exact arcs: the pose, the path
    /// length and the largest speed and turn rate commanded.
    fn drive(prog: &Program, limits: ProfileLimits) -> (crate::odometry::Pose<f64>, f64, f64, f64) {
        let mut r = prog.runner(limits);
        let mut pose = crate::odometry::Pose::<f64>::default();
        let (mut dist, mut v_peak, mut w_peak) = (0.0f64, 0.0f64, 0.0f64);
        let dt = 1e-3;
        while let Some(t) = r.twist_at_tick(dt) {
            pose = crate::odometry::integrate_arc(pose, &t.scale(dt));
            dist += t.vx * dt;
            v_peak = v_peak.max(t.vx.abs());
            w_peak = w_peak.max(t.omega.abs());
        }
        (pose, dist, v_peak, w_peak)
    }

    /// A circle of radius r drives 2 pi r per lap on a constant curvature, so exact arc
    /// integration ends where it started, turned by 2 pi per lap (counter-clockwise
    /// positive), to rounding (1e-9); its speed and turn rate keep both limits (on a
    /// 0.1 m circle the turn rate limit of 1 rad/s caps the speed at 0.1 m/s).
    #[test]
    fn a_circle_program_drives_its_circle_within_the_limits() {
        use core::f64::consts::TAU;
        let l = ProfileLimits::default();
        for (radius, dir, laps) in [
            (0.5, Direction::Ccw, 1),
            (0.5, Direction::Cw, 2),
            (0.1, Direction::Ccw, 1),
        ] {
            let prog = Program::circle(radius, dir, laps);
            let (pose, dist, v_peak, w_peak) = drive(&prog, l);
            let sign = if dir == Direction::Ccw { 1.0 } else { -1.0 };
            let turned = sign * TAU * laps as f64;
            assert!(
                libm::fabs(pose.x) < 1e-9 && libm::fabs(pose.y) < 1e-9,
                "{radius}: {pose:?}"
            );
            assert!(libm::fabs(pose.theta - turned) < 1e-9, "{radius}: {pose:?}");
            assert!(
                libm::fabs(dist - TAU * radius * laps as f64) < 1e-9,
                "{dist}"
            );
            let v_cap = l.v_max.min(l.omega_max * radius);
            assert!(
                v_peak <= v_cap + 1e-9 && v_peak > 0.99 * v_cap,
                "{radius}: {v_peak}"
            );
            assert!(w_peak <= l.omega_max + 1e-9, "{radius}: {w_peak}");
        }
        // Half a lap of a 0.5 m counter-clockwise arc ends across the circle, at (0, 1).
        let mut half = Program::default();
        let _ = half.segments.push(Segment::Arc {
            radius_m: 0.5,
            angle_rad: core::f64::consts::PI,
        });
        let (pose, ..) = drive(&half, l);
        assert!(
            libm::fabs(pose.x) < 1e-9 && libm::fabs(pose.y - 1.0) < 1e-9,
            "{pose:?}"
        );
    }
}
