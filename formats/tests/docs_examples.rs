//! The examples of `docs/formats.md`, read with the real readers.
//!
//! Every fenced TOML and CSV block of that page must carry a `wheelcal-example` tag
//! (`kind=... name=... file=...`, and `robot=NAME` for recordings) and is parsed here:
//! valid examples must parse and give the numbers the page states; invalid ones must be
//! refused with exactly the message of the `wheelcal-error of=NAME` block that follows
//! them, which names the file, the line and the column.

use calib_core::motion::OmniPath;
use calib_core::omni_cal::IdleWheels;
use calib_core::robot::{DriveType, Robot, RobotKind};
use formats::recording::Recording;
use formats::robot_file;
use formats::runs_file::{Phase, RunsFile, TestKind};
use std::collections::BTreeMap;
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;

/// One fenced block of the page.
struct Block {
    /// The language word after the fence (`toml`, `csv`, `text`, ...).
    lang: String,
    /// `wheelcal-example` or `wheelcal-error`, if tagged.
    tag: Option<String>,
    /// The `key=value` words of the info string.
    attrs: BTreeMap<String, String>,
    /// The block's text, the fence's indentation removed.
    text: String,
    /// Line of the opening fence in the page (for messages).
    line: usize,
}

impl Block {
    fn attr(&self, key: &str) -> &str {
        self.attrs
            .get(key)
            .unwrap_or_else(|| panic!("docs/formats.md:{}: no `{key}=`", self.line))
    }
}

fn page() -> String {
    std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/formats.md"))
        .expect("docs/formats.md is in the repository")
}

/// The fenced blocks of a Markdown page (fences of three backticks, possibly indented
/// inside a list item).
fn blocks(page: &str) -> Vec<Block> {
    let mut out = Vec::new();
    let mut lines = page.lines().enumerate();
    while let Some((i, line)) = lines.next() {
        let trimmed = line.trim_start();
        let Some(info) = trimmed.strip_prefix("```") else {
            continue;
        };
        let indent = line.len() - trimmed.len();
        let mut words = info.split_whitespace();
        let lang = words.next().unwrap_or("").to_string();
        let mut tag = None;
        let mut attrs = BTreeMap::new();
        for w in words {
            match w.split_once('=') {
                Some((k, v)) => {
                    attrs.insert(k.to_string(), v.to_string());
                }
                None => tag = Some(w.to_string()),
            }
        }
        let mut text = String::new();
        for (_, l) in lines.by_ref() {
            if l.trim() == "```" {
                break;
            }
            let cut = l.len() - l.trim_start().len();
            text.push_str(&l[cut.min(indent)..]);
            text.push('\n');
        }
        out.push(Block {
            lang,
            tag,
            attrs,
            text,
            line: i + 1,
        });
    }
    out
}

/// The page's examples by name.
fn examples() -> BTreeMap<String, Block> {
    let mut out = BTreeMap::new();
    for b in blocks(&page()) {
        if b.tag.as_deref() == Some("wheelcal-example") {
            let name = b.attr("name").to_string();
            let line = b.line;
            assert!(
                out.insert(name.clone(), b).is_none(),
                "docs/formats.md:{line}: a second example named {name}"
            );
        }
    }
    out
}

fn robot(name: &str) -> Robot {
    let ex = examples();
    let b = &ex[name];
    assert_eq!(b.attr("kind"), "robot", "{name} is not a robot example");
    robot_file::parse(&b.text, Path::new(b.attr("file"))).unwrap()
}

fn recording(name: &str) -> Recording {
    let ex = examples();
    let b = &ex[name];
    assert_eq!(b.attr("kind"), "recording");
    Recording::parse(&b.text, Path::new(b.attr("file")), &robot(b.attr("robot"))).unwrap()
}

fn runs(name: &str) -> RunsFile {
    let ex = examples();
    let b = &ex[name];
    assert_eq!(b.attr("kind"), "runs");
    RunsFile::parse(&b.text, Path::new(b.attr("file"))).unwrap()
}

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol
}

/// No TOML or CSV block escapes the test, every invalid example has its expected error
/// and every expected error its example.
#[test]
fn every_toml_and_csv_block_is_a_tested_example() {
    let all = blocks(&page());
    let mut invalid = Vec::new();
    let mut errors = Vec::new();
    for b in &all {
        if matches!(b.lang.as_str(), "toml" | "csv") {
            assert_eq!(
                b.tag.as_deref(),
                Some("wheelcal-example"),
                "docs/formats.md:{}: a {} block without a wheelcal-example tag",
                b.line,
                b.lang
            );
            let kind = b.attr("kind");
            assert!(
                [
                    "robot",
                    "robot-invalid",
                    "robot-procedure",
                    "recording",
                    "recording-invalid",
                    "runs",
                    "runs-invalid"
                ]
                .contains(&kind),
                "docs/formats.md:{}: unknown kind {kind}",
                b.line
            );
            if kind.ends_with("-invalid") {
                invalid.push(b.attr("name").to_string());
            }
        }
        if b.tag.as_deref() == Some("wheelcal-error") {
            errors.push(b.attr("of").to_string());
        }
    }
    invalid.sort();
    errors.sort();
    assert_eq!(
        invalid, errors,
        "invalid examples and their expected errors"
    );
    // The examples this file asserts numbers of.
    let ex = examples();
    for name in [
        "mobolab",
        "omni4",
        "wlr",
        "bad-radius",
        "mobolab-straight",
        "wlr-legs",
        "repeated-time",
        "umbmark",
        "omni",
        "unit-suffix",
        "procedure",
    ] {
        assert!(ex.contains_key(name), "docs/formats.md lost example {name}");
    }
}

/// Every example parses (or is refused with the page's message) with the real reader.
#[test]
fn every_example_reads_as_the_page_says() {
    let all = blocks(&page());
    let expected: BTreeMap<String, String> = all
        .iter()
        .filter(|b| b.tag.as_deref() == Some("wheelcal-error"))
        .map(|b| (b.attr("of").to_string(), b.text.trim().to_string()))
        .collect();
    for b in all
        .iter()
        .filter(|b| b.tag.as_deref() == Some("wheelcal-example"))
    {
        let name = b.attr("name");
        let path = Path::new(b.attr("file"));
        let at = format!("docs/formats.md:{} ({name})", b.line);
        match b.attr("kind") {
            "robot" => {
                robot_file::parse(&b.text, path).unwrap_or_else(|e| panic!("{at}: {e}"));
            }
            "robot-procedure" => {
                robot_file::parse(&b.text, path).unwrap_or_else(|e| panic!("{at}: {e}"));
                robot_file::parse_procedure(&b.text, path).unwrap_or_else(|e| panic!("{at}: {e}"));
            }
            "recording" => {
                Recording::parse(&b.text, path, &robot(b.attr("robot")))
                    .unwrap_or_else(|e| panic!("{at}: {e}"));
            }
            "runs" => {
                RunsFile::parse(&b.text, path).unwrap_or_else(|e| panic!("{at}: {e}"));
            }
            "robot-invalid" => {
                let e = robot_file::parse(&b.text, path).expect_err(&at);
                assert!(e.line.is_some() && e.column.is_some(), "{at}: {e}");
                assert_eq!(e.to_string(), expected[name], "{at}");
            }
            "recording-invalid" => {
                let e = Recording::parse(&b.text, path, &robot(b.attr("robot"))).expect_err(&at);
                assert!(e.line.is_some() && e.column.is_some(), "{at}: {e}");
                assert_eq!(e.to_string(), expected[name], "{at}");
            }
            "runs-invalid" => {
                let e = RunsFile::parse(&b.text, path).expect_err(&at);
                assert!(e.line.is_some() && e.column.is_some(), "{at}: {e}");
                assert_eq!(e.to_string(), expected[name], "{at}");
            }
            other => panic!("{at}: unknown kind {other}"),
        }
    }
}

#[test]
fn robot_examples_give_the_stated_geometry() {
    let m = robot("mobolab");
    assert_eq!((m.name.as_str(), m.kind), ("mobolab", RobotKind::DiffDrive));
    assert_eq!(m.drive.kind, DriveType::Stepper);
    assert_eq!((m.drive.steps_per_rev, m.drive.microsteps), (200, 1));
    assert_eq!(m.drive.gear_ratio, 4.875);
    assert_eq!(m.drive.gear_ratio, 78.0 / 16.0);
    assert_eq!(m.drive.encoder_counts_per_rev, 1920.0);
    assert_eq!(m.wheel_count(), 2);
    for (w, name, alpha, beta) in [
        (&m.wheels[0], "left", FRAC_PI_2, 0.0),
        (&m.wheels[1], "right", -FRAC_PI_2, PI),
    ] {
        assert_eq!(w.name.as_str(), name);
        assert_eq!(w.radius_m, 0.05);
        assert_eq!(w.l_m, 0.20);
        assert!(close(w.alpha_rad, alpha, 1e-15) && close(w.beta_rad, beta, 1e-15));
        assert_eq!((w.gamma_rad, w.driven), (0.0, true));
        // Positive wheel rate drives forward: the rolling row's x part is +1 on both.
        assert!(close(w.rolling_row()[0], 1.0, 1e-15), "{name}");
    }
    assert_eq!(m.half_wheelbase_m(), 0.20);

    let o = robot("omni4");
    assert_eq!(o.kind, RobotKind::Omni);
    assert_eq!(o.drive.kind, DriveType::Dc);
    assert_eq!(o.drive.encoder_counts_per_rev, 1920.0);
    let alphas: Vec<f64> = o.wheels.iter().map(|w| w.alpha_rad.to_degrees()).collect();
    for (got, want) in alphas.iter().zip([90.0, 180.0, 270.0, 0.0]) {
        assert!(close(*got, want, 1e-12), "{alphas:?}");
    }
    for w in &o.wheels {
        assert_eq!((w.radius_m, w.l_m), (0.03, 0.035));
        // Left out of the file: beta = gamma = 0, driven.
        assert_eq!((w.beta_rad, w.gamma_rad, w.driven), (0.0, 0.0, true));
    }

    let l = robot("wlr");
    assert_eq!(l.kind, RobotKind::WheeledLegged);
    assert_eq!(l.drive.encoder_counts_per_rev, 4096.0);
    let legs = l.legs.expect("[legs]");
    assert_eq!(
        (
            legs.length_m,
            legs.body_length_m,
            legs.body_mass_kg,
            legs.leg_mass_kg
        ),
        (0.135, 0.35, 2.8, 0.05)
    );
    // With vertical legs the wheel-centre x is +-body_length/2, where the wheels are.
    let (xf, xr) = legs.wheel_x(FRAC_PI_2, FRAC_PI_2);
    assert!(close(xf, 0.175, 1e-12) && close(xr, -0.175, 1e-12));
    let positions: Vec<(f64, f64)> = l.wheels.iter().map(|w| w.position()).collect();
    for (got, want) in positions.iter().zip([
        (0.175, 0.16),
        (0.175, -0.16),
        (-0.175, 0.16),
        (-0.175, -0.16),
    ]) {
        assert!(
            close(got.0, want.0, 1e-6) && close(got.1, want.1, 1e-6),
            "{positions:?}"
        );
    }
    let driven: Vec<bool> = l.wheels.iter().map(|w| w.driven).collect();
    assert_eq!(driven, [true, true, false, false]);
    // beta = 90 - alpha: every wheel rolls along body x.
    for w in &l.wheels {
        let row = w.rolling_row();
        assert!(
            close(row[0].abs(), 1.0, 1e-12) && close(row[1], 0.0, 1e-12),
            "{row:?}"
        );
    }

    // The [procedure] table; a DC drive without the key gets the default 1920 counts.
    let ex = examples();
    let p = &ex["procedure"];
    let path = Path::new(p.attr("file"));
    assert_eq!(
        robot_file::parse_procedure(&p.text, path)
            .unwrap()
            .idle_wheels,
        Some(IdleWheels::Held)
    );
    let with_procedure = robot_file::parse(&p.text, path).unwrap();
    assert_eq!(with_procedure.drive.encoder_counts_per_rev, 1920.0);
    assert_eq!(with_procedure.drive.gear_ratio, 1.0);
}

// The page writes a vertical leg as 1.5708 rad, as a recording would.
#[allow(clippy::approx_constant)]
#[test]
fn recording_examples_give_the_stated_rows() {
    let r = recording("mobolab-straight");
    assert_eq!(r.t, [0.00, 0.01, 0.02, 0.03, 0.04]);
    let enc = |i: usize| r.wheels[i].enc.clone().unwrap();
    assert_eq!(
        enc(0),
        [1000, 1000, 1006, 1012, 1018].map(Some).to_vec(),
        "enc_left"
    );
    assert_eq!(
        enc(1),
        [-250, -250, -244, -238, -232].map(Some).to_vec(),
        "enc_right"
    );
    assert_eq!(
        r.wheels[0].cmd.clone().unwrap(),
        [0.0, 2.0, 2.0, 2.0, 2.0].map(Some).to_vec()
    );
    let poses: Vec<_> = r.pose_rows().collect();
    assert_eq!(
        poses,
        [(0, 0.0, 0.0, 0.0), (4, 0.0030, 0.0001, 0.0002)],
        "the pose on the first and last rows only"
    );
    assert_eq!(r.notes.len(), 1);
    assert!(r.notes[0].contains("battery_v"), "{:?}", r.notes);
    // "At 2 rad/s for 0.01 s a wheel turns 0.02 rad: 6.1 of its 1920 counts".
    let counts = 2.0 * 0.01 / (2.0 * PI / robot("mobolab").drive.encoder_counts_per_rev);
    assert_eq!(format!("{counts:.1}"), "6.1");
    // And the example's encoders advance by 6 counts a row while the wheels turn.
    assert!(enc(0)
        .windows(2)
        .skip(1)
        .all(|p| p[1].unwrap() - p[0].unwrap() == 6));

    let w = recording("wlr-legs");
    assert_eq!(w.len(), 3);
    assert_eq!(
        w.leg_front.clone().unwrap(),
        [1.5708, 1.4, 1.2].map(Some).to_vec()
    );
    assert_eq!(w.leg_rear.clone().unwrap(), [Some(1.5708); 3].to_vec());
    assert_eq!(
        w.wheels[1].enc.clone().unwrap(),
        [0, 121, 247].map(Some).to_vec()
    );
    // The free rear wheels have no columns.
    assert!(w.wheels[2].enc.is_none() && w.wheels[2].cmd.is_none());
    assert_eq!(w.pose_rows().count(), 2);
}

#[test]
fn runs_examples_give_the_stated_runs() {
    let u = runs("umbmark");
    assert_eq!(u.rows.len(), 8);
    assert!(u.rows.iter().all(|r| r.test == TestKind::Umbmark));
    let before = u.umbmark(Phase::Before).unwrap().unwrap();
    assert_eq!(before.side_m, 4.0);
    assert_eq!(before.cw, [(0.080, 0.052), (0.091, 0.047)]);
    assert_eq!(before.ccw, [(-0.061, 0.075), (-0.055, 0.069)]);
    let after = u.umbmark(Phase::After).unwrap().unwrap();
    assert_eq!(after.cw, [(0.006, -0.004), (0.004, 0.003)]);
    assert_eq!(after.ccw, [(-0.005, 0.002), (0.003, 0.006)]);
    let thetas: Vec<Option<f64>> = u.rows.iter().map(|r| r.theta_err_rad).collect();
    assert_eq!(thetas[2..4], [Some(0.012), Some(0.010)]);
    assert_eq!(thetas.iter().filter(|t| t.is_some()).count(), 2);

    // The circle test's example: squares and circles of 2 laps; the law it states.
    let c = runs("circles");
    let circles = c.circles(Phase::Before);
    assert_eq!(circles.len(), 4);
    assert!(circles.iter().all(|r| r.laps == 2 && r.radius_m == 0.5));
    let sq = c.umbmark(Phase::Before).unwrap().unwrap();
    let run = |v: &[(f64, f64)]| {
        v.iter()
            .map(|&(x, y)| calib_core::umbmark::Run {
                x_err_m: x,
                y_err_m: y,
            })
            .collect::<Vec<_>>()
    };
    let fit = calib_core::umbmark::exact_fit(&run(&sq.cw), &run(&sq.ccw), 4.0, 0.4).unwrap();
    let law = calib_core::circle_test::turn_law(&circles, fit.result.eb, 0.0, 0.4).unwrap();
    assert!((law.e_b_arc - 0.039).abs() < 5e-4, "{law:?}");

    let o = runs("omni");
    assert!(o.rows.iter().all(|r| r.phase == Phase::Before));
    let paths = o.omni(Phase::Before).unwrap();
    assert_eq!(paths.len(), 2);
    assert_eq!(
        (paths[0].path.as_str(), paths[0].omni_path),
        ("4W-1", Some(OmniPath::W1))
    );
    assert_eq!(paths[1].omni_path, Some(OmniPath::W2));
    assert!(paths.iter().all(|p| p.length_m == 0.6));
    assert_eq!(
        paths[0].runs,
        [(-0.052, 0.011, Some(0.021)), (-0.048, 0.009, None)]
    );
    assert_eq!(
        paths[1].runs,
        [(-0.031, -0.020, Some(-0.015)), (-0.035, -0.018, None)]
    );
    assert!(o.omni(Phase::After).unwrap().is_empty());
}
