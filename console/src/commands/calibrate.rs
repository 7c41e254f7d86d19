//! `wheelcal calibrate`: the robot's geometry from whole trajectories with ground truth.
//! A thin shell over the `calibrate` crate: gathers recordings ([`crate::recordings`]),
//! refuses another robot's among them, prints or writes the result.

use crate::args::CalibrateArgs;
use crate::calibration::saved::laws_from;
use crate::mcap_out::{write_pose_paths, PoseSeries};
use crate::output::Output;
use crate::recordings::{load, load_all, load_encoders, recording_files, refuse_mixed_robots};
use crate::ros2;
use anyhow::{bail, Context, Result};
use calib_core::robot::Robot;
use calibrate::plots;
use calibrate::{calibrate, CalOptions, Calibration, CvBy, Factors};
use formats::recording::Recording;
use formats::robot_file;
use std::path::Path;

/// Runs `wheelcal calibrate`: fits the robot's geometry to the recordings and prints or writes the result.
pub fn run(a: &CalibrateArgs, out: Output) -> Result<()> {
    let robot = robot_file::load(&a.robot)?;
    // Before any recording is read: a bad --laws-from costs nothing.
    let known = match &a.laws_from {
        Some(p) => Some(laws_from(p, &robot)?),
        None => None,
    };
    let got = load_all(&a.recording, &robot, &a.robot, &a.bag, out)?;
    let held = match &a.holdout {
        Some(h) => {
            let f = recording_files(h)?;
            if f.len() != 1 {
                bail!(
                    "{}: --holdout takes one recording, found {}",
                    h.display(),
                    f.len()
                );
            }
            let canon = std::fs::canonicalize(&f[0]).unwrap_or_else(|_| f[0].clone());
            if got
                .paths
                .iter()
                .any(|q| std::fs::canonicalize(q).unwrap_or_else(|_| q.clone()) == canon)
            {
                bail!(
                    "{}: --holdout names a recording that is also fitted: a held-out error needs a recording the fit did not see",
                    f[0].display()
                );
            }
            Some(load(&f[0], &robot, &a.robot, &a.bag)?)
        }
        None => None,
    };
    let all: Vec<(&Path, &Recording)> = got
        .by_file()
        .into_iter()
        .chain(
            held.as_ref()
                .zip(a.holdout.as_deref())
                .map(|((_, r), p)| (p, r)),
        )
        .collect();
    refuse_mixed_robots(&robot, &all)?;
    let mut driving = Vec::new();
    let mut driving_paths = Vec::new();
    for p in &a.e_b_for {
        for f in recording_files(p)? {
            driving.push(load_encoders(&f, &robot, &a.robot, &a.bag)?);
            driving_paths.push(f);
        }
    }
    let cv = a.cv.as_deref().and_then(CvBy::parse);
    let opts = CalOptions {
        leave_one_out: !a.no_cross_validation && cv.is_none(),
        marker_offset: a.marker_offset,
        free_start: a.free_start,
        robust: a.robust,
        cv: if a.no_cross_validation { None } else { cv },
        heading_lever_m: a.heading_lever,
        turn_law: known.as_ref().map_or(a.turn_law, |k| k.turn),
        speed_law: known.as_ref().map_or(a.speed_law, |k| k.speed),
        e_b_for: driving,
        hold: a.hold.clone(),
    };
    let recs = &got.recs;
    let mut cal = calibrate(&robot, recs, held.as_ref(), &opts).map_err(|mut e| {
        // Name the file, not only the short name; the error stays the calibration's.
        let file = e
            .recording
            .as_ref()
            .and_then(|n| {
                got.file_of(n).map(|f| f.display().to_string()).or_else(|| {
                    opts.e_b_for
                        .iter()
                        .position(|(r, _)| r == n)
                        .map(|i| driving_paths[i].display().to_string())
                })
            })
            .or_else(|| {
                e.recording
                    .clone()
                    .and(a.holdout.as_ref().map(|h| h.display().to_string()))
            });
        if file.is_some() {
            e.recording = file;
        }
        e
    })?;
    if let Some(k) = known {
        cal.notes.insert(0, k.note);
    }
    // Outputs only once everything succeeded: the robot files' targets are checked
    // first, the report (which can still fail) is written, and only then the robot
    // files, so a failed report leaves no fitted robot file beside its error.
    for p in [&a.write_robot, &a.write_board_robot].into_iter().flatten() {
        formats::safe_write::check_target(
            p,
            "robot description",
            formats::robot_file::is_robot_file,
        )
        .with_context(|| format!("cannot write {}", p.display()))?;
    }
    if let Some(dir) = &a.report {
        write_report(&cal, &robot, recs, held.as_ref(), dir)
            .with_context(|| format!("cannot write the report into {}", dir.display()))?;
    }
    if let Some(p) = &a.write_robot {
        formats::robot_file::write(p, &cal.robot_toml())
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!("fitted robot: {}", p.display()));
    }
    if let Some(p) = &a.write_board_robot {
        formats::robot_file::write(p, &cal.board_robot_toml())
            .with_context(|| format!("cannot write {}", p.display()))?;
        out.note(&format!(
            "board robot: {} (put it on the board with this calibration's JSON (--json, or a --report folder): `wheelcal apply CALIBRATION.json --board-robot {} --save` sets the geometry and the factors together or not at all; step by step: `wheelcal robot set {}`, `robot save`, `{}`, `factors save`)",
            p.display(),
            p.display(),
            p.display(),
            cal.board_robot_factors()
        ));
    }
    if let Some(dir) = &a.report {
        out.note(&format!("report: {}", dir.display()));
    }
    out.emit(&cal, || human(&cal))
}

fn ros2_yaml(cal: &Calibration) -> Option<String> {
    match cal.factors {
        // Factors the board would refuse are not exported (the text says why not).
        Factors::Diff {
            c_l,
            c_r,
            e_b,
            board,
            ..
        } => Some(
            ros2::diff_drive_yaml(
                &ros2::DiffFactors {
                    c_l,
                    c_r,
                    e_b,
                    board,
                    skid_steer: (cal.kind == "skid_steer").then(|| {
                        let get = |n: &str| cal.params.iter().find(|p| p.spec.name == n);
                        ros2::SkidNote {
                            law: get("eb_arc")
                                .zip(get("eb"))
                                .map(|(a, b)| (b.value, a.value)),
                        }
                    }),
                },
                "diff_drive_controller",
                "a geometry fit by wheelcal calibrate",
            )
            .unwrap_or_else(|e| format!("# {e}\n")),
        ),
        Factors::Wheels { .. } => None,
    }
}

fn human(cal: &Calibration) -> String {
    let mut s = cal.to_string();
    match ros2_yaml(cal) {
        Some(y) => {
            s.push_str("ROS 2 (diff_drive_controller):\n");
            s.push_str(&y);
        }
        None => s.push_str(
            "ROS 2: no multiplier parameters for this drive; use the fitted robot file (--write-robot)\n",
        ),
    }
    s
}

/// A path's topic name under `/paths/` and its planar poses (x m, y m, yaw rad).
type NamedPoses = (String, Vec<(f64, f64, f64)>);

/// The MCAP file of `calibrate --report`.
pub const PATHS_MCAP: &str = "paths.mcap";

/// Writes the `--report` folder: calibration.json, summary.txt, robot.toml, ros2.yaml
/// (differential drive), the figures (`calibrate::plots::write_calibration_svgs`),
/// index.html ([`crate::report::calibrate`]: the factors and the apply command first)
/// and paths.mcap (per recording, held-out one included, its measured, nominal and
/// fitted poses at its pose samples as `geometry_msgs/PoseStamped` on
/// `/paths/<recording>/measured|nominal|fitted` and transforms on `/tf`:
/// [`crate::mcap_out::write_pose_paths`]).
fn write_report(
    cal: &Calibration,
    robot: &Robot,
    recs: &[(String, Recording)],
    held: Option<&(String, Recording)>,
    dir: &Path,
) -> Result<()> {
    use formats::safe_write::{claim_dir, replace_file};
    // A folder the tool made (or a new one); each file through a temporary and a rename,
    // so a failed write leaves the previous report's file whole.
    claim_dir(dir)?;
    replace_file(
        &dir.join("calibration.json"),
        serde_json::to_string_pretty(cal)?.as_bytes(),
    )?;
    let summary = human(cal);
    replace_file(&dir.join("summary.txt"), summary.as_bytes())?;
    replace_file(&dir.join("robot.toml"), cal.robot_toml().as_bytes())?;
    if let Some(y) = ros2_yaml(cal) {
        replace_file(&dir.join("ros2.yaml"), y.as_bytes())?;
    }
    let series = plots::calibration_series(cal, robot, recs, held)?;
    let figures = plots::write_calibration_svgs(cal, &series, dir)?;
    crate::report::calibrate::write(cal, robot, &figures, &summary, dir)?;
    // Per recording its measured, nominal and fitted poses, as PoseStamped on
    // `/paths/<recording>/<path>` and transforms on `/tf`.
    let poses: Vec<[NamedPoses; 3]> = series
        .iter()
        .map(|s| {
            let with = |xy: &[(f64, f64)], th: &[f64]| -> Vec<(f64, f64, f64)> {
                xy.iter().zip(th).map(|(&(x, y), &h)| (x, y, h)).collect()
            };
            [
                ("measured", with(&s.measured, &s.heading_measured)),
                ("nominal", with(&s.nominal, &s.heading_nominal)),
                ("fitted", with(&s.fitted, &s.heading_fitted)),
            ]
            .map(|(k, p)| (format!("{}/{k}", s.key), p))
        })
        .collect();
    let paths: Vec<PoseSeries<'_>> = series
        .iter()
        .zip(&poses)
        .flat_map(|(s, three)| {
            three.iter().map(|(name, pose)| PoseSeries {
                name,
                t: &s.t,
                pose,
            })
        })
        .collect();
    write_pose_paths(&paths, &dir.join(PATHS_MCAP))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    const DIFF: &str = "name = \"d\"\nkind = \"diff_drive\"\n[drive]\ntype = \"dc\"\ngear_ratio = 1.0\nencoder_counts_per_rev = 1000\n[[wheels]]\nname = \"left\"\nradius_m = 0.04\nalpha_deg = 90.0\nl_m = 0.1\nbeta_deg = 0.0\n[[wheels]]\nname = \"right\"\nradius_m = 0.04\nalpha_deg = -90.0\nl_m = 0.1\nbeta_deg = 180.0\n";

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("calcmd-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn args(robot: &Path, rec: &Path) -> CalibrateArgs {
        CalibrateArgs {
            robot: robot.to_path_buf(),
            recording: vec![rec.to_path_buf()],
            holdout: None,
            write_robot: None,
            write_board_robot: None,
            report: None,
            no_cross_validation: true,
            marker_offset: false,
            free_start: false,
            robust: false,
            cv: None,
            heading_lever: None,
            turn_law: None,
            speed_law: None,
            laws_from: None,
            e_b_for: Vec::new(),
            hold: Vec::new(),
            bag: default_bag_flags(),
        }
    }

    /// The bag flags as clap fills them when none is given.
    fn default_bag_flags() -> crate::args::BagFlags {
        use clap::Parser;
        #[derive(Parser)]
        struct Only {
            #[command(flatten)]
            bag: crate::args::BagFlags,
        }
        Only::parse_from(["wheelcal"]).bag
    }

    #[test]
    fn no_ground_truth_names_the_file() {
        let d = dir("nogt");
        std::fs::write(d.join("robot.toml"), DIFF).unwrap();
        // Pose columns blank but for a start-frame sample or five: no usable ground truth.
        let mut csv = String::from("t,enc_left,enc_right,x,y,theta\n");
        for k in 0..50 {
            let pose = if k < 5 { "0,0,0" } else { ",," };
            csv.push_str(&format!(
                "{},{},{},{pose}\n",
                k as f64 * 0.05,
                k * 10,
                k * 11
            ));
        }
        std::fs::write(d.join("recording.csv"), csv).unwrap();
        let e = run(&args(&d.join("robot.toml"), &d), Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(
            text.contains(&d.join("recording.csv").display().to_string()),
            "{text}"
        );
        assert!(text.contains("motion capture"), "{text}");
        // The calibration's own error, not its text: a caller can still tell what failed.
        assert!(
            e.downcast_ref::<calibrate::CalibrateError>()
                .is_some_and(|c| c.recording.is_some()),
            "{e:?}"
        );
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn another_robots_recording_names_both_files() {
        let d = dir("other");
        let run_dir = d.join("run");
        std::fs::create_dir_all(&run_dir).unwrap();
        std::fs::write(d.join("robot.toml"), DIFF).unwrap();
        std::fs::write(
            run_dir.join("robot.toml"),
            DIFF.replace("\"d\"", "\"other\""),
        )
        .unwrap();
        std::fs::write(
            run_dir.join("recording.csv"),
            "t,enc_left,enc_right\n0,0,0\n",
        )
        .unwrap();
        let e = run(&args(&d.join("robot.toml"), &run_dir), Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(
            text.contains("recording.csv") && text.contains("'other'"),
            "{text}"
        );
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn different_wheel_names_name_the_file() {
        let d = dir("wheels");
        std::fs::write(d.join("robot.toml"), DIFF).unwrap();
        std::fs::write(
            d.join("recording.csv"),
            "t,enc_w1,enc_w2,x,y,theta\n0,0,0,0,0,0\n",
        )
        .unwrap();
        let e = run(&args(&d.join("robot.toml"), &d), Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(text.contains("recording.csv"), "{text}");
        std::fs::remove_dir_all(&d).ok();
    }

    fn real_square() -> PathBuf {
        testdata::real("diff-square-run-01")
    }

    #[test]
    fn one_row_recording_names_the_file() {
        let d = dir("onerow");
        std::fs::write(d.join("robot.toml"), DIFF).unwrap();
        std::fs::write(
            d.join("recording.csv"),
            "t,enc_left,enc_right,x,y,theta\n0,0,0,0,0,0\n",
        )
        .unwrap();
        let e = run(&args(&d.join("robot.toml"), &d), Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(
            text.contains(&d.join("recording.csv").display().to_string()) && text.contains("1 row"),
            "{text}"
        );
        std::fs::remove_dir_all(&d).ok();
    }

    #[test]
    fn holdout_also_fitted_is_refused() {
        let sq = real_square();
        let mut a = args(&sq.join("robot.toml"), &sq);
        a.holdout = Some(sq.join("recording.csv"));
        let e = run(&a, Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(
            text.contains("recording.csv") && text.contains("also fitted"),
            "{text}"
        );
    }

    #[test]
    fn marker_offset_on_a_differential_drive_is_an_error() {
        let sq = real_square();
        let mut a = args(&sq.join("robot.toml"), &sq);
        a.marker_offset = true;
        let e = run(&a, Output::Json).unwrap_err();
        let text = format!("{e:#}");
        assert!(text.contains("omni robots only"), "{text}");
    }
}
