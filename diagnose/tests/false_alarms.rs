//! The false-alarm rate of the whole diagnosis on noise-only recordings (issue 55 item 5):
//! perfect robots of six kinds, driven by two habits, seen through six kinds of pose noise
//! (white, AR(1) 0.97, a drifting capture frame, quantised, SLAM-like 10 Hz, late poses),
//! from the habits generator (`habits/mod.rs`) with seeds no suite uses. A false alarm is any
//! verdict but `none`. The thresholds behind the verdict (docs/diagnose.md, "Thresholds and
//! their false-alarm rates") are judged here as a whole: the rate measured is written there
//! with its 95 % upper bound.

mod habits;

use calib_core::robot::{presets, Drive, Robot};
use diagnose::{diagnose, Options};
use habits::{generate, Gen, Style};

fn robot(k: usize) -> Robot {
    let file = |n: &str| {
        let p = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../robots")
            .join(format!("{n}.toml"));
        formats::robot_file::load(&p).unwrap()
    };
    match k % 6 {
        0 => presets::diff_drive("d1", 0.04, 0.32, Drive::default()),
        1 => file("mobolab"),
        2 => presets::omni3(0.035, 0.14),
        3 => file("sweeper"),
        4 => presets::diff_drive("d2", 0.06, 0.5, Drive::default()),
        _ => file("omni4"),
    }
}

/// The noise-only recording number `k`.
fn control(k: usize) -> Gen {
    let style = if k.is_multiple_of(2) {
        Style::Joystick
    } else {
        Style::Legs
    };
    let r = robot(k);
    let slow = r.name == "omni4";
    let mut g = Gen::new(r, 7100 + k as u64, style);
    if slow {
        g.v_max = 0.15;
        g.a_max = 0.4;
    }
    match (k / 6) % 6 {
        0 => {}
        1 => {
            g.rho = 0.97;
            g.sigma_m = 0.002;
            g.sigma_rad = 0.004;
        }
        2 => {
            g.drift_m = 0.0003;
            g.drift_rad = 0.0004;
            g.sigma_m = 0.0005;
        }
        3 => {
            g.quant_m = 0.001;
            g.quant_rad = 0.002;
            g.sigma_m = 0.0002;
            g.sigma_rad = 0.0004;
        }
        4 => {
            g.pose_hz = 10.0;
            g.sigma_m = 0.004;
            g.sigma_rad = 0.008;
        }
        _ => g.latency_s = 0.05,
    }
    g
}

/// Controls run (six robots by six noises).
const CONTROLS: usize = 36;

/// Most false alarms allowed: the count of the first run (2026-12-07), which may only fall.
const MOST_FALSE_ALARMS: usize = 4;

#[test]
fn noise_only_recordings_say_none() {
    let ks: Vec<usize> = (0..CONTROLS).collect();
    let out = std::thread::scope(|s| {
        let hs: Vec<_> = ks
            .chunks(CONTROLS / 2)
            .map(|c| {
                s.spawn(move || {
                    c.iter()
                        .map(|&k| {
                            let g = control(k);
                            let rec = generate(&g).0.expect("clean clock");
                            let r = diagnose(&g.robot, &rec, &Options::default()).unwrap();
                            let artefacts: Vec<&str> =
                                r.recording_artefacts.iter().map(|a| a.id).collect();
                            println!("control {k:2}: artefacts {artefacts:?}; {:?}", r.depends_on);
                            let wander = r
                                .notes
                                .iter()
                                .any(|n| n.contains("wanders as a drifting pose reference"));
                            (
                                k,
                                g.robot.name.to_string(),
                                r.verdict.to_string(),
                                r.findings.len(),
                                wander,
                            )
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        hs.into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect::<Vec<_>>()
    });
    let alarms: Vec<&(usize, String, String, usize, bool)> =
        out.iter().filter(|(_, _, v, ..)| v != "none").collect();
    for (k, robot, v, n, w) in &out {
        println!(
            "control {k:2} {robot:10} noise kind {} verdict {v} ({n} findings){}",
            (k / 6) % 6,
            if *w {
                "; says the reference wanders"
            } else {
                ""
            }
        );
    }
    println!("FALSE ALARMS: {} of {CONTROLS}: {:?}", alarms.len(), alarms);
    assert!(alarms.len() <= MOST_FALSE_ALARMS, "{alarms:?}");
    // An unexplained drifting frame says what it looks like (drift::test): first run 3 of
    // the 4 (omni3's fails the spread test), which may only rise.
    let said = alarms.iter().filter(|a| a.4).count();
    println!(
        "the reference wander said on {said} of {} false alarms",
        alarms.len()
    );
    assert!(said >= 3, "{alarms:?}");
}
