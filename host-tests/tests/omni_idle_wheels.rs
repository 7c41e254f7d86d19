//! Issue 12: idle wheels held or released on the omni paths. [Redundant omni]'s four-wheel robot over
//! its cable strip, with per-wheel radius errors of a few per cent, on a virtual board
//! (the firmware's application on the simulator). The guided procedure runs in each mode;
//! factors from `omni compute` in the matching mode cut the mean radial error, and factors
//! computed in the wrong mode, put on the same robot, show the loss.
//!
//! Measured (seeds 21/22): on a flat floor the matching mode cuts the error 99.0 %
//! (released) and 99.2 % (held), the wrong mode 0.3 % and 0.1 %. Over cables costing
//! 0.5 mm of travel per crossing: 87.2 % and 79.8 % (matching) against -13.5 % and -16.0 %
//! (wrong). What remains over cables (3.8-3.9 mm) is the crossings' run-to-run scatter,
//! which no per-wheel factor can remove ([Redundant omni] reports 80 % over its cables); the issue's
//! 90 % over cables is not reached in this simulator.

use calib_core::protocol::IdleWheels;
use calib_core::Corrections;
use formats::robot_file;
use formats::runs_file::RunsFile;
use std::path::{Path, PathBuf};
use wheelcal::calibration::omni;
use wheelcal::calibration::procedure::{self, Kind, Options, ProcedureReport, TruthChannel};
use wheelcal::link::Faults;
use wheelcal::virtual_board::InProcessBoard;

fn robot() -> calib_core::Robot {
    robot_file::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/omni4.toml")).unwrap()
}

fn runs_file(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("wheelcal-idle-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d.join("runs.csv")
}

/// The robot of [Redundant omni] with wheels 4 %, -2 %, 3 % and -3 % off their nominal radius, over
/// cables every 30 mm costing `cable_loss_m` of travel per crossing (0: a flat floor).
fn board(seed: u64, cable_loss_m: f64) -> InProcessBoard {
    let r = robot();
    let effects = [
        sim::Effect::parse(&format!("floor_bumps=spacing_m:0.03,loss_m:{cable_loss_m}")).unwrap(),
        sim::Effect::parse(
            "wheel_diameter_mismatch=radius_scale_w1:1.04,radius_scale_w2:0.98,radius_scale_w3:1.03,radius_scale_w4:0.97",
        )
        .unwrap(),
    ];
    let (faults, surface) = sim::Faults::from_effects(&r, &effects, sim::Surface::flat()).unwrap();
    let s = sim::SimRobot::new(
        &r,
        faults,
        surface,
        sim::SimConfig {
            seed,
            ..Default::default()
        },
    )
    .unwrap();
    InProcessBoard::start(&r, s, Faults::none(), Faults::none(), seed).unwrap()
}

fn options(runs_file: PathBuf, idle: IdleWheels, after: bool) -> Options {
    Options {
        kind: Kind::Omni,
        side_m: 0.6,
        length_m: 0.6,
        runs: 5,
        after_runs: if after { 5 } else { 0 },
        runs_file,
        auto_measure: None,
        report: None,
        after,
        second_pass: false,
        idle_wheels: idle,
        circles: None,
    }
}

/// (error before, error with matching-mode factors, error with wrong-mode factors), mm.
fn errors_in_mode(truth_mode: IdleWheels, seed: u64, cable_loss_m: f64) -> (f64, f64, f64) {
    let wrong = match truth_mode {
        IdleWheels::Held => IdleWheels::Released,
        IdleWheels::Released => IdleWheels::Held,
    };
    let mut b = board(seed, cable_loss_m);
    let first = runs_file(&format!("{}-{cable_loss_m}-first", truth_mode.as_str()));
    let rep = {
        let mut truth = TruthChannel {
            rx: &b.truths,
            seen: Vec::new(),
            progress: None,
        };
        b.client.hello().unwrap();
        procedure::run(
            &mut b.client,
            &options(first.clone(), truth_mode, true),
            &mut truth,
        )
        .unwrap()
    };
    let ProcedureReport::Omni(o) = rep else {
        panic!("omni report expected")
    };
    assert_eq!(o.idle_wheels, truth_mode.as_str());
    // The mode is kept beside the runs: a later compute without the flag uses it.
    assert_eq!(omni::read_idle_sidecar(&first).unwrap(), Some(truth_mode));
    let before = o.mean_radial_error_m * 1e3;
    let matched = o.mean_radial_error_after_m.unwrap() * 1e3;

    // The same 'before' runs computed in the wrong mode, put on the robot, measured.
    let runs = RunsFile::load(&first).unwrap();
    let w = omni::compute(&robot(), &runs, wrong).unwrap();
    assert_eq!(w.idle_wheels, wrong.as_str());
    b.client
        .set_corrections(Corrections::Omni {
            f_lat: heapless::Vec::from_slice(&w.f_lat).unwrap(),
            f_lon: w.f_lon,
        })
        .unwrap();
    let second = runs_file(&format!("{}-{cable_loss_m}-wrong", truth_mode.as_str()));
    let rep = {
        let mut truth = TruthChannel {
            rx: &b.truths,
            seen: Vec::new(),
            progress: None,
        };
        procedure::run(
            &mut b.client,
            &options(second, truth_mode, false),
            &mut truth,
        )
        .unwrap()
    };
    let ProcedureReport::Omni(o2) = rep else {
        panic!("omni report expected")
    };
    (before, matched, o2.mean_radial_error_m * 1e3)
}

fn improvement(before: f64, after: f64) -> f64 {
    100.0 * (before - after) / before
}

/// Runs both modes and checks: matching-mode improvement at least `min_matching` %, the
/// wrong mode at most 10 % and at least three times the matching mode's error.
fn check_both_modes(cable_loss_m: f64, min_matching: f64) {
    let results: Vec<_> = [(IdleWheels::Released, 21), (IdleWheels::Held, 22)]
        .into_iter()
        .map(|(mode, seed)| (mode, errors_in_mode(mode, seed, cable_loss_m)))
        .collect();
    for (mode, (before, matched, wrong)) in &results {
        let (im, iw) = (improvement(*before, *matched), improvement(*before, *wrong));
        eprintln!(
            "cables {:.1} mm, idle wheels {}: mean radial error {before:.2} mm; matching-mode factors {matched:.2} mm ({im:.1} %), wrong-mode factors {wrong:.2} mm ({iw:.1} %)",
            cable_loss_m * 1e3,
            mode.as_str()
        );
    }
    for (mode, (before, matched, wrong)) in results {
        let (im, iw) = (improvement(before, matched), improvement(before, wrong));
        let m = mode.as_str();
        assert!(im >= min_matching, "{m}: matching mode only {im:.1} %");
        assert!(iw <= 10.0, "{m}: the wrong mode still improved {iw:.1} %");
        assert!(
            wrong > 3.0 * matched,
            "{m}: wrong {wrong:.2} vs matching {matched:.2} mm"
        );
    }
}

/// Flat floor: the model of each mode is exact (quantisation and noise leave ~1 %).
#[test]
fn flat_floor_matching_mode_cuts_the_error_95_percent_and_the_wrong_mode_does_not() {
    check_both_modes(0.0, 95.0);
}

/// Over [Redundant omni]'s cables (0.5 mm per crossing): the crossings' scatter stays.
#[test]
fn over_cables_matching_mode_cuts_the_error_75_percent_and_the_wrong_mode_does_not() {
    check_both_modes(0.0005, 75.0);
}
