//! Counts the instructions of firmware-app's control tick for four DC wheels on a
//! Cortex-M4F (QEMU mps2-an386, semihosting); `run.sh` builds, runs and counts.
//!
//! The robot is [Redundant omni]'s four-wheel omni robot (DC drive, 480-ppr encoders) with omni
//! corrections, driving a 0.5 m translate and then a 6 rad turn in place, logging a trial at
//! 100 Hz: the tick reads four encoders, extends them, estimates rates, samples the
//! program's f64 trapezoid (every tenth tick), inverse and forward kinematics, odometry,
//! four PI loops and (every tenth tick) a log record. Markers: `bench_mark(1)`, N ticks
//! while translating, `bench_mark(2)`, N plant-only steps, `bench_mark(3)`; later
//! `bench_mark(4)`, N ticks while turning (odometry's exact arc then needs two more
//! sines), `bench_mark(5)`. Per tick = (ticks - plant) / N for each phase.
//!
//! Then the longest spans for which the firmware holds the application's lock, each
//! between two markers (minus an empty span, `bench_mark(10)`/`bench_mark(11)`): the last
//! byte of a `ReadLog` request for a full 992-byte chunk, which decodes it and encodes the
//! ~1 KiB answer (postcard, CRC, COBS), `bench_mark(6)`/`bench_mark(7)`; one telemetry
//! frame, `bench_mark(8)`/`bench_mark(9)`. Under a critical-section mutex these masked
//! the stepper interrupt; under the ceiling mutex they mask only the control executor.
//! Last, the critical sections that remain: an `embassy_sync` `Signal` signalled and
//! taken (what the storage and control tasks exchange), `bench_mark(12)`/`bench_mark(13)`;
//! a settings save handed to the storage task and taken there (`Channel` of a
//! `PersistItem`, copied inside its critical sections), `bench_mark(14)`/`bench_mark(15)`.
//! Then N turn-law steps of a differential drive's odometry (a law stored),
//! `bench_mark(16)`/`bench_mark(17)`, per step; N law steps with all three laws stored,
//! `bench_mark(18)`/`bench_mark(19)`; N turn-law steps of an omni robot's odometry (a law
//! stored), `bench_mark(20)`/`bench_mark(21)`.
#![no_std]
#![no_main]

use calib_core::correction::DiffLaws;
use calib_core::diff_laws::DiffLawOdometry;
use calib_core::omni_laws::OmniLawOdometry;
use calib_core::encoder::CounterWidth;
use calib_core::motion::Segment;
use calib_core::protocol::{encode, MAX_WIRE};
use calib_core::protocol::{BootReport, Params, ProgramSpec, Request, Stored};
use calib_core::robot::presets;
use calib_core::Corrections;
use core::panic::PanicInfo;
use cortex_m_rt::entry;
use cortex_m_semihosting::{debug, hprintln};
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::signal::Signal;
use firmware_app::{defaults, App, EncoderSource, PersistItem, Server, Step, WheelDriver};

/// Ticks counted.
pub const N: u32 = 1000;
const WARMUP: u32 = 1000;

/// Wheel angles of a first-order DC plant, in encoder counts.
#[derive(Clone)]
struct Enc {
    counts: [f32; 4],
}

impl EncoderSource for Enc {
    fn width(&self) -> CounterWidth {
        CounterWidth::Bits16
    }
    fn raw(&mut self, wheel: usize) -> u32 {
        self.counts
            .get(wheel)
            .map_or(0, |c| *c as i32 as u32 & 0xFFFF)
    }
}

#[derive(Clone)]
struct Drv {
    duty: [f32; 4],
    omega: [f32; 4],
}

impl WheelDriver for Drv {
    fn set_duty(&mut self, wheel: usize, duty: f32) {
        if let Some(d) = self.duty.get_mut(wheel) {
            *d = duty;
        }
    }
    fn set_steps(&mut self, _: usize, _: f32, _: i32) {}
    fn stop_all(&mut self) {
        self.duty = [0.0; 4];
    }
}

/// One millisecond of the plant: 20 rad/s at full duty, 50 ms time constant.
#[inline(never)]
fn plant(enc: &mut Enc, drv: &mut Drv) {
    const COUNTS_PER_RAD: f32 = 1920.0 / core::f32::consts::TAU;
    for i in 0..4 {
        drv.omega[i] += 0.02 * (20.0 * drv.duty[i] - drv.omega[i]);
        enc.counts[i] += drv.omega[i] * 1e-3 * COUNTS_PER_RAD;
    }
}

/// A marker whose address the counting script looks for.
#[no_mangle]
#[inline(never)]
pub extern "C" fn bench_mark(id: u32) {
    core::hint::black_box(id);
}

#[entry]
fn main() -> ! {
    static mut LOG: [u8; 16 * 1024] = [0; 16 * 1024];
    let params = Params {
        robot: presets::omni4(),
        ..defaults::params()
    };
    let corrections = Corrections::Omni {
        f_lat: heapless::Vec::from_slice(&[1.02, 0.98, 1.01, 0.99]).unwrap_or_default(),
        f_lon: 0.97,
    };
    let boot = BootReport {
        corrections: Stored::Loaded,
        params: Stored::Loaded,
    };
    let mut app = App::new(params, corrections, boot, LOG, 0);
    let segments = [
        Segment::Translate {
            dx_m: 0.4,
            dy_m: 0.3,
        },
        Segment::Turn { angle_rad: 6.0 },
    ];
    let program = ProgramSpec::Custom(heapless::Vec::from_slice(&segments).unwrap_or_default());
    let _ = app.handle(
        Request::RunProgram {
            program,
            log_rate_hz: 100,
            link_timeout_ms: 0,
        },
        0,
    );
    let mut enc = Enc { counts: [0.0; 4] };
    let mut drv = Drv {
        duty: [0.0; 4],
        omega: [0.0; 4],
    };
    let mut t = 0u64;
    for _ in 0..WARMUP {
        t += 1000;
        app.tick(t, &mut enc, &mut drv);
        plant(&mut enc, &mut drv);
    }
    bench_mark(1);
    for _ in 0..N {
        t += 1000;
        app.tick(t, &mut enc, &mut drv);
        plant(&mut enc, &mut drv);
    }
    bench_mark(2);
    // The plant alone, on a copy: the application's world is not disturbed.
    let (mut e2, mut d2) = (enc.clone(), drv.clone());
    for _ in 0..N {
        plant(&mut e2, &mut d2);
    }
    core::hint::black_box((&e2, &d2));
    bench_mark(3);
    // Into the turn: the translate ends after 2.67 s, the turn cruises from 3.2 s.
    for _ in 0..1300 {
        t += 1000;
        app.tick(t, &mut enc, &mut drv);
        plant(&mut enc, &mut drv);
    }
    bench_mark(4);
    for _ in 0..N {
        t += 1000;
        app.tick(t, &mut enc, &mut drv);
        plant(&mut enc, &mut drv);
    }
    bench_mark(5);

    // The longest lock holders of the firmware's link task.
    let mut server = Server::new();
    let mut req = [0u8; MAX_WIRE];
    let read = Request::ReadLog {
        trial: 1,
        offset: 0,
        max_len: 992,
    };
    let frame = encode(7, &read, &mut req).unwrap_or(&[]);
    let (last, head) = frame.split_last().unwrap_or((&0, &[]));
    for &b in head {
        let _ = server.push(b, &mut app, t);
    }
    bench_mark(6);
    let answer = match server.push(*last, &mut app, t) {
        Step::Send(w) => w.len(),
        _ => 0,
    };
    bench_mark(7);
    let _ = app.handle(Request::SetTelemetry { period_ms: 10 }, t);
    t += 20_000;
    app.tick(t, &mut enc, &mut drv);
    bench_mark(8);
    let tele = server.telemetry(&mut app).map_or(0, |w| w.len());
    bench_mark(9);
    bench_mark(10);
    bench_mark(11);
    static SIG: Signal<CriticalSectionRawMutex, u32> = Signal::new();
    bench_mark(12);
    SIG.signal(8_000_000);
    let taken = SIG.try_take();
    bench_mark(13);
    static SAVE: Channel<CriticalSectionRawMutex, PersistItem, 1> = Channel::new();
    let item = PersistItem::Params(defaults::params());
    bench_mark(14);
    let sent = SAVE.try_send(item).is_ok();
    let got = SAVE.try_receive().is_ok();
    bench_mark(15);
    core::hint::black_box((sent, got));
    // The odometry's law step of a differential drive with a law stored (the omni robot
    // above stores none, so its tick skips it): N ticks on an arc, first the turn law
    // alone, then all three laws (turn, speed, acceleration).
    let diff = presets::mobolab();
    let mut d = calib_core::Twist::new(0.0f32, 0.0, 0.0);
    for (mark, laws) in [
        (16, DiffLaws {
            e_b_arc: 0.0057,
            ..DiffLaws::default()
        }),
        (18, DiffLaws {
            e_b_arc: 0.0057,
            speed_rel: -0.03,
            accel_slip_s: 0.02,
        }),
    ] {
        let c = calib_core::Corrections::diff_drive(1.0, 1.0, 1.0, laws);
        let mut law = DiffLawOdometry::<f32>::new(&diff, &c, 1e-3);
        bench_mark(mark);
        for i in 0..N {
            let k = core::hint::black_box(i as f32 * 1e-6);
            // A stand-in for the kinematics that reads the rotations (else the speed and
            // acceleration laws' work on them would be optimised away).
            d = law.apply(&[2e-3 + k, 3e-3 - k], |p| {
                calib_core::Twist::new(p[0] * 0.05, 0.0, (p[1] - p[0]) * 0.25)
            });
        }
        bench_mark(mark + 1);
    }
    // An omni robot's turn law stored (protocol v8, `calib_core::omni_laws`): N steps on
    // an arc of the bench's four-wheel omni robot, whose own tick above stores none.
    let omni = presets::omni4();
    let f_lat = [1.0; 4].into_iter().collect();
    let c = calib_core::Corrections::omni(f_lat, 1.0, 0.019);
    let mut law = OmniLawOdometry::<f32>::new(&omni, &c, 1e-3);
    bench_mark(20);
    for i in 0..N {
        let k = core::hint::black_box(i as f32 * 1e-6);
        d = law.apply(&[2e-3 + k, 3e-3 - k, 2e-3, 3e-3], |p| {
            calib_core::Twist::new((p[0] + p[1]) * 0.03, (p[1] - p[2]) * 0.03, (p[3] - p[0]) * 0.1)
        });
    }
    bench_mark(21);
    core::hint::black_box(d);
    hprintln!(
        "read-log answer {} bytes, telemetry {} bytes, signal {:?}",
        answer,
        tele,
        taken
    );
    let s = app.status();
    hprintln!(
        "ticks {} fault {} pose ({} mm, {} mm, {} mrad) records {}",
        N,
        s.fault.is_some(),
        (s.pose.x * 1000.0) as i32,
        (s.pose.y * 1000.0) as i32,
        (s.pose.theta * 1000.0) as i32,
        app.log().list().trials.first().map_or(0, |t| t.records)
    );
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(_: &PanicInfo) -> ! {
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
