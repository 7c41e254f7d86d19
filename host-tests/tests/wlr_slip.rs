//! [Korayem et al.]'s wheeled-legged robot in the accelerated straight run with the rear legs sweeping
//! from 30 to 150 deg (front legs fixed at 30 deg, front wheels driven, rear wheels free):
//! the no-slip kinematic model (the driven wheels' encoders through a differential-drive
//! model of the front pair) against the simulated truth, with and without slip.

use calib_core::correction::Corrections;
use calib_core::kinematics::Kinematics;
use calib_core::odometry::{Odometry, Pose};
use calib_core::robot::{presets, Drive};
use host_tests::robot;
use sim::{Effect, Patch, SimConfig, SimRobot, Surface, WheelInput};
use std::f64::consts::TAU;

struct Outcome {
    /// Distance the no-slip model predicts and the body really went, m.
    predicted_m: f64,
    true_m: f64,
    /// Largest lateral deviation of the true path from the straight line, m.
    lateral_m: f64,
    /// Same for the no-slip prediction.
    predicted_lateral_m: f64,
}

/// Front wheels: accelerate at 40 rad/s^2 (1.36 m/s^2 at the rim) to 15 rad/s, hold,
/// decelerate at 40 rad/s^2, four wheel revolutions in all (002: "the wheels complete
/// four rotations"); rear legs 30 -> 150 deg over the run.
fn accelerated_run(effects: &[Effect], surface: Surface) -> Outcome {
    let r = robot("wlr");
    let (leg_f, leg_r0, leg_r1) = (30f64.to_radians(), 30f64.to_radians(), 150f64.to_radians());
    let cfg = SimConfig {
        leg_front_rad: leg_f,
        leg_rear_rad: leg_r0,
        random_counter_start: false,
        ..SimConfig::default()
    };
    let mut sim = SimRobot::with_effects(&r, effects, surface, cfg).unwrap();
    // The no-slip model of the driven pair: a differential drive with the front wheels'
    // radius and track (y = +-0.16 m), fed by their encoders (4096 counts/rev).
    let track = 2.0 * r.wheels[0].position().1;
    let front = presets::diff_drive(
        "front",
        r.wheels[0].radius_m,
        track,
        Drive {
            encoder_counts_per_rev: r.drive.encoder_counts_per_rev,
            ..Drive::default()
        },
    );
    let kin = Kinematics::<f64>::new(&front, &Corrections::None).unwrap();
    let mut odo = Odometry::new(Pose::new(0.0, 0.0, 0.0));
    let mut last = [0i64; 2];
    let rad_per_count = TAU / r.drive.encoder_counts_per_rev;
    let (acc, top, total) = (40.0, 15.0, 4.0 * TAU);
    let ramp = top / acc;
    let cruise = (total - top * ramp) / top;
    let duration = 2.0 * ramp + cruise;
    let dt = 1e-3;
    let (mut lateral, mut pred_lateral) = (0.0f64, 0.0f64);
    let mut t = 0.0;
    while t < duration + 1.0 {
        let w = if t < ramp {
            acc * (t + 0.5 * dt)
        } else if t < ramp + cruise {
            top
        } else {
            (acc * (duration - t - 0.5 * dt)).max(0.0)
        };
        let s = (t / duration).min(1.0);
        sim.set_legs(leg_f, leg_r0 + (leg_r1 - leg_r0) * s).unwrap();
        sim.step(
            dt,
            &[
                WheelInput::Rate(w),
                WheelInput::Rate(w),
                WheelInput::Free,
                WheelInput::Free,
            ],
        )
        .unwrap();
        let now = [sim.encoder_count(0), sim.encoder_count(1)];
        let inc = [
            (now[0] - last[0]) as f64 * rad_per_count,
            (now[1] - last[1]) as f64 * rad_per_count,
        ];
        last = now;
        odo.update(&kin.forward(&inc));
        lateral = lateral.max(sim.true_pose().y.abs());
        pred_lateral = pred_lateral.max(odo.pose().y.abs());
        t += dt;
    }
    let p = sim.true_pose();
    let o = odo.pose();
    Outcome {
        predicted_m: o.x.hypot(o.y),
        true_m: p.x.hypot(p.y),
        lateral_m: lateral,
        predicted_lateral_m: pred_lateral,
    }
}

#[test]
fn slip_makes_the_no_slip_model_miss_by_percent_and_centimetres() {
    // With slip: mu = 0.5; with the rear legs at 30 deg the driven front pair carries
    // only 17 % of the weight (moment balance), so the body can accelerate at
    // 0.5 g 0.17 = 0.8 m/s^2 while the wheels ask 1.36: the wheels spin up ahead of the
    // body. The floor is a little less grippy under the left wheels at the start (a
    // patch with 0.85 mu), so the two sides slip differently and the robot yaws.
    let slip = [Effect::parse("longitudinal_slip=mu:0.5").unwrap()];
    let patch = Surface {
        patches: vec![Patch {
            x_min: -1.0,
            x_max: 0.8,
            y_min: 0.0,
            y_max: 1.0,
            mu_scale: 0.85,
        }],
        ..Surface::flat()
    };
    let with = accelerated_run(&slip, patch.clone());
    let err = (with.predicted_m - with.true_m) / with.true_m;
    println!(
        "\n002 accelerated run, rear legs 30 -> 150 deg\nwith slip (mu 0.5):   predicted {:.4} m, true {:.4} m, error {:.1} %, lateral {:.1} cm (predicted {:.1} cm)",
        with.predicted_m,
        with.true_m,
        err * 100.0,
        with.lateral_m * 100.0,
        with.predicted_lateral_m * 100.0
    );
    // Four revolutions of a 34 mm wheel: 0.8545 m predicted (to an encoder count).
    assert!((with.predicted_m - 4.0 * TAU * 0.034).abs() < 1e-3);
    // [Korayem et al.] reports 5 to 11.5 %; by hand: lost distance = v^2/2 (1/a_body - 1/a_wheel) =
    // 0.26 (1/0.8.. - 1/1.36) = 5-7 % of 0.85 m, less what the stop gives back. Asked:
    // "several percent", 3 % to 15 %.
    assert!(err > 0.03 && err < 0.15, "error {err}");
    // [Korayem et al.] reports 1.1 to 5.2 cm of lateral deviation; asked: 1 to 6 cm.
    assert!(
        with.lateral_m > 0.01 && with.lateral_m < 0.06,
        "lateral {}",
        with.lateral_m
    );

    // Without slip (unlimited traction, same floor): prediction and truth agree to the
    // encoder resolution (2 pi 0.034 / 4096 = 0.05 mm per count) and the path is straight.
    let without = accelerated_run(&[], patch);
    let err0 = (without.predicted_m - without.true_m).abs();
    println!(
        "without slip:         predicted {:.4} m, true {:.4} m, error {:.4} %, lateral {:.3} mm",
        without.predicted_m,
        without.true_m,
        err0 / without.true_m * 100.0,
        without.lateral_m * 1e3
    );
    assert!(err0 < 1e-4, "{err0}");
    assert!(without.lateral_m < 1e-4, "{}", without.lateral_m);
}
