//! The firmware's application (firmware-app, the code the STM32 runs) against the
//! simulator, through the virtual board with no link: tick by tick, requests handed to
//! the application directly, physics and encoders from the simulator.

use calib_core::kinematics::Twist;
use calib_core::motion::{Direction, OmniPath};
use calib_core::protocol::{Mode, ProgramSpec, Request, StopReason};
use calib_core::Corrections;
use firmware_app::{ByteStream, Handled};
use formats::robot_file;
use sim::{SimConfig, SimRobot, Surface};
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

fn board(name: &str, faults: sim::Faults) -> VirtualBoard {
    let robot = robot_file::load(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(name),
    )
    .unwrap();
    let sim = SimRobot::new(&robot, faults, Surface::flat(), SimConfig::default()).unwrap();
    VirtualBoard::boot(&robot, sim, board_flash(None).unwrap()).unwrap()
}

fn request(b: &mut VirtualBoard, r: Request) {
    let now = b.now_us();
    match b.app.handle(r, now) {
        Handled::Reply(calib_core::protocol::Response::Ok) => {}
        Handled::Reply(other) => panic!("unexpected answer {other:?}"),
        Handled::Persist(_) => panic!("unexpected persist"),
    }
}

#[test]
fn dc_wheels_track_the_profile_within_two_percent() {
    // 001's omni robot with the simulator's DC motors (inertia, friction, back-EMF),
    // closed by the firmware's PI loops: a 1 m path along x, wheels 1 and 3 cruising at
    // 0.3 m/s / 0.03 m = 10 rad/s.
    let mut b = board("omni4.toml", sim::Faults::none(4));
    request(
        &mut b,
        Request::RunProgram {
            program: ProgramSpec::Omni {
                idle: calib_core::protocol::IdleWheels::Released,
                path: OmniPath::W1,
                length_m: 1.0,
            },
            log_rate_hz: 0,
            link_timeout_ms: 0,
        },
    );
    let mut worst: f64 = 0.0;
    let mut cruise_ticks = 0;
    let mut window_start = [0f64; 4];
    for _ in 0..6000 {
        b.step(&mut Quiet);
        let s = b.app.status();
        let cmd = s.wheel_cmds[0];
        if (cmd.abs() - 10.0).abs() > 1e-3 {
            cruise_ticks = 0;
            continue;
        }
        cruise_ticks += 1;
        // The true wheel rate from the simulator's wheel angles over 50 ms windows, from
        // 0.5 s into the cruise (steady state: the PI and the rate estimate have settled).
        if cruise_ticks % 50 == 0 {
            for i in [0, 2] {
                let angle = b.hw.sim.wheel_angle(i);
                if cruise_ticks > 500 {
                    let rate = (angle - window_start[i]) / 0.05;
                    worst =
                        worst.max(((rate - s.wheel_cmds[i] as f64) / s.wheel_cmds[i] as f64).abs());
                }
                window_start[i] = angle;
            }
        }
    }
    assert!(worst > 0.0, "no steady-state window was measured");
    assert!(
        worst < 0.02,
        "worst steady-state error {:.2} %",
        worst * 100.0
    );
    eprintln!("worst steady-state tracking error {:.3} %", worst * 100.0);
}

#[test]
fn command_timeout_stops_the_motors_within_100_ms() {
    let mut b = board("omni4.toml", sim::Faults::none(4));
    // The host drives for 0.5 s, refreshing every 100 ms, then falls silent.
    for _ in 0..5 {
        request(
            &mut b,
            Request::Drive {
                twist: Twist::new(0.2, 0.0, 0.0),
                timeout_ms: 0,
            },
        );
        for _ in 0..100 {
            b.step(&mut Quiet);
        }
    }
    let silent_at = b.now_us();
    let timeout_ms = b.app.params().safety.command_timeout_ms as u64;
    let mut stopped_at = None;
    for _ in 0..2000 {
        b.step(&mut Quiet);
        let s = b.app.status();
        if stopped_at.is_none()
            && matches!(s.mode, Mode::Idle)
            && s.wheel_cmds.iter().all(|c| *c == 0.0)
        {
            assert_eq!(s.stop, StopReason::CommandTimeout);
            stopped_at = Some(b.now_us());
        }
    }
    let late_ms = (stopped_at.expect("the motors never stopped") - silent_at) as f64 / 1000.0
        - timeout_ms as f64;
    assert!(
        late_ms <= 100.0,
        "motors stopped {late_ms} ms after the timeout expired"
    );
    // And the robot comes to rest: the simulated wheels stop turning.
    let t = b.hw.sim.true_twist();
    assert!(t.vx.abs() < 1e-3, "still moving at {} m/s", t.vx);
}

#[test]
fn corrected_umbmark_square_lands_where_calib_core_predicts() {
    // MoboLab (stepper) with E_d = 1.006 and E_b = 1.04 hidden in the simulator; the board
    // runs with partial corrections (E_d 1.002, E_b 1.02). What remains is the ratio of
    // truth to correction, and calib-core's exact square model must predict the end error.
    let (ed, eb) = (1.006, 1.04);
    let mut f = sim::Faults::none(2);
    f.radius_scale = vec![2.0 / (ed + 1.0), 2.0 * ed / (ed + 1.0)];
    f.wheelbase_scale = eb;
    let mut b = board("mobolab.toml", f);
    let (ed_c, eb_c) = (1.002, 1.02);
    let corr = Corrections::DiffDrive {
        c_l: 2.0 / (ed_c + 1.0),
        c_r: 2.0 / (1.0 / ed_c + 1.0),
        e_b: eb_c,
    };
    request(&mut b, Request::SetCorrections(corr));
    let side = 2.0;
    request(
        &mut b,
        Request::RunProgram {
            program: ProgramSpec::Umbmark {
                side_m: side,
                dir: Direction::Ccw,
            },
            log_rate_hz: 10,
            link_timeout_ms: 0,
        },
    );
    let mut n = 0;
    while b.truths().is_empty() && n < 200_000 {
        b.step(&mut Quiet);
        n += 1;
    }
    let t = b.truths()[0];
    // The robot believes its wheels are in ratio ed_c and its wheelbase eb_c times
    // nominal; relative to that belief the residual errors are ed/ed_c and eb/eb_c.
    let (px, py, _) = calib_core::umbmark::square_end_error(
        ed / ed_c,
        eb / eb_c,
        side,
        0.4 * eb_c,
        Direction::Ccw,
    )
    .unwrap();
    let miss = (t.x_err_m - px).hypot(t.y_err_m - py);
    // Tolerance: one full step of a 100 mm wheel through 78/16 gears moves it 0.32 mm;
    // step quantisation at the ends of 8 segments and the encoder's 0.16 mm resolution
    // stay within a few millimetres of an error of ~10 cm.
    assert!(
        miss < 3e-3,
        "simulated ({:.4}, {:.4}) vs predicted ({px:.4}, {py:.4}): {miss} m",
        t.x_err_m,
        t.y_err_m
    );
    assert!(
        px.hypot(py) > 0.02,
        "the residual error should be measurable: {px} {py}"
    );
}
