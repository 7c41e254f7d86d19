//! Bad input: malformed recordings are rejected by calib-core's reader with file, line and
//! column; anything that parsed is diagnosed without panicking (a clear error or a
//! verdict).

use calib_core::robot::presets;
use diagnose::{diagnose, DiagnoseError, Options};
use formats::recording::Recording;
use std::path::Path;

fn parse(text: &str) -> Result<Recording, String> {
    Recording::parse(text, Path::new("rec.csv"), &presets::mobolab()).map_err(|e| e.to_string())
}

#[test]
fn malformed_recordings_name_file_line_column() {
    let cases = [
        (
            "t,enc_left,enc_right,x,y,theta\n0,0,0,0,0,0\n0,1,1,0,0,0\n",
            "rec.csv:3:1",
        ),
        (
            "t,enc_left,enc_right,x,y,theta\n0,0,0,0,0,NaN\n",
            "rec.csv:2:6",
        ),
        (
            "t,enc_left,enc_middle,x,y,theta\n0,0,0,0,0,0\n",
            "rec.csv:1:3",
        ),
        (
            "t,enc_left,enc_right,x,y\n0,0,0,0,0\n",
            "missing required column 'theta'",
        ),
        ("t,enc_left,enc_right,x,y,theta\n", "empty recording"),
    ];
    for (text, want) in cases {
        let e = parse(text).unwrap_err();
        assert!(e.contains(want), "{e:?} should contain {want:?}");
    }
}

fn rows(n: usize, f: impl Fn(usize) -> String) -> String {
    let mut s = String::from("t,cmd_left,cmd_right,enc_left,enc_right,x,y,theta\n");
    for k in 0..n {
        s.push_str(&f(k));
        s.push('\n');
    }
    s
}

#[test]
fn parsed_oddities_never_panic() {
    let robot = presets::mobolab();
    let texts = vec![
        // One and two rows.
        rows(1, |_| "0,0,0,0,0,0,0,0".into()),
        rows(2, |k| format!("{k},0,0,0,0,0,0,0")),
        // Robot standing still, constant pose: nothing to explain.
        rows(400, |k| format!("{},0,0,7,7,1,2,0.5", k as f64 * 0.02)),
        // Wheels turning, pose constant (lifted robot).
        rows(400, |k| {
            format!("{},5,5,{},{},0,0,0", k as f64 * 0.02, k * 30, k * 30)
        }),
        // Pose only in one row.
        rows(400, |k| {
            let pose = if k == 10 { "0,0,0" } else { ",," };
            format!("{},1,1,{k},{k},{pose}", k as f64 * 0.02)
        }),
        // Wrapped heading spinning in place.
        rows(600, |k| {
            let th = (k as f64 * 0.05 + std::f64::consts::PI) % std::f64::consts::TAU
                - std::f64::consts::PI;
            format!(
                "{},-4,4,{},{},0,0,{th}",
                k as f64 * 0.02,
                -(k as i64) * 10,
                k * 10
            )
        }),
        // A long gap in the log (the stepper model sub-steps each row: must stay bounded).
        // Half an hour: a jump of over an hour is a data error since the reader's bounds.
        rows(300, |k| {
            let t = k as f64 * 0.02 + if k > 150 { 1800.0 } else { 0.0 };
            format!("{t},3,3,{},{},{},0,0", k * 12, k * 12, k as f64 * 0.003)
        }),
        // Huge counts and tiny time steps.
        rows(300, |k| {
            format!(
                "{},1e6,-1e6,{},{},{k},0,0",
                k as f64 * 1e-6,
                k as i64 * 1_000_000_000,
                -(k as i64) * 1_000_000_000
            )
        }),
    ];
    for text in texts {
        // Values no robot reaches (1e6 rad/s commands) are data errors at their cell since
        // the reader checks physical bounds; whatever parses must diagnose without panic.
        let rec = match parse(&text) {
            Ok(rec) => rec,
            Err(e) => {
                assert!(e.starts_with("rec.csv:") && e.contains("1e6"), "{e}");
                continue;
            }
        };
        match diagnose(&robot, &rec, &Options::default()) {
            Ok(r) => {
                assert!(!r.verdict.as_str().is_empty());
                assert!(r.rmse.ground.before_m.is_finite() && r.rmse.ground.after_m.is_finite());
                let _ = r.to_json();
                let _ = r.to_string();
            }
            Err(e) => assert!(!e.to_string().is_empty()),
        }
    }
}

#[test]
fn too_little_data_is_a_clear_error() {
    let rec = parse(&rows(2, |k| format!("{k},0,0,0,0,0,0,0"))).unwrap();
    let e = diagnose(&presets::mobolab(), &rec, &Options::default()).unwrap_err();
    assert!(matches!(e, DiagnoseError::NotEnoughData(_)), "{e}");
    assert!(e.to_string().contains("rows"));
}

#[test]
fn commands_only_and_encoders_only() {
    let robot = presets::mobolab();
    // No encoders: the ground stage runs on the commands.
    let mut s = String::from("t,cmd_left,cmd_right,x,y,theta\n");
    for k in 0..500 {
        let t = k as f64 * 0.02;
        // 2 rad/s on r = 0.05: 0.1 m/s straight.
        s.push_str(&format!("{t},2,2,{},0,0\n", 0.1 * t));
    }
    let rec = parse(&s).unwrap();
    let r = diagnose(&robot, &rec, &Options::default()).unwrap();
    assert_eq!(r.verdict, "none", "{r}");
    assert!(r.rmse.ground.before_m < 1e-3);
    assert!(r.notes.iter().any(|n| n.contains("no encoders")));
    // No commands.
    let mut s = String::from("t,enc_left,enc_right,x,y,theta\n");
    let counts_per_m = 1920.0 / (std::f64::consts::TAU * 0.05);
    for k in 0..500 {
        let t = k as f64 * 0.02;
        let c = (0.1 * t * counts_per_m).round() as i64;
        s.push_str(&format!("{t},{c},{c},{},0,0\n", 0.1 * t));
    }
    let rec = parse(&s).unwrap();
    let r = diagnose(&robot, &rec, &Options::default()).unwrap();
    assert!(r.rmse.ground.before_m < 1e-3, "{r}");
    assert!(r.notes.iter().any(|n| n.contains("no commands")));
}
