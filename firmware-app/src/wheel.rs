//! One wheel's part of the control tick: encoder wrap extension, rate estimate, velocity
//! loop or step generation, and the fault monitor.

use calib_core::control::{PiController, PiGains};
use calib_core::encoder::{CounterExtender, CounterWidth};
use calib_core::protocol::{Fault, Safety};
use calib_core::stepper::StepAccumulator;

/// Ticks over which the rate is estimated. One count of a 1920-count wheel is 3.3 mrad: a
/// single 1 ms difference would quantise the rate to 3.3 rad/s; over 8 ms it is 0.41 rad/s
/// with 4 ms of delay, which the PI (crossover well below 100 rad/s) tolerates.
pub const RATE_WINDOW: usize = 8;

/// State of one wheel.
#[derive(Debug, Clone)]
pub struct WheelState {
    ext: Option<CounterExtender>,
    /// Positions of the last RATE_WINDOW ticks (ring).
    hist: [i64; RATE_WINDOW],
    hist_at: usize,
    /// Counts moved over the window.
    rate_counts: i64,
    /// Velocity controller (DC drives).
    pub pi: PiController,
    /// Step generator (stepper drives).
    pub steps: StepAccumulator,
    /// Commanded rate, rad/s (corrections applied).
    pub cmd: f32,
    /// Estimated rate, rad/s.
    pub rate: f32,
    /// Ticks (ms) commanded above the stall threshold without an encoder count.
    still: u32,
    /// Position at the start of the running trial.
    pub origin: i64,
}

impl WheelState {
    /// A wheel with these gains and steps per wheel radian, before its first encoder reading.
    pub fn new(gains: PiGains, steps_per_rad: f64) -> Self {
        WheelState {
            ext: None,
            hist: [0; RATE_WINDOW],
            hist_at: 0,
            rate_counts: 0,
            pi: PiController::new(gains),
            steps: StepAccumulator::new(steps_per_rad),
            cmd: 0.0,
            rate: 0.0,
            still: 0,
            origin: 0,
        }
    }

    /// Extended encoder position (counts since the first reading).
    pub fn position(&self) -> i64 {
        self.ext.map_or(0, |e| e.position())
    }

    /// Feeds a raw counter reading; returns this tick's movement in counts. The first
    /// reading only sets the origin.
    pub fn read(&mut self, width: CounterWidth, raw: u32) -> i64 {
        let delta = match &mut self.ext {
            Some(e) => e.update(raw),
            None => {
                self.ext = Some(CounterExtender::new(width, raw));
                self.hist = [0; RATE_WINDOW];
                0
            }
        };
        let pos = self.position();
        let oldest = self.hist[self.hist_at];
        self.hist[self.hist_at] = pos;
        self.hist_at = (self.hist_at + 1) % RATE_WINDOW;
        // The entry overwritten was RATE_WINDOW ticks old.
        self.rate_counts = pos - oldest;
        delta
    }

    /// Rate over the window in rad/s.
    pub fn update_rate(&mut self, rad_per_count: f32, dt: f32) {
        // Through i32: an i64 -> f32 conversion is a library call on the M4F.
        let counts = self.rate_counts.clamp(i32::MIN as i64, i32::MAX as i64) as i32;
        self.rate = counts as f32 * rad_per_count / (RATE_WINDOW as f32 * dt);
    }

    /// Checks this tick's movement against the safety limits.
    pub fn monitor(&mut self, index: usize, delta: i64, safety: &Safety) -> Option<Fault> {
        if delta.unsigned_abs() > safety.max_jump_counts as u64 {
            return Some(Fault::CounterJump {
                wheel: index as u8,
                delta: delta.clamp(i32::MIN as i64, i32::MAX as i64) as i32,
            });
        }
        if self.cmd.abs() >= safety.stall_min_rate && safety.stall_min_rate > 0.0 && delta == 0 {
            self.still += 1;
            if self.still >= safety.stall_timeout_ms as u32 {
                return Some(Fault::Stall { wheel: index as u8 });
            }
        } else {
            self.still = 0;
        }
        None
    }

    /// Zero command, integrator cleared (after a stop, so a restart does not lurch).
    pub fn halt(&mut self) {
        self.cmd = 0.0;
        self.pi.reset();
        self.still = 0;
    }
}
