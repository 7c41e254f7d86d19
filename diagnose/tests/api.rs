//! The interface the console wraps: `--json` fields, the human summary, the
//! report directory and `--write-robot`.

use calib_core::robot::{presets, Drive};
use diagnose::{diagnose, plots, write_robot, Options};
use sim::{record, Effect, Motion, RandomMotion, RecordConfig, Surface};

fn ed_recording() -> (calib_core::Robot, formats::recording::Recording) {
    let robot = presets::diff_drive("dc_diff", 0.05, 0.40, Drive::default());
    let mut cfg = RecordConfig::default();
    cfg.sim.seed = 5;
    cfg.row_rate_hz = 50.0;
    let motion = Motion::Random(RandomMotion {
        duration_s: 40.0,
        ..RandomMotion::default()
    });
    let effects = [Effect::parse("wheel_diameter_mismatch=ed:1.02").unwrap()];
    let rec = record(&robot, &effects, Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording;
    (robot, rec)
}

#[test]
fn json_has_the_issue_fields_and_write_robot_applies_the_fit() {
    let (robot, rec) = ed_recording();
    let r = diagnose(&robot, &rec, &Options::default()).unwrap();
    let v: serde_json::Value = serde_json::from_str(&r.to_json()).unwrap();
    assert_eq!(v["verdict"], "wheel_diameter_mismatch");
    for key in ["rmse_nominal_m", "rmse_final_m"] {
        assert!(v[key].as_f64().unwrap() > 0.0, "{key}");
    }
    let f = &v["findings"][0];
    assert_eq!(f["effect"], "wheel_diameter_mismatch");
    assert_eq!(f["stage"], "ground");
    let ed = f["parameters"]["ed"].as_f64().unwrap();
    // 0.1 %: the suite's tolerance for ed.
    assert!((ed - 1.02).abs() < 1e-3, "ed {ed}");
    assert!(f["uncertainties"]["ed"].as_f64().unwrap() < 1e-3);
    assert!(f["rmse_after_m"].as_f64().unwrap() < f["rmse_before_m"].as_f64().unwrap());
    for w in v["windows"].as_array().unwrap() {
        assert!(w["t_end_s"].as_f64().unwrap() >= w["t_start_s"].as_f64().unwrap());
        assert!(w["stage"].is_string() && w["axis"].is_string());
    }
    let text = r.to_string();
    assert!(text.contains("verdict: wheel_diameter_mismatch") && text.contains("ed = "));

    // --write-robot: Borenstein's split of ed with the mean diameter kept.
    let dir = std::env::temp_dir().join(format!("diagnose-api-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let out = dir.join("fitted.toml");
    write_robot(&robot, &r, &out).unwrap();
    let fitted = formats::robot_file::load(&out).unwrap();
    let (rl, rr) = (fitted.wheels[0].radius_m, fitted.wheels[1].radius_m);
    assert!((rr / rl - ed).abs() < 1e-9);
    assert!(((rl + rr) / 2.0 - 0.05).abs() < 1e-9);

    // --report: plots and index.html.
    plots::write_report_dir(&r, &dir.join("report")).unwrap();
    for f in [
        "index.html",
        "path.svg",
        "position_residual.svg",
        "heading_residual.svg",
        "actuator_left.svg",
        "report.json",
    ] {
        let p = dir.join("report").join(f);
        assert!(
            std::fs::metadata(&p).unwrap().len() > 200,
            "{}",
            p.display()
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Values the JSON gives twice (flat and as objects, pairs and advice, table and means,
/// wheel geometry) are stored once and derived when serialised: each copy must equal its
/// source exactly.
#[test]
fn json_copies_are_derived_from_one_stored_value() {
    let (robot, rec) = ed_recording();
    let r = diagnose(&robot, &rec, &Options::default()).unwrap();
    let v: serde_json::Value = serde_json::from_str(&r.to_json()).unwrap();
    assert_eq!(v["rmse_nominal_m"], v["ground_rmse"]["before_m"]);
    assert_eq!(v["rmse_final_m"], v["ground_rmse"]["after_m"]);
    // serde_json reads a float back to within an ulp or two.
    let same = |j: &serde_json::Value, x: f64| (j.as_f64().unwrap() - x).abs() <= 1e-12 * x.abs();
    assert!(same(&v["rmse_nominal_m"], r.rmse.ground.before_m));
    let act = r
        .rmse
        .actuator
        .expect("commands and encoders were recorded");
    assert!(same(&v["actuator_rmse_nominal_m"], act.before_m));
    assert_eq!(v["actuator_rmse_final_m"], v["actuator_rmse"]["after_m"]);
    assert_eq!(v["verdict"], r.verdict.as_str());
    assert_eq!(
        v["not_separable"].as_array().unwrap().len(),
        v["separation_advice"].as_array().unwrap().len()
    );

    // Calibrate: three recordings, cross-validated by run.
    let recs: Vec<_> = (0..3)
        .map(|seed| {
            let mut cfg = RecordConfig::default();
            cfg.sim.seed = 20 + seed;
            cfg.row_rate_hz = 50.0;
            let motion = Motion::Random(RandomMotion {
                duration_s: 20.0,
                ..RandomMotion::default()
            });
            let effects = [Effect::parse("wheel_diameter_mismatch=ed:1.01").unwrap()];
            let rec = record(&robot, &effects, Surface::flat(), &motion, &cfg)
                .unwrap()
                .recording;
            (format!("run{seed}"), rec)
        })
        .collect();
    let opts = calibrate::CalOptions {
        leave_one_out: true,
        ..Default::default()
    };
    let c = calibrate::calibrate(&robot, &recs, None, &opts).unwrap();
    let v: serde_json::Value = serde_json::to_value(&c).unwrap();
    let table = v["leave_one_out"].as_array().unwrap();
    assert_eq!(table.len(), 3);
    let mean_after = table
        .iter()
        .map(|h| h["rmse_after_m"].as_f64().unwrap())
        .sum::<f64>()
        / 3.0;
    assert!(same(&v["leave_one_out_mean_after_m"], mean_after));
    let means = c.leave_one_out.means().unwrap();
    assert!(same(
        &v["leave_one_out_aligned_before_m"],
        means.aligned_before_m
    ));
    assert_eq!(
        v["not_separable"].as_array().unwrap().len(),
        v["inseparable"].as_array().unwrap().len()
    );
    let geometry = v["geometry"].as_array().unwrap();
    for (g, w) in geometry.iter().zip(&c.fitted_robot.wheels) {
        assert!(same(&g["radius_m"], w.radius_m));
    }
    for (p, q) in v["params"].as_array().unwrap().iter().zip(&c.params) {
        assert_eq!(p["name"], q.spec.name.as_str());
        assert!(same(&p["nominal"], q.spec.nominal));
    }
}
