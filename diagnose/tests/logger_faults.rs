//! Issue 55.4: the faults a logger really makes, beyond whole counts ratios and clocks.
//! Each case is a clean simulated run (no physics hidden; the wheels do what is commanded)
//! with its pose noise put in by this file (white, AR(1) 0.97, a drifting capture frame,
//! quantised) and one logger fault put in by editing the columns or the CSV text. Each
//! fault must be listed under its own recording-artefact id with its time (within one row
//! or pose interval) and size (within a tolerance from the noise), removed before the
//! physics, and the verdict must stay `none`. Noise-only controls (several robots, rates
//! and noises) must show none of these artefacts.
//!
//! Seeds and robots are this file's own (not those of any suite).

#![allow(clippy::needless_range_loop)] // rows of several columns indexed alike

use calib_core::robot::{presets, Drive, DriveType, Robot};
use diagnose::recording_stage::Artefact;
use diagnose::{diagnose, Options, Report};
use formats::recording::Recording;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;
use sim::{record, Motion, RandomMotion, RecordConfig, SimRecording, Surface};
use std::path::Path;

/// The ids this file's faults are reported under (none may appear on a control).
const NEW_IDS: [&str; 7] = [
    "encoder_scale",
    "encoder_sign",
    "wheels_swapped",
    "stale_samples",
    "time_backwards",
    "time_jitter",
    "pose_jump",
];

fn robot_file(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

/// A small DC differential drive (closed-loop motors: a wheel's size is physics).
fn dc_diff() -> Robot {
    presets::diff_drive(
        "dcdiff",
        0.035,
        0.21,
        Drive {
            kind: DriveType::Dc,
            ..Drive::default()
        },
    )
}

#[derive(Clone, Copy, Debug)]
enum Noise {
    /// White, sigma 1 mm / 2 mrad.
    White,
    /// AR(1) with coefficient 0.97 per pose sample, marginal sigma 1 mm / 2 mrad.
    Ar1,
    /// A capture frame drifting as a random walk (0.15 mm, 0.15 mrad per sample) plus
    /// white 0.5 mm / 1 mrad.
    Drift,
    /// Truth rounded to 1 mm and 1 mrad, plus white 0.3 mm / 0.5 mrad.
    Quantised,
}

struct Run {
    robot: Robot,
    sim: SimRecording,
    rec: Recording,
}

/// A random drive of `robot`, `secs` long, rows at `rate_hz`, poses at `pose_hz`, poses
/// replaced by truth plus `noise`.
fn drive(
    robot: &Robot,
    rate_hz: f64,
    pose_hz: f64,
    secs: f64,
    noise: Noise,
    seed: u64,
    effects: &[sim::Effect],
) -> Run {
    let mut cfg = RecordConfig {
        row_rate_hz: rate_hz,
        ..RecordConfig::default()
    };
    cfg.sim.seed = seed;
    cfg.sim.vision.rate_hz = pose_hz;
    let omni = robot.kind == calib_core::robot::RobotKind::Omni;
    let motion = Motion::Random(RandomMotion {
        duration_s: secs,
        v_max_m_s: if omni { 0.2 } else { 0.3 },
        ..RandomMotion::default()
    });
    let sim = record(robot, effects, Surface::flat(), &motion, &cfg).unwrap();
    let mut rec = sim.recording.clone();
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ 0x9e37_79b9);
    let mut n = move || rng.sample::<f64, _>(StandardNormal);
    let (mut ax, mut ay, mut ath) = (0.0f64, 0.0f64, 0.0f64);
    let (mut fx, mut fy, mut fth) = (0.0f64, 0.0f64, 0.0f64);
    let a = 0.97f64;
    let s = (1.0 - a * a).sqrt();
    for k in 0..rec.len() {
        if rec.x[k].is_none() {
            continue;
        }
        let tr = sim.truth[k].pose;
        let (x, y, th) = match noise {
            Noise::White => (
                tr.x + 0.001 * n(),
                tr.y + 0.001 * n(),
                tr.theta + 0.002 * n(),
            ),
            Noise::Ar1 => {
                ax = a * ax + s * 0.001 * n();
                ay = a * ay + s * 0.001 * n();
                ath = a * ath + s * 0.002 * n();
                (tr.x + ax, tr.y + ay, tr.theta + ath)
            }
            Noise::Drift => {
                fx += 0.00015 * n();
                fy += 0.00015 * n();
                fth += 0.00015 * n();
                let (c, si) = (fth.cos(), fth.sin());
                (
                    c * tr.x - si * tr.y + fx + 0.0005 * n(),
                    si * tr.x + c * tr.y + fy + 0.0005 * n(),
                    tr.theta + fth + 0.001 * n(),
                )
            }
            Noise::Quantised => (
                (tr.x / 0.001).round() * 0.001 + 0.0003 * n(),
                (tr.y / 0.001).round() * 0.001 + 0.0003 * n(),
                (tr.theta / 0.001).round() * 0.001 + 0.0005 * n(),
            ),
        };
        rec.x[k] = Some(x);
        rec.y[k] = Some(y);
        rec.theta[k] = Some(th);
    }
    Run {
        robot: robot.clone(),
        sim,
        rec,
    }
}

fn run(r: &Robot, rec: &Recording) -> Report {
    let rep = diagnose(r, rec, &Options::default()).unwrap();
    println!("{rep}");
    rep
}

fn artefact<'a>(rep: &'a Report, id: &str) -> &'a Artefact {
    rep.recording_artefacts
        .iter()
        .find(|a| a.id == id)
        .unwrap_or_else(|| panic!("no {id} in {:?}", ids(rep)))
}

fn ids(rep: &Report) -> Vec<String> {
    rep.recording_artefacts
        .iter()
        .map(|a| a.to_string())
        .collect()
}

fn assert_none(rep: &Report, what: &str) {
    assert_eq!(
        rep.verdict,
        diagnose::VERDICT_NONE,
        "{what}: {:?}; {:?}",
        rep.findings,
        ids(rep)
    );
}

fn enc(rec: &mut Recording, i: usize) -> &mut Vec<Option<i64>> {
    rec.wheels[i].enc.as_mut().unwrap()
}

/// Noise-only recordings: none of the new artefacts, and no physics.
#[test]
fn controls_show_no_logger_fault() {
    let cases: Vec<(Robot, f64, f64, Noise, u64)> = vec![
        (robot_file("mobolab"), 50.0, 30.0, Noise::White, 7101),
        (robot_file("mobolab"), 100.0, 100.0, Noise::Ar1, 7102),
        (presets::omni3(0.04, 0.15), 100.0, 50.0, Noise::Drift, 7103),
        (robot_file("omni4"), 100.0, 100.0, Noise::Quantised, 7104),
        (dc_diff(), 20.0, 10.0, Noise::White, 7105),
        (dc_diff(), 200.0, 100.0, Noise::Ar1, 7106),
        (robot_file("robotest"), 100.0, 30.0, Noise::Drift, 7107),
        (robot_file("sweeper"), 60.0, 60.0, Noise::Quantised, 7108),
    ];
    let mut bad = vec![];
    for (r, rate, pose_hz, noise, seed) in cases {
        let g = drive(&r, rate, pose_hz, 60.0, noise, seed, &[]);
        let rep = run(&g.robot, &g.rec);
        let what = format!(
            "{} {rate} Hz poses {pose_hz} Hz {noise:?} seed {seed}",
            r.name
        );
        let new: Vec<&Artefact> = rep
            .recording_artefacts
            .iter()
            .filter(|a| NEW_IDS.contains(&a.id))
            .collect();
        println!("{what}: verdict {}; artefacts {:?}", rep.verdict, ids(&rep));
        // The drifting capture's verdict is the physics stages' (a frame turning 8 mrad
        // over the run; main said `unexplained` on two of them before this change): only
        // the recording artefacts are asserted there.
        let drift = matches!(noise, Noise::Drift);
        if !new.is_empty() || (!drift && rep.verdict != diagnose::VERDICT_NONE) {
            bad.push(format!("{what}: {} {:?}", rep.verdict, ids(&rep)));
        }
    }
    assert!(bad.is_empty(), "{bad:#?}");
}

/// An encoder whose disc gives 0.97 (or 1.04) of the configured counts, on an open-loop
/// stepper robot whose wheels follow the commands: encoder over commanded travel is the
/// scale, and the poses agree with the commands. Tolerance: 0.004 (the ratio of whole
/// counts over ~60 s of travel is exact to 1e-4; the segments' scatter from decimation
/// and the rounding of counts is far below).
#[test]
fn encoder_scale_on_a_stepper_is_found_and_removed() {
    for (name, wheel, k, seed) in [
        ("mobolab", 1usize, 0.97, 7201u64),
        ("robotest", 0, 1.04, 7202),
    ] {
        let r = robot_file(name);
        let mut g = drive(&r, 50.0, 30.0, 60.0, Noise::White, seed, &[]);
        for c in enc(&mut g.rec, wheel).iter_mut().flatten() {
            *c = (*c as f64 * k).round() as i64;
        }
        let rep = run(&r, &g.rec);
        let a = artefact(&rep, "encoder_scale");
        let key = format!("encoder_scale_{}", r.wheels[wheel].name);
        let other = format!("encoder_scale_{}", r.wheels[1 - wheel].name);
        assert!((a.parameters[&key] - k).abs() < 0.004, "{name}: {a}");
        assert!(!a.parameters.contains_key(&other), "{name}: {a}");
        assert!(a.removed, "{a}");
        assert_none(&rep, name);
    }
}

/// A wheel 3 % large is physics, not an encoder: on a DC robot (encoders close the loop,
/// nothing separates a wheel's size from its encoder's scale against the poses) and on a
/// stepper (encoder over commanded travel is 1; the poses disagree with both). No
/// `encoder_scale`, and the verdict is not `none` (which effect the physics names is the
/// physics stages' business: main said `unexplained` on the DC robot before this change).
#[test]
fn a_wheel_size_is_not_an_encoder_scale() {
    let fx = [sim::Effect::parse("wheel_diameter_mismatch=ed:1.03").unwrap()];
    for (r, seed) in [(dc_diff(), 7211u64), (robot_file("mobolab"), 7212)] {
        let g = drive(&r, 50.0, 30.0, 60.0, Noise::White, seed, &fx);
        let rep = run(&r, &g.rec);
        assert!(
            !rep.recording_artefacts
                .iter()
                .any(|a| a.id == "encoder_scale"),
            "{}: {:?}",
            r.name,
            ids(&rep)
        );
        assert_ne!(rep.verdict, diagnose::VERDICT_NONE, "{}", r.name);
    }
}

/// One encoder counting backwards: its travel against what the body motion asks of it
/// correlates near -1. Reported per wheel (`sign_<wheel>` = -1), negated back, `none`.
#[test]
fn sign_flipped_encoder_is_found_and_removed() {
    let cases = [
        (presets::omni3(0.04, 0.15), 2usize, Noise::Ar1, 7301u64),
        (dc_diff(), 0, Noise::White, 7302),
    ];
    for (r, wheel, noise, seed) in cases {
        let mut g = drive(&r, 100.0, 50.0, 60.0, noise, seed, &[]);
        for c in enc(&mut g.rec, wheel).iter_mut().flatten() {
            *c = -*c;
        }
        let rep = run(&r, &g.rec);
        let a = artefact(&rep, "encoder_sign");
        assert_eq!(
            a.parameters.get(&format!("sign_{}", r.wheels[wheel].name)),
            Some(&-1.0),
            "{}: {a}",
            r.name
        );
        assert_eq!(
            a.parameters.len(),
            1,
            "{}: only the flipped wheel: {a}",
            r.name
        );
        assert!(a.removed);
        assert!(!rep
            .recording_artefacts
            .iter()
            .any(|a| a.id == "wheels_swapped"));
        assert_none(&rep, &r.name);
    }
}

/// Two encoder columns exchanged: each matches the other wheel's demand. Reported as the
/// pair (`source_<wheel>`: 1-based index of the wheel whose counts the column holds),
/// swapped back, `none`.
#[test]
fn swapped_encoder_columns_are_found_and_removed() {
    let cases = [
        (dc_diff(), (0usize, 1usize), Noise::Ar1, 7401u64),
        (robot_file("omni4"), (1, 2), Noise::White, 7402),
    ];
    for (r, (p, q), noise, seed) in cases {
        let mut g = drive(&r, 100.0, 50.0, 60.0, noise, seed, &[]);
        let (ep, eq) = (g.rec.wheels[p].enc.take(), g.rec.wheels[q].enc.take());
        g.rec.wheels[p].enc = eq;
        g.rec.wheels[q].enc = ep;
        let rep = run(&r, &g.rec);
        let a = artefact(&rep, "wheels_swapped");
        let (np, nq) = (&r.wheels[p].name, &r.wheels[q].name);
        assert_eq!(
            a.parameters.get(&format!("source_{np}")),
            Some(&(q as f64 + 1.0)),
            "{a}"
        );
        assert_eq!(
            a.parameters.get(&format!("source_{nq}")),
            Some(&(p as f64 + 1.0)),
            "{a}"
        );
        assert_eq!(a.parameters.len(), 2, "{a}");
        assert!(a.removed);
        assert!(!rep
            .recording_artefacts
            .iter()
            .any(|a| a.id == "encoder_sign"));
        assert_none(&rep, &r.name);
    }
}

/// Random rows (4 %) repeat the previous row's encoder values (a stale buffer) and the
/// next row catches up; the poses are fresh. Every stale row where a wheel turns at least
/// 2 counts per row on the two rows before it and the row after is listed at its time, no
/// other row is, and the encoders are repaired: `none`.
#[test]
fn stale_encoder_rows_are_timed_and_repaired() {
    for (r, rate, seed) in [
        (dc_diff(), 100.0, 7501u64),
        (robot_file("omni4"), 50.0, 7502),
    ] {
        let mut g = drive(&r, rate, 30.0, 60.0, Noise::White, seed, &[]);
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let n = g.rec.len();
        let mut stale = vec![false; n];
        for (k, s) in stale.iter_mut().enumerate().take(n - 2).skip(3) {
            *s = rng.random::<f64>() < 0.04;
            let _ = k;
        }
        // Runs of one row only (the catch-up row is fresh).
        for k in 1..n {
            if stale[k] && stale[k - 1] {
                stale[k] = false;
            }
        }
        let clean = g.rec.clone();
        for k in 0..n {
            if stale[k] {
                for i in 0..r.wheels.len() {
                    let e = enc(&mut g.rec, i);
                    e[k] = e[k - 1];
                }
            }
        }
        // The detectable ones: a wheel turns >= 2 counts per row on the two rows before
        // and the row after, the same way.
        let fast = |k: usize| {
            clean.wheels.iter().any(|w| {
                let e = w.enc.as_ref().unwrap();
                let d = |a: usize, b: usize| e[b].unwrap() - e[a].unwrap();
                let v = [d(k - 2, k - 1), d(k - 1, k), d(k, k + 1)];
                v.iter().all(|x| x.abs() >= 2)
                    && (v[0] > 0) == (v[2] > 0)
                    && (v[1] > 0) == (v[2] > 0)
            })
        };
        let want: Vec<f64> = (0..n)
            .filter(|&k| stale[k] && fast(k))
            .map(|k| g.rec.t[k])
            .collect();
        let rep = run(&r, &g.rec);
        let a = artefact(&rep, "stale_samples");
        let got: Vec<f64> = a.events.iter().map(|e| e.at_s).collect();
        println!(
            "{}: {} stale, {} detectable, {} listed",
            r.name,
            stale.iter().filter(|s| **s).count(),
            want.len(),
            got.len()
        );
        for t in &got {
            assert!(
                stale
                    .iter()
                    .enumerate()
                    .any(|(k, s)| *s && (g.rec.t[k] - t).abs() < 1e-9),
                "{}: {t} listed, not stale",
                r.name
            );
        }
        // A stale row without a pose on either side repeats its whole row: main's
        // `sample_glitch` lists it as a duplicated sample (and drops it) before this
        // check runs; either listing counts.
        let dup: Vec<f64> = rep
            .recording_artefacts
            .iter()
            .filter(|a| a.id == "sample_glitch")
            .flat_map(|a| a.duplicated_at_s.clone())
            .collect();
        for t in &dup {
            assert!(
                stale
                    .iter()
                    .enumerate()
                    .any(|(k, s)| *s && (g.rec.t[k] - t).abs() < 1e-9),
                "{}: {t} listed as duplicated, not stale",
                r.name
            );
        }
        println!("{}: {} more listed as duplicated rows", r.name, dup.len());
        for t in &want {
            if !got.iter().chain(&dup).any(|g| (g - t).abs() < 1e-9) {
                let k = g.rec.t.iter().position(|x| x == t).unwrap_or(3).max(3);
                for m in k - 3..(k + 3).min(g.rec.len()) {
                    let e: Vec<_> = g
                        .rec
                        .wheels
                        .iter()
                        .map(|w| w.enc.as_ref().unwrap()[m])
                        .collect();
                    println!("  row {m} t {} stale {} enc {e:?}", g.rec.t[m], stale[m]);
                }
            }
            assert!(
                got.iter().chain(&dup).any(|g| (g - t).abs() < 1e-9),
                "{}: {t} missed",
                r.name
            );
        }
        assert_eq!(a.parameters["stale_encoder_rows"], got.len() as f64);
        assert!(a.removed);
        assert_none(&rep, &r.name);
    }
}

/// Pose samples (5 %) repeating the previous pose sample (a tracker that did not update):
/// every one where the robot moved 10 noise sigmas by the next sample is listed at its
/// time, no fresh sample is, and they are blanked: `none`.
#[test]
fn stale_pose_samples_are_timed_and_blanked() {
    let r = presets::omni3(0.04, 0.15);
    let mut g = drive(&r, 100.0, 50.0, 60.0, Noise::White, 7511, &[]);
    let mut rng = ChaCha8Rng::seed_from_u64(7511);
    let rows: Vec<usize> = (0..g.rec.len()).filter(|&k| g.rec.x[k].is_some()).collect();
    let (mut want, mut put) = (vec![], vec![]);
    for j in 2..rows.len() - 1 {
        let (k, k0, k1) = (rows[j], rows[j - 1], rows[j + 1]);
        // Travel from the sample repeated to the next fresh one.
        let moved = (g.sim.truth[k1].pose.x - g.sim.truth[k0].pose.x)
            .hypot(g.sim.truth[k1].pose.y - g.sim.truth[k0].pose.y);
        if rng.random::<f64>() < 0.05 && g.rec.x[k0] != g.rec.x[rows[j - 2]] {
            g.rec.x[k] = g.rec.x[k0];
            g.rec.y[k] = g.rec.y[k0];
            g.rec.theta[k] = g.rec.theta[k0];
            put.push(g.rec.t[k]);
            // Detectable when the robot moved 10 noise sigmas (1 mm) by the next sample.
            if moved > 0.010 {
                want.push(g.rec.t[k]);
            }
        }
    }
    let rep = run(&r, &g.rec);
    let a = artefact(&rep, "stale_samples");
    let got: Vec<f64> = a.events.iter().map(|e| e.at_s).collect();
    println!("{} detectable, {} listed", want.len(), got.len());
    for t in &want {
        assert!(got.iter().any(|g| (g - t).abs() < 1e-9), "{t} missed");
    }
    for t in &got {
        assert!(
            put.iter().any(|p| (p - t).abs() < 1e-9),
            "{t} listed, not stale"
        );
    }
    assert!(a.parameters["stale_pose_samples"] >= want.len() as f64);
    assert_none(&rep, "omni3");
}

/// The CSV text of `rec` with row `k`'s time replaced by `t(k)`.
fn csv_with_times(rec: &Recording, t: &[f64]) -> String {
    let mut r = rec.clone();
    r.t = t.to_vec();
    let mut buf = Vec::new();
    r.write_csv(&mut buf).unwrap();
    String::from_utf8(buf).unwrap()
}

/// Times that go back: the clock steps back 25 ms and stays (at 4 places), and 3 single
/// rows are written 30 ms early. The parser reads the file (as `wheelcal diagnose`
/// does), each place is listed with its written time and size (within 3 ms),
/// the rows are re-timed, and the verdict is `none`.
#[test]
fn times_that_go_back_are_read_listed_and_retimed() {
    let r = robot_file("omni4");
    let g = drive(&r, 100.0, 50.0, 60.0, Noise::White, 7601, &[]);
    let t = g.rec.t.clone();
    let n = t.len();
    let mut w = t.clone();
    let steps = [n / 7, 2 * n / 7, 4 * n / 7, 6 * n / 7];
    let singles = [n / 5 + 3, n / 2 + 7, 4 * n / 5 + 1];
    for &k in &steps {
        for v in w.iter_mut().skip(k) {
            *v -= 0.025;
        }
    }
    for &k in &singles {
        w[k] -= 0.030;
    }
    let text = csv_with_times(&g.rec, &w);
    let path = Path::new("back.csv");
    let rec = Recording::parse(&text, path, &r).expect("read, not refused");
    let dec = formats::decimate::parse(&text, path, &r, 100.0).expect("read when merging");
    assert_eq!(rec.len(), n);
    assert!(rec.t.windows(2).all(|p| p[1] > p[0]));
    assert!(dec.t.windows(2).all(|p| p[1] > p[0]));
    let rep = run(&r, &rec);
    let a = artefact(&rep, "time_backwards");
    assert_eq!(a.events.len(), steps.len() + singles.len(), "{a}");
    // The size is the clock's error: 25 ms for a step, 30 ms for a row written early
    // (the written time goes back 15 and 20 ms below the row before it); the time is the
    // written time of the row that goes back, as in the file.
    for (k, back) in steps
        .iter()
        .map(|&k| (k, 0.025))
        .chain(singles.iter().map(|&k| (k, 0.030)))
    {
        let e = a
            .events
            .iter()
            .find(|e| (e.at_s - w[k]).abs() < 1e-9)
            .unwrap_or_else(|| panic!("row {k} (t {}) not listed: {a}", w[k]));
        let size = e.size.get("back_s").copied().unwrap_or(f64::NAN);
        assert!(
            (size - back).abs() < 0.003,
            "row {k}: back {size} for {back}: {a}"
        );
    }
    assert!(a.removed);
    assert_none(&rep, "omni4");
    // The same file, merged as `wheelcal diagnose` reads it.
    let rep = run(&r, &dec);
    assert!(rep
        .recording_artefacts
        .iter()
        .any(|a| a.id == "time_backwards"));
    assert_none(&rep, "omni4 merged");
}

/// A time going back further than any logger's clock step (here to 0 after 20 s: two
/// runs in one file) is refused, naming the line.
#[test]
fn a_time_going_far_back_is_refused() {
    let r = robot_file("omni4");
    let g = drive(&r, 50.0, 25.0, 20.0, Noise::White, 7602, &[]);
    let mut w = g.rec.t.clone();
    let n = w.len();
    for (j, v) in w.iter_mut().skip(n / 2).enumerate() {
        *v = j as f64 * 0.02;
    }
    let e = Recording::parse(&csv_with_times(&g.rec, &w), Path::new("two.csv"), &r).unwrap_err();
    assert_eq!(e.line, Some(n / 2 + 2), "{e}");
    assert!(e.message.contains("time"), "{e}");
}

/// Written times jittering with sd 2 ms around rows sampled every 10 ms: the jitter's
/// size is reported (`time_jitter_s` within 25 % of 2 ms) and the rows re-timed; `none`.
/// Rows sampled at irregular instants with exact times are not jitter.
#[test]
fn jittered_times_are_measured() {
    let r = dc_diff();
    let g = drive(&r, 100.0, 50.0, 60.0, Noise::White, 7701, &[]);
    let mut rng = ChaCha8Rng::seed_from_u64(7701);
    let mut w = g.rec.t.clone();
    let t0 = w[0];
    for (k, v) in w.iter_mut().enumerate() {
        *v = t0 + k as f64 * 0.01 + 0.002 * rng.sample::<f64, _>(StandardNormal);
    }
    let rec = Recording::parse(&csv_with_times(&g.rec, &w), Path::new("j.csv"), &r).unwrap();
    println!(
        "time faults: {} back, rows {}, median {}, sd {}",
        rec.time_faults.count,
        rec.time_faults.rows,
        rec.time_faults.step_median_s,
        rec.time_faults.step_sd_s
    );
    let rep = run(&r, &rec);
    let a = artefact(&rep, "time_jitter");
    let s = a.parameters["time_jitter_s"];
    assert!((s - 0.002).abs() < 0.0005, "{a}");
    assert_none(&rep, "jitter");

    // Irregular sampling, exact times: rows picked from a 1 kHz run at 10 ms +- 2 ms.
    let mut cfg = RecordConfig {
        row_rate_hz: 1000.0,
        ..RecordConfig::default()
    };
    cfg.sim.seed = 7702;
    cfg.sim.vision.rate_hz = 50.0;
    let motion = Motion::Random(RandomMotion {
        duration_s: 60.0,
        ..RandomMotion::default()
    });
    let fine = record(&r, &[], Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording;
    let mut keep = vec![false; fine.len()];
    let mut k = 0usize;
    while k < fine.len() {
        keep[k] = true;
        let step = (10.0 + 2.0 * rng.sample::<f64, _>(StandardNormal))
            .round()
            .max(4.0);
        k += step as usize;
    }
    // The pose rows (every 20 ms) kept too: their times are exact as well.
    let mut irregular = Recording {
        wheels: fine
            .wheels
            .iter()
            .map(|w| formats::recording::WheelSeries {
                name: w.name.clone(),
                cmd: w.cmd.as_ref().map(|_| vec![]),
                enc: w.enc.as_ref().map(|_| vec![]),
            })
            .collect(),
        ..Default::default()
    };
    for (k, kept) in keep.iter().enumerate() {
        if *kept || fine.x[k].is_some() {
            formats::recording::Cells::of(&fine, k).push_to(&mut irregular);
        }
    }
    let rep = run(&r, &irregular);
    assert!(
        !rep.recording_artefacts
            .iter()
            .any(|a| NEW_IDS.contains(&a.id)),
        "{:?}",
        ids(&rep)
    );
    assert_none(&rep, "irregular rows, exact times");
}

/// A relocalisation: at 55 % of the run the pose frame jumps rigidly (5 cm, -4 cm,
/// 0.04 rad) and stays. Listed at its time (within one pose interval) with its size
/// (within 5 mm and 5 mrad: a few pose sigmas), the poses after it re-aligned: `none`.
#[test]
fn a_relocalisation_jump_is_found_and_realigned() {
    for (r, noise, seed) in [
        (dc_diff(), Noise::White, 7801u64),
        (presets::omni3(0.04, 0.15), Noise::Ar1, 7802),
    ] {
        let mut g = drive(&r, 100.0, 30.0, 60.0, noise, seed, &[]);
        let (dx, dy, dth): (f64, f64, f64) = (0.05, -0.04, 0.04);
        let t_jump = 0.55 * 60.0;
        let (c, s) = (dth.cos(), dth.sin());
        let mut first = None;
        for k in 0..g.rec.len() {
            if g.rec.t[k] < t_jump || g.rec.x[k].is_none() {
                continue;
            }
            first.get_or_insert(g.rec.t[k]);
            let (x, y) = (g.rec.x[k].unwrap(), g.rec.y[k].unwrap());
            g.rec.x[k] = Some(c * x - s * y + dx);
            g.rec.y[k] = Some(s * x + c * y + dy);
            g.rec.theta[k] = Some(g.rec.theta[k].unwrap() + dth);
        }
        let first = first.unwrap();
        let rep = run(&r, &g.rec);
        let a = artefact(&rep, "pose_jump");
        assert_eq!(a.events.len(), 1, "{}: {a}", r.name);
        let e = &a.events[0];
        assert!(
            (e.at_s - first).abs() <= 1.0 / 30.0 + 1e-9,
            "{}: {a}",
            r.name
        );
        assert!(
            (e.size["dtheta_rad"] - dth).abs() < 0.005,
            "{}: {a}",
            r.name
        );
        assert!((e.size["dx_m"] - dx).abs() < 0.005, "{}: {a}", r.name);
        assert!((e.size["dy_m"] - dy).abs() < 0.005, "{}: {a}", r.name);
        assert!(a.removed);
        assert_none(&rep, &r.name);
    }
}

/// Single pose samples 8 cm off (a marker swap) at three places: listed with their times,
/// blanked, `none`.
#[test]
fn single_sample_pose_jumps_are_found_and_blanked() {
    let r = robot_file("mobolab");
    let mut g = drive(&r, 50.0, 50.0, 60.0, Noise::White, 7811, &[]);
    let rows: Vec<usize> = (0..g.rec.len()).filter(|&k| g.rec.x[k].is_some()).collect();
    let at = [
        rows[rows.len() / 4],
        rows[rows.len() / 2],
        rows[3 * rows.len() / 4],
    ];
    for &k in &at {
        g.rec.x[k] = g.rec.x[k].map(|x| x + 0.08);
    }
    let rep = run(&r, &g.rec);
    let a = artefact(&rep, "pose_jump");
    assert_eq!(a.events.len(), 3, "{a}");
    for &k in &at {
        assert!(
            a.events.iter().any(|e| (e.at_s - g.rec.t[k]).abs() < 1e-9),
            "{a}"
        );
    }
    assert_none(&rep, "mobolab");
}

/// Dropped rows (1 % at random) are gaps of `sample_glitch` with their count: `none`.
#[test]
fn dropped_rows_are_gaps() {
    let r = dc_diff();
    let g = drive(&r, 100.0, 30.0, 60.0, Noise::White, 7901, &[]);
    let mut rng = ChaCha8Rng::seed_from_u64(7901);
    let n = g.rec.len();
    let drop: Vec<bool> = (0..n)
        .map(|k| k > 0 && k + 1 < n && rng.random::<f64>() < 0.01)
        .collect();
    let mut rec = Recording {
        wheels: g
            .rec
            .wheels
            .iter()
            .map(|w| formats::recording::WheelSeries {
                name: w.name.clone(),
                cmd: w.cmd.as_ref().map(|_| vec![]),
                enc: w.enc.as_ref().map(|_| vec![]),
            })
            .collect(),
        ..Default::default()
    };
    for k in 0..n {
        if !drop[k] {
            formats::recording::Cells::of(&g.rec, k).push_to(&mut rec);
        }
    }
    let rep = run(&r, &rec);
    let a = artefact(&rep, "sample_glitch");
    let dropped = drop.iter().filter(|d| **d).count() as f64;
    assert_eq!(a.parameters["missing_samples"], dropped, "{a}");
    assert_none(&rep, "dropped rows");
}

/// Each check's statistic on noise-only recordings (16: 8 robots/rates/noises, 2 seeds
/// each, merged to 100 rows/s as diagnose does), against its threshold: the margins
/// docs/diagnose.md states. No control reaches a threshold.
#[test]
fn threshold_margins_on_controls() {
    use diagnose::recording_stage::{
        statistics, JITTER_FRACTION, JUMP_Z, SCALE_MIN, WIRING_MIN_CORR, WIRING_RATIO,
    };
    let cases: Vec<(Robot, f64, f64, Noise)> = vec![
        (robot_file("mobolab"), 50.0, 30.0, Noise::White),
        (robot_file("mobolab"), 100.0, 100.0, Noise::Ar1),
        (presets::omni3(0.04, 0.15), 100.0, 50.0, Noise::Drift),
        (robot_file("omni4"), 100.0, 100.0, Noise::Quantised),
        (dc_diff(), 20.0, 10.0, Noise::White),
        (dc_diff(), 200.0, 100.0, Noise::Ar1),
        (robot_file("robotest"), 100.0, 30.0, Noise::Drift),
        (robot_file("sweeper"), 60.0, 60.0, Noise::Quantised),
    ];
    let (mut own, mut ratio, mut off, mut z, mut jit) =
        (f64::INFINITY, f64::INFINITY, 0.0f64, 0.0f64, 0.0f64);
    for (r, rate, pose_hz, noise) in &cases {
        for seed in [7111u64, 7112] {
            let g = drive(r, *rate, *pose_hz, 60.0, *noise, seed ^ (*rate as u64), &[]);
            let rec = g.rec.decimated(100.0).0;
            let s = statistics(r, &rec);
            println!(
                "{:9} {rate:5} Hz poses {pose_hz:5} Hz {noise:9?} seed {seed}: own corr {:.4}, permuted {:.1}, scale off {:.2e} ({:.1} sigma), innovation z {:.2}, jitter {:.3}",
                r.name,
                s.own_correlation_min,
                s.permuted_ratio_min,
                s.scale_off_max,
                s.scale_off_sigmas_max,
                s.innovation_z_max,
                s.jitter_fraction
            );
            own = own.min(s.own_correlation_min);
            ratio = ratio.min(s.permuted_ratio_min);
            if s.scale_off_max.is_finite() {
                off = off.max(s.scale_off_max);
            }
            z = z.max(s.innovation_z_max);
            if s.jitter_fraction.is_finite() {
                jit = jit.max(s.jitter_fraction);
            }
        }
    }
    println!(
        "controls: own correlation >= {own:.4} (sign flip at <= -{WIRING_MIN_CORR}); permuted share >= {ratio:.1} x (swap below {WIRING_RATIO}); stepper scale off <= {off:.2e} (threshold {SCALE_MIN}); innovation z <= {z:.2} (threshold {JUMP_Z}); jitter <= {jit:.3} of the interval (threshold {JITTER_FRACTION})"
    );
    assert!(own > WIRING_MIN_CORR && ratio > 1.0 / WIRING_RATIO);
    assert!(off < SCALE_MIN && z < JUMP_Z && jit < JITTER_FRACTION);
}
