//! The small traits the application is written against: what a board (or the simulator)
//! must provide. Each is one concept so a board port implements exactly what it has.

use calib_core::encoder::CounterWidth;

/// Raw quadrature counters, one per wheel (a timer in QEI mode on the STM32).
pub trait EncoderSource {
    /// Width of the hardware counters (wrap extension depends on it).
    fn width(&self) -> CounterWidth;
    /// Current raw counter of wheel `i` (only the low `width` bits are used).
    fn raw(&mut self, wheel: usize) -> u32;
}

/// Motor outputs.
pub trait WheelDriver {
    /// DC wheel: signed duty in [-1, 1]; the sign selects the H-bridge direction.
    fn set_duty(&mut self, wheel: usize, duty: f32);
    /// Stepper wheel: signed step rate in steps/s for the coming tick (a hardware timer
    /// generates the pulses; `steps` is the exact count the accumulator asks for this tick,
    /// for drivers that count pulses instead of running at a rate).
    fn set_steps(&mut self, wheel: usize, steps_per_s: f32, steps: i32);
    /// Every output off now (E-stop, fault, command timeout).
    fn stop_all(&mut self);
    /// DC wheel: motor off, free to be turned by the ground ([Redundant omni] switches off the
    /// actuators a path does not use). Boards whose bridges cannot coast keep the default,
    /// zero duty.
    fn release(&mut self, wheel: usize) {
        self.set_duty(wheel, 0.0);
    }
}

/// A non-blocking byte stream (UART, pseudo-terminal, in-memory pipe).
pub trait ByteStream {
    /// Reads what is available into `buf`; returns the count (0 when nothing).
    fn read(&mut self, buf: &mut [u8]) -> usize;
    /// Queues `data` for sending.
    fn write(&mut self, data: &[u8]);
}
