//! Rows merged to about 100 per second (formats::decimate) before diagnosis: a fast
//! recording gives the same findings as at its full rate, from a fraction of the rows.

use calib_core::robot::presets;
use diagnose::{diagnose, Options, Report};
use sim::{record, Effect, Motion, RandomMotion, RecordConfig, Surface};

/// 90 s of the four-wheel omni at 400 rows/s (vision at 30 Hz), two wheels 1 % and
/// -0.5 % off and a 50 ms motor lag: the bench's case, shorter and faster.
fn fast_recording() -> (calib_core::Robot, formats::recording::Recording) {
    let robot = presets::omni4();
    let mut cfg = RecordConfig::default();
    cfg.sim.seed = 11;
    cfg.row_rate_hz = 400.0;
    let motion = Motion::Random(RandomMotion {
        duration_s: 90.0,
        ..RandomMotion::default()
    });
    let effects = [
        Effect::parse("wheel_diameter_mismatch=radius_scale_w1:1.01,radius_scale_w4:0.995")
            .unwrap(),
        Effect::parse("motor_lag=tau_s:0.05").unwrap(),
    ];
    let rec = record(&robot, &effects, Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording;
    (robot, rec)
}

fn param(r: &Report, effect: &str, name: &str) -> (f64, f64) {
    let f = r
        .findings
        .iter()
        .find(|f| f.effect == effect)
        .unwrap_or_else(|| panic!("{effect} not found: {r}"));
    (
        f.parameters[name],
        f.uncertainties[name].expect("a fitted parameter has a sigma"),
    )
}

#[test]
fn merged_rows_find_what_the_full_rate_finds() {
    let (robot, rec) = fast_recording();
    let rows = rec.len();
    let full = diagnose(
        &robot,
        &rec,
        &Options {
            max_row_rate_hz: None,
            ..Options::default()
        },
    )
    .unwrap();
    let merged = diagnose(&robot, &rec, &Options::default()).unwrap();
    // Rows 2.5 ms apart: every third or fourth is kept, plus the vision rows between.
    assert_eq!(full.rows, rows);
    assert!(
        merged.rows * 2 < rows,
        "{} of {rows} rows kept",
        merged.rows
    );
    assert!(
        merged.notes.iter().any(|n| n.contains("rows kept")),
        "{:?}",
        merged.notes
    );
    // The same verdict (the lag or the radii, whichever explains more; both are found).
    assert_eq!(full.verdict, merged.verdict, "{full}\n{merged}");
    // The radii: within the truth's 2-sigma and 0.05 % of each other; the lag within 10 %
    // of each other (the merged rows are 10 ms apart, a fifth of the lag).
    for (name, truth) in [("radius_scale_w1", 1.01), ("radius_scale_w4", 0.995)] {
        let (a, sa) = param(&full, "wheel_diameter_mismatch", name);
        let (b, sb) = param(&merged, "wheel_diameter_mismatch", name);
        assert!((a - b).abs() < 5e-4, "{name}: {a} full, {b} merged");
        assert!((b - truth).abs() < 2.0 * sb + 5e-4, "{name}: {b} ± {sb}");
        assert!((a - truth).abs() < 2.0 * sa + 5e-4, "{name}: {a} ± {sa}");
    }
    let (ta, _) = param(&full, "motor_lag", "tau_s");
    let (tb, _) = param(&merged, "motor_lag", "tau_s");
    assert!((ta - tb).abs() < 0.1 * ta, "tau {ta} full, {tb} merged");
    assert!((tb - 0.05).abs() < 0.01, "tau {tb}");
    // The fit is as good: ground RMSE after within 20 % (the merged stage has fewer vision
    // samples only where two fell within 7.5 ms, so nearly the same).
    let (ga, gb) = (full.rmse.ground.after_m, merged.rmse.ground.after_m);
    assert!(
        (ga - gb).abs() < 0.2 * ga,
        "ground RMSE {ga} full, {gb} merged"
    );
}
