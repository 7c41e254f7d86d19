//! The habits suite: issue 55's own judge, written before any change to diagnose for that
//! issue. Recordings from `habits/mod.rs` (its own code: other driving habits, robots,
//! rates, noise and loggers, and physics no other generator of this repository has: a lag
//! that differs per wheel, a second-order motor, a dead band that differs per wheel or by
//! direction, a weak motor's acceleration limit on one wheel, a delay on one wheel, and
//! the faults a logger makes that are not whole ratios or clocks). The classes follow
//! issue 55's list of misses, not its cases (which stay kept apart):
//!
//! | class | cases |
//! |---|---|
//! | noise only (6) | drifting motion capture at 100 Hz, SLAM-like poses at 10 Hz, AR(1) 0.99, quantised poses on a stepper, a fast omni, heading drift with coloured noise |
//! | the right family, partial (3) | lag per wheel (0.04 / 0.09 s), a second-order motor, dead band per wheel |
//! | a flexible mechanism must not take the place (2) | wheelbase 0.965 with 0.08 s pose latency, one omni wheel 3 % larger under drifting capture |
//! | recording faults (6) | one encoder 3 % off on a stepper, a sign-flipped encoder, swapped encoder columns, stale encoder rows, timestamps that jitter and go back, a relocalisation jump |
//! | actuator physics in other forms (3) | one weak motor (acceleration limit), a delay on one wheel, a dead band that differs by direction |
//! | two effects at once (2) | diameter mismatch + lag, play + wheelbase |
//!
//! Each case states the verdicts a roboticist would accept (the family; a partial fit
//! counts), and for a fully right score the parameters within tolerances from the physics
//! and, for logger faults, the artefact ids accepted. Tolerances and expectations were
//! written with the cases and committed with the first run (below) before diagnose changed.
//!
//! Goals (issue 55): every noise-only case `none`; at most one wrong effect named as a
//! verdict. The test asserts the floors measured on the first run (it may only rise).
//!
//! First run (2026-12-07, diagnose of main 2a76ed6, no change to diagnose or to these
//! cases since they were written): **9 / 22 fully right, 11 / 22 right verdicts, 5 / 6
//! controls `none`, 2 wrong effects named as the verdict**; the suite in 7.9 s.
//!
//! | case | first run |
//! |---|---|
//! | ctl_small_diff_drift_100hz | **`wheelbase_error`** (eb 0.99744, 17 %; lateral_slip 31 %, a floor region 8 %): 1.58 -> 1.10 mm against 0.40 mm white noise; the drift of the capture frame is taken for physics |
//! | ctl_omni4_slam_10hz, ctl_mobolab_ar099_90s, ctl_robotest_quantised, ctl_omni3_fast, ctl_wide_diff_heading_drift | `none` |
//! | lag_per_wheel_diff | `unexplained`: motor_lag first_order tau 0.069 explains 94 %, actuator 12.2 -> 4.1 mm; what is left follows each wheel's change of command with opposite signs |
//! | second_order_motor_omni3 | `motor_lag` (delay 0.049 s, 100 %) |
//! | dead_band_per_wheel_diff | `unexplained`: droop 0.118 rad/s, 66 %; actuator 37.2 -> 21.6 mm |
//! | wheelbase_with_latency_diff | `wheelbase_error` eb 0.96500, time_offset 0.0798 s removed |
//! | one_wheel_larger_omni3_drift | `wheel_diameter_mismatch`, w2 x 1.0312 |
//! | encoder_scale_stepper | `unexplained` (ed 1.031, 4 %), no artefact; identification names "right error proportional to commanded travel (-3.0 %)" |
//! | sign_flip_omni3 | `unexplained`, 472 -> 316 mm, no artefact |
//! | swapped_encoders_diff | `unexplained` (a 5.7 rad/s dead band, 55 %), 1023 -> 527 mm, no artefact |
//! | stale_encoder_rows_diff | `none`, the stale rows not listed |
//! | clock_jitter_and_back_omni4 | refused by the parser ("time must increase strictly") |
//! | relocalisation_jump_diff | `unexplained`, no findings, 33.3 mm, no artefact |
//! | weak_motor_diff | `unexplained`: slew 8.8 rad/s^2 (one value for both wheels), 42 % |
//! | delay_one_wheel_diff | `unexplained`: first_order tau 0.028, 50 % |
//! | dead_band_by_direction_omni3 | **`backlash`** (asymmetric, 0.035 rad, 95 %) |
//! | diameter_and_lag_diff | `motor_lag` tau 0.0590 and ed 1.00794: both found |
//! | play_and_wheelbase_diff | `wheelbase_error` eb 1.02543; the play not found (reversals named by identification as outside the catalogue) |
//!
//! `DIAG_CASE=name` runs only the cases whose name contains it.

mod check;
mod habits;

use calib_core::robot::{presets, Drive, Robot};
use diagnose::{diagnose, Options};
use habits::{generate, Act, Fault, Gen, Stats, Style, Wheel};
use std::time::Instant;

struct Case {
    name: &'static str,
    truth: &'static str,
    gen: Gen,
    /// Accepted verdicts (families), the expected one first.
    verdicts: Vec<&'static str>,
    /// Effects that must also be among the findings for a fully right score.
    also: Vec<&'static str>,
    params: Vec<check::ParamCheck>,
    /// Accepted recording-artefact ids, one of which must be listed (logger faults).
    artefacts: Vec<&'static str>,
}

fn case(name: &'static str, truth: &'static str, robot: Robot, seed: u64, style: Style) -> Case {
    Case {
        name,
        truth,
        gen: Gen::new(robot, seed, style),
        verdicts: vec!["none"],
        also: vec![],
        params: vec![],
        artefacts: vec![],
    }
}

fn small_diff() -> Robot {
    presets::diff_drive("small_diff", 0.035, 0.28, Drive::default())
}

fn wide_diff() -> Robot {
    presets::diff_drive("wide_diff", 0.08, 0.56, Drive::default())
}

fn lag(tau: f64) -> Wheel {
    Wheel {
        chain: vec![Act::Lag(tau)],
        ..Wheel::default()
    }
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();

    // --- Noise only: `none` on every one.
    let mut c = case(
        "ctl_small_diff_drift_100hz",
        "noise only: 0.4 mm / 1 mrad white at 100 Hz poses, 200 Hz rows, the capture frame drifting 0.3 mm and 0.5 mrad per sqrt(s)",
        small_diff(),
        5501,
        Style::Joystick,
    );
    c.gen.row_hz = 200.0;
    c.gen.pose_hz = 100.0;
    c.gen.sigma_m = 0.0004;
    c.gen.sigma_rad = 0.001;
    c.gen.drift_m = 0.0003;
    c.gen.drift_rad = 0.0005;
    out.push(c);

    let mut c = case(
        "ctl_omni4_slam_10hz",
        "noise only: SLAM-like poses, 10 Hz, 5 mm / 10 mrad white; 50 Hz rows",
        check::robot_file("omni4"),
        5502,
        Style::Legs,
    );
    c.gen.row_hz = 50.0;
    c.gen.pose_hz = 10.0;
    c.gen.sigma_m = 0.005;
    c.gen.sigma_rad = 0.01;
    c.gen.v_max = 0.15;
    c.gen.a_max = 0.4;
    out.push(c);

    let mut c = case(
        "ctl_mobolab_ar099_90s",
        "noise only: stepper, 90 s of legs, AR(1) 0.99 per 100 Hz sample, 2 mm / 3 mrad",
        check::robot_file("mobolab"),
        5503,
        Style::Legs,
    );
    c.gen.duration_s = 90.0;
    c.gen.pose_hz = 100.0;
    c.gen.rho = 0.99;
    c.gen.sigma_m = 0.002;
    c.gen.sigma_rad = 0.003;
    out.push(c);

    let mut c = case(
        "ctl_robotest_quantised",
        "noise only: stepper, poses quantised to 1 mm / 2 mrad (0.3 mm / 0.5 mrad white below)",
        check::robot_file("robotest"),
        5504,
        Style::Joystick,
    );
    c.gen.sigma_m = 0.0003;
    c.gen.sigma_rad = 0.0005;
    c.gen.quant_m = 0.001;
    c.gen.quant_rad = 0.002;
    out.push(c);

    let mut c = case(
        "ctl_omni3_fast",
        "noise only: omni3 (r 0.04, l 0.16) driven fast (0.6 m/s, 1.5 m/s^2), 1.5 mm / 3 mrad",
        presets::omni3(0.04, 0.16),
        5505,
        Style::Joystick,
    );
    c.gen.v_max = 0.6;
    c.gen.w_max = 2.0;
    c.gen.a_max = 1.5;
    c.gen.sigma_m = 0.0015;
    c.gen.sigma_rad = 0.003;
    out.push(c);

    let mut c = case(
        "ctl_wide_diff_heading_drift",
        "noise only: 120 s, AR(1) 0.95 1 mm / 2 mrad, the capture's heading drifting 0.3 mrad per sqrt(s)",
        wide_diff(),
        5506,
        Style::Legs,
    );
    c.gen.duration_s = 120.0;
    c.gen.rho = 0.95;
    c.gen.drift_rad = 0.0003;
    out.push(c);

    // --- The right family, a form the catalogue does not hold exactly: the family is the
    // verdict (a partial fit counts).
    // Each wheel its own lag: left 0.04 s, right 0.09 s. A single tau must lie between.
    let mut c = case(
        "lag_per_wheel_diff",
        "first-order lag, left 0.04 s, right 0.09 s",
        small_diff(),
        5511,
        Style::Joystick,
    );
    c.gen.wheels = vec![lag(0.04), lag(0.09)];
    c.verdicts = vec!["motor_lag"];
    out.push(c);

    // A second-order motor (wn 18 rad/s, damping 0.45: it overshoots by 20 %), every wheel.
    let mut c = case(
        "second_order_motor_omni3",
        "every wheel's motor second order, wn 18 rad/s, zeta 0.45",
        presets::omni3(0.03, 0.12),
        5512,
        Style::Joystick,
    );
    let w = Wheel {
        chain: vec![Act::SecondOrder {
            wn: 18.0,
            zeta: 0.45,
        }],
        ..Wheel::default()
    };
    c.gen.wheels = vec![w.clone(), w.clone(), w];
    c.verdicts = vec!["motor_lag"];
    out.push(c);

    // Dead band per wheel: left 0.4 rad/s, right 1.2 rad/s (a stiff gearbox on the right).
    let mut c = case(
        "dead_band_per_wheel_diff",
        "dead band 0.4 rad/s on the left, 1.2 rad/s on the right, both directions",
        wide_diff(),
        5513,
        Style::Joystick,
    );
    c.gen.wheels = vec![
        Wheel {
            chain: vec![Act::DeadBand {
                fwd: 0.4,
                back: 0.4,
            }],
            ..Wheel::default()
        },
        Wheel {
            chain: vec![Act::DeadBand {
                fwd: 1.2,
                back: 1.2,
            }],
            ..Wheel::default()
        },
    ];
    c.verdicts = vec!["coulomb_friction"];
    out.push(c);

    // --- A catalogue effect with a nuisance beside it: no flexible mechanism may take its
    // place.
    // Wheelbase 3.5 % short, poses 0.08 s late (a capture system's latency).
    let mut c = case(
        "wheelbase_with_latency_diff",
        "eb 0.965 (every wheel's distance x 0.965), poses 0.08 s late",
        small_diff(),
        5521,
        Style::Legs,
    );
    c.gen.wheels = vec![
        Wheel {
            l_scale: 0.965,
            ..Wheel::default()
        };
        2
    ];
    c.gen.latency_s = 0.08;
    c.verdicts = vec!["wheelbase_error"];
    c.params = vec![("wheelbase_error", "eb", 0.965, 0.006, false)];
    c.artefacts = vec!["time_offset"];
    out.push(c);

    // One omni wheel 3 % larger (a different tyre), drifting capture. A wheel's size:
    // `wheel_diameter_mismatch` (`wheel_scale` when the radii are fitted as one scale is
    // not the physics: one wheel differs).
    let mut c = case(
        "one_wheel_larger_omni3_drift",
        "w2 rolling radius x 1.03; capture drifting 0.3 mm / 0.3 mrad per sqrt(s)",
        presets::omni3(0.04, 0.16),
        5522,
        Style::Legs,
    );
    c.gen.wheels[1].radius_scale = 1.03;
    c.gen.drift_m = 0.0003;
    c.gen.drift_rad = 0.0003;
    c.verdicts = vec!["wheel_diameter_mismatch"];
    out.push(c);

    // --- Logger faults; the robot is perfect: `none`, with the fault listed.
    let mut c = case(
        "encoder_scale_stepper",
        "mobolab (open-loop stepper): the right encoder's counts x 0.97 (a 3 % wrong disc); the wheels move as commanded",
        check::robot_file("mobolab"),
        5531,
        Style::Joystick,
    );
    c.gen.faults = vec![Fault::EncoderScale { wheel: 1, k: 0.97 }];
    c.artefacts = vec!["counts_per_rev_error", "encoder_scale"];
    out.push(c);

    let mut c = case(
        "sign_flip_omni3",
        "omni3: w3's encoder counts with the wrong sign",
        presets::omni3(0.04, 0.16),
        5532,
        Style::Joystick,
    );
    c.gen.faults = vec![Fault::SignFlip { wheel: 2 }];
    c.artefacts = vec!["encoder_sign", "counts_per_rev_error"];
    out.push(c);

    let mut c = case(
        "swapped_encoders_diff",
        "the left and right encoder columns swapped",
        wide_diff(),
        5533,
        Style::Legs,
    );
    c.gen.faults = vec![Fault::Swap { a: 0, b: 1 }];
    c.artefacts = vec!["wheels_swapped", "encoder_swap"];
    out.push(c);

    let mut c = case(
        "stale_encoder_rows_diff",
        "5 % of rows repeat the previous row's encoder values (a stale buffer), poses fresh",
        small_diff(),
        5534,
        Style::Joystick,
    );
    c.gen.faults = vec![Fault::StaleEncoders { p: 0.05 }];
    c.artefacts = vec!["sample_glitch", "stale_samples"];
    out.push(c);

    let mut c = case(
        "clock_jitter_and_back_omni4",
        "omni4: written times jitter 2 ms, and go back 25 ms at 4 places",
        check::robot_file("omni4"),
        5535,
        Style::Legs,
    );
    c.gen.v_max = 0.15;
    c.gen.a_max = 0.4;
    c.gen.faults = vec![Fault::Clock {
        jitter_s: 0.002,
        back: 4,
        back_s: 0.025,
    }];
    c.artefacts = vec!["sample_glitch", "time_jitter", "time_backwards"];
    out.push(c);

    let mut c = case(
        "relocalisation_jump_diff",
        "at 45 % of the run the pose frame jumps by (6 cm, -3 cm, 0.05 rad) and stays",
        small_diff(),
        5536,
        Style::Legs,
    );
    c.gen.faults = vec![Fault::PoseJump {
        at: 0.45,
        dx: 0.06,
        dy: -0.03,
        dth: 0.05,
    }];
    c.artefacts = vec!["pose_jump"];
    out.push(c);

    // --- Actuator physics in forms the catalogue does not hold.
    // A weak right motor: its acceleration at most 6 rad/s^2 (0.21 m/s^2 at the wheel;
    // commands ramp at 0.8 m/s^2). What the encoders show against the command is lag.
    let mut c = case(
        "weak_motor_diff",
        "the right motor's acceleration limited to 6 rad/s^2, the left follows",
        small_diff(),
        5541,
        Style::Legs,
    );
    c.gen.wheels[1].chain = vec![Act::Slew(6.0)];
    c.verdicts = vec!["motor_lag"];
    out.push(c);

    let mut c = case(
        "delay_one_wheel_diff",
        "the left motor sees its command 0.06 s late (a slow bus), the right at once",
        wide_diff(),
        5542,
        Style::Joystick,
    );
    c.gen.wheels[0].chain = vec![Act::Delay(0.06)];
    c.verdicts = vec!["motor_lag"];
    out.push(c);

    let mut c = case(
        "dead_band_by_direction_omni3",
        "every wheel: dead band 0.8 rad/s forward, 0.2 rad/s backward",
        presets::omni3(0.03, 0.12),
        5543,
        Style::Joystick,
    );
    let w = Wheel {
        chain: vec![Act::DeadBand {
            fwd: 0.8,
            back: 0.2,
        }],
        ..Wheel::default()
    };
    c.gen.wheels = vec![w.clone(), w.clone(), w];
    c.verdicts = vec!["coulomb_friction"];
    out.push(c);

    // --- Two effects at once: either may be the verdict, both must be found.
    let mut c = case(
        "diameter_and_lag_diff",
        "right radius x 1.008 (ed 1.008) and a 0.06 s lag on both wheels",
        small_diff(),
        5551,
        Style::Joystick,
    );
    c.gen.wheels = vec![lag(0.06), lag(0.06)];
    c.gen.wheels[1].radius_scale = 1.008;
    c.verdicts = vec!["wheel_diameter_mismatch", "motor_lag"];
    c.also = vec!["wheel_diameter_mismatch", "motor_lag"];
    c.params = vec![("wheel_diameter_mismatch", "ed", 1.008, 0.002, false)];
    out.push(c);

    let mut c = case(
        "play_and_wheelbase_diff",
        "0.06 rad of gear play on each wheel and eb 1.025",
        wide_diff(),
        5552,
        Style::Legs,
    );
    c.gen.wheels = vec![
        Wheel {
            play_rad: 0.06,
            l_scale: 1.025,
            ..Wheel::default()
        };
        2
    ];
    c.verdicts = vec!["wheelbase_error", "backlash"];
    c.also = vec!["wheelbase_error", "backlash"];
    c.params = vec![("wheelbase_error", "eb", 1.025, 0.006, false)];
    out.push(c);
    out
}

impl Case {
    fn control(&self) -> bool {
        self.verdicts == ["none"] && self.artefacts.is_empty()
    }
}

fn run(case: &Case) -> check::Outcome {
    let start = Instant::now();
    let (rec, stats) = generate(&case.gen);
    let rec = match rec {
        Ok(r) => r,
        Err(e) => {
            return check::Outcome {
                name: case.name.into(),
                control: case.control(),
                verdict: "refused".into(),
                verdict_ok: false,
                full_ok: false,
                wrong_effect: false,
                seconds: start.elapsed().as_secs_f64(),
                detail: format!("the recording was refused: {e}"),
            }
        }
    };
    let r = match diagnose(&case.gen.robot, &rec, &Options::default()) {
        Ok(r) => r,
        Err(e) => {
            return check::Outcome {
                name: case.name.into(),
                control: case.control(),
                verdict: "error".into(),
                verdict_ok: false,
                full_ok: false,
                wrong_effect: false,
                seconds: start.elapsed().as_secs_f64(),
                detail: format!("diagnose refused: {e}"),
            }
        }
    };
    let seconds = start.elapsed().as_secs_f64();
    let verdict = r.verdict.as_str().to_string();
    let verdict_ok = case.verdicts.contains(&verdict.as_str());
    let wrong_effect = check::wrong_effect(&verdict, verdict_ok);
    let (_, mut problems) = check::verdict_and_params(&r, "any", &case.also, &case.params);
    problems.retain(|p| !p.starts_with("verdict"));
    if !verdict_ok {
        problems.push(format!("verdict {verdict} (expected {:?})", case.verdicts));
    }
    if !case.artefacts.is_empty()
        && !r
            .recording_artefacts
            .iter()
            .any(|a| case.artefacts.contains(&a.id))
    {
        problems.push(format!("no artefact of {:?} listed", case.artefacts));
    }
    if let Some(t) = case
        .artefacts
        .contains(&"time_offset")
        .then_some(case.gen.latency_s)
    {
        if let Some(a) = r.recording_artefacts.iter().find(|a| a.id == "time_offset") {
            let v = a
                .parameters
                .get("time_offset_s")
                .copied()
                .unwrap_or(f64::NAN);
            if (v - t).abs().is_nan() || (v - t).abs() > 0.01 {
                problems.push(format!("time_offset_s {v:.4} for {t}"));
            }
        }
    }
    let findings: Vec<String> = r
        .findings
        .iter()
        .map(|f| {
            format!(
                "{}/{}({}, {:.0} %) {:?}",
                f.effect,
                f.mechanism,
                f.fit,
                f.explained_share * 100.0,
                f.parameters
            )
        })
        .collect();
    let detail = format!(
        "{}; {findings:?}; ground {:.2}->{:.2} mm, actuator {:.3}->{:.3} mm, noise {:.2} mm; \
         artefacts {:?}; implausible {}; depends_on {:?}; signal dr {:.1} mm / {:.1} mrad",
        problems.join("; "),
        r.rmse.ground.before_m * 1e3,
        r.rmse.ground.after_m * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.before_m) * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.after_m) * 1e3,
        r.noise.pose_sigma_m * 1e3,
        r.recording_artefacts
            .iter()
            .map(|a| a.to_string())
            .collect::<Vec<_>>(),
        r.implausible.len(),
        r.depends_on,
        stats.dr_rms_m * 1e3,
        stats.dr_rms_rad * 1e3,
    );
    check::Outcome {
        name: case.name.into(),
        control: case.control(),
        verdict,
        verdict_ok,
        full_ok: problems.is_empty(),
        wrong_effect,
        seconds,
        detail,
    }
}

/// Floors from the first run (may only rise): fully right and right verdicts.
const FULLY_RIGHT_FLOOR: usize = 19;
const RIGHT_VERDICTS_FLOOR: usize = 20;

#[test]
fn habits_physics() {
    let all = cases();
    let t0 = Instant::now();
    let outcomes: Vec<check::Outcome> = check::run_selected(&all, |c| c.name, run);
    let check::Score {
        n, full, verdicts, ..
    } = check::score(&outcomes, t0);
    if n == all.len() {
        assert!(full >= FULLY_RIGHT_FLOOR, "{full} fully right");
        assert!(
            verdicts >= RIGHT_VERDICTS_FLOOR,
            "{verdicts} right verdicts"
        );
    }
}

/// The generator alone (no diagnose): each case's physics or fault happens, and physics
/// leaves the pose noise.
#[test]
fn habits_generator_does_what_the_cases_say() {
    for c in cases() {
        let (rec, s) = generate(&c.gen);
        println!("{:32} {s:?}", c.name);
        let _ = rec;
        check_stats(&c, &s);
    }
}

fn check_stats(c: &Case, s: &Stats) {
    let name = c.name;
    assert!(s.distance_m > 0.04 * c.gen.duration_s, "{name}: {s:?}");
    assert!(
        s.reversals >= 3 || c.gen.robot.kind == calib_core::robot::RobotKind::Omni,
        "{name}: {s:?}"
    );
    let leaves_noise = || {
        assert!(
            s.dr_rms_m > 3.0 * c.gen.sigma_m || s.dr_rms_rad > 3.0 * c.gen.sigma_rad,
            "{name}: the physics must leave the noise: {s:?}"
        )
    };
    // Actuator chains act before the encoder (on the motor shaft): their signal is the
    // encoders against the command (checked per wheel below), not the poses.
    let ground = c
        .gen
        .wheels
        .iter()
        .any(|w| w.play_rad > 0.0 || w.radius_scale != 1.0 || w.l_scale != 1.0);
    let actuator = c.gen.wheels.iter().any(|w| !w.chain.is_empty());
    if ground {
        leaves_noise();
    } else if !actuator {
        // A perfect robot: dead reckoning from the motors is the truth.
        assert!(s.dr_rms_m < 1e-4, "{name}: {s:?}");
    }
    for w in 0..c.gen.wheels.len() {
        if !c.gen.wheels[w].chain.is_empty() {
            assert!(s.motor_gap_rms[w] > 0.05, "{name} wheel {w}: {s:?}");
        }
        if c.gen.wheels[w].play_rad > 0.0 {
            assert!(
                s.play_taken_rad[w] > 10.0 * c.gen.wheels[w].play_rad,
                "{name}: {s:?}"
            );
        }
    }
    for f in &c.gen.faults {
        match f {
            Fault::StaleEncoders { p } => {
                let want = p * s.rows as f64;
                assert!(
                    (s.stale_rows as f64 - want).abs() < 0.3 * want,
                    "{name}: {s:?}"
                )
            }
            Fault::Clock { back, .. } => {
                assert_eq!(s.times_back, *back, "{name}");
            }
            _ => {}
        }
    }
}

/// Prints one case's report (`DIAG_CASE=name`).
#[test]
#[ignore]
fn explain_habits_case() {
    let filter = std::env::var("DIAG_CASE").unwrap_or_default();
    for c in cases().iter().filter(|c| c.name.contains(filter.as_str())) {
        let (rec, _) = generate(&c.gen);
        match rec {
            Ok(rec) => {
                let r = diagnose(&c.gen.robot, &rec, &Options::default()).unwrap();
                println!("== {} ({})\n{r}", c.name, c.truth);
                check::explain(&r);
            }
            Err(e) => println!("== {}: refused: {e}", c.name),
        }
    }
}
