//! Issue 21's held-out proxy on `shared/real/sessions/`: `calibrate` trained on each
//! square session of the differential robot, its geometry dead-reckoned on the circles and
//! Ivanjko paths of the nearest day, against the OptiOdom authors' parameters from the same
//! session (see `tests/support/proxy.rs`). Prints a markdown table (docs/calibrate.md's).
//!
//!     cargo run --release -p calibrate --features examples --example heldout_proxy [-- OPTIONS]
//!
//! Options: `--robot diff|omni3|omni4` (default diff; omni3 trains on its two square
//! sessions and tests on the 44 circles of the same day, against `omni3-sousa`; omni4, the
//! mecanum robot, whose circles are kept apart, trains on each of its four square sessions
//! and tests on the other three's squares, against `omni4-sousa`),
//! `--sessions DIR` (default: `shared/real/sessions` beside the checkout),
//! `--only S1,S2`, `--max-tests N`, `--json` (per-run numbers), `--free-start`,
//! `--robust`, `--marker-offset`, `--heading-lever M`, `--hold P1,P2` (calibrate's
//! options),
//! `--law-from-other-month [turn|speed]`: first fit the law on each month's runs (June: 23
//! June squares, 25 June circles and Ivanjko paths; December: 23 December; the turn law
//! as calibrate keeps it, the speed law as its `law_tests` fit it on its own), then train
//! each square session with the other month's law held fixed (`--turn-law` or
//! `--speed-law`) and dead-reckon its test runs with that law;
//! `--robot-file`: dead-reckon the test runs with the robot file `calibrate` writes (one
//! E_b, no law: what ROS 2 or another tool gets) instead of the law;
//! `--e-b-for-other-month`: give calibrate the other month's circles and Ivanjko paths as
//! `--e-b-for`, the driving the robot file's E_b (or, with a speed law, its wheel size) is
//! placed for;
//! `--other-days`: test each square session on the circles and Ivanjko paths of the
//! other month instead of its own day's (the robot as it was on other days, as the
//! free-form runs kept apart were driven on days of their own; not for omni3, whose runs
//! are of one day);
//! `--ivanjko`: test each square session on the Ivanjko paths of the nearest day alone
//! (a third kind of motion, mostly spins in place);
//! `--with-circles`: the same tests, with the circles of the nearest day trained on
//! beside the squares (the workflow the README recommends: squares and circles); the
//! authors' row is still their square session's, and `runs` counts the squares;
//! `--first-run`: train on each session's first square alone (the one-recording ladder,
//! as the `one_square_keeps_a_model_that_transfers` test does);
//! `--turn-law K`: train each square session with the turn law K held (eb_arc / eb, as
//! the circle test of `umbmark compute` gives it) and dead-reckon its test runs with it;
//! `--eb-scale F`: multiply the trained geometry's wheel distances (E_b) by F before the
//! test runs, and print what that costs on the training squares themselves (each run
//! dead-reckoned from its first pose, every pose sample: the mean change over the runs
//! and its standard error), to show how well the squares pin E_b.

#[path = "../tests/support/proxy.rs"]
mod proxy;

use calibrate::{calibrate, dead_reckoning_rmse_law, CalOptions, Series};
use std::path::PathBuf;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let val = |k: &str| {
        args.iter()
            .position(|a| a == k)
            .and_then(|i| args.get(i + 1).cloned())
    };
    let flag = |k: &str| args.iter().any(|a| a == k);
    let dir = val("--sessions")
        .map(PathBuf::from)
        .or_else(|| testdata::sessions_dir_if_set().ok());
    let Some(dir) = dir else {
        eprintln!("the OptiOdom sessions are not given: --sessions DIR or WHEELCAL_SESSIONS (data/real/README.md)");
        std::process::exit(2);
    };
    let only: Option<Vec<String>> = val("--only").map(|s| s.split(',').map(String::from).collect());
    let only_refs: Option<Vec<&str>> = only
        .as_ref()
        .map(|v| v.iter().map(|s| s.as_str()).collect());
    let max_tests = val("--max-tests").and_then(|s| s.parse().ok());
    let opts = CalOptions {
        free_start: flag("--free-start"),
        robust: flag("--robust"),
        marker_offset: flag("--marker-offset"),
        heading_lever_m: val("--heading-lever").and_then(|v| v.parse().ok()),
        hold: val("--hold")
            .map(|h| h.split(',').map(String::from).collect())
            .unwrap_or_default(),
        ..Default::default()
    };
    let t0 = std::time::Instant::now();
    let speed = val("--law-from-other-month").as_deref() == Some("speed");
    let laws = flag("--law-from-other-month").then(|| {
        ["06", "12"].map(|m| {
            let law = month_law(&dir, m, speed).unwrap_or_else(|e| {
                eprintln!("{e}");
                std::process::exit(1)
            });
            let what = if speed {
                "speed law, speed_rel per m/s"
            } else {
                "turn law, eb_arc/eb"
            };
            eprintln!("{what} fitted on month {m}: {law:+.4}");
            law
        })
    });
    // The other month's circles and Ivanjko paths, as a log of the driving the robot
    // file is for (their encoders only).
    let driving = flag("--e-b-for-other-month").then(|| {
        ["06", "12"].map(|m| {
            let (_, recs) = proxy::month_runs(&dir, "diff", m).unwrap_or_else(|e| {
                eprintln!("{e}");
                std::process::exit(1)
            });
            recs.into_iter()
                .filter(|(n, _)| !n.contains("-square-"))
                .collect::<Vec<_>>()
        })
    });
    let robot_name = val("--robot").unwrap_or_else(|| "diff".into());
    let days = if flag("--other-days") {
        proxy::TestDays::OtherMonths
    } else if flag("--with-circles") || flag("--ivanjko") {
        proxy::TestDays::Ivanjko {
            with_circles: flag("--with-circles"),
        }
    } else {
        proxy::TestDays::Nearest
    };
    let res = proxy::run_robot_on(
        &dir,
        &robot_name,
        only_refs.as_deref(),
        max_tests,
        days,
        &|robot, recs, session| {
            let other = laws.map(|l| {
                if session.get(2..4) == Some("06") {
                    l[1]
                } else {
                    l[0]
                }
            });
            let june = session.get(2..4) == Some("06");
            let given = val("--turn-law").map(|v| {
                v.parse::<f64>().ok().filter(|k| k.is_finite()).unwrap_or_else(|| {
                    eprintln!("--turn-law {v}: give eb_arc / eb, e.g. 0.006");
                    std::process::exit(2)
                })
            });
            let opts = CalOptions {
                turn_law: other.filter(|_| !speed).or(given),
                speed_law: other.filter(|_| speed),
                e_b_for: driving
                    .as_ref()
                    .map(|d| d[usize::from(june)].clone())
                    .unwrap_or_default(),
                ..opts.clone()
            };
            let t = std::time::Instant::now();
            let recs = if flag("--first-run") {
                &recs[..1]
            } else {
                recs
            };
            let c = calibrate(robot, recs, None, &opts).map_err(|e| e.to_string())?;
            eprintln!(
                "trained on {} recordings in {:.2} s: {}",
                recs.len(),
                t.elapsed().as_secs_f64(),
                c.params
                    .iter()
                    .map(|p| format!("{} {:.5}", p.spec.name, p.value))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            if flag("--verbose") {
                eprintln!("{c}");
            }
            for e in &c.events {
                eprintln!(
                    "  event {} {} at {:.2} s for {:.2} s: {:+.3} rad",
                    e.recording, e.kind, e.t_s, e.duration_s, e.heading_rad
                );
            }
            let (mut robot, law) = if flag("--robot-file") {
                (c.fitted_robot, Default::default())
            } else {
                (c.law_base_robot, c.turn_law)
            };
            if let Some(f) = val("--eb-scale").map(|v| {
                v.parse::<f64>().ok().filter(|f| *f > 0.0).unwrap_or_else(|| {
                    eprintln!("--eb-scale {v}: give a positive factor, e.g. 1.001");
                    std::process::exit(2)
                })
            }) {
                let mut wider = robot.clone();
                for w in wider.wheels.iter_mut() {
                    w.l_m *= f;
                }
                let d: Vec<f64> = recs
                    .iter()
                    .filter_map(|(name, rec)| {
                        let s = Series::new(name, &robot, rec).ok()?;
                        Some(
                            dead_reckoning_rmse_law(&wider, &law, &s)?
                                - dead_reckoning_rmse_law(&robot, &law, &s)?,
                        )
                    })
                    .collect();
                let n = d.len() as f64;
                let mean = d.iter().sum::<f64>() / n;
                let sd = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
                eprintln!(
                    "  E_b x {f}: training squares' dead reckoning {:+.2} ± {:.2} mm (mean change over {} runs ± its standard error)",
                    mean * 1e3,
                    sd / n.sqrt() * 1e3,
                    d.len()
                );
                robot = wider;
            }
            Ok((robot, law))
        },
    )
    .unwrap_or_else(|e| {
        eprintln!("{e}");
        std::process::exit(1)
    });
    if flag("--json") {
        println!("{}", serde_json::to_string_pretty(&res).unwrap());
    }
    print!("{}", proxy::table(&res));
    eprintln!("total {:.1} s", t0.elapsed().as_secs_f64());
}

/// The turn law (eb_arc / eb) `calibrate` keeps on every differential-drive run of month
/// `month` (`"06"`, `"12"`), 0 when it keeps none; with `speed`, the speed law it fits
/// there on its own (its `law_tests`), kept or not.
fn month_law(dir: &std::path::Path, month: &str, speed: bool) -> Result<f64, String> {
    let (robot, recs) = proxy::month_runs(dir, "diff", month)?;
    let c = calibrate(&robot, &recs, None, &CalOptions::default()).map_err(|e| e.to_string())?;
    if !speed {
        return Ok(c.turn_law.arc_rel);
    }
    c.law_tests
        .iter()
        .find(|t| t.law == "speed")
        .map(|t| t.value)
        .ok_or(format!("no speed law was tested on month {month}"))
}
