//! Simulator tests against physics worked out by hand.

use calib_core::correction::Corrections;
use calib_core::encoder::{CounterExtender, CounterWidth};
use calib_core::kinematics::{Kinematics, Twist};
use calib_core::motion::{Direction, ProfileLimits, Program};
use calib_core::odometry::{integrate_arc, Odometry, Pose};
use calib_core::robot::{presets, Robot};
use sim::{
    record, Effect, EncoderMount, Faults, LegMotion, Motion, RandomMotion, RecordConfig, SimConfig,
    SimRobot, Surface, WheelInput,
};
use std::f64::consts::{FRAC_PI_2, TAU};
use std::path::Path;

fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

fn quiet() -> SimConfig {
    SimConfig {
        random_counter_start: false,
        ..SimConfig::default()
    }
}

fn rates(sim: &SimRobot, k: &Kinematics<f64>, t: &Twist<f64>) -> Vec<WheelInput> {
    let mut w = vec![0.0; sim.wheel_count()];
    k.inverse_into(t, &mut w);
    w.into_iter().map(WheelInput::Rate).collect()
}

#[test]
fn ideal_inputs_reproduce_calib_core_kinematics() {
    // A fault-free robot driven with ideal wheel rates moves exactly as calib-core's
    // kinematics says: the body follows the exact arc of the twist every tick. The only
    // differences are f64 rounding over 5000 ticks (~1e-13 m).
    for r in [robot("omni4"), robot("mobolab"), robot("omni3")] {
        let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
        let mut sim =
            SimRobot::new(&r, Faults::none(r.wheel_count()), Surface::flat(), quiet()).unwrap();
        let tw = if r.kind == calib_core::RobotKind::Omni {
            Twist::new(0.12, -0.07, 0.6)
        } else {
            Twist::new(0.25, 0.0, 0.6)
        };
        let mut expect = Pose::new(0.0, 0.0, 0.0);
        let mut odo = Odometry::<f64>::default();
        let mut ext: Vec<_> = (0..r.wheel_count())
            .map(|i| CounterExtender::new(CounterWidth::Bits16, sim.encoder_raw(i) as u32))
            .collect();
        let cpr = r.drive.encoder_counts_per_rev;
        for _ in 0..5000 {
            let inp = rates(&sim, &k, &tw);
            sim.step(1e-3, &inp).unwrap();
            expect = integrate_arc(expect, &tw.scale(1e-3));
            let inc: Vec<f64> = ext
                .iter_mut()
                .enumerate()
                .map(|(i, e)| e.update(sim.encoder_raw(i) as u32) as f64 * TAU / cpr)
                .collect();
            odo.update(&k.forward(&inc));
        }
        let p = sim.true_pose();
        assert!(
            (p.x - expect.x).abs() < 1e-12 && (p.y - expect.y).abs() < 1e-12,
            "{p:?} {expect:?}"
        );
        assert!((p.theta - expect.theta).abs() < 1e-12);
        // Odometry from the quantised encoders: each wheel reads at most one count
        // (2 pi / 1920 rad, 0.1 mm of a 3 cm wheel, 0.16 mm of a 5 cm one) behind the truth,
        // bounded, not accumulating. The heading error is then at most the sum of the
        // forward kinematics' |omega| gains times a count (omni4: 4 x 0.098 mm / (4 x 35 mm)
        // = 2.8e-3 rad), and the position error at most that heading error times the path
        // (< 0.75 m here): 2 mm.
        let o = odo.pose();
        assert!((o.theta - p.theta).abs() < 3e-3, "{o:?} vs {p:?}");
        assert!(
            (o.x - p.x).abs() < 2e-3 && (o.y - p.y).abs() < 2e-3,
            "{o:?} vs {p:?}"
        );
    }
}

#[test]
fn encoder_reads_1920_counts_per_wheel_rev_on_wheel_or_motor() {
    for mount in [EncoderMount::Wheel, EncoderMount::Motor] {
        let r = robot("mobolab"); // 1920 counts per wheel rev, gear 4.875
        let cfg = SimConfig {
            encoder_mount: mount,
            ..SimConfig::default() // random counter start: the count is relative anyway
        };
        let mut sim = SimRobot::new(&r, Faults::none(2), Surface::flat(), cfg).unwrap();
        let mut ext = CounterExtender::new(CounterWidth::Bits16, sim.encoder_raw(0) as u32);
        // 40 wheel revolutions at 2 pi rad/s: 76800 counts, more than the 16-bit range.
        for _ in 0..40_000 {
            sim.step(1e-3, &[WheelInput::Rate(TAU), WheelInput::Rate(0.0)])
                .unwrap();
            ext.update(sim.encoder_raw(0) as u32);
        }
        // 40 revolutions exactly, up to f64 rounding in the angle sum (the encoder reads
        // floor, so it may sit one count below).
        assert!((ext.position() - 76_800).abs() <= 1, "{}", ext.position());
        assert_eq!(ext.position(), sim.encoder_count(0));
    }
}

#[test]
fn stepper_beyond_pull_out_loses_multiples_of_four_full_steps() {
    // MoboLab: 200 steps/rev x 4.875 = 155.2 steps per wheel rad. Pull-out at 5 rad/s^2;
    // commanded: 40 rad/s^2 to 3 rad/s, hold, then down at 2 rad/s^2 (within the limit).
    let r = robot("mobolab");
    let e = Effect::parse("missed_steps=max_accel_rad_s2:5").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), quiet()).unwrap();
    let mut acc = calib_core::stepper::StepAccumulator::new(r.drive.steps_per_wheel_rad());
    let mut w = 0.0f64;
    let mut commanded = 0i64;
    for k in 0..6000 {
        w = if k < 3000 {
            (w + 0.04).min(3.0)
        } else {
            (w - 0.002).max(0.0)
        };
        let n = acc.advance(w as f32, 1e-3);
        commanded += n as i64;
        sim.step(1e-3, &[WheelInput::Steps(n), WheelInput::Steps(n)])
            .unwrap();
    }
    for _ in 0..1000 {
        sim.step(1e-3, &[WheelInput::Steps(0), WheelInput::Steps(0)])
            .unwrap();
    }
    let lost = sim.steps_lost(0);
    assert!(lost > 0 && lost % 4 == 0, "lost {lost}");
    // The wheel stands exactly `lost` steps short of the command (the pull-in has decayed).
    let wheel_steps = sim.wheel_angle(0) * r.drive.steps_per_wheel_rad();
    assert!((commanded as f64 - wheel_steps - lost as f64).abs() < 1e-6);
    // Size: at 5 rad/s^2 the rotor needs 0.6 s to reach 3 rad/s and covers 0.9 rad; the
    // command (75 ms ramp) covers 1.69 rad: ~0.79 rad = 123 steps lost, within the
    // re-lock granularity (4 steps) and pull-in dynamics.
    assert!((lost as f64 - 123.0).abs() < 40.0, "lost {lost}");
}

#[test]
fn backlash_delays_the_robot_after_a_reversal() {
    // 0.04 rad of play, wheel rate 2 rad/s: after the command reverses, the wheels (and
    // the robot) stand still for 0.04 / 2 = 20 ms.
    let r = robot("omni4");
    let e = Effect::parse("backlash=backlash_rad:0.04").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), quiet()).unwrap();
    let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
    let fwd = rates(&sim, &k, &Twist::new(0.06, 0.0, 0.0)); // 2 rad/s on wheels 1 and 3
    let back = rates(&sim, &k, &Twist::new(-0.06, 0.0, 0.0));
    for _ in 0..500 {
        sim.step(1e-3, &fwd).unwrap();
    }
    let x0 = sim.true_pose().x;
    let mut still = 0;
    for _ in 0..200 {
        sim.step(1e-3, &back).unwrap();
        if sim.true_pose().x == x0 {
            still += 1;
        }
    }
    assert!(
        (still as f64 * 1e-3 - 0.020).abs() <= 1e-3 + 1e-12,
        "still {still} ms"
    );
}

#[test]
fn cable_crossings_shorten_a_straight_run_by_loss_times_crossings() {
    // The MoboLab of [Measuring errors] drives 1 m along x over cables every 30 mm costing
    // 0.8 mm each: the body comes short by exactly 0.8 mm per cable its wheels crossed (both
    // wheels cross together, so the body loses what each wheel loses).
    let r = robot("mobolab");
    let e = Effect::parse("floor_bumps=spacing_m:0.03,loss_m:0.0008").unwrap();
    let cfg = SimConfig {
        start: Pose::new(0.001, 0.0, 0.0),
        ..quiet()
    };
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), cfg).unwrap();
    let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
    let prog = Program::from_segments(&[calib_core::motion::Segment::Straight { distance_m: 1.0 }])
        .unwrap();
    let mut run = prog.runner(ProfileLimits::default());
    let mut w = vec![0.0; 2];
    while let Some(t) = run.twist_at_tick(1e-3) {
        k.inverse_into(&t, &mut w);
        sim.step(1e-3, &[WheelInput::Rate(w[0]), WheelInput::Rate(w[1])])
            .unwrap();
    }
    let crossings = sim.cable_crossings().to_vec();
    assert_eq!(crossings[0], crossings[1]);
    // The contacts (at x = body x) reach 1.001 - 32 * 0.0008 = 0.9754: cables 0.03 .. 0.96.
    assert_eq!(crossings[0], 32);
    let travelled = sim.true_pose().x - 0.001;
    // Exact up to f64 rounding of the per-tick sums.
    assert!(
        (travelled - (1.0 - 0.0008 * 32.0)).abs() < 1e-9,
        "{travelled}"
    );
}

#[test]
fn traction_limit_bounds_body_acceleration() {
    // mu = 0.2 on a differential drive whose weight is on its driven wheels: the body
    // accelerates at most 0.2 * 9.81 = 1.962 m/s^2 however hard the wheels spin up.
    let r = robot("mobolab");
    let e = Effect::parse("longitudinal_slip=mu:0.2").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), quiet()).unwrap();
    let w = 0.5 / 0.05; // 0.5 m/s at once
    let mut v = Vec::new();
    for _ in 0..400 {
        sim.step(1e-3, &[WheelInput::Rate(w), WheelInput::Rate(w)])
            .unwrap();
        v.push(sim.true_twist().vx);
    }
    // After 100 ms: 0.1962 m/s; reaches 0.5 m/s at 0.255 s and stays.
    assert!((v[99] - 0.1962).abs() < 1e-9, "{}", v[99]);
    assert!((v[399] - 0.5).abs() < 1e-12);
    // The wheels spun: their encoders count the full 0.5 m/s from the start, the body lags.
    let wheel_m = sim.wheel_angle(0) * 0.05;
    let body_m = sim.true_pose().x;
    // Lost distance: v^2/2 * (1/a) for an instant command = 0.25/2/1.962 = 63.7 mm.
    assert!(
        (wheel_m - body_m - 0.0637).abs() < 1e-3,
        "{}",
        wheel_m - body_m
    );
}

#[test]
fn side_slip_in_a_turn() {
    // v_y = -k v_x omega with k = 0.05 s: at 0.3 m/s and 1 rad/s, v_y = -0.015 m/s.
    let r = robot("mobolab");
    let e = Effect::parse("lateral_slip=side_slip_s:0.05").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), quiet()).unwrap();
    let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
    let inp = rates(&sim, &k, &Twist::new(0.3, 0.0, 1.0));
    sim.step(1e-3, &inp).unwrap();
    let t = sim.true_twist();
    assert!((t.vy + 0.015).abs() < 1e-12 && (t.vx - 0.3).abs() < 1e-12);
}

/// `SimConfig::speed_scale` 0.1 per m/s: wheels commanded for 0.3 m/s roll 3 % further
/// than their radius says, so the body moves at 0.309 m/s; at 0.1 m/s, 1 % (0.101 m/s).
/// The rolling speed is smoothed over 0.1 s, so each speed is held 2 s (e^-20 of the last
/// remains: 1e-10 m/s).
#[test]
fn wheels_whose_size_grows_with_speed_roll_further_the_faster_they_turn() {
    let r = robot("mobolab");
    let cfg = SimConfig {
        speed_scale: 0.1,
        ..quiet()
    };
    let mut sim = SimRobot::new(&r, Faults::none(2), Surface::flat(), cfg).unwrap();
    let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
    for v in [0.3, 0.1] {
        let inp = rates(&sim, &k, &Twist::new(v, 0.0, 0.0));
        for _ in 0..2000 {
            sim.step(1e-3, &inp).unwrap();
        }
        let t = sim.true_twist();
        let want = v * (1.0 + 0.1 * v);
        assert!(
            (t.vx - want).abs() < 1e-10 && t.omega.abs() < 1e-12,
            "{v}: {t:?}"
        );
    }
    // Out of its range (|speed_scale| <= 0.5): refused.
    let bad = SimConfig {
        speed_scale: 0.8,
        ..quiet()
    };
    assert!(SimRobot::new(&r, Faults::none(2), Surface::flat(), bad).is_err());
}

#[test]
fn free_wheels_roll_with_the_ground() {
    // [Korayem et al.]'s robot: front wheels driven, rear free. Driving straight 0.5 m, the
    // rear encoders (4096 counts/rev, r = 0.034 m) count the ground distance: 0.5 / (2 pi
    // 0.034) * 4096 = 9587 counts, to a count.
    let r = robot("wlr");
    let mut sim = SimRobot::new(&r, Faults::none(4), Surface::flat(), quiet()).unwrap();
    let w = 0.25 / 0.034;
    for _ in 0..2000 {
        sim.step(
            1e-3,
            &[
                WheelInput::Rate(w),
                WheelInput::Rate(w),
                WheelInput::Rate(99.0),
                WheelInput::Rate(-5.0),
            ],
        )
        .unwrap();
    }
    assert!((sim.true_pose().x - 0.5).abs() < 1e-9);
    for i in 2..4 {
        assert!(
            (sim.encoder_count(i) - 9587).abs() <= 1,
            "{}",
            sim.encoder_count(i)
        );
    }
}

#[test]
fn legs_shift_the_traction_limit() {
    // [Korayem et al.]: front legs at 30 deg, rear at 30 deg: the rear contact is 58 mm
    // behind the mass, the front 292 mm ahead, so the driven front pair carries
    // 0.058/0.350 = 16.6 % of the weight; rear legs at 150 deg: 0.292/0.584 = 50 %. With
    // mu = 0.5 the body's acceleration limit is mu g share: 0.81 and 2.45 m/s^2.
    let r = robot("wlr");
    for (rear_deg, share) in [(30.0f64, 0.0583 / 0.35), (150.0, 0.5)] {
        let legs = r.legs.unwrap();
        let exact = legs
            .front_load_share(30f64.to_radians(), rear_deg.to_radians())
            .unwrap();
        assert!((exact - share).abs() < 2e-3);
        let cfg = SimConfig {
            leg_front_rad: 30f64.to_radians(),
            leg_rear_rad: rear_deg.to_radians(),
            ..quiet()
        };
        let e = Effect::parse("longitudinal_slip=mu:0.5").unwrap();
        let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), cfg).unwrap();
        let w = 20.0;
        for _ in 0..100 {
            sim.step(
                1e-3,
                &[
                    WheelInput::Rate(w),
                    WheelInput::Rate(w),
                    WheelInput::Rate(0.0),
                    WheelInput::Rate(0.0),
                ],
            )
            .unwrap();
        }
        let a = sim.true_twist().vx / 0.1;
        assert!((a - 0.5 * 9.81 * exact).abs() < 1e-9, "a {a} share {exact}");
    }
}

#[test]
fn motors_off_roll_with_the_ground() {
    // [Redundant omni]'s 4W-1 path with wheels 2 and 4 off: wheels 1 and 3 alone set vx and
    // omega (no slip), the sideways velocity stays 0, and the free wheels' encoders see the
    // rotation: wheel 1 at r = 1.003 r0, wheel 3 nominal: omega = -(c1 + c3) / (2 l).
    let r = robot("omni4");
    let e = Effect::parse("wheel_diameter_mismatch=radius_scale_w1:1.003").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), quiet()).unwrap();
    let w = 0.1 / 0.03;
    for _ in 0..1000 {
        sim.step(
            1e-3,
            &[
                WheelInput::Rate(w),
                WheelInput::Free,
                WheelInput::Rate(-w),
                WheelInput::Free,
            ],
        )
        .unwrap();
    }
    let t = sim.true_twist();
    let omega = -(0.1 * 1.003 - 0.1) / (2.0 * 0.035);
    assert!((t.omega - omega).abs() < 1e-9 && t.vy.abs() < 1e-9, "{t:?}");
    assert!((t.vx - 0.1 * 2.003 / 2.0).abs() < 1e-9);
    // Wheel 2 (alpha 180: row [0, 1, -l]) turns at -l omega / r.
    let expect = -0.035 * omega * 1.0 / 0.03;
    assert!(
        (sim.wheel_angle(1) - expect).abs() < 1e-6,
        "{}",
        sim.wheel_angle(1)
    );
}

/// A three-wheel omni robot on [Redundant omni]'s 4W-1 path: wheel 2 (alpha 180 deg, it
/// rolls sideways) off, wheels 1 and 3 driven to move the body along x. With wheel 2 free
/// the sideways drift and the turn are free together (the driven rows leave free the
/// direction vy = -0.3 omega on the 0.15 m omni3), not along an axis; the body still
/// moves at exactly the speed the two wheels set, sqrt(3) / 2 of its rim speed each way,
/// with no drift and no turn, and wheel 2 does not turn. (Its normal equations were once
/// refused as singular, which left the robot standing and the board reporting a stall.)
#[test]
fn a_three_wheel_omni_robot_drives_straight_with_one_wheel_off() {
    let r = robot("omni3");
    let mut sim = SimRobot::new(&r, Faults::none(3), Surface::flat(), quiet()).unwrap();
    let rim = 0.1;
    let w = rim / 0.04;
    for _ in 0..1000 {
        sim.step(
            1e-3,
            &[WheelInput::Rate(w), WheelInput::Free, WheelInput::Rate(-w)],
        )
        .unwrap();
    }
    let t = sim.true_twist();
    let vx = rim / (3f64.sqrt() / 2.0);
    assert!((t.vx - vx).abs() < 1e-9 * vx, "{t:?}");
    assert!(t.vy.abs() < 1e-9 && t.omega.abs() < 1e-9, "{t:?}");
    assert!(sim.wheel_angle(1).abs() < 1e-9, "{}", sim.wheel_angle(1));
}

#[test]
fn all_motors_off_coasts_to_a_stop() {
    // E-stop at 0.2 m/s: every wheel free, the body rolls out at 1 m/s^2 (rolling
    // resistance and gear drag): 0.2 s and 0.2^2 / 2 = 20 mm.
    let r = robot("mobolab");
    let mut sim = SimRobot::new(&r, Faults::none(2), Surface::flat(), quiet()).unwrap();
    for _ in 0..100 {
        sim.step(1e-3, &[WheelInput::Rate(4.0); 2]).unwrap();
    }
    let x0 = sim.true_pose().x;
    for _ in 0..1000 {
        sim.step(1e-3, &[WheelInput::Free; 2]).unwrap();
    }
    assert_eq!(sim.true_twist().vx, 0.0);
    // One tick of discretisation: 0.2 m/s x 1 ms / 2.
    assert!(
        (sim.true_pose().x - x0 - 0.02).abs() < 2e-4,
        "{}",
        sim.true_pose().x - x0
    );
}

#[test]
fn recordings_are_deterministic_per_seed() {
    let r = robot("omni4");
    let effects = [
        Effect::parse("floor_bumps").unwrap(),
        Effect::parse("motor_lag=tau_s:0.05").unwrap(),
    ];
    let motion = Motion::Random(RandomMotion {
        duration_s: 5.0,
        v_max_m_s: 0.15,
        ..RandomMotion::default()
    });
    let csv = |seed| {
        let mut cfg = RecordConfig::default();
        cfg.sim.seed = seed;
        let rec = record(&r, &effects, Surface::flat(), &motion, &cfg).unwrap();
        let mut out = Vec::new();
        rec.recording.write_csv(&mut out).unwrap();
        (out, rec)
    };
    let (a, rec) = csv(7);
    let (b, _) = csv(7);
    let (c, _) = csv(8);
    assert_eq!(a, b);
    assert_ne!(a, c);
    // 200 Hz rows over 5 s plus the closing rest; vision on every 6th-7th row (30 Hz).
    assert!(rec.recording.len() >= 1000 && rec.recording.len() <= 1010);
    let poses = rec.recording.pose_rows().count();
    assert!((poses as f64 - 5.0 * 30.0).abs() <= 2.0, "{poses}");
    // The robot moved and the written directory reads back through calib-core.
    let dir = std::env::temp_dir().join(format!("sim-record-test-{}", std::process::id()));
    rec.write_dir(&dir).unwrap();
    let robot_back = formats::robot_file::load(&dir.join("robot.toml")).unwrap();
    let back =
        formats::recording::Recording::load(&dir.join("recording.csv"), &robot_back).unwrap();
    assert_eq!(back.len(), rec.recording.len());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn physical_recordings_close_the_pi_loop() {
    // omni4 with DC motors under calib-core's PI: the encoders follow the commands closely
    // but not exactly (motor dynamics), unlike the ideal mode where they match to a count.
    let r = robot("omni4");
    let motion = Motion::Program {
        program: Box::new(Program::omni_path(calib_core::motion::OmniPath::W1, 0.5)),
        limits: ProfileLimits::default(),
    };
    let mut cfg = RecordConfig::default();
    let ideal = record(&r, &[], Surface::flat(), &motion, &cfg).unwrap();
    cfg.actuator = sim::ActuatorMode::Physical;
    let phys = record(&r, &[], Surface::flat(), &motion, &cfg).unwrap();
    let end = |rec: &sim::SimRecording| rec.truth.last().unwrap().pose.x;
    // Both reach 0.5 m: ideal exactly, physical within 2 mm (the PI's integral makes up
    // the ramps' lag; the position itself is not closed).
    assert!((end(&ideal) - 0.5).abs() < 1e-9);
    assert!((end(&phys) - 0.5).abs() < 2e-3, "{}", end(&phys));
    assert_ne!(ideal.recording.wheels[0].enc, phys.recording.wheels[0].enc);
}

#[test]
fn wheeled_legged_recordings_carry_leg_angles() {
    let r = robot("wlr");
    let mut cfg = RecordConfig {
        legs: LegMotion::Random {
            min: 0.6,
            max: 2.5,
            period_s: 1.5,
        },
        ..RecordConfig::default()
    };
    cfg.sim.seed = 3;
    let rec = record(
        &r,
        &[Effect::parse("longitudinal_slip=mu:0.4").unwrap()],
        Surface::flat(),
        &Motion::Random(RandomMotion {
            duration_s: 4.0,
            ..RandomMotion::default()
        }),
        &cfg,
    )
    .unwrap();
    let lf = rec.recording.leg_front.as_ref().unwrap();
    assert!(lf
        .iter()
        .all(|v| v.is_some_and(|a| (0.6..=2.5).contains(&a))));
    // Rear wheels are free: no command column, but encoders.
    assert!(rec.recording.wheels[2].cmd.is_none() && rec.recording.wheels[2].enc.is_some());
    // The directory reads back through calib-core with the legs and the blank commands.
    let dir = std::env::temp_dir().join(format!("sim-wlr-test-{}", std::process::id()));
    rec.write_dir(&dir).unwrap();
    let back = formats::recording::Recording::load(&dir.join("recording.csv"), &r).unwrap();
    assert_eq!(back.len(), rec.recording.len());
    assert!(back.leg_rear.is_some() && back.wheels[3].cmd.is_none());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let r = presets::mobolab();
    let mut f = Faults::none(2);
    f.mu = Some(f64::NAN);
    assert!(SimRobot::new(&r, f, Surface::flat(), quiet()).is_err());
    let mut f = Faults::none(2);
    f.mu = Some(-0.3);
    let e = SimRobot::new(&r, f, Surface::flat(), quiet()).unwrap_err();
    assert!(e.to_string().contains("mu"), "{e}");
    assert!(SimRobot::new(&r, Faults::none(3), Surface::flat(), quiet()).is_err());
    let mut sim = SimRobot::new(&r, Faults::none(2), Surface::flat(), quiet()).unwrap();
    assert!(sim.step(1e-3, &[WheelInput::Rate(1.0)]).is_err());
    assert!(sim.step(f64::NAN, &[WheelInput::Rate(1.0); 2]).is_err());
    // NaN and absurd commands are treated as zero / clamped, never a panic.
    sim.step(
        1e-3,
        &[WheelInput::Rate(f64::NAN), WheelInput::Duty(f64::INFINITY)],
    )
    .unwrap();
    sim.step(
        1e-3,
        &[WheelInput::Steps(i32::MAX), WheelInput::Steps(i32::MIN)],
    )
    .unwrap();
    let cfg = RecordConfig {
        row_rate_hz: -1.0,
        ..RecordConfig::default()
    };
    let m = Motion::Program {
        program: Box::new(Program::umbmark_square(1.0, Direction::Cw)),
        limits: ProfileLimits::default(),
    };
    assert!(record(&r, &[], Surface::flat(), &m, &cfg).is_err());
    // A robot file with a negative radius names the file, the wheel and the field.
    let text = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/mobolab.toml"),
    )
    .unwrap()
    .replacen("radius_m = 0.05", "radius_m = -0.05", 1);
    let e = formats::robot_file::parse(&text, Path::new("bad.toml"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("bad.toml") && e.contains("radius_m"), "{e}");
    let _ = FRAC_PI_2;
}

#[test]
fn skid_steer_turns_in_place_at_the_effective_separation_of_its_friction() {
    // rover4 (track 0.40 m, wheelbase 0.31 m) with friction-circle tyres and equal loads:
    // the contacts balance at an effective separation of 1 + (0.31 / 0.40)^2 = 1.600625
    // times the track. Wheels asked for a 1 rad/s turn with the nominal track turn the
    // body at 1 / 1.600625 rad/s; with E_b = 1.600625 applied, at 1 rad/s. Over 2 s (the
    // wheels at speed within 1 ms) the heading comes within 0.2 % of that.
    let r = robot("rover4");
    let want = 1.0 + (0.31f64 / 0.40).powi(2);
    for (corr, rate) in [
        (Corrections::None, 1.0 / want),
        (
            Corrections::DiffDrive {
                c_l: 1.0,
                c_r: 1.0,
                e_b: want,
            },
            1.0,
        ),
    ] {
        let k = Kinematics::<f64>::new(&r, &corr).unwrap();
        let mut sim = SimRobot::new(&r, Faults::none(4), Surface::flat(), quiet()).unwrap();
        for _ in 0..2000 {
            let inp = rates(&sim, &k, &Twist::new(0.0, 0.0, 1.0));
            sim.step(1e-3, &inp).unwrap();
        }
        let p = sim.true_pose();
        assert!(
            (p.theta - 2.0 * rate).abs() < 2e-3 * 2.0 * rate,
            "heading {} vs {}",
            p.theta,
            2.0 * rate
        );
        // A turn in place stays in place: the contacts are symmetric.
        assert!(p.x.hypot(p.y) < 1e-6, "{p:?}");
    }
}

/// `SimConfig::turn_scrub` acts on robots that turn by rolling: a differential drive
/// (through its sides) and an omni robot (through its twist). A skid-steer robot turns by
/// skidding (its tyres' friction sets that) and is refused, naming the field and the
/// robot's kind; out of its ±0.5 range is refused too.
#[test]
fn turn_scrub_is_a_rolling_robots_and_refused_on_skid_steer() {
    let cfg = |k| SimConfig {
        turn_scrub: k,
        ..quiet()
    };
    let r = robot("rover4");
    let e = SimRobot::new(
        &r,
        Faults::none(r.wheel_count()),
        Surface::flat(),
        cfg(0.04),
    )
    .err()
    .unwrap_or_else(|| panic!("rover4: turn_scrub taken"))
    .to_string();
    assert!(
        e.starts_with("turn_scrub: widens the wheels' effective"),
        "{e}"
    );
    assert!(e.contains(r.kind.as_str()), "{e}");
    for name in ["mobolab", "omni3"] {
        let r = robot(name);
        let n = r.wheel_count();
        assert!(SimRobot::new(&r, Faults::none(n), Surface::flat(), cfg(0.04)).is_ok());
        assert!(SimRobot::new(&r, Faults::none(n), Surface::flat(), cfg(0.6)).is_err());
    }
}

/// An omni robot with a 2 % turn scrub: its wheels' effective distance from the centre
/// grows by 2 % times 1 - rho^2 from a turn in place (rho = 1) to an arc, rho = |omega|
/// L / |v|. omni3 (L = 0.15 m) driven on an arc of 0.7 m radius at 0.2 m/s turns at
/// 1 / (1 + 0.02 (1 - (0.15 / 0.7)^2)) = 0.981276 of the commanded rate; spinning in
/// place or driving straight it moves as commanded (after 2 s of a twist held, e^-20 of
/// the smoothing's start remains).
#[test]
fn an_omni_robots_turn_scrub_turns_it_less_on_arcs_only() {
    let r = robot("omni3");
    let cfg = SimConfig {
        turn_scrub: 0.02,
        ..quiet()
    };
    let k = Kinematics::<f64>::new(&r, &Corrections::None).unwrap();
    let l = r.wheels.iter().map(|w| w.l_m).sum::<f64>() / 3.0;
    let rho = l / 0.7;
    let arc = 1.0 / (1.0 + 0.02 * (1.0 - rho * rho));
    for (cmd, gain) in [
        (Twist::new(0.2, 0.0, 0.2 / 0.7), arc),
        (Twist::new(0.0, 0.2, -0.2 / 0.7), arc),
        (Twist::new(0.0, 0.0, 1.0), 1.0),
        (Twist::new(0.1, 0.2, 0.0), 1.0),
    ] {
        let mut sim = SimRobot::new(&r, Faults::none(3), Surface::flat(), cfg.clone()).unwrap();
        let inp = rates(&sim, &k, &cmd);
        for _ in 0..2000 {
            sim.step(1e-3, &inp).unwrap();
        }
        let t = sim.true_twist();
        assert!(
            (t.omega - gain * cmd.omega).abs() < 1e-9
                && (t.vx - cmd.vx).abs() < 1e-9
                && (t.vy - cmd.vy).abs() < 1e-9,
            "{cmd:?}: {t:?}, omega gain {} against {gain}",
            t.omega / cmd.omega
        );
    }
    assert!((arc - 0.981276).abs() < 5e-7, "{arc}");
}
