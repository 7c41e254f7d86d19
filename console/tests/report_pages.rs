//! The `index.html` of `calibrate --report` and `diagnose --report` on the real squares in
//! data/real leads with the answer: the factors (with the exact `wheelcal apply` command
//! that puts them on a board) or the verdict in words, in tables, before the first plot;
//! the plots follow with a sentence each; the printed text is there, folded; and no run
//! of text is long enough to widen the page. (scripts/check-reports.sh renders the same
//! pages in Chromium.)

mod common;

use calib_core::correction::{Corrections, DiffLaws};
use clap::Parser;
use std::path::PathBuf;
use wheelcal::args::{Cli, Command};
use wheelcal::calibration::saved::SavedCalibration;

fn real(name: &str) -> PathBuf {
    testdata::real(name)
}

fn run(args: &[&str]) {
    let o = common::wheelcal().args(args).output().unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The page's visible text: tags dropped, entities of the escaper undone.
fn text_of(html: &str) -> String {
    let mut out = String::new();
    let mut in_tag = false;
    let body = &html[html.find("<body>").unwrap_or(0)..];
    for c in body.chars() {
        match c {
            '<' => {
                in_tag = true;
                out.push(' ');
            }
            '>' => in_tag = false,
            c if !in_tag => out.push(c),
            _ => {}
        }
    }
    out.replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&quot;", "\"")
        .replace("&amp;", "&")
}

/// The longest run of text without a space (what a browser could not wrap at a space).
fn longest_word(html: &str) -> usize {
    text_of(html)
        .split_whitespace()
        .map(|w| w.chars().count())
        .max()
        .unwrap_or(0)
}

fn pos(html: &str, needle: &str) -> usize {
    html.find(needle)
        .unwrap_or_else(|| panic!("{needle:?} not in the page"))
}

/// Structure every page shares: the answer first, then tables, then the first plot, the
/// text folded at the end and wrapped by the style, nothing wider than 80 characters
/// unbroken.
fn assert_leads_with_the_answer(html: &str) {
    let answer = pos(html, "<p class=\"answer\">");
    let table = pos(html, "<table>");
    let img = pos(html, "<img ");
    assert!(answer < table && table < img, "answer, table, plot order");
    let details = pos(html, "<details><summary>");
    assert!(details > img, "the text is folded after the plots");
    assert!(html.contains("pre{white-space:pre-wrap;overflow-wrap:anywhere"));
    // Every plot has its sentence, in a figcaption just before it.
    let figures = html.matches("<figure><figcaption><b>").count();
    assert_eq!(figures, html.matches("<img ").count());
    let w = longest_word(html);
    assert!(w <= 80, "an unbroken run of {w} characters");
}

/// calibrate on the four real squares 01, 02 (cw), 04, 05 (ccw), 03 held out. The
/// factors, as the fit gives them on these recordings: c_L 0.996973, c_R 0.995979, E_b
/// 1.006651; cross-validation mean 69.48 -> 49.46 mm; the speed and acceleration laws
/// tested and refused. The page's command, parsed by wheelcal's own argument parser, is
/// `apply` of the report's calibration.json with --save, and what `apply` reads from that
/// file for the nominal robot are exactly the factors in the page's table.
#[test]
fn calibrate_page_leads_with_the_factors_and_the_command_that_applies_them() {
    let dir = common::scratch("report-page-cal");
    let report = dir.join("report");
    let robot_file = real("diff-square-run-01").join("robot.toml");
    let rec = |n: &str| real(n).to_str().unwrap().to_string();
    run(&[
        "calibrate",
        "--robot",
        robot_file.to_str().unwrap(),
        "--recording",
        &rec("diff-square-run-01"),
        "--recording",
        &rec("diff-square-run-02"),
        "--recording",
        &rec("diff-square-run-04"),
        "--recording",
        &rec("diff-square-run-05"),
        "--holdout",
        &rec("diff-square-run-03"),
        "--report",
        report.to_str().unwrap(),
    ]);
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert_leads_with_the_answer(&html);
    let img = pos(&html, "<img ");

    // The factors, before the first plot.
    for (name, v) in [
        ("c_L", "0.996973"),
        ("c_R", "0.995979"),
        ("E_b", "1.006651"),
    ] {
        let cell = format!("<tr><td>{name}</td><td class=\"n\">{v}</td>");
        assert!(pos(&html, &cell) < img, "{cell}");
    }
    // The held-out table: cross-validation by run and the --holdout recording.
    let answer = &html[pos(&html, "<p class=\"answer\">")..pos(&html, "</p>")];
    assert!(
        answer.contains("69.48 mm") && answer.contains("49.46 mm"),
        "{answer}"
    );
    assert!(html.contains("<td>mean</td><td class=\"n\">69.48 mm → 49.46 mm</td>"));
    assert!(html.contains(
        "<td>diff-square-run-03 (--holdout)</td><td class=\"n\">22.21 mm → 20.79 mm</td>"
    ));
    // The laws: both tested and refused.
    assert!(html.contains("<td>speed (speed_rel)</td><td class=\"n\">+0.1252 ± 0.3069</td>"));
    assert!(html.contains("<td>acceleration (accel_slip_s)</td>"));
    assert_eq!(html.matches("<td>refused</td>").count(), 2);
    assert!(!html.contains("<td>kept</td>"));

    // The command, exactly; parsed as wheelcal parses it.
    let json = report.join("calibration.json");
    let cmd = format!(
        "wheelcal apply {} --save",
        shell_words::quote(&json.display().to_string())
    );
    let shown = format!("<pre class=\"cmd\"><code>{cmd}</code></pre>");
    assert!(pos(&html, &shown) < img, "{shown}");
    let cli = Cli::try_parse_from(shell_words::split(&cmd).unwrap()).unwrap();
    let Command::Apply(a) = cli.command else {
        panic!("{cmd} is not apply");
    };
    assert_eq!(a.calibration, json);
    assert!(a.save && a.board_robot.is_none());
    // What apply reads from it for the robot fitted from: the table's factors.
    let robot = formats::robot_file::load(&robot_file).unwrap();
    let got = SavedCalibration::read(&a.calibration, &robot, "apply")
        .unwrap()
        .factors_for(&robot)
        .unwrap();
    let Corrections::DiffDrive { c_l, c_r, e_b } = got else {
        panic!("{got:?}");
    };
    for (name, v) in [("c_L", c_l), ("c_R", c_r), ("E_b", e_b)] {
        assert!(html.contains(&format!("<tr><td>{name}</td><td class=\"n\">{v:.6}</td>")));
    }
    assert_eq!(
        got,
        Corrections::diff_drive(c_l, c_r, e_b, DiffLaws::default())
    );

    // The printed text, folded, whole.
    let summary = std::fs::read_to_string(report.join("summary.txt")).unwrap();
    let folded = &html[pos(&html, "<details>")..];
    assert!(folded
        .contains("firmware factors: factors set --c-l 0.996973 --c-r 0.995979 --e-b 1.006651"));
    assert_eq!(
        text_of(folded).split_whitespace().collect::<Vec<_>>(),
        "Full text output (as calibrate prints it)"
            .split_whitespace()
            .chain(summary.split_whitespace())
            .chain(["wheelcal", env!("CARGO_PKG_VERSION")])
            .collect::<Vec<_>>()
    );
    // Each figure of the folder is on the page, in the correlation-then-recordings order.
    let mut last = 0;
    for f in [
        "correlations.svg",
        "path_diff-square-run-01.svg",
        "error_diff-square-run-03.svg",
    ] {
        let p = pos(&html, &format!("<img src=\"{f}\""));
        assert!(p > last, "{f} out of order");
        last = p;
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// diagnose of the real square diff-square-run-01: the position error 6.93 -> 3.31 mm,
/// the first finding wheel_scale (geometry, 73 % of the excess, held-out ratio 0.337,
/// scale 0.996297), then longitudinal_slip. The verdict is put in words from its string
/// (whatever diagnose concludes: the page renders any verdict), before the first plot.
#[test]
fn diagnose_page_leads_with_the_verdict_and_the_findings() {
    let dir = common::scratch("report-page-diag");
    let report = dir.join("report");
    let sq = real("diff-square-run-01");
    run(&[
        "diagnose",
        "--robot",
        sq.join("robot.toml").to_str().unwrap(),
        "--recording",
        sq.to_str().unwrap(),
        "--report",
        report.to_str().unwrap(),
    ]);
    let html = std::fs::read_to_string(report.join("index.html")).unwrap();
    assert_leads_with_the_answer(&html);
    let img = pos(&html, "<img ");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(report.join("report.json")).unwrap())
            .unwrap();
    let answer = &html[pos(&html, "<p class=\"answer\">")..];
    let answer = &answer[..answer.find("</p>").unwrap()];
    let verdict = json["verdict"].as_str().unwrap();
    let words = match verdict {
        "none" => "Nothing to correct".to_string(),
        "unexplained" => "Unexplained:".to_string(),
        v => v.replace('_', " "),
    };
    assert!(answer.contains(&words), "{verdict}: {answer}");
    assert!(answer.contains("from 6.93 mm to 3.31 mm RMS"), "{answer}");
    let explained = json["explained_fraction"].as_f64().unwrap();
    assert!(answer.contains(&format!("explain {:.0} %", explained * 100.0)));

    // The findings table, each row from report.json, before the first plot.
    let findings = json["findings"].as_array().unwrap();
    assert_eq!(findings[0]["effect"], "wheel_scale");
    assert_eq!(findings[0]["mechanism"], "geometry");
    for f in findings {
        let row = format!(
            "<tr><td>{}</td><td>{} ({} fit)</td><td>{}</td><td class=\"n\">{:.0} %</td>",
            f["effect"].as_str().unwrap().replace('_', " "),
            f["mechanism"].as_str().unwrap(),
            f["fit"].as_str().unwrap(),
            f["stage"].as_str().unwrap(),
            f["explained_share"].as_f64().unwrap() * 100.0
        );
        assert!(pos(&html, &row) < img, "{row}");
        let ratio = format!(
            "<td class=\"n\">{:.3}</td></tr>",
            f["heldout_ratio"].as_f64().unwrap()
        );
        assert!(html[pos(&html, &row)..].contains(&ratio));
    }
    let first = &html[pos(&html, "<tr><td>wheel scale</td>")..];
    let first = &first[..first.find("</tr>").unwrap()];
    assert!(first.contains("<td class=\"n\">73 %</td>"), "{first}");
    assert!(first.contains("<td class=\"n\">0.337</td>"), "{first}");
    assert!(first.contains("scale = 0.996297"), "{first}");
    // Before and after.
    assert!(html.contains("<tr><td>position (ground stage)</td><td class=\"n\">6.93 mm</td><td class=\"n\">3.31 mm</td>"));
    // The plots diagnose writes, each on the page with its sentence.
    for f in ["path.svg", "position_residual.svg", "heading_residual.svg"] {
        assert!(report.join(f).exists(), "{f}");
        assert!(pos(&html, &format!("<img src=\"{f}\"")) > img - 1);
    }
    // The printed text, folded.
    let folded = &html[pos(&html, "<details>")..];
    assert!(folded.contains(&format!("verdict: {verdict}")));
    assert!(folded.contains("ground RMSE: 6.93 mm nominal -&gt; 3.31 mm fitted"));
    std::fs::remove_dir_all(&dir).ok();
}
