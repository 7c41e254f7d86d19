//! Scratch: prints calibrate on the real data.
use diagnose::calibrate::{calibrate, CalOptions};
use formats::recording::Recording;
use std::path::PathBuf;

fn load(folder: &str) -> Option<(calib_core::robot::Robot, (String, Recording))> {
    let base = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = base
        .ancestors()
        .map(|a| a.join("shared/real"))
        .find(|d| d.exists())?
        .join(folder);
    if !dir.exists() {
        return None;
    }
    let robot = formats::robot_file::load(&dir.join("robot.toml")).unwrap();
    let rec = Recording::load(&dir.join("recording.csv"), &robot).unwrap();
    Some((robot, (folder.to_string(), rec)))
}

#[test]
fn scratch() {
    let mut recs = vec![];
    let mut robot = None;
    for i in 1..=6 {
        let Some((r, x)) = load(&format!("diff-square-run-0{i}")) else {
            return;
        };
        robot = Some(r);
        recs.push(x);
    }
    let robot = robot.unwrap();
    let t = std::time::Instant::now();
    let c = calibrate(
        &robot,
        &recs,
        None,
        &CalOptions {
            leave_one_out: true,
            ..Default::default()
        },
    )
    .unwrap();
    println!("{c}\n{:?}\n{:?}", t.elapsed(), c.correlations);
    for sub in [&recs[0..3], &recs[3..6], &recs[0..1]] {
        let c = calibrate(
            &robot,
            sub,
            None,
            &CalOptions {
                leave_one_out: false,
                ..Default::default()
            },
        )
        .unwrap();
        println!("{c}\n{:?}", c.correlations);
    }
    let (r, x) = load("omni3-square-run-01").unwrap();
    let c = calibrate(
        &r,
        &[x],
        None,
        &CalOptions {
            leave_one_out: false,
            ..Default::default()
        },
    )
    .unwrap();
    println!("{c}\n");
}
