//! The series and figures of `calibrate --report`: the plotted errors are the
//! ones the fit compared (their RMS is the calibration's own RMSE per recording), and no
//! legend covers a plotted point or cell.

use calib_core::motion::{Direction, Program};
use calib_core::robot::Robot;
use calibrate::plots::{
    calibration_series, correlation_chart, correlation_figure_size, recording_error_chart,
    recording_path_chart, RecordingSeries, ERROR_FIGURE, PATH_FIGURE,
};
use calibrate::{calibrate, param_specs, robot_with, CalOptions, Calibration};
use fitkit::plot::register_font;
use formats::recording::Recording;
use plotters::prelude::*;
use sim::{record, Motion, RecordConfig, Surface};
use std::path::Path;

/// Relative agreement of a plotted RMS with the calibration's: the series come from the
/// same residuals, converted from the fit's millimetre unit to metres and summed in
/// another order, so they differ only by a few rounding steps (~1e-15); 1e-9 leaves room
/// for that and nothing else (a wrong start pose or clock moves the RMS by > 1e-4).
const SAME: f64 = 1e-9;

fn close(what: &str, got: f64, want: f64) {
    println!(
        "{what}: RMS {:.4} mm, relative difference {:.1e}",
        got * 1e3,
        ((got - want) / want).abs()
    );
    assert!(
        (got - want).abs() <= SAME * want.abs(),
        "{what}: plotted RMS {got} vs calibration {want} (rel {:.1e})",
        ((got - want) / want).abs()
    );
}

/// Every recording's plotted RMS against the calibration's numbers; returns the series.
fn check_consistent(
    c: &Calibration,
    robot: &Robot,
    recs: &[(String, Recording)],
    held: Option<&(String, Recording)>,
) -> Vec<RecordingSeries> {
    let s = calibration_series(c, robot, recs, held).unwrap();
    assert_eq!(s.len(), recs.len() + usize::from(held.is_some()));
    for (r, p) in s.iter().zip(&c.per_recording) {
        assert_eq!(r.name, p.name);
        assert!(!r.heldout);
        assert_eq!(r.t.len(), p.pose_samples, "{}: one value per pose", r.name);
        for v in [&r.measured, &r.nominal, &r.fitted] {
            assert_eq!(v.len(), p.pose_samples);
        }
        // Dead-reckoning fits are plotted dead-reckoned from the first pose; aligned
        // (--free-start) fits as the fit placed them.
        let (want_fit, want_nom) = if c.free_start {
            (p.rmse_after_m, p.rmse_before_m)
        } else {
            (p.dead_reckoning_after_m, p.dead_reckoning_before_m)
        };
        close(&format!("{} fitted", r.name), r.rms_fitted_m(), want_fit);
        close(&format!("{} nominal", r.name), r.rms_nominal_m(), want_nom);
    }
    if let Some(h) = &c.heldout {
        let r = s.last().unwrap();
        assert!(r.heldout);
        assert_eq!(r.name, h.name);
        close("held out fitted", r.rms_fitted_m(), h.rmse_after_m);
        close("held out nominal", r.rms_nominal_m(), h.rmse_before_m);
        // Dead reckoning from the first measured pose starts on it (to rounding, 1 nm).
        for p in [&r.nominal[0], &r.fitted[0]] {
            let d = (p.0 - r.measured[0].0).hypot(p.1 - r.measured[0].1);
            assert!(d < 1e-9, "held out starts {d} m from its first pose");
        }
    }
    s
}

fn robot(name: &str) -> Robot {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../robots")
        .join(format!("{name}.toml"));
    formats::robot_file::load(&p).unwrap()
}

fn square(truth: &Robot, dir: Direction, seed: u64) -> Recording {
    let mut cfg = RecordConfig {
        row_rate_hz: 50.0,
        ..RecordConfig::default()
    };
    cfg.sim.seed = seed;
    let motion = Motion::Program {
        program: Box::new(Program::umbmark_square(1.0, dir)),
        limits: Default::default(),
    };
    record(truth, &[], Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording
}

/// The nominal robot, its calibration, the fitted recordings and the held-out one.
type Simulated = (
    Robot,
    Calibration,
    Vec<(String, Recording)>,
    (String, Recording),
);

/// mobolab with a known geometry error: a cw and a ccw square fitted, a second cw
/// square held out.
fn simulated() -> Simulated {
    let nominal = robot("mobolab");
    let specs = param_specs(&nominal, false);
    let actual = robot_with(&nominal, &specs, &[0.99, 1.006, 1.03]);
    let recs = vec![
        ("cw".to_string(), square(&actual, Direction::Cw, 3)),
        (
            "ccw square/2".to_string(),
            square(&actual, Direction::Ccw, 4),
        ),
    ];
    let held = ("cw".to_string(), square(&actual, Direction::Cw, 5));
    let c = calibrate(&nominal, &recs, Some(&held), &CalOptions::default()).unwrap();
    (nominal, c, recs, held)
}

#[test]
fn simulated_series_are_what_the_fit_compared() {
    let (robot, c, recs, held) = simulated();
    let s = check_consistent(&c, &robot, &recs, Some(&held));
    // Keys are file- and topic-safe and unique (the held-out "cw" repeats a name).
    let keys: Vec<&str> = s.iter().map(|r| r.key.as_str()).collect();
    assert_eq!(keys, ["cw", "ccw_square_2", "cw_2"]);
    // The fit removes a 3 % wheelbase error: every recording's fitted error is below a
    // third of the nominal (the simulated motion capture's 1 mm noise is the floor).
    for r in &s {
        assert!(
            r.rms_fitted_m() < r.rms_nominal_m() / 3.0,
            "{}: {} -> {}",
            r.name,
            r.rms_nominal_m(),
            r.rms_fitted_m()
        );
    }
    // The measured path is the 1 m square: its extent along x and y is 1 m within the
    // robot's start offset and the noise (5 %).
    let m = &s[0].measured;
    for axis in [0, 1] {
        let v: Vec<f64> = m
            .iter()
            .map(|p| if axis == 0 { p.0 } else { p.1 })
            .collect();
        let span = v.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
            - v.iter().cloned().fold(f64::INFINITY, f64::min);
        assert!((span - 1.0).abs() < 0.05, "axis {axis}: span {span} m");
    }
}

fn assert_clear(what: &str, layout: &fitkit::plot::Layout, points: usize) {
    assert_eq!(layout.data.len(), points, "{what}: data boxes");
    if let Err(e) = layout.check() {
        panic!("{what}: {e}");
    }
}

#[test]
fn no_legend_covers_data() {
    assert!(register_font(), "DejaVu Sans needed for text layout");
    let (robot, c, recs, held) = simulated();
    let s = calibration_series(&c, &robot, &recs, Some(&held)).unwrap();
    for r in &s {
        let n = r.t.len();
        let mut svg = String::new();
        let l = {
            let root = SVGBackend::with_string(&mut svg, PATH_FIGURE).into_drawing_area();
            recording_path_chart(r, &root).unwrap()
        };
        // Three lines (measured, nominal, fitted), one vertex per pose sample.
        assert_clear(&format!("{} path", r.name), &l, 3 * n);
        let mut svg = String::new();
        let l = {
            let root = SVGBackend::with_string(&mut svg, ERROR_FIGURE).into_drawing_area();
            recording_error_chart(r, &root).unwrap()
        };
        assert_clear(&format!("{} error", r.name), &l, 2 * n);
        assert!(svg.contains("fitted, RMS"), "the legend gives the RMS");
    }
    // Correlation grid: one cell per parameter pair, for 3 (diff) and 11 (omni with
    // marker) parameters; the legend beside the grid covers none.
    let mut big = c.clone();
    let g: usize = 11;
    big.params = (0..g)
        .map(|i| {
            let mut p = c.params[0].clone();
            p.spec.name = format!("alpha_offset_rad_w{i}");
            p
        })
        .collect();
    big.correlations = (0..g)
        .map(|a| {
            (0..g)
                .map(|b| {
                    if a == b {
                        1.0
                    } else {
                        0.97 * (-1f64).powi((a + b) as i32)
                    }
                })
                .collect()
        })
        .collect();
    big.inseparable = calibrate::Inseparables(vec![calibrate::Inseparable {
        params: [
            big.params[0].spec.name.clone(),
            big.params[1].spec.name.clone(),
        ],
        correlation: 0.97,
        identifiable: [std::f64::consts::FRAC_1_SQRT_2; 2],
        advice: "drive the other way".into(),
    }]);
    for (what, cal) in [("diff", &c), ("omni", &big)] {
        let n = cal.params.len();
        let mut svg = String::new();
        let l = {
            let root =
                SVGBackend::with_string(&mut svg, correlation_figure_size(n)).into_drawing_area();
            correlation_chart(cal, &root).unwrap()
        };
        assert_clear(&format!("{what} correlations"), &l, n * n);
        // Cells at least 40 px: the values printed in them stay legible.
        let cell = l.data[0].x1 - l.data[0].x0;
        assert!(cell >= 40, "{what}: {cell} px cells");
        assert!(svg.contains(&format!("{:+.2}", cal.correlations[0][1])));
    }
}

// ---- the real squares (data/real) ----

fn load(base: &Path, folder: &str, robot: &Robot) -> (String, Recording) {
    let r = Recording::load(&base.join(folder).join("recording.csv"), robot).unwrap();
    (folder.to_string(), r)
}

#[test]
fn real_squares_series_are_what_the_fit_compared() {
    let base = testdata::real_dir();
    let robot = formats::robot_file::load(&base.join("diff-square-run-01/robot.toml")).unwrap();
    let recs = vec![
        load(&base, "diff-square-run-01", &robot),
        load(&base, "diff-square-run-04", &robot),
    ];
    let held = load(&base, "diff-square-run-02", &robot);
    let c = calibrate(&robot, &recs, Some(&held), &CalOptions::default()).unwrap();
    println!("{c}");
    let s = check_consistent(&c, &robot, &recs, Some(&held));
    for r in &s {
        println!(
            "{}: {} poses, RMS nominal {:.3} mm, fitted {:.3} mm",
            r.name,
            r.t.len(),
            r.rms_nominal_m() * 1e3,
            r.rms_fitted_m() * 1e3
        );
    }
}

#[test]
fn real_omni3_with_marker_offset_series_are_what_the_fit_compared() {
    let base = testdata::real_dir();
    let robot = formats::robot_file::load(&base.join("omni3-square-run-01/robot.toml")).unwrap();
    let recs = vec![load(&base, "omni3-square-run-01", &robot)];
    // The marker offset is placed by the aligned fit's own residual code.
    let opts = CalOptions {
        marker_offset: true,
        free_start: true,
        ..CalOptions::default()
    };
    let c = calibrate(&robot, &recs, None, &opts).unwrap();
    assert!(c.params.iter().any(|p| p.spec.name == "marker_x_m"));
    check_consistent(&c, &robot, &recs, None);
}

/// With a turn law (here a known one, `--turn-law 0.05`), the plotted fitted paths are
/// dead-reckoned with the law, as the errors the calibration reports: the same RMS to
/// rounding (they differed once the law was left out of the figures).
#[test]
fn series_with_a_turn_law_are_what_the_fit_compared() {
    let (robot, _, recs, held) = simulated();
    let opts = CalOptions {
        turn_law: Some(0.05),
        ..Default::default()
    };
    let c = calibrate(&robot, &recs, Some(&held), &opts).unwrap();
    assert_eq!(c.turn_law.arc_rel, 0.05);
    check_consistent(&c, &robot, &recs, Some(&held));
}
