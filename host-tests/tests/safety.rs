//! The board's own safety, through the virtual board (the firmware's application on the
//! simulator, requests handed to it directly, no link):
//!
//! - a NaN anywhere on the way to a motor register is caught before it is written: the
//!   motor command is 0, a `NonFinite` fault is latched and reported, and every other
//!   wheel stops in the same tick (the policy for every fault: all motors off);
//! - the host-link failsafe: a program whose host stops sending requests is cut after its
//!   link timeout; one whose host keeps polling runs on; 0 turns it off explicitly.

use calib_core::motion::{Direction, OmniPath};
use calib_core::protocol::{
    ControlValue, Fault, IdleWheels, Mode, ProgramSpec, Rejection, Request, Response, StopReason,
    TrialEnd, DEFAULT_LINK_TIMEOUT_MS, MIN_LINK_TIMEOUT_MS,
};
use firmware_app::{ByteStream, Handled};
use formats::robot_file;
use sim::{SimConfig, SimRobot, Surface, WheelInput};
use std::path::Path;
use wheelcal::virtual_board::{board_flash, VirtualBoard};

/// A link on which nothing arrives.
struct Quiet;
impl ByteStream for Quiet {
    fn read(&mut self, _: &mut [u8]) -> usize {
        0
    }
    fn write(&mut self, _: &[u8]) {}
}

fn board(name: &str) -> VirtualBoard {
    let robot = robot_file::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(name),
    )
    .unwrap();
    let n = robot.wheel_count();
    let sim = SimRobot::new(
        &robot,
        sim::Faults::none(n),
        Surface::flat(),
        SimConfig::default(),
    )
    .unwrap();
    VirtualBoard::boot(&robot, sim, board_flash(None).unwrap()).unwrap()
}

fn answer(b: &mut VirtualBoard, r: Request) -> Response<'static> {
    let now = b.now_us();
    match b.app.handle(r, now) {
        Handled::Reply(resp) => match resp {
            Response::Ok => Response::Ok,
            Response::Rejected(why) => Response::Rejected(why),
            Response::Status(s) => Response::Status(s),
            other => panic!("unexpected answer {other:?}"),
        },
        Handled::Persist(_) => panic!("unexpected persist"),
    }
}

fn ok(b: &mut VirtualBoard, r: Request) {
    match answer(b, r) {
        Response::Ok => {}
        other => panic!("expected Ok, got {other:?}"),
    }
}

fn run_ms(b: &mut VirtualBoard, ms: u64) {
    for _ in 0..ms {
        b.step(&mut Quiet);
    }
}

fn is_off(i: &WheelInput) -> bool {
    matches!(i, WheelInput::Duty(d) if *d == 0.0) || matches!(i, WheelInput::Steps(0))
}

/// A program that keeps every wheel busy for several seconds.
fn program(robot: &str) -> ProgramSpec {
    if robot.starts_with("omni") {
        ProgramSpec::Omni {
            idle: IdleWheels::Held,
            path: OmniPath::W1,
            length_m: 2.0,
        }
    } else {
        ProgramSpec::Umbmark {
            side_m: 2.0,
            dir: Direction::Cw,
        }
    }
}

/// Every f32 of the control path that reaches a register or a timer, with the robot it is
/// tested on: the commanded and measured rates feed the PI loop (DC) or the step
/// generator; the duty becomes TIM2's compare value and a direction pin; the step rate
/// becomes TIM2's half period and a direction pin. (The step count is an i32: a NaN rate
/// gives 0 steps, and the step rate is checked.)
const AUDIT: [(&str, ControlValue); 5] = [
    ("omni4.toml", ControlValue::Command),
    ("omni4.toml", ControlValue::Rate),
    ("omni4.toml", ControlValue::Duty),
    ("mobolab.toml", ControlValue::Command),
    ("mobolab.toml", ControlValue::StepRate),
];

#[test]
fn every_value_on_the_way_to_a_register_is_checked() {
    // The list covers every value the application checks, on both drive types.
    for v in ControlValue::ALL {
        assert!(AUDIT.iter().any(|(_, a)| *a == v), "{v:?} is not tested");
    }
}

/// A NaN forced into wheel 2's control path (as a bug upstream would put it there) never
/// reaches the motor: in the very tick it appears every motor input is off, the fault
/// names the wheel and the value, and the robot comes to rest.
#[test]
fn a_nan_in_the_control_path_stops_every_wheel() {
    for (robot, value) in AUDIT {
        let mut b = board(robot);
        ok(
            &mut b,
            Request::RunProgram {
                program: program(robot),
                log_rate_hz: 50,
                link_timeout_ms: 0,
            },
        );
        run_ms(&mut b, 1500);
        let n = b.hw.inputs().len();
        let moving = b.hw.inputs().iter().filter(|i| !is_off(i)).count();
        assert!(
            moving >= 2,
            "{robot}: only {moving} wheels driven before the NaN"
        );
        let wheel = 1;
        b.app.inject_nan(Some((wheel, value)));
        b.step(&mut Quiet);
        // The same tick: nothing non-finite written, every motor off.
        for (i, inp) in b.hw.inputs().iter().enumerate() {
            assert!(
                is_off(inp),
                "{robot} {value:?}: wheel {i} still gets {inp:?} after the NaN"
            );
        }
        let s = b.app.status();
        // A stepper has no measured rate in its path and its duty is a step rate: the
        // first value found non-finite is the one the NaN entered at, or the command for
        // an output whose inputs were poisoned.
        let expected = match value {
            ControlValue::Duty | ControlValue::StepRate => ControlValue::Command,
            v => v,
        };
        assert_eq!(
            s.fault,
            Some(Fault::NonFinite {
                wheel: wheel as u8,
                value: expected
            }),
            "{robot} {value:?}"
        );
        assert_eq!(s.stop, StopReason::Fault);
        assert!(matches!(s.mode, Mode::Idle));
        let trial = b.app.log().list().trials.last().cloned().unwrap();
        assert_eq!(trial.end, TrialEnd::Fault);
        // Latched: motion is refused until ClearFault, and the motors stay off.
        match answer(
            &mut b,
            Request::RunProgram {
                program: program(robot),
                log_rate_hz: 0,
                link_timeout_ms: 0,
            },
        ) {
            Response::Rejected(Rejection::Faulted(f)) => assert_eq!(Some(f), s.fault),
            other => panic!("{robot}: a program started while faulted: {other:?}"),
        }
        run_ms(&mut b, 400);
        assert!(b.hw.inputs().iter().all(is_off));
        // At rest 400 ms later: every wheel's true rate below 0.2 rad/s (a DC wheel coasts
        // down through the motor's friction and back-EMF; a stepper stops at once).
        for i in 0..n {
            let w = if robot.starts_with("omni") {
                b.hw.sim.motor_rate(i)
            } else {
                0.0
            };
            assert!(w.abs() < 0.2, "{robot}: wheel {i} still turns at {w} rad/s");
        }
        let twist = b.hw.sim.true_twist();
        assert!(
            twist.vx.hypot(twist.vy) < 0.01 && twist.omega.abs() < 0.05,
            "{robot} {value:?}: still moving {twist:?}"
        );
        // Once the cause is gone, ClearFault lets the robot drive again.
        b.app.inject_nan(None);
        ok(&mut b, Request::ClearFault);
        ok(
            &mut b,
            Request::RunProgram {
                program: program(robot),
                log_rate_hz: 0,
                link_timeout_ms: 0,
            },
        );
        run_ms(&mut b, 500);
        assert_eq!(b.app.status().fault, None);
        assert!(b.hw.inputs().iter().any(|i| !is_off(i)));
    }
}

/// The host-link failsafe: with the console's default timeout (500 ms) and no request
/// after the start, the program is cut 500 ms later (to the 1 ms tick), logged as
/// `LinkLost`, and the motors are off.
#[test]
fn a_silent_host_stops_the_program_after_its_link_timeout() {
    let mut b = board("omni4.toml");
    let start = b.now_us();
    ok(
        &mut b,
        Request::RunProgram {
            program: program("omni4"),
            log_rate_hz: 50,
            link_timeout_ms: DEFAULT_LINK_TIMEOUT_MS,
        },
    );
    let mut cut_at = None;
    for _ in 0..2000 {
        b.step(&mut Quiet);
        if cut_at.is_none() && matches!(b.app.status().mode, Mode::Idle) {
            cut_at = Some(b.now_us() - start);
        }
    }
    let cut_ms = cut_at.expect("the program was never cut") as f64 / 1000.0;
    let want = DEFAULT_LINK_TIMEOUT_MS as f64;
    assert!(
        (want..=want + 2.0).contains(&cut_ms),
        "cut {cut_ms} ms after the last request"
    );
    let s = b.app.status();
    assert_eq!(s.stop, StopReason::LinkLost);
    assert_eq!(s.fault, None, "a lost link is a stop, not a latched fault");
    assert!(b.hw.inputs().iter().all(is_off));
    let trial = b.app.log().list().trials.last().cloned().unwrap();
    assert_eq!(trial.end, TrialEnd::LinkLost);
}

/// A host that polls (the console asks for the status every 50 ms while it waits) keeps
/// the program alive: polling every 200 ms for 3 s, the program still runs; silence then
/// ends it within the timeout.
#[test]
fn a_polling_host_keeps_the_program_running() {
    let mut b = board("omni4.toml");
    ok(
        &mut b,
        Request::RunProgram {
            program: program("omni4"),
            log_rate_hz: 0,
            link_timeout_ms: DEFAULT_LINK_TIMEOUT_MS,
        },
    );
    for _ in 0..15 {
        run_ms(&mut b, 200);
        match answer(&mut b, Request::GetStatus) {
            Response::Status(s) => assert!(
                matches!(s.mode, Mode::Program { .. }),
                "stopped while polled: {:?}",
                s.stop
            ),
            other => panic!("{other:?}"),
        }
    }
    run_ms(&mut b, DEFAULT_LINK_TIMEOUT_MS as u64 + 2);
    assert_eq!(b.app.status().stop, StopReason::LinkLost);
}

/// 0 turns the failsafe off (an explicit choice: `--no-link-failsafe`): the program runs
/// 3 s without a request. A timeout below the minimum is refused and nothing starts.
#[test]
fn zero_turns_the_failsafe_off_and_too_short_is_refused() {
    let mut b = board("omni4.toml");
    match answer(
        &mut b,
        Request::RunProgram {
            program: program("omni4"),
            log_rate_hz: 0,
            link_timeout_ms: MIN_LINK_TIMEOUT_MS - 1,
        },
    ) {
        Response::Rejected(Rejection::InvalidProgram(e)) => {
            assert!(e.to_string().contains("at least 250 ms"), "{e}")
        }
        other => panic!("a too-short link timeout was accepted: {other:?}"),
    }
    assert!(matches!(b.app.status().mode, Mode::Idle));
    assert!(b.app.log().list().trials.is_empty());
    ok(
        &mut b,
        Request::RunProgram {
            program: program("omni4"),
            log_rate_hz: 0,
            link_timeout_ms: 0,
        },
    );
    run_ms(&mut b, 3000);
    assert!(matches!(b.app.status().mode, Mode::Program { .. }));
    assert_eq!(b.app.status().stop, StopReason::None);
}
