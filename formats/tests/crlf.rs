//! Issue 23 §5: files saved by Excel or on Windows end their lines with CR LF; errors in
//! them named every line one too low. The same broken cell must be reported at the same
//! line:column with either line ending, in recordings, runs files and robot files.

use calib_core::robot::presets;
use formats::recording::Recording;
use formats::runs_file::RunsFile;
use std::path::Path;

fn crlf(s: &str) -> String {
    s.replace('\n', "\r\n")
}

#[test]
fn crlf_files_report_the_same_line_as_lf_files() {
    // Line 4 has a bad encoder cell in column 2.
    let rec =
        "t,enc_left,enc_right,x,y,theta\n0,1,2,0,0,0\n0.1,2,3,,,\n0.2,x,4,,,\n0.3,4,5,0,0,0\n";
    let r = presets::mobolab();
    for text in [rec.to_string(), crlf(rec)] {
        let e = Recording::parse(&text, Path::new("r.csv"), &r).unwrap_err();
        assert_eq!(
            (e.line, e.column.as_ref().map(|c| c.0)),
            (Some(4), Some(2)),
            "{e}"
        );
    }
    // A blank line before the bad row counts as a line too.
    let runs =
        "test,path,length_m,x_err_m,y_err_m\numbmark,cw,1,0.01,0.02\n\numbmark,ccw,1,abc,0.02\n";
    for text in [runs.to_string(), crlf(runs)] {
        let e = RunsFile::parse(&text, Path::new("runs.csv")).unwrap_err();
        assert_eq!(e.line, Some(4), "{e}");
    }
    let wheel = |n: &str, a: i32, b: i32| {
        format!("[[wheels]]\nname = \"{n}\"\nradius_m = 0.05\nalpha_deg = {a}\nl_m = 0.2\nbeta_deg = {b}\n")
    };
    let robot = format!(
        "name = \"x\"\nkind = \"diff_drive\"\n\n[drive]\ntype = \"dc\"\nencoder_counts_per_rev = -5\n{}{}",
        wheel("left", 90, 0),
        wheel("right", -90, 180)
    );
    let robot = robot.as_str();
    for text in [robot.to_string(), crlf(robot)] {
        let e = formats::robot_file::parse(&text, Path::new("r.toml")).unwrap_err();
        assert_eq!(e.line, Some(6), "{e}");
    }
}
