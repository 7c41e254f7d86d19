//! Every effect of the diagnose catalogue is simulatable from its `--effect`
//! string and acts in the stage the catalogue puts it in: ground effects move the body
//! but leave the encoders exactly as commanded; actuator effects change the encoders.

use calib_core::robot::Robot;
use sim::effects::EFFECT_IDS;
use sim::{
    record, Effect, Motion, RandomMotion, RecordConfig, SimConfig, SimRobot, Surface, WheelInput,
};
use std::path::Path;

fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

fn run(r: &Robot, effects: &[Effect]) -> sim::SimRecording {
    let mut cfg = RecordConfig::default();
    cfg.sim.seed = 11;
    let motion = Motion::Random(RandomMotion {
        duration_s: 20.0,
        v_max_m_s: 0.25,
        a_max_m_s2: 1.0,
        ..RandomMotion::default()
    });
    record(r, effects, Surface::flat(), &motion, &cfg).unwrap()
}

fn encoders(rec: &sim::SimRecording) -> Vec<Option<i64>> {
    rec.recording
        .wheels
        .iter()
        .flat_map(|w| w.enc.clone().unwrap_or_default())
        .collect()
}

#[test]
fn each_effect_acts_in_its_stage() {
    for id in EFFECT_IDS {
        // Robots the effect applies to: steppers for missed steps, a differential drive
        // for ed, otherwise both a differential drive and the omni robot.
        let robots: &[&str] = match id {
            "missed_steps" | "wheel_diameter_mismatch" => &["mobolab"],
            _ => &["mobolab", "omni4"],
        };
        for name in robots {
            let r = robot(name);
            // Default parameters, except a traction limit below the motion's 1 m/s^2.
            let text = if id == "longitudinal_slip" {
                "longitudinal_slip=mu:0.05"
            } else {
                id
            };
            let e = Effect::parse(text).unwrap();
            let nominal = run(&r, &[]);
            let with = run(&r, std::slice::from_ref(&e));
            let moved = nominal
                .truth
                .iter()
                .zip(&with.truth)
                .map(|(a, b)| (a.pose.x - b.pose.x).hypot(a.pose.y - b.pose.y))
                .fold(0.0, f64::max);
            let same_enc = encoders(&nominal) == encoders(&with);
            let actuator = matches!(
                id,
                "backlash" | "missed_steps" | "motor_lag" | "coulomb_friction"
            );
            if actuator {
                assert!(!same_enc, "{id} on {name}: encoders unchanged");
            } else {
                assert!(
                    same_enc,
                    "{id} on {name}: a ground effect changed the encoders"
                );
            }
            // Every effect moves the body by more than a millimetre over 20 s of driving.
            assert!(moved > 1e-3, "{id} on {name}: truth moved only {moved}");
        }
    }
}

#[test]
fn vision_and_imu_rates_and_noise() {
    let r = robot("omni4");
    let cfg = SimConfig {
        seed: 5,
        ..SimConfig::default()
    };
    let imu = cfg.imu;
    let mut sim = SimRobot::new(&r, sim::Faults::none(4), Surface::flat(), cfg).unwrap();
    let mut frames = 0;
    let mut gyro = Vec::new();
    for _ in 0..10_000 {
        sim.step(1e-3, &[WheelInput::Rate(0.0); 4]).unwrap();
        frames += sim.vision().is_some() as u32;
        gyro.push(sim.imu_yaw_rate());
    }
    // 30 Hz over 10 s, the first frame at t = 1 ms.
    assert!((frames as i32 - 300).abs() <= 1, "{frames}");
    // Standing still: the gyro reads its bias plus noise. Mean of 10 000 samples: within
    // 4 sigma / sqrt(n) = 2e-4 rad/s of the bias; spread within 5 % of sigma.
    let n = gyro.len() as f64;
    let mean = gyro.iter().sum::<f64>() / n;
    let sd = (gyro.iter().map(|g| (g - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    assert!((mean - imu.bias_rad_s).abs() < 4.0 * imu.sigma_rad_s / n.sqrt());
    assert!((sd / imu.sigma_rad_s - 1.0).abs() < 0.05, "{sd}");
}

#[test]
fn tilted_floor_drifts_while_moving() {
    // 5 mm/s downhill (world +y) whenever the wheels turn: 10 s of driving along x drifts
    // 50 mm sideways; standing still does not drift.
    let r = robot("mobolab");
    let e = Effect::parse("tilted_floor=drift_m_s:0.005,direction_rad:1.5707963267948966").unwrap();
    let mut sim = SimRobot::with_effects(&r, &[e], Surface::flat(), SimConfig::default()).unwrap();
    for _ in 0..10_000 {
        sim.step(1e-3, &[WheelInput::Rate(4.0); 2]).unwrap();
    }
    let y = sim.true_pose().y;
    assert!((y - 0.05).abs() < 1e-9, "{y}");
    for _ in 0..1000 {
        sim.step(1e-3, &[WheelInput::Rate(0.0); 2]).unwrap();
    }
    assert!((sim.true_pose().y - y).abs() < 1e-12);
}
