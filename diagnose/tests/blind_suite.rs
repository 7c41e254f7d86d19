//! The blind suite: how well `diagnose` names physics it was never tuned to. Recordings
//! from a generator with its own code (`blind/mod.rs`, structured as `independent/mod.rs`:
//! held commands, 1 kHz integration, formats.md CSV read back by the project's parser)
//! and with physics that neither the `sim` crate, nor diagnose's catalogue, nor the
//! independent generator has: an eccentric wheel, a tyre warming up (a diameter mismatch
//! that grows during the run), a payload off-centre (traction that differs per wheel),
//! carpet grain, an encoder counter that drops counts above a count rate, a floor slope
//! (sideways tyre drift in proportion to speed), a hub slipping on its motor shaft, a
//! wheelbase error under heavy coloured motion-capture noise, and controls: two
//! noise-only recordings on other robots and a perfect robot with motion-capture marker
//! swaps.
//!
//! Cases, seeds, expectations and tolerances were written and committed ("blind suite:
//! cases, expectations and tolerances, before the first run") before diagnose was run on
//! any of them. Each expectation is what a roboticist would accept as the physically right
//! name (a catalogue effect, `unexplained` for physics outside the catalogue, or `none`),
//! with the accepted alternatives and mechanisms, and parameter tolerances from the
//! physics; the reasons are in the comments of `cases`. A case is fully right when the
//! verdict is accepted, the verdict effect's mechanism is accepted (where stated) and
//! every stated parameter is within its tolerance.
//!
//! | case | robot | truth | expected (also accepted) |
//! |---|---|---|---|
//! | control_omni3 | omni3.toml | noise only, 1 mm / 2 mrad | `none` |
//! | control_sweeper_coloured | sweeper.toml (stepper) | noise only, AR(1) 0.97, 2 mm / 4 mrad | `none` |
//! | marker_swaps_diff | DC diff drive | perfect robot, 6 single-sample jumps 3-5 cm, 0.03-0.1 rad | `none` |
//! | eccentric_wheel_sweeper | sweeper.toml | left rolling radius +-1.5 % once per revolution, mean nominal; noise 0.3 mm / 0.6 mrad | `unexplained` |
//! | tyre_warmup_diff | DC diff drive, 90 s | left radius -0.6 % linearly over the run | `wheel_diameter_mismatch`, ed 1.003 +- 0.0015 |
//! | payload_offset_diff | DC diff drive | traction mu 0.15 x load 1.3 (left) / 0.7 (right) | `longitudinal_slip` by `wheel`, mu 0.15 +- 30 % |
//! | carpet_grain_diff | DC diff drive | 3 % of travel lost along the grain, none against | `unexplained` (`floor_bumps`) |
//! | encoder_saturation_omni4 | omni4 | counts clipped at 2500 counts/s | `unexplained` |
//! | wheelbase_in_coloured_noise_diff | DC diff drive, 120 s | eb 1.004, AR(1) 3 mm / 5 mrad | `wheelbase_error`, eb 1.004 +- 0.003 |
//! | floor_slope_mobolab | mobolab.toml (stepper) | sideways drift 0.02 \|v\| downhill | `unexplained` |
//! | hub_slip_omni3 | omni3.toml | w2's hub slips above 16 rad/s^2 | `longitudinal_slip` by `wheel`, mu 0.065 +- 40 % |
//!
//! The generator's own check (`blind_generator_does_what_the_cases_say`, no diagnose)
//! shows each mechanism happens and leaves the noise: dead reckoning from the encoders
//! with the nominal geometry departs from the true pose by (RMS) 5.0 mm / 3.3 mrad
//! (eccentric; its mean rolling radius 1.0005 of nominal over the run), 4.3 mm / 6.3 mrad
//! (warm-up; travel-weighted mean ed 1.00315), 69 mm (payload; the right wheel loses
//! 0.47 m to slip, the left 0.02 m), 132 mm (carpet; 1.54 % of travel lost), 371 mm
//! (encoder; 1.1-2.6 % of counts dropped), 20 mm / 13.6 mrad (wheelbase), 50 mm (slope;
//! 0.11 m of sideways drift), 103 mm (hub; 0.45 m slipped, 10.6 s). Before the first run,
//! diagnose's run time was probed on three recordings of this generator that are not
//! cases (seeds 9001-9003, only the times read: 0.4-1.2 s each).
//!
//! First run (2026-11-30, commit 09fea67 on main = diagnose of fe3d9b3, no generator fix
//! since): **7 / 11 fully right, 7 / 11 right verdicts, 3 / 3 controls `none`**, the whole
//! suite in 3.4 s (generation and diagnosis, two workers; per case below, generation
//! 0.0-0.1 s of it). No panic, no case over 1.2 s.
//!
//! | case | got (findings: mechanism, parameters, share of the excess) | ground RMSE | score | time |
//! |---|---|---|---|---|
//! | control_omni3 | `none` | 1.40 -> 1.40 mm (noise 1.00) | right | 0.3 s |
//! | control_sweeper_coloured | `none` | 2.61 -> 2.61 mm (noise estimated 0.33) | right | 0.4 s |
//! | marker_swaps_diff | `none` (no recording artefact listed) | 2.72 -> 2.72 mm (noise 1.01) | right | 0.4 s |
//! | eccentric_wheel_sweeper | `unexplained`; floor_bumps/region 28 % (listed implausible, localised 2.8 sigma), lateral_slip side_slip_s -0.0020 12 %; explained 0.40 | 1.90 -> 1.23 mm (noise 0.31) | right | 1.1 s |
//! | tyre_warmup_diff | `wheel_diameter_mismatch` ed 1.00310 (62 %), wheel_scale 0.99884 (26 %; the true mean scale 0.99843), lateral_slip -0.0022 (4 %); explained 0.92 | 3.01 -> 1.54 mm (noise 0.99) | right | 0.6 s |
//! | payload_offset_diff | `unexplained`; wheel_diameter_mismatch ed 0.98391 (51 %), floor_bumps/region (32 %, listed implausible); depends_on: heading error proportional to forward acceleration (outside the catalogue), along-track error proportional to forward acceleration (longitudinal_slip); the slip candidate (mu 0.1447) gained only dBIC -4.2 | 56.4 -> 18.4 mm (noise 1.06) | wrong | 0.6 s |
//! | carpet_grain_diff | `unexplained`; wheelbase_error eb 1.0245 (69 %); depends_on: drift in time, distance, turn, v omega | 41.7 -> 28.8 mm (noise 1.05) | right | 0.4 s |
//! | encoder_saturation_omni4 | `floor_bumps` by region, partial (45 %; signature "travel lost 7.35 % of distance for world x in [-0.87, 0.48] m (17 sigma)"), coulomb_friction/droop 0.316 rad/s (41 %), radius scales 0.968 / 1.235 / 1.028 / 1.170 (w2, w4 listed implausible); actuator 51.0 -> 36.5 mm | 314.7 -> 82.8 mm (noise 2.17) | wrong | 0.5 s |
//! | wheelbase_in_coloured_noise_diff | `unexplained`; wheelbase_error eb 1.00413 (89 %, within tolerance) | 11.81 -> 4.23 mm against an estimated noise of 0.51 mm (true: 3 mm, correlated) | wrong verdict, parameter right | 1.1 s |
//! | floor_slope_mobolab | `unexplained`; no findings, no depends_on, no windows | 25.73 -> 25.73 mm (noise 1.02) | right | 0.4 s |
//! | hub_slip_omni3 | `unexplained`; no findings (best candidate longitudinal_slip mu 0.116, dBIC -7), no depends_on | 84.6 -> 84.6 mm (noise 1.22) | wrong | 0.4 s |
//!
//! Why the four are wrong (from the reports, `explain_blind_case`): traction that differs
//! per wheel (payload, hub) cannot be fitted by one mu for every wheel: with the right mu
//! for the slipping wheel the model makes the others slip too; the payload's heading
//! error that follows forward acceleration is named by identification but mapped to no
//! catalogue physics. Coloured noise of 3 mm is estimated at 0.51 mm from the
//! short-interval scatter, so the right wheelbase fit (eb 1.00413) leaves a stage "far
//! outside the noise" with 89 % explained (under 95 %): `unexplained`. The encoder's
//! dropped counts (the body goes further than the encoders say, at high speed only) are
//! read as a floor region from its signature and as droop friction in the actuator stage.
//!
//! After the first run, one change to diagnose came from it (so this case is no longer
//! blind): what the findings leave on a stage counts as noise when it does not drift and
//! the findings took the stage out of its level (`select::verdict`). The wheelbase in
//! coloured noise is then `wheelbase_error` (eb 1.00413; 89 % of the excess over the
//! short-interval noise estimate, the rest stationary): **8 / 11 fully right, 8 / 11 right
//! verdicts, 3 / 3 controls `none`**. The other suites did not move (independent 11 / 12,
//! mechanisms 23 / 25, the creep case there stays `unexplained`: its finding took the
//! ground stage from 1.46 to 1.40 mm only).
//!
//! A second change followed (`per_wheel_traction.rs`, its cases written first):
//! `longitudinal_slip` by `per_wheel`, tried when identification finds a heading error
//! that follows acceleration. The payload case is then `longitudinal_slip` by `per_wheel`,
//! mu_left 0.200 and mu_right 0.102 (0.195 and 0.105 at the contacts), 56.4 -> 2.25 mm: the
//! verdict is right, the mechanism is not the `wheel` written here, so it is not counted
//! fully right. The omni3 hub stays `unexplained` (identification finds no term). **8 / 11
//! fully right, 9 / 11 right verdicts, 3 / 3 controls.**
//!
//! Hard assertions: the three controls give `none`, at least `FULLY_RIGHT_FLOOR` (8)
//! cases are fully right and at least `RIGHT_VERDICTS_FLOOR` (9) verdicts are right.
//!
//! `DIAG_CASE=name` runs only the cases whose name contains it.

mod blind;
mod check;

use blind::{generate, Gen, Mech, Stats};
use calib_core::robot::{presets, Drive, Robot};
use diagnose::{diagnose, Options};
use std::time::Instant;

fn dc_diff() -> Robot {
    presets::diff_drive("dc_diff", 0.05, 0.40, Drive::default())
}

struct Case {
    name: &'static str,
    /// The truth in words (for the table).
    truth: &'static str,
    gen: Gen,
    /// Accepted verdicts, the expected one first.
    verdicts: Vec<&'static str>,
    /// Accepted mechanisms of the verdict's effect.
    mechanisms: Vec<(&'static str, Vec<&'static str>)>,
    params: Vec<check::ParamCheck>,
}

impl Case {
    fn control(&self) -> bool {
        self.verdicts == ["none"]
    }
}

fn case(name: &'static str, truth: &'static str, robot: Robot, seed: u64) -> Case {
    Case {
        name,
        truth,
        gen: Gen::new(robot, seed),
        verdicts: vec!["none"],
        mechanisms: vec![],
        params: vec![],
    }
}

fn cases() -> Vec<Case> {
    let mut out = Vec::new();

    // Controls. Noise only, on two robots no other control of this generator uses: the
    // three-wheel omni (white 1 mm / 2 mrad) and the stepper sweeper with motion-capture
    // noise correlated over about a second (AR(1) 0.97 per 30 Hz sample, 2 mm / 4 mrad).
    let c = case(
        "control_omni3",
        "noise only, white 1 mm / 2 mrad",
        check::robot_file("omni3"),
        2601,
    );
    out.push(c);
    let mut c = case(
        "control_sweeper_coloured",
        "noise only, AR(1) 0.97, 2 mm / 4 mrad",
        check::robot_file("sweeper"),
        2602,
    );
    c.gen.noise_rho = 0.97;
    c.gen.pose_noise_m = 0.002;
    c.gen.heading_noise_rad = 0.004;
    out.push(c);
    // A perfect robot seen by a motion-capture system that swaps markers now and then: six
    // single pose samples off by 3-5 cm and 0.03-0.1 rad. Not physics: `none`.
    let mut c = case(
        "marker_swaps_diff",
        "perfect robot, 6 single-sample pose jumps of 3-5 cm / 0.03-0.1 rad",
        dc_diff(),
        2603,
    );
    c.gen.marker_swaps = 6;
    out.push(c);

    // An eccentric wheel: the left wheel's rolling radius varies by +-1.5 % once per
    // revolution (axle 1.46 mm off the rim's centre on the 97.5 mm sweeper wheel), its mean
    // exactly nominal. The odometry error it makes is periodic in the wheel's angle and
    // bounded (about +-3 mrad of heading, about 1 mm of position); with a good
    // motion-capture system (0.3 mm / 0.6 mrad) that is well outside the noise. No
    // catalogue effect follows the wheel angle: not a diameter mismatch (the mean is
    // right), not backlash (nothing happens at reversals), not floor bumps (the period is
    // in the wheel's angle, not in world x, and travel is gained as much as lost).
    // Expected: `unexplained`.
    let mut c = case(
        "eccentric_wheel_sweeper",
        "left wheel rolling radius r0 (1 + 0.015 cos(phi + 0.7)), mean nominal; noise 0.3 mm / 0.6 mrad",
        check::robot_file("sweeper"),
        2604,
    );
    c.gen.mechs = vec![Mech::Eccentric {
        wheel: 0,
        amp: 0.015,
        phase: 0.7,
    }];
    c.gen.pose_noise_m = 0.0003;
    c.gen.heading_noise_rad = 0.0006;
    c.verdicts = vec!["unexplained"];
    out.push(c);

    // Tyre warm-up / wear: the left tyre's radius shrinks linearly by 0.6 % over 90 s, so
    // D_R / D_L goes from 1 to 1.00604 (its travel-weighted mean over the run about 1.003).
    // Physically a diameter mismatch that drifts; the catalogue's constant
    // `wheel_diameter_mismatch` is its right name, with ed at the run's mean: to 0.15 %
    // (half the drift over the run, which a constant cannot follow).
    let mut c = case(
        "tyre_warmup_diff",
        "left radius 1.000 -> 0.994 linearly over 90 s (ed 1 -> 1.006, mean 1.003)",
        dc_diff(),
        2605,
    );
    c.gen.duration_s = 90.0;
    c.gen.mechs = vec![Mech::RadiusDrift {
        wheel: 0,
        end_scale: 0.994,
    }];
    c.verdicts = vec!["wheel_diameter_mismatch"];
    c.params = vec![("wheel_diameter_mismatch", "ed", 1.003, 0.0015, false)];
    out.push(c);

    // A payload off-centre to the left: the left wheel carries 1.3 times the mean load, the
    // right 0.7 times; the floor's friction coefficient is 0.15, so the right contact can
    // follow at most 1.03 m/s^2 and the left 1.91 m/s^2 (commands ramp at 1.2 m/s^2, yaw
    // at 3.6 rad/s^2). Traction-limited wheel slip: `longitudinal_slip` by the per-wheel
    // mechanism `wheel` (the slip differs per wheel and turns the body; `body` leaves the
    // heading free, `creep` has no limit). A single mu for both wheels must lie between
    // the two wheels' effective coefficients 0.105 and 0.195: 0.15 +- 30 %.
    let mut c = case(
        "payload_offset_diff",
        "per-wheel traction mu 0.15 x load (left 1.3, right 0.7), a_max 1.2 m/s^2",
        dc_diff(),
        2606,
    );
    c.gen.a_max = 1.2;
    c.gen.mechs = vec![Mech::Traction {
        mu: 0.15,
        load: vec![1.3, 0.7],
    }];
    c.verdicts = vec!["longitudinal_slip"];
    c.mechanisms = vec![("longitudinal_slip", vec!["wheel"])];
    c.params = vec![("longitudinal_slip", "mu", 0.15, 0.3, true)];
    out.push(c);

    // Carpet grain (the known carpet drift of floor-cleaning robots): a wheel keeps all its
    // travel rolling against the grain and 3 % less rolling along it (world direction
    // 0.4 rad), cos-weighted in between. Driving back and forth along the grain the robot
    // drifts against it in proportion to the distance rolled. A floor property outside
    // the catalogue: expected `unexplained`. Also accepted: `floor_bumps`, the catalogue's
    // one floor effect that takes travel depending on the world direction of motion
    // (whole-floor cables take it along world x only); a roboticist could defend it as
    // the nearest floor name. Not a wheel scale or slip (the loss follows the world
    // direction, not the wheel or the acceleration).
    let mut c = case(
        "carpet_grain_diff",
        "travel kept 1 - 0.03 (1 + cos(psi - 0.4)) / 2, psi the contact's world direction",
        dc_diff(),
        2607,
    );
    c.gen.mechs = vec![Mech::CarpetGrain {
        dir_rad: 0.4,
        loss: 0.03,
    }];
    c.verdicts = vec!["unexplained", "floor_bumps"];
    out.push(c);

    // An encoder counter that cannot count faster than 2500 counts/s (an interrupt-driven
    // decoder too slow for its edge rate): above 8.2 rad/s (0.245 m/s at the 3 cm omni
    // wheels) counts are dropped (1-3 % of each wheel's counts over the run). The wheels and the body move as commanded; only the
    // count is short. A sensor fault outside the catalogue, with the opposite sign of
    // every slip (the body goes further than the encoders say) and not an actuator effect
    // (the measured motion follows the command): expected `unexplained`.
    let mut c = case(
        "encoder_saturation_omni4",
        "encoder counts clipped at 2500 counts/s (8.2 rad/s) on every wheel",
        presets::omni4(),
        2608,
    );
    c.gen.mechs = vec![Mech::CountRateLimit {
        counts_per_s: 2500.0,
    }];
    c.verdicts = vec!["unexplained"];
    out.push(c);

    // A wheelbase 0.4 % wider than nominal, concealed in heavy motion-capture noise: 120 s,
    // 3 mm / 5 mrad correlated over about a second (AR(1) 0.97 per sample). The physics is
    // exactly the catalogue's `wheelbase_error`; eb to 0.3 % (absolute 0.003).
    let mut c = case(
        "wheelbase_in_coloured_noise_diff",
        "eb 1.004; 120 s; AR(1) 0.97 pose noise 3 mm / 5 mrad",
        dc_diff(),
        2609,
    );
    c.gen.duration_s = 120.0;
    c.gen.noise_rho = 0.97;
    c.gen.pose_noise_m = 0.003;
    c.gen.heading_noise_rad = 0.005;
    c.gen.mechs = vec![Mech::Wheelbase(1.004)];
    c.verdicts = vec!["wheelbase_error"];
    c.params = vec![("wheelbase_error", "eb", 1.004, 0.003, false)];
    out.push(c);

    // A floor slope: the tyres hold the downhill force at a slip angle, so the robot drifts
    // sideways, downhill, at 2 % of its forward speed times the share of the slope across
    // its heading, only while it moves. Not the catalogue's lateral slip (which follows
    // v omega in turns; this follows |v| and the world heading), nor the other suites'
    // tilted floor (a constant drift). Outside the catalogue: expected `unexplained`.
    let mut c = case(
        "floor_slope_mobolab",
        "v_y = 0.02 |v_x| (y_body . downhill), downhill at 1.2 rad in the world",
        check::robot_file("mobolab"),
        2610,
    );
    c.gen.mechs = vec![Mech::Slope {
        down_rad: 1.2,
        k: 0.02,
    }];
    c.verdicts = vec!["unexplained"];
    out.push(c);

    // A hub slipping on its motor shaft (a loose set screw) on omni wheel w2: the wheel's
    // angular acceleration is bounded by 16 rad/s^2 (0.64 m/s^2 at its 4 cm radius) while
    // the motor and its encoder follow the command. From encoders and poses this is the
    // per-wheel traction limit: `longitudinal_slip` by `wheel` (the encoder says the wheel
    // rolled more than the ground saw, in hard accelerations, on one wheel). Its limit as a
    // mu: 16 x 0.04 / 9.81 = 0.065. The catalogue's single mu also binds the two good
    // wheels, so a fit may sit somewhat higher: 0.065 +- 40 %.
    let mut c = case(
        "hub_slip_omni3",
        "w2 hub slips: wheel angular acceleration <= 16 rad/s^2 (mu-equivalent 0.065), a_max 0.8",
        check::robot_file("omni3"),
        2611,
    );
    c.gen.a_max = 0.8;
    c.gen.mechs = vec![Mech::HubSlip {
        wheel: 1,
        alpha_max: 16.0,
    }];
    c.verdicts = vec!["longitudinal_slip"];
    c.mechanisms = vec![("longitudinal_slip", vec!["wheel"])];
    c.params = vec![("longitudinal_slip", "mu", 16.0 * 0.04 / 9.81, 0.4, true)];
    out.push(c);
    out
}

fn run(case: &Case) -> check::Outcome {
    let start = Instant::now();
    let (rec, stats) = generate(&case.gen);
    let gen_s = start.elapsed().as_secs_f64();
    let r = diagnose(&case.gen.robot, &rec, &Options::default()).expect("diagnosable");
    let seconds = start.elapsed().as_secs_f64();
    let verdict_ok = case.verdicts.contains(&r.verdict.as_str());
    let mut problems = Vec::new();
    if !verdict_ok {
        problems.push(format!(
            "verdict {} (expected {:?})",
            r.verdict, case.verdicts
        ));
    }
    // Parameters of effects found (the verdict checked above).
    let (_, p) = check::verdict_and_params(&r, r.verdict.as_str(), &[], &case.params);
    problems.extend(p);
    for (e, ok) in &case.mechanisms {
        if let Some(f) = r.findings.iter().find(|f| f.effect == *e) {
            if !ok.contains(&f.mechanism.as_str()) {
                problems.push(format!("{e} mechanism {} (expected {ok:?})", f.mechanism));
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
        "{findings:?}; ground {:.2}->{:.2} mm, actuator {:.3}->{:.3} mm, noise {:.2} mm, \
         explained {:.2}; implausible {:?}; artefacts {}; depends_on {:?}; \
         generated in {gen_s:.1} s; {stats:?}",
        r.rmse.ground.before_m * 1e3,
        r.rmse.ground.after_m * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.before_m) * 1e3,
        r.rmse.actuator.map_or(0.0, |a| a.after_m) * 1e3,
        r.noise.pose_sigma_m * 1e3,
        r.explained_fraction,
        r.implausible
            .iter()
            .map(|i| format!("{} {} {:.5}", i.effect, i.parameter, i.value))
            .collect::<Vec<_>>(),
        r.recording_artefacts.len(),
        r.depends_on,
    );
    check::Outcome {
        name: case.name.to_string(),
        control: case.control(),
        verdict: r.verdict.to_string(),
        verdict_ok,
        full_ok: problems.is_empty(),
        wrong_effect: check::wrong_effect(r.verdict.as_str(), verdict_ok),
        seconds,
        detail: format!("{}; {detail}", problems.join("; ")),
    }
}

/// The regression floor: fully right cases, 7 of 11 in the first run (2026-11-30, commit
/// 09fea67 = diagnose of fe3d9b3), 8 since a stage's remainder that does not drift
/// counts as noise (`select::verdict`).
const FULLY_RIGHT_FLOOR: usize = 8;

/// The right verdicts' floor: 7 in the first run, 9 since traction per wheel
/// (`longitudinal_slip` by `per_wheel`).
const RIGHT_VERDICTS_FLOOR: usize = 9;

#[test]
fn blind_physics() {
    let all = cases();
    let t0 = Instant::now();
    let outcomes: Vec<check::Outcome> = check::run_selected(&all, |c| c.name, run);
    let check::Score {
        n, full, verdicts, ..
    } = check::score(&outcomes, t0);
    let bad: Vec<&str> = outcomes
        .iter()
        .filter(|o| o.control && !o.verdict_ok)
        .map(|o| o.name.as_str())
        .collect();
    assert!(bad.is_empty(), "controls not none: {bad:?}");
    if n == all.len() {
        assert!(
            full >= FULLY_RIGHT_FLOOR,
            "{full} fully right, floor {FULLY_RIGHT_FLOOR}"
        );
        assert!(
            verdicts >= RIGHT_VERDICTS_FLOOR,
            "{verdicts} right verdicts, floor {RIGHT_VERDICTS_FLOOR}"
        );
    }
}

/// The generator itself (no diagnose): each case's mechanism happens and does what the
/// case says, by the generator's own bookkeeping; prints each case's stats.
#[test]
fn blind_generator_does_what_the_cases_say() {
    for c in cases() {
        let (rec, s) = generate(&c.gen);
        println!("{:34} {s:?}", c.name);
        let rows = (c.gen.duration_s * c.gen.row_hz).round() as usize + 1;
        assert_eq!(rec.len(), rows, "{}", c.name);
        assert!(
            s.reversals >= 5 && s.distance_m > 0.05 * c.gen.duration_s,
            "{}: {s:?}",
            c.name
        );
        let signal = |s: &Stats, times: f64| {
            assert!(
                s.dr_rms_m > times * c.gen.pose_noise_m
                    || s.dr_rms_heading_rad > times * c.gen.heading_noise_rad,
                "{}: the physics must leave the noise: {s:?}",
                c.name
            )
        };
        match c.name {
            "marker_swaps_diff" => assert_eq!(s.swaps, 6),
            "eccentric_wheel_sweeper" => {
                // Mean rolling radius nominal (within what a partial revolution leaves),
                // and the wobble above the pose noise.
                assert!((s.mean_radius_ratio[0] - 1.0).abs() < 5e-4, "{s:?}");
                assert!((s.mean_radius_ratio[1] - 1.0).abs() < 1e-9, "{s:?}");
                signal(&s, 2.0);
            }
            "tyre_warmup_diff" => {
                assert!((s.mean_ed - 1.003).abs() < 3e-4, "{s:?}");
                signal(&s, 2.0);
            }
            "payload_offset_diff" => {
                // The right wheel slips (travel lost), the left hardly (it only smooths
                // the row-to-row command steps).
                assert!(
                    s.slip_m[1] > 0.05 && s.slip_m[1] > 5.0 * s.slip_m[0],
                    "{s:?}"
                );
                signal(&s, 2.0);
            }
            "carpet_grain_diff" => {
                assert!((0.008..0.022).contains(&s.carpet_loss), "{s:?}");
                signal(&s, 2.0);
            }
            "encoder_saturation_omni4" => {
                assert!(s.counts_dropped.iter().any(|&d| d > 0.01), "{s:?}");
                signal(&s, 2.0);
            }
            "wheelbase_in_coloured_noise_diff" => signal(&s, 2.0),
            "floor_slope_mobolab" => {
                assert!(s.slope_drift_m > 0.02, "{s:?}");
                signal(&s, 2.0);
            }
            "hub_slip_omni3" => {
                assert!(s.slipping_s[1] > 2.0 && s.slipping_s[0] == 0.0, "{s:?}");
                signal(&s, 2.0);
            }
            _ => {
                assert!(c.gen.mechs.is_empty());
                assert!(s.dr_rms_m < 1e-3, "{}: {s:?}", c.name);
            }
        }
    }
}

/// Prints one case's report, identification and candidates (`DIAG_CASE=name`).
#[test]
#[ignore]
fn explain_blind_case() {
    let filter = std::env::var("DIAG_CASE").unwrap_or_default();
    for c in cases().iter().filter(|c| c.name.contains(filter.as_str())) {
        let (rec, _) = generate(&c.gen);
        let r = diagnose(&c.gen.robot, &rec, &Options::default()).unwrap();
        println!("== {} ({})\n{r}", c.name, c.truth);
        check::explain(&r);
    }
}
