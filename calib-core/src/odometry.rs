//! Dead reckoning: integrates body displacements per tick with the exact arc formula.
//!
//! Precision choices for f32 on the target (tested in `tests::square_16m_*`):
//! - the heading is kept wrapped to (-pi, pi] plus a whole-turn count, so its resolution
//!   stays at 2.4e-7 rad however many turns the robot makes;
//! - x, y and the heading are Kahan-compensated sums: adding 0.5 mm steps to a 4 m
//!   position in plain f32 loses up to half an ulp (2.4e-7 m) per tick *in the same
//!   direction* every tick, about 1 mm over a 4 m leg at 1 kHz; compensated, well under
//!   0.1 mm;
//! - sin/cos come from libm (correctly rounded to within 1 ulp). micromath's fast
//!   approximations are off by up to ~1e-3 (measured in `tests::micromath_error`), which
//!   over a 4 m leg misplaces the robot by millimetres, so they are not used here.
//! - but libm is not called every tick: a tick turns the robot by at most a few
//!   milliradians, so the arc coefficients come from their Taylor series (exact to f32
//!   below 0.1 rad) and the heading's cos/sin are rotated by the tick's small angle, then
//!   recomputed exactly every [`RESYNC_TICKS`] ticks. On the Cortex-M4F libm's sinf/cosf
//!   cost hundreds of cycles each; this keeps the tick free of them 63 times in 64.

use crate::kinematics::Twist;
use num_traits::{Float, FloatConst};

/// A planar pose in the world frame.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    postcard_schema::Schema,
)]
pub struct Pose<T> {
    /// World-frame x (m).
    pub x: T,
    /// World-frame y (m).
    pub y: T,
    /// Heading, unwrapped (counts whole turns).
    pub theta: T,
}

impl<T: Float> Pose<T> {
    /// A pose from its components (m, m, rad).
    pub fn new(x: T, y: T, theta: T) -> Self {
        Pose { x, y, theta }
    }
}

/// A running sum with Kahan compensation.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct Compensated<T> {
    sum: T,
    carry: T,
}

impl<T: Float> Compensated<T> {
    fn new(v: T) -> Self {
        Compensated {
            sum: v,
            carry: T::zero(),
        }
    }

    fn add(&mut self, v: T) {
        let y = v - self.carry;
        let t = self.sum + y;
        self.carry = (t - self.sum) - y;
        self.sum = t;
    }

    fn value(&self) -> T {
        self.sum - self.carry
    }
}

/// Ticks between exact recomputations of the heading's cos/sin.
pub const RESYNC_TICKS: u8 = 64;

/// Below this angle per tick the Taylor series replace libm.
fn series_limit<T: Float>() -> T {
    T::from(0.1).unwrap_or_else(T::zero)
}

/// (sin(d)/d, (1 - cos(d))/d): the exact-arc coefficients, accurate for small d too.
pub fn arc_coefficients<T: Float>(d: T) -> (T, T) {
    let two = T::one() + T::one();
    if d.abs() < series_limit() {
        // Taylor series; the first omitted terms, d^8/9! and d^7/8!, are below 3e-13.
        let k = |v: f64| T::from(v).unwrap_or_else(T::zero);
        let d2 = d * d;
        let s = T::one() - d2 * (k(1.0 / 6.0) - d2 * (k(1.0 / 120.0) - d2 * k(1.0 / 5040.0)));
        let c = d * (k(0.5) - d2 * (k(1.0 / 24.0) - d2 * (k(1.0 / 720.0) - d2 * k(1.0 / 40320.0))));
        (s, c)
    } else {
        let h = (d / two).sin();
        // 1 - cos d = 2 sin^2(d/2) keeps the digits cancellation would lose.
        (d.sin() / d, two * h * h / d)
    }
}

/// One exact-arc step in the frame of the pose it starts from: the chord of the circular
/// arc a body-frame displacement draws at constant twist, with the arc coefficients that
/// gave it. The one exact-arc step of the house: [`integrate_arc`] and [`Odometry`] turn
/// it by their heading, and so do the host's calibration models (which also need the
/// coefficients for their sensitivities).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chord<T> {
    /// sin(omega)/omega of the step's turn omega ([`arc_coefficients`]).
    pub s: T,
    /// (1 - cos(omega))/omega.
    pub c: T,
    /// The chord along the start pose's heading (m).
    pub lx: T,
    /// The chord to the start pose's left (m).
    pub ly: T,
}

impl<T: Float> Chord<T> {
    /// The chord of the body-frame displacement `d` (forward, left, turn).
    #[inline]
    pub fn of(d: &Twist<T>) -> Self {
        let (s, c) = arc_coefficients(d.omega);
        Chord {
            s,
            c,
            lx: s * d.vx - c * d.vy,
            ly: c * d.vx + s * d.vy,
        }
    }

    /// The point (`x`, `y`) moved by the chord, turned by a heading whose cosine and sine
    /// are `ct` and `st`.
    #[inline]
    pub fn moved(&self, x: T, y: T, ct: T, st: T) -> (T, T) {
        (
            x + ct * self.lx - st * self.ly,
            y + st * self.lx + ct * self.ly,
        )
    }
}

/// Moves `pose` by a body-frame displacement assumed to happen at constant twist (a
/// circular arc), returning the new world pose: its [`Chord`] turned by the pose's
/// heading. Used by the simulator and calibration models; [`Odometry`] takes the same
/// chord.
pub fn integrate_arc<T: Float>(pose: Pose<T>, d: &Twist<T>) -> Pose<T> {
    let chord = Chord::of(d);
    let (st, ct) = pose.theta.sin_cos();
    let (x, y) = chord.moved(pose.x, pose.y, ct, st);
    Pose {
        x,
        y,
        theta: pose.theta + d.omega,
    }
}

/// Odometry state: a pose updated by body displacements, one per control tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Odometry<T> {
    x: Compensated<T>,
    y: Compensated<T>,
    /// Heading wrapped to (-pi, pi].
    heading: Compensated<T>,
    turns: i32,
    /// cos and sin of the heading, rotated tick by tick between exact recomputations.
    cos_sin: (T, T),
    since_sync: u8,
}

impl<T: Float + FloatConst> Default for Odometry<T> {
    fn default() -> Self {
        Self::new(Pose::new(T::zero(), T::zero(), T::zero()))
    }
}

impl<T: Float + FloatConst> Odometry<T> {
    /// Dead reckoning that starts at `start`.
    pub fn new(start: Pose<T>) -> Self {
        let mut o = Odometry {
            x: Compensated::new(start.x),
            y: Compensated::new(start.y),
            heading: Compensated::new(T::zero()),
            turns: 0,
            cos_sin: (T::one(), T::zero()),
            since_sync: 0,
        };
        o.heading.add(start.theta);
        o.wrap();
        o.resync();
        o
    }

    fn resync(&mut self) {
        let (s, c) = self.heading.value().sin_cos();
        self.cos_sin = (c, s);
        self.since_sync = 0;
    }

    fn wrap(&mut self) {
        let pi = T::PI();
        let tau = pi + pi;
        while self.heading.value() > pi {
            self.heading.add(-tau);
            self.turns += 1;
        }
        while self.heading.value() <= -pi {
            self.heading.add(tau);
            self.turns -= 1;
        }
    }

    /// Adds one tick's body displacement (dx, dy forward/left in metres, dtheta in rad).
    pub fn update(&mut self, d: &Twist<T>) {
        let Chord { s, c, lx, ly } = Chord::of(d);
        let (ct, st) = self.cos_sin;
        self.x.add(ct * lx - st * ly);
        self.y.add(st * lx + ct * ly);
        self.heading.add(d.omega);
        self.wrap();
        if d.omega.abs() < series_limit() && self.since_sync < RESYNC_TICKS - 1 {
            // The tick's rotation from the arc coefficients already computed:
            // sin d = d * s and 1 - cos d = d * c.
            let (cd, sd) = (T::one() - d.omega * c, d.omega * s);
            self.cos_sin = (ct * cd - st * sd, st * cd + ct * sd);
            self.since_sync += 1;
        } else {
            self.resync();
        }
    }

    /// The current pose with the heading unwrapped.
    pub fn pose(&self) -> Pose<T> {
        let tau = T::PI() + T::PI();
        let turns = T::from(self.turns).unwrap_or_else(T::zero);
        Pose {
            x: self.x.value(),
            y: self.y.value(),
            theta: self.heading.value() + turns * tau,
        }
    }

    /// Heading wrapped to (-pi, pi].
    pub fn heading_wrapped(&self) -> T {
        self.heading.value()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::correction::Corrections;
    use crate::kinematics::Kinematics;
    use crate::motion::{ProfileLimits, Program};
    use crate::robot::presets;

    #[test]
    fn arc_is_exact_for_a_quarter_circle() {
        // A quarter circle of radius 1 m from the origin heading +x ends at (1, 1, pi/2).
        let q = core::f64::consts::FRAC_PI_2;
        let p = integrate_arc(Pose::new(0.0, 0.0, 0.0), &Twist::new(q, 0.0, q));
        assert!((p.x - 1.0).abs() < 1e-15 && (p.y - 1.0).abs() < 1e-15);
        // Split in 1000 ticks it must land at the same place.
        let mut o = Odometry::<f64>::default();
        for _ in 0..1000 {
            o.update(&Twist::new(q / 1000.0, 0.0, q / 1000.0));
        }
        let p = o.pose();
        assert!((p.x - 1.0).abs() < 1e-12 && (p.y - 1.0).abs() < 1e-12);
    }

    #[test]
    fn arc_coefficients_match_f64_in_f32() {
        for &d in &[1e-7f64, 1e-5, 9.9e-5, 1.1e-4, 1e-3, 0.01, 0.3, 1.5] {
            let h = (d / 2.0).sin();
            let (s64, c64) = (d.sin() / d, 2.0 * h * h / d);
            let (s32, c32) = arc_coefficients(d as f32);
            assert!((s32 as f64 - s64).abs() < 2e-7, "sin coefficient at {d}");
            // Relative error of the (1 - cos)/d term stays at f32 precision.
            assert!(
                ((c32 as f64 - c64) / c64).abs() < 1e-6,
                "cos coefficient at {d}"
            );
        }
    }

    /// Drives a commanded UMBmark square of side `side` through the robot's own wheel
    /// increments at 1 kHz and returns the f32 odometry end pose.
    fn square_f32(side: f32) -> Pose<f32> {
        let robot = presets::mobolab();
        let k = Kinematics::<f32>::new(&robot, &Corrections::None).unwrap();
        let program = Program::umbmark_square(side as f64, crate::motion::Direction::Ccw);
        let limits = ProfileLimits {
            v_max: 0.4,
            a_max: 0.5,
            omega_max: 1.0,
            alpha_max: 2.0,
        };
        let mut runner = program.runner(limits);
        let dt = 1e-3f32;
        let mut odo = Odometry::<f32>::default();
        let mut rates = [0f32; 2];
        while let Some(t) = runner.twist_at_tick(dt as f64) {
            let t32 = Twist::new(t.vx as f32, t.vy as f32, t.omega as f32);
            k.inverse_into(&t32, &mut rates);
            let inc = [rates[0] * dt, rates[1] * dt];
            odo.update(&k.forward(&inc));
        }
        odo.pose()
    }

    #[test]
    fn square_4m_returns_to_start_in_f32() {
        // The wheels are commanded by a perfect square, so odometry must close it; what is
        // left is the arithmetic's error: the bound is 0.1 mm.
        let p = square_f32(4.0);
        assert!(p.x.abs() < 1e-4 && p.y.abs() < 1e-4, "end at {p:?}");
        assert!((p.theta - core::f32::consts::TAU).abs() < 1e-4);
    }

    #[test]
    fn square_16m_returns_to_start_in_f32() {
        let p = square_f32(16.0);
        std::eprintln!("16 m square closes to ({:.2e}, {:.2e}) m", p.x, p.y);
        assert!(p.x.abs() < 1e-4 && p.y.abs() < 1e-4, "end at {p:?}");
    }

    #[test]
    fn micromath_error() {
        // Why libm and not micromath: measure micromath's sin/cos against f64 over a turn.
        use micromath::F32Ext;
        let mut worst_mm = 0f64;
        let mut worst_libm = 0f64;
        for i in 0..=3600 {
            let a = (i as f64 / 3600.0 - 0.5) * core::f64::consts::TAU;
            let (s, c) = (a.sin(), a.cos());
            let m = (F32Ext::sin(a as f32), F32Ext::cos(a as f32));
            let l = (libm::sinf(a as f32), libm::cosf(a as f32));
            worst_mm = worst_mm
                .max((m.0 as f64 - s).abs())
                .max((m.1 as f64 - c).abs());
            worst_libm = worst_libm
                .max((l.0 as f64 - s).abs())
                .max((l.1 as f64 - c).abs());
        }
        // micromath is a fast approximation: errors of order 1e-4..1e-3, i.e. 0.4 to 4 mm
        // of sideways error per 4 m leg; libm stays at f32 rounding (plus the f32 angle).
        assert!(worst_mm > 1e-5, "micromath worst {worst_mm}");
        assert!(worst_libm < 5e-7, "libm worst {worst_libm}");
    }

    #[test]
    fn heading_wraps_without_losing_turns() {
        let mut o = Odometry::<f32>::default();
        for _ in 0..100_000 {
            o.update(&Twist::new(0.0, 0.0, 0.001));
        }
        // 100 rad = 15.915 turns.
        let p = o.pose();
        assert!((p.theta - 100.0).abs() < 1e-3, "theta {}", p.theta);
        assert!(o.heading_wrapped().abs() <= core::f32::consts::PI);
    }
}
