//! `wheelcal calibrate --report DIR` end to end: the folder holds the named
//! files, the SVGs are well-formed XML with one polyline vertex per pose sample, and
//! paths.mcap reads back as ROS 2 `PoseStamped` on `/paths/<recording>/measured|nominal|fitted`
//! carrying every pose sample, the measured poses unchanged and the fitted error at the
//! fit's RMSE (Python's independent reader: `interop.rs`).

mod common;

use calib_core::motion::Direction;
use calib_core::robot::Robot;
use calibrate::{param_specs, robot_with};
use formats::recording::Recording;
use std::collections::BTreeMap;
use std::path::Path;

/// An XML element: its name and attributes.
type Element = (String, BTreeMap<String, String>);

/// A small XML well-formedness check (no XML crate in the workspace): one root element,
/// tags nest and close, attributes are quoted `name="value"` pairs, `&` starts an entity
/// and text holds no `<`. Returns the elements as (name, attributes).
fn parse_xml(text: &str) -> Result<Vec<Element>, String> {
    let b = text.as_bytes();
    let mut i = 0;
    let mut stack: Vec<String> = Vec::new();
    let mut elems = Vec::new();
    let mut roots = 0;
    let entity_ok = |s: &str| -> bool {
        let mut rest = s;
        while let Some(k) = rest.find('&') {
            let tail = &rest[k + 1..];
            let Some(end) = tail.find(';') else {
                return false;
            };
            let name = &tail[..end];
            let known = ["amp", "lt", "gt", "quot", "apos"].contains(&name)
                || (name.starts_with('#') && name.len() > 1);
            if !known {
                return false;
            }
            rest = &tail[end + 1..];
        }
        true
    };
    while i < b.len() {
        if b[i] != b'<' {
            let k = text[i..].find('<').map_or(b.len(), |k| i + k);
            let t = &text[i..k];
            if stack.is_empty() && !t.trim().is_empty() {
                return Err(format!("text outside the root: {t:?}"));
            }
            if !entity_ok(t) {
                return Err(format!("bad entity in text {t:?}"));
            }
            i = k;
            continue;
        }
        let rest = &text[i..];
        if rest.starts_with("<?") {
            i += rest.find("?>").ok_or("unclosed <?")? + 2;
        } else if rest.starts_with("<!--") {
            i += rest.find("-->").ok_or("unclosed comment")? + 3;
        } else if rest.starts_with("<!") {
            i += rest.find('>').ok_or("unclosed <!")? + 1;
        } else if let Some(r) = rest.strip_prefix("</") {
            let end = r.find('>').ok_or("unclosed end tag")?;
            let name = r[..end].trim();
            match stack.pop() {
                Some(open) if open == name => {}
                other => return Err(format!("</{name}> closes {other:?}")),
            }
            i += 2 + end + 1;
        } else {
            // Start tag: scan to the '>' outside quotes.
            let mut j = 1;
            let mut quote = None;
            let rb = rest.as_bytes();
            while j < rb.len() {
                match (quote, rb[j]) {
                    (None, b'"' | b'\'') => quote = Some(rb[j]),
                    (Some(q), c) if c == q => quote = None,
                    (None, b'>') => break,
                    (None, b'<') => return Err("'<' inside a tag".into()),
                    _ => {}
                }
                j += 1;
            }
            if j == rb.len() {
                return Err("unclosed start tag".into());
            }
            let inner = &rest[1..j];
            let self_closing = inner.ends_with('/');
            let inner = inner.trim_end_matches('/');
            let name_end = inner
                .find(|c: char| c.is_whitespace())
                .unwrap_or(inner.len());
            let name = &inner[..name_end];
            if name.is_empty()
                || !name
                    .chars()
                    .all(|c| c.is_alphanumeric() || ":-_.".contains(c))
            {
                return Err(format!("bad element name {name:?}"));
            }
            let mut attrs = BTreeMap::new();
            let mut a = inner[name_end..].trim_start();
            while !a.is_empty() {
                let eq = a
                    .find('=')
                    .ok_or(format!("attribute without value in <{name}>"))?;
                let an = a[..eq].trim();
                let v = a[eq + 1..].trim_start();
                let q = v.chars().next().ok_or("empty attribute")?;
                if q != '"' && q != '\'' {
                    return Err(format!("unquoted attribute {an} in <{name}>"));
                }
                let close = v[1..].find(q).ok_or("unclosed attribute")?;
                let value = &v[1..1 + close];
                if !entity_ok(value) || value.contains('<') {
                    return Err(format!("bad attribute value {value:?}"));
                }
                if attrs.insert(an.to_string(), value.to_string()).is_some() {
                    return Err(format!("duplicate attribute {an} in <{name}>"));
                }
                a = v[1 + close + 1..].trim_start();
            }
            if stack.is_empty() {
                roots += 1;
            }
            elems.push((name.to_string(), attrs));
            if !self_closing {
                stack.push(name.to_string());
            }
            i += j + 1;
        }
    }
    if !stack.is_empty() {
        return Err(format!("unclosed elements {stack:?}"));
    }
    if roots != 1 {
        return Err(format!("{roots} root elements"));
    }
    Ok(elems)
}

/// Vertices of every polyline of an SVG.
fn polylines(path: &Path) -> Vec<usize> {
    let text = std::fs::read_to_string(path).unwrap();
    let elems = parse_xml(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    assert_eq!(elems[0].0, "svg", "{}", path.display());
    elems
        .iter()
        .filter(|(n, _)| n == "polyline")
        .map(|(_, a)| a["points"].split_whitespace().count())
        .collect()
}

#[test]
fn the_xml_check_rejects_broken_svg() {
    assert!(parse_xml("<svg a=\"1\"><g><polyline points=\"1,2 3,4\"/></g></svg>").is_ok());
    for bad in [
        "<svg><g></svg>",
        "<svg a=1></svg>",
        "<svg></svg><svg></svg>",
        "<svg>a & b</svg>",
        "<svg><text>x</tex></svg>",
    ] {
        assert!(parse_xml(bad).is_err(), "{bad}");
    }
}

/// Planar poses per topic: (log time ns, (x m, y m, yaw rad)).
type Topics = BTreeMap<String, Vec<(u64, (f64, f64, f64))>>;

/// The `geometry_msgs/msg/PoseStamped` channels of `path` (CDR with their `ros2msg`
/// schema, decoded by the ros2bag reader), and the number of `/tf` messages.
fn read_mcap(path: &Path) -> (Topics, usize) {
    use ros2bag::messages::{decode, PoseStamped};
    let bytes = std::fs::read(path).unwrap();
    let (mut by_topic, mut tf) = (Topics::new(), 0);
    for m in mcap::MessageStream::new(&bytes).unwrap() {
        let m = m.unwrap();
        assert_eq!(m.channel.message_encoding, "cdr");
        let schema = m.channel.schema.as_ref().unwrap();
        assert_eq!(schema.encoding, "ros2msg");
        if m.channel.topic == "/tf" {
            assert_eq!(schema.name, "tf2_msgs/msg/TFMessage");
            tf += 1;
            continue;
        }
        assert_eq!(schema.name, "geometry_msgs/msg/PoseStamped");
        let p: PoseStamped = decode(&m.data).unwrap();
        let q = p.pose.orientation;
        assert!(q.x == 0.0 && q.y == 0.0 && (q.z.hypot(q.w) - 1.0).abs() < 1e-12);
        let stamp = p.header.stamp.sec as u64 * 1_000_000_000 + p.header.stamp.nanosec as u64;
        assert_eq!(stamp, m.log_time);
        by_topic.entry(m.channel.topic.clone()).or_default().push((
            m.log_time,
            (p.pose.position.x, p.pose.position.y, 2.0 * q.z.atan2(q.w)),
        ));
    }
    (by_topic, tf)
}

#[test]
fn report_has_plots_index_and_mcap() {
    let dir = common::scratch("calibrate-report");
    let nominal = formats::robot_file::load(&common::robot("mobolab")).unwrap();
    let specs = param_specs(&nominal, false);
    let actual = robot_with(&nominal, &specs, &[0.99, 1.006, 1.03]);
    let runs = [
        ("cw", Direction::Cw, 3),
        ("ccw", Direction::Ccw, 4),
        ("held", Direction::Cw, 5),
    ];
    let mut recs = BTreeMap::new();
    for (name, d, seed) in runs {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        let file = dir.join(name).join("recording.csv");
        common::sim_square(&actual, d, seed).save(&file).unwrap();
        // What the binary reads (the CSV's rounding included).
        recs.insert(name, Recording::load(&file, &nominal).unwrap());
    }
    let report = dir.join("report");
    let out = common::wheelcal()
        .args(["--json", "calibrate", "--no-cross-validation", "--robot"])
        .arg(common::robot("mobolab"))
        .arg("--recording")
        .arg(dir.join("cw"))
        .arg("--recording")
        .arg(dir.join("ccw"))
        .arg("--holdout")
        .arg(dir.join("held"))
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    let mut files: Vec<String> = std::fs::read_dir(&report)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    files.sort();
    let mut want = vec![
        // The marker that the folder is wheelcal's (only such a folder is
        // written into again).
        formats::safe_write::MARKER,
        "calibration.json",
        "correlations.svg",
        "error_ccw.svg",
        "error_cw.svg",
        "error_held.svg",
        "index.html",
        "path_ccw.svg",
        "path_cw.svg",
        "path_held.svg",
        "paths.mcap",
        "robot.toml",
        "ros2.yaml",
        "summary.txt",
    ];
    want.sort();
    assert_eq!(files, want);

    let cal: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("calibration.json")).unwrap())
            .unwrap();
    let poses = |name: &str| recs[name].pose_rows().count();
    // The fit's RMSE of each recording (held out: dead reckoning from its first pose).
    let mut rmse: BTreeMap<&str, (f64, f64)> = BTreeMap::new();
    for (i, name) in ["cw", "ccw"].into_iter().enumerate() {
        let p = &cal["per_recording"][i];
        assert_eq!(p["name"], name);
        assert_eq!(p["pose_samples"].as_u64().unwrap() as usize, poses(name));
        // Dead-reckoning fits (the default) are drawn dead-reckoned from the first pose;
        // aligned fits (--free-start) as the fit placed them.
        let (b, f) = if cal["free_start"].as_bool().unwrap() {
            ("rmse_before_m", "rmse_after_m")
        } else {
            ("dead_reckoning_before_m", "dead_reckoning_after_m")
        };
        rmse.insert(name, (p[b].as_f64().unwrap(), p[f].as_f64().unwrap()));
    }
    let h = &cal["heldout"];
    rmse.insert(
        "held",
        (
            h["rmse_before_m"].as_f64().unwrap(),
            h["rmse_after_m"].as_f64().unwrap(),
        ),
    );

    // SVGs: well-formed; the path figure has its three lines (measured, nominal, fitted)
    // and the error figure its two (nominal, fitted) with one vertex per pose sample.
    for name in ["cw", "ccw", "held"] {
        let n = poses(name);
        let full = |f: &str| {
            polylines(&report.join(f))
                .into_iter()
                .filter(|&k| k == n)
                .count()
        };
        assert_eq!(full(&format!("path_{name}.svg")), 3, "path_{name}.svg");
        assert_eq!(full(&format!("error_{name}.svg")), 2, "error_{name}.svg");
    }
    // The correlation figure prints every pair's correlation of the calibration.
    let corr_svg = std::fs::read_to_string(report.join("correlations.svg")).unwrap();
    parse_xml(&corr_svg).unwrap();
    let corr = cal["correlations"].as_array().unwrap();
    assert_eq!(corr.len(), 3, "scale, ed, eb");
    // (plotters writes each text on a line of its own)
    let texts: Vec<&str> = corr_svg.lines().map(str::trim).collect();
    for (a, row) in corr.iter().enumerate() {
        for (b, v) in row.as_array().unwrap().iter().enumerate() {
            if a != b {
                let s = format!("{:+.2}", v.as_f64().unwrap());
                assert!(texts.contains(&s.as_str()), "{s} not in correlations.svg");
            }
        }
    }
    let index = std::fs::read_to_string(report.join("index.html")).unwrap();
    for f in want.iter().filter(|f| f.ends_with(".svg")) {
        assert!(
            index.contains(&format!("src=\"{f}\"")),
            "index.html lacks {f}"
        );
    }
    assert!(
        index.contains("firmware factors"),
        "the summary is in index.html"
    );

    // MCAP: 3 PoseStamped topics per recording, one message per pose sample, and each
    // pose as a transform on /tf.
    let (topics, tf) = read_mcap(&report.join("paths.mcap"));
    let mut want_topics: Vec<String> = ["cw", "ccw", "held"]
        .iter()
        .flat_map(|n| ["measured", "nominal", "fitted"].map(|k| format!("/paths/{n}/{k}")))
        .collect();
    want_topics.sort();
    assert_eq!(topics.keys().cloned().collect::<Vec<_>>(), want_topics);
    assert_eq!(
        tf,
        3 * ["cw", "ccw", "held"].map(poses).iter().sum::<usize>()
    );
    for name in ["cw", "ccw", "held"] {
        let rec = &recs[name];
        let n = poses(name);
        let get = |k: &str| &topics[&format!("/paths/{name}/{k}")];
        for k in ["measured", "nominal", "fitted"] {
            assert_eq!(get(k).len(), n, "/paths/{name}/{k}");
        }
        // Measured: the recording's poses unchanged (the yaw through the quaternion's
        // half angles: within 1e-12 rad), stamped at the row's time since the first row
        // (to the nanosecond).
        for ((row, x, y, th), (t_ns, (mx, my, mth))) in rec.pose_rows().zip(get("measured")) {
            assert!(*mx == x && *my == y, "({mx}, {my}) vs ({x}, {y})");
            let d = (mth - th + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            assert!(d.abs() < 1e-12, "yaw {mth} vs {th}");
            let t = rec.t[row] - rec.t[0];
            assert_eq!(*t_ns, (t * 1e9).round() as u64);
        }
        // The position error of the MCAP's paths is the fit's: its RMS equals the
        // calibration's RMSE to 1e-9 relative (positions near 1 m, errors near 1 mm: the
        // subtraction loses at most ~1e-13 relative).
        for (k, want) in [("nominal", rmse[name].0), ("fitted", rmse[name].1)] {
            let ms = get("measured");
            let sq: f64 = get(k)
                .iter()
                .zip(ms)
                .map(|((_, a), (_, b))| (a.0 - b.0).powi(2) + (a.1 - b.1).powi(2))
                .sum();
            let got = (sq / n as f64).sqrt();
            assert!(
                (got - want).abs() <= 1e-9 * want,
                "/paths/{name}/{k}: RMS {got} vs calibration {want}"
            );
        }
        // The fitted heading follows the measured one: a 3 % wheelbase error fitted
        // away leaves under 0.01 rad anywhere on a 4 m square (nominal: more).
        let worst = |k: &str| {
            get(k)
                .iter()
                .zip(get("measured"))
                .map(|((_, a), (_, b))| {
                    ((a.2 - b.2 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                        - std::f64::consts::PI)
                        .abs()
                })
                .fold(0.0, f64::max)
        };
        let (wn, wf) = (worst("nominal"), worst("fitted"));
        eprintln!("{name}: worst heading error nominal {wn:.4} rad, fitted {wf:.4} rad");
        assert!(wf < 0.01 && wf < wn, "{name}: fitted {wf}, nominal {wn}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Two squares of `nominal` (cw seed 3, ccw seed 4) saved in run folders under `dir`,
/// as `--recording` arguments.
fn two_squares(dir: &Path, nominal: &Robot) -> Vec<std::ffi::OsString> {
    let mut args = vec![];
    for (name, d, seed) in [("cw", Direction::Cw, 3), ("ccw", Direction::Ccw, 4)] {
        std::fs::create_dir_all(dir.join(name)).unwrap();
        let file = dir.join(name).join("recording.csv");
        common::sim_square(nominal, d, seed).save(&file).unwrap();
        args.push("--recording".into());
        args.push(dir.join(name).into_os_string());
    }
    args
}

/// `--speed-law` through the binary: a negative law reads as a number, is held (the
/// JSON's `turn_law.speed_rel`, no law tested, the board's factors carry it exactly with
/// c_L and c_R at standstill), and one outside the board's ±0.2 per m/s is refused with a
/// message naming the option, writing nothing.
#[test]
fn a_known_speed_law_reaches_the_json_and_a_bad_one_is_refused() {
    let dir = common::scratch("calibrate-speed-law");
    let nominal = formats::robot_file::load(&common::robot("mobolab")).unwrap();
    let args = two_squares(&dir, &nominal);
    let run = |law: &str, json: &Path| {
        common::calibrate_mobolab(
            &args,
            &["--speed-law".as_ref(), law.as_ref()],
            &json.with_extension("toml"),
        )
    };
    let out = run("-0.05", &dir.join("good"));
    let cal = common::json_of(&out);
    assert_eq!(cal["turn_law"]["speed_rel"].as_f64(), Some(-0.05));
    assert_eq!(cal["law_tests"].as_array().map(|a| a.len()), Some(0));
    assert_eq!(
        cal["factors"]["board"]["speed_rel"].as_f64(),
        Some(-0.05),
        "{}",
        cal["factors"]
    );
    // The robot file's and ROS's constant c_L is the wheel at the squares' mean speed:
    // 1 - 0.05 x a speed between 0.03 and 0.5 m/s of the board's at standstill.
    let f = &cal["factors"];
    let grown = f["c_l"].as_f64().unwrap() / f["board"]["c_l"].as_f64().unwrap() - 1.0;
    assert!((-0.025..=-0.0015).contains(&grown), "{grown}");
    let out = run("0.5", &dir.join("bad"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--speed-law 0.5 is outside"), "{err}");
    assert!(!dir.join("bad.toml").exists());
}

/// `--e-b-for` through the binary: with `--turn-law 0.04` held on two squares, a log of
/// driving on paths (a 40 s random run whose yaw rate stays under 0.3 rad/s, saved
/// without poses: only the encoders are read) places the robot file's one E_b between the
/// board's in-place E_b and 4 % above it, and past where it sits without the log (the
/// squares' mean turn) by at least a tenth of the law (the simulator's runs of this kind
/// want 3-72 %; measured 2.2 % against 0); the JSON's notes say so. A log that does not
/// exist is refused naming it, writing nothing.
#[test]
fn a_log_of_driving_places_the_robot_files_e_b() {
    let dir = common::scratch("calibrate-e-b-for");
    let nominal = formats::robot_file::load(&common::robot("mobolab")).unwrap();
    let args = two_squares(&dir, &nominal);
    let mut cfg = sim::RecordConfig {
        row_rate_hz: 50.0,
        ..sim::RecordConfig::default()
    };
    cfg.sim.seed = 61;
    cfg.sim.turn_scrub = 0.04;
    let motion = sim::Motion::Random(sim::RandomMotion {
        duration_s: 40.0,
        omega_max_rad_s: 0.3,
        ..sim::RandomMotion::default()
    });
    let mut log = sim::record(&nominal, &[], sim::Surface::flat(), &motion, &cfg)
        .unwrap()
        .recording;
    for v in [&mut log.x, &mut log.y, &mut log.theta] {
        v.iter_mut().for_each(|c| *c = None);
    }
    let log_file = dir.join("driving.csv");
    log.save(&log_file).unwrap();
    let run = |log: &Path, out: &Path| {
        let extra = [
            "--turn-law".as_ref(),
            "0.04".as_ref(),
            "--e-b-for".as_ref(),
            log.as_os_str(),
        ];
        common::calibrate_mobolab(&args, &extra, out)
    };
    let out = run(&log_file, &dir.join("good.toml"));
    let cal = common::json_of(&out);
    let wider = |cal: &serde_json::Value| {
        let f = &cal["factors"];
        f["e_b"].as_f64().unwrap() / f["board"]["e_b"].as_f64().unwrap() - 1.0
    };
    let default = common::calibrate_mobolab(
        &args,
        &["--turn-law".as_ref(), "0.04".as_ref()],
        &dir.join("default.toml"),
    );
    let default: serde_json::Value = serde_json::from_slice(&default.stdout).unwrap();
    println!(
        "E_b over the board's: {:.5} for the log, {:.5} at the squares' mean turn",
        wider(&cal),
        wider(&default)
    );
    assert!(wider(&cal) <= 0.04 + 1e-12, "{}", cal["factors"]);
    assert!(
        wider(&cal) - wider(&default) >= 0.1 * 0.04,
        "{} against {}",
        cal["factors"],
        default["factors"]
    );
    assert!(
        cal["notes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("--e-b-for's 1 recording(s)")),
        "{}",
        cal["notes"]
    );
    let missing = dir.join("no-such-log.csv");
    let out = run(&missing, &dir.join("bad.toml"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no-such-log.csv"), "{err}");
    assert!(!dir.join("bad.toml").exists());
}

/// `--hold` through the binary: `--hold ed` on two squares leaves scale and eb in the
/// JSON's `params`, the robot file's factors alike (c_L = c_R to the printed digits), and
/// a note naming what was held; a name that is not a parameter is refused by the
/// argument parser, and an omni robot's family (`radius`) by calibrate, each naming the
/// option and writing nothing.
#[test]
fn a_held_parameter_is_not_fitted() {
    let dir = common::scratch("calibrate-hold");
    let nominal = formats::robot_file::load(&common::robot("mobolab")).unwrap();
    let args = two_squares(&dir, &nominal);
    let run = |hold: &str, out: &Path| {
        common::calibrate_mobolab(&args, &["--hold".as_ref(), hold.as_ref()], out)
    };
    let out = run("ed", &dir.join("good.toml"));
    let cal = common::json_of(&out);
    let names: Vec<&str> = cal["params"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| p["name"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(names, ["scale", "eb"], "{}", cal["params"]);
    let f = &cal["factors"];
    assert_eq!(f["c_l"].as_f64(), f["c_r"].as_f64(), "{f}");
    assert!(
        cal["notes"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n.as_str().unwrap().contains("(--hold): ed")),
        "{}",
        cal["notes"]
    );
    let out = run("wheel", &dir.join("bad.toml"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--hold"), "{err}");
    assert!(!dir.join("bad.toml").exists());
    // An omni robot's family on a differential drive: past the parser, refused by
    // calibrate with the names this robot may hold.
    let out = run("radius", &dir.join("omni.toml"));
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--hold radius") && err.contains("scale, ed, eb"),
        "{err}"
    );
    assert!(!dir.join("omni.toml").exists());
}

/// `--laws-from` through the binary: the laws of an earlier calibration's JSON (its
/// `--json` output, or a `--report` folder) are held as `--turn-law` and `--speed-law` hold
/// them: the same law values to the last digit, the same fit to the last digit, a note
/// naming the file. A file that is not JSON is refused naming its line and column, one
/// without `turn_law` or of another kind of robot naming what is wrong, the option
/// beside `--turn-law` by the parser, and on a robot that is not a differential drive
/// before any recording is read; none writes a robot file.
#[test]
fn laws_from_an_earlier_calibration_are_held() {
    let dir = common::scratch("calibrate-laws-from");
    let nominal = formats::robot_file::load(&common::robot("mobolab")).unwrap();
    let args = two_squares(&dir, &nominal);
    let earlier = common::calibrate_mobolab(
        &args,
        &[
            "--turn-law".as_ref(),
            "0.004".as_ref(),
            "--speed-law".as_ref(),
            "-0.05".as_ref(),
            "--report".as_ref(),
            dir.join("earlier").as_os_str(),
        ],
        &dir.join("earlier.toml"),
    );
    assert!(
        earlier.status.success(),
        "{}",
        String::from_utf8_lossy(&earlier.stderr)
    );
    std::fs::write(dir.join("earlier.json"), &earlier.stdout).unwrap();
    let a: serde_json::Value = serde_json::from_slice(&earlier.stdout).unwrap();
    let from = |what: &Path, out: &Path| {
        common::calibrate_mobolab(&args, &["--laws-from".as_ref(), what.as_os_str()], out)
    };
    for source in [dir.join("earlier.json"), dir.join("earlier")] {
        let out = from(&source, &dir.join("later.toml"));
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let b: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(b["turn_law"]["arc_rel"].as_f64(), Some(0.004));
        assert_eq!(b["turn_law"]["speed_rel"].as_f64(), Some(-0.05));
        assert_eq!(b["params"], a["params"]);
        assert_eq!(b["factors"], a["factors"]);
        let notes = b["notes"].as_array().unwrap();
        assert!(
            notes.iter().any(|n| {
                let n = n.as_str().unwrap();
                n.starts_with("laws from ") && n.contains("+0.004") && n.contains("-0.05")
            }),
            "{notes:?}"
        );
    }
    let refused = |name: &str, text: &str, wants: &[&str]| {
        let file = dir.join(name);
        std::fs::write(&file, text).unwrap();
        let out_toml = dir.join(format!("{name}.toml"));
        let out = from(&file, &out_toml);
        assert!(!out.status.success(), "{name} was taken");
        let err = String::from_utf8_lossy(&out.stderr);
        for w in wants {
            assert!(err.contains(w), "{name}: wants {w:?} in {err}");
        }
        assert!(!out_toml.exists());
    };
    refused(
        "broken.json",
        "{\"kind\": \"diff_drive\",\n \"turn_law\": {\"arc_rel\": 0.004,}}\n",
        &["broken.json:2:", "not a calibration's JSON"],
    );
    refused(
        "nolaw.json",
        "{\"kind\": \"diff_drive\"}",
        &["nolaw.json", "turn_law"],
    );
    refused(
        "omni.json",
        "{\"kind\": \"omni\", \"robot\": \"x\", \"turn_law\": {\"arc_rel\": 0.0, \"speed_rel\": 0.0}}",
        &["omni.json", "omni", "diff_drive"],
    );
    let out = common::calibrate_mobolab(
        &args,
        &[
            "--laws-from".as_ref(),
            dir.join("earlier.json").as_os_str(),
            "--turn-law".as_ref(),
            "0.001".as_ref(),
        ],
        &dir.join("both.toml"),
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("--laws-from") && err.contains("--turn-law"),
        "{err}"
    );
    assert!(!dir.join("both.toml").exists());
    // A robot with no known laws (skid-steer: its law is fitted from its recordings), or
    // a calibration of another kind of robot, before any recording is read (these are
    // the mobolab's).
    for (robot, words) in [
        ("rover4", "kind skid_steer"),
        (
            "omni3",
            "is of kind omni: --laws-from takes a calibration of the same kind",
        ),
    ] {
        let out = common::wheelcal()
            .args(["--json", "calibrate", "--no-cross-validation", "--robot"])
            .arg(common::robot(robot))
            .args(&args)
            .arg("--laws-from")
            .arg(dir.join("earlier.json"))
            .arg("--write-robot")
            .arg(dir.join("other.toml"))
            .output()
            .unwrap();
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--laws-from") && err.contains(words), "{err}");
        assert!(!dir.join("other.toml").exists());
    }
}
