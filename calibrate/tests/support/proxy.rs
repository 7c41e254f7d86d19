//! The held-out proxy on the OptiOdom sessions (`WHEELCAL_SESSIONS`): train
//! on one square session of a robot, dead-reckon the circular and Ivanjko runs of the same
//! robot on the nearest day from their first row, and compare with the OptiOdom authors'
//! parameters fitted on the same training session, on the same runs.
//!
//! Pairing (nearest day with circles or Ivanjko paths, same robot): the 23 December 2020
//! squares are tested on the 23 December circles and Ivanjko paths; the 23 June 2020
//! squares on those of 25 June 2020 (there are none on 23 June). [`TestDays::OtherMonths`]
//! tests each month's squares on the other month's runs instead.
//!
//! Metric: dead reckoning from the first row (motion capture is in the robot's start
//! frame, the first pose is exactly (0, 0, 0)), RMS position error over every pose sample
//! of a run ([`dead_reckoning_rmse`]).
//!
//! An evaluation harness, not part of the library: `tests/heldout_proxy.rs` and the
//! examples include it (`#[path]`), each using part of it.
#![allow(dead_code)]

use calib_core::robot::Robot;
use calibrate::{dead_reckoning_rmse, dead_reckoning_rmse_law, Series, Spread, TurnLaw};
use formats::recording::Recording;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The examples' sessions folder: `--sessions DIR` on the command line, else
/// `WHEELCAL_SESSIONS`; without either the process exits (2) saying so.
pub fn sessions_dir_from_args() -> std::path::PathBuf {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = args
        .iter()
        .position(|a| a == "--sessions")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from)
        .or_else(|| testdata::sessions_dir_if_set().ok());
    dir.unwrap_or_else(|| {
        eprintln!("the OptiOdom sessions are not given: --sessions DIR or WHEELCAL_SESSIONS (data/real/README.md)");
        std::process::exit(2)
    })
}

/// One run folder of the sessions directory: `<robot>-<path>-<session>-run-NN`.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord)]
pub struct RunDir {
    /// Robot (`diff`, `omni3`, `omni4`).
    pub robot: String,
    /// Path kind (`square`, `circular`, `ivanjko`).
    pub path: String,
    /// Session id, DDMMYYYYhhmm.
    pub session: String,
    /// The folder's name.
    pub folder: String,
}

impl RunDir {
    /// Day of the session as (year, month, day).
    pub fn day(&self) -> (u32, u32, u32) {
        let n = |a: usize, b: usize| self.session.get(a..b).and_then(|s| s.parse().ok());
        (
            n(4, 8).unwrap_or(0),
            n(2, 4).unwrap_or(0),
            n(0, 2).unwrap_or(0),
        )
    }
}

/// Every run folder of `dir` whose name parses, sorted.
pub fn list_runs(dir: &Path) -> std::io::Result<Vec<RunDir>> {
    let mut v = Vec::new();
    for e in std::fs::read_dir(dir)? {
        let name = e?.file_name().to_string_lossy().to_string();
        let parts: Vec<&str> = name.split('-').collect();
        if parts.len() == 5 && parts[3] == "run" {
            v.push(RunDir {
                robot: parts[0].into(),
                path: parts[1].into(),
                session: parts[2].into(),
                folder: name,
            });
        }
    }
    v.sort();
    Ok(v)
}

fn day_number(d: (u32, u32, u32)) -> i64 {
    // Good enough to find the nearest day (months as 31 days).
    (d.0 as i64) * 372 + (d.1 as i64) * 31 + d.2 as i64
}

/// Which days' runs test a training session.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum TestDays {
    /// The circles and Ivanjko paths of the nearest day that has any (the proxy).
    #[default]
    Nearest,
    /// Those of the other months: the robot as it was on other days, as the free-form
    /// runs kept apart were driven on days no square session was.
    OtherMonths,
    /// The nearest day's Ivanjko paths alone (a third kind of motion, mostly spins in
    /// place); `with_circles`: that day's circles join the training session's squares,
    /// the workflow the README recommends (squares and circles).
    Ivanjko {
        /// Train on the nearest day's circles too.
        with_circles: bool,
    },
    /// The squares of the robot's other sessions (the same kind of motion on other
    /// days: how a geometry carries from one session to the next).
    OtherSquareSessions,
}

/// The test runs of a training session: the circular and Ivanjko runs of the same robot
/// on the days `days` says; for a robot with none (the mecanum robot: its circles are kept
/// apart), the squares of its other sessions.
pub fn test_runs<'a>(all: &'a [RunDir], train: &RunDir, days: TestDays) -> Vec<&'a RunDir> {
    let other_squares = || {
        all.iter()
            .filter(|r| r.robot == train.robot && r.path == "square" && r.session != train.session)
            .collect()
    };
    if days == TestDays::OtherSquareSessions {
        return other_squares();
    }
    let tests: Vec<&RunDir> = all
        .iter()
        .filter(|r| r.robot == train.robot && (r.path == "circular" || r.path == "ivanjko"))
        .collect();
    let d0 = day_number(train.day());
    let Some(best) = tests.iter().map(|r| (day_number(r.day()) - d0).abs()).min() else {
        return other_squares();
    };
    let (year, month, _) = train.day();
    tests
        .into_iter()
        .filter(|r| match days {
            TestDays::Nearest => (day_number(r.day()) - d0).abs() == best,
            TestDays::OtherMonths => (r.day().0, r.day().1) != (year, month),
            TestDays::Ivanjko { .. } => {
                (day_number(r.day()) - d0).abs() == best && r.path == "ivanjko"
            }
            TestDays::OtherSquareSessions => false,
        })
        .collect()
}

/// The circles of the nearest day with circles ([`TestDays::Ivanjko`] with circles
/// trains on them beside the squares).
pub fn nearest_circles<'a>(all: &'a [RunDir], train: &RunDir) -> Vec<&'a RunDir> {
    let d0 = day_number(train.day());
    let of_robot = |r: &&RunDir| r.robot == train.robot && r.path == "circular";
    let Some(best) = all
        .iter()
        .filter(of_robot)
        .map(|r| (day_number(r.day()) - d0).abs())
        .min()
    else {
        return Vec::new();
    };
    all.iter()
        .filter(of_robot)
        .filter(|r| (day_number(r.day()) - d0).abs() == best)
        .collect()
}

/// The OptiOdom authors' differential-drive parameters for `session` and `path`
/// (`diff-Sousa` of authors_params.json, the row fitted on all the session's runs): the
/// nominal robot with D_L, D_R and b applied.
pub fn authors_diff_robot(
    params: &serde_json::Value,
    nominal: &Robot,
    session: &str,
    path: &str,
) -> Option<Robot> {
    let row = params.get("diff-Sousa")?.as_array()?.iter().find(|r| {
        r["session"].as_str() == Some(session)
            && r["path"].as_str() == Some(path)
            && r["note"].as_str() == Some("")
    })?;
    let (dr, dl, b) = (
        row["D_R"].as_f64()?,
        row["D_L"].as_f64()?,
        row["b"].as_f64()?,
    );
    let mut r = nominal.clone();
    for w in r.wheels.iter_mut() {
        // Left is the +y wheel.
        w.radius_m = if w.is_left() { dl } else { dr } / 2.0;
        w.l_m = b / 2.0;
    }
    Some(r)
}

/// The OptiOdom authors' omni parameters for `session` and `path` (`omni3-sousa` or
/// `omni4-sousa` of authors_params.json, the row fitted on all the session's runs): the
/// nominal robot with each wheel's radius, distance and angles from the row's `wheels`.
pub fn authors_omni_robot(
    params: &serde_json::Value,
    key: &str,
    nominal: &Robot,
    session: &str,
    path: &str,
) -> Option<Robot> {
    let row = params.get(key)?.as_array()?.iter().find(|r| {
        r["session"].as_str() == Some(session)
            && r["path"].as_str() == Some(path)
            && r["note"].as_str() == Some("")
    })?;
    let mut r = nominal.clone();
    for w in r.wheels.iter_mut() {
        let a = row["wheels"]
            .as_array()?
            .iter()
            .find(|a| a["name"].as_str() == Some(w.name.as_str()))?;
        w.radius_m = a["radius_m"].as_f64()?;
        w.l_m = a["l_m"].as_f64()?;
        w.alpha_rad = a["alpha_deg"].as_f64()?.to_radians();
        w.beta_rad = a["beta_deg"].as_f64()?.to_radians();
        w.gamma_rad = a["gamma_deg"].as_f64()?.to_radians();
    }
    Some(r)
}

/// Held-out errors of one training session.
#[derive(Debug, Clone, Serialize)]
pub struct SessionResult {
    /// Training session id.
    pub session: String,
    /// Its runs (trained on).
    pub train_runs: usize,
    /// Test runs with their dead-reckoned RMS (m): ours, the authors'.
    pub tests: Vec<(String, f64, f64)>,
}

impl SessionResult {
    /// Ours: mean, median, worst over the test runs.
    pub fn ours(&self) -> Spread {
        Spread::of(self.tests.iter().map(|t| t.1))
    }
    /// The authors': mean, median, worst over the test runs.
    pub fn authors(&self) -> Spread {
        Spread::of(self.tests.iter().map(|t| t.2))
    }
    /// Mean ours over mean the authors'.
    pub fn ratio(&self) -> f64 {
        self.ours().mean_m / self.authors().mean_m
    }
}

/// Geometric mean of the sessions' ratios.
pub fn geometric_mean_ratio(r: &[SessionResult]) -> f64 {
    (r.iter().map(|s| s.ratio().ln()).sum::<f64>() / r.len().max(1) as f64).exp()
}

/// A markdown table of the results (mm), with the geometric mean of the ratios.
pub fn table(r: &[SessionResult]) -> String {
    let mut s = String::from(
        "| training session | runs | test runs | ours mean / median / worst (mm) | authors mean / median / worst (mm) | ratio |\n|---|---|---|---|---|---|\n",
    );
    for x in r {
        let (o, a) = (x.ours(), x.authors());
        s.push_str(&format!(
            "| {} | {} | {} | {:.1} / {:.1} / {:.1} | {:.1} / {:.1} / {:.1} | {:.3} |\n",
            x.session,
            x.train_runs,
            x.tests.len(),
            o.mean_m * 1e3,
            o.median_m * 1e3,
            o.worst_m * 1e3,
            a.mean_m * 1e3,
            a.median_m * 1e3,
            a.worst_m * 1e3,
            x.ratio()
        ));
    }
    let worst = r.iter().map(|x| x.ratio()).fold(f64::NAN, f64::max);
    s.push_str(&format!(
        "\ngeometric mean of the ratios {:.3}, worst {:.3}\n",
        geometric_mean_ratio(r),
        worst
    ));
    s
}

/// Loads a run folder's robot and recording.
pub fn load_run(dir: &Path, folder: &str) -> Result<(Robot, Recording), String> {
    let d = dir.join(folder);
    let robot = formats::robot_file::load(&d.join("robot.toml")).map_err(|e| e.to_string())?;
    let rec = Recording::load(&d.join("recording.csv"), &robot).map_err(|e| e.to_string())?;
    Ok((robot, rec))
}

/// Every run of robot `robot` whose session is in month `month` (`"06"`, `"12"`), with
/// the robot of the first: the data a month's turn law is fitted on.
pub fn month_runs(
    dir: &Path,
    robot: &str,
    month: &str,
) -> Result<(Robot, Vec<(String, Recording)>), String> {
    let mut nominal = None;
    let mut recs = Vec::new();
    for r in list_runs(dir).map_err(|e| e.to_string())? {
        if r.robot == robot && r.session.get(2..4) == Some(month) {
            let (rb, rec) = load_run(dir, &r.folder)?;
            nominal.get_or_insert(rb);
            recs.push((r.folder.clone(), rec));
        }
    }
    let nominal = nominal.ok_or(format!("no {robot} run in month {month}"))?;
    Ok((nominal, recs))
}

/// A training procedure: the nominal robot and the training recordings in, the fitted
/// robot out.
pub type Train<'a> = dyn Fn(&Robot, &[(String, Recording)]) -> Result<Robot, String> + 'a;

/// A training procedure that may fit a turn law: the nominal robot, the training
/// recordings and the session id in; the fitted robot (the separation of a turn in place)
/// and its law out.
pub type TrainLaw<'a> =
    dyn Fn(&Robot, &[(String, Recording)], &str) -> Result<(Robot, TurnLaw), String> + 'a;

/// Runs the proxy for the differential robot: every square session of `dir` (or those in
/// `only`), trained by `train`, tested on its paired runs (at most `max_tests` of them,
/// evenly spread, when given).
pub fn run_diff(
    dir: &Path,
    only: Option<&[&str]>,
    max_tests: Option<usize>,
    train: &Train<'_>,
) -> Result<Vec<SessionResult>, String> {
    run_diff_with_law(dir, only, max_tests, &|robot, recs, _| {
        Ok((train(robot, recs)?, TurnLaw::default()))
    })
}

/// [`run_diff`] with a training that may fit a turn law: the test runs are dead-reckoned
/// with the law (as a board that applies it would).
pub fn run_diff_with_law(
    dir: &Path,
    only: Option<&[&str]>,
    max_tests: Option<usize>,
    train: &TrainLaw<'_>,
) -> Result<Vec<SessionResult>, String> {
    run_robot(dir, "diff", only, max_tests, train)
}

/// The proxy for robot `robot` of the sessions folder (`diff`, `omni3`): each of its
/// square sessions trained by `train` and tested on the circular and Ivanjko runs of the
/// nearest day, against the authors' parameters fitted on the same session.
pub fn run_robot(
    dir: &Path,
    robot_name: &str,
    only: Option<&[&str]>,
    max_tests: Option<usize>,
    train: &TrainLaw<'_>,
) -> Result<Vec<SessionResult>, String> {
    run_robot_on(dir, robot_name, only, max_tests, TestDays::Nearest, train)
}

/// [`run_robot`] tested on the runs of `days` ([`test_runs`]).
pub fn run_robot_on(
    dir: &Path,
    robot_name: &str,
    only: Option<&[&str]>,
    max_tests: Option<usize>,
    days: TestDays,
    train: &TrainLaw<'_>,
) -> Result<Vec<SessionResult>, String> {
    let params: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.join("authors_params.json")).map_err(|e| e.to_string())?,
    )
    .map_err(|e| e.to_string())?;
    let all = list_runs(dir).map_err(|e| e.to_string())?;
    let mut sessions: BTreeMap<String, Vec<&RunDir>> = BTreeMap::new();
    for r in all
        .iter()
        .filter(|r| r.robot == robot_name && r.path == "square")
    {
        if only.is_none_or(|o| o.contains(&r.session.as_str())) {
            sessions.entry(r.session.clone()).or_default().push(r);
        }
    }
    let mut test_cache: BTreeMap<String, Series> = BTreeMap::new();
    let mut out = Vec::new();
    for (session, runs) in sessions {
        let mut tests = test_runs(&all, runs[0], days);
        if tests.is_empty() {
            return Err(format!(
                "no test runs for square {session}: no circles or Ivanjko paths of {robot_name} {}",
                match days {
                    TestDays::Nearest => "on any day",
                    TestDays::OtherMonths => "in another month",
                    TestDays::Ivanjko { .. } => "(Ivanjko paths) on the nearest day",
                    TestDays::OtherSquareSessions => "(squares) in another session",
                }
            ));
        }
        if let Some(m) = max_tests.filter(|m| *m < tests.len()) {
            let step = tests.len() as f64 / m as f64;
            tests = (0..m).map(|i| tests[(i as f64 * step) as usize]).collect();
        }
        let mut robot = None;
        let mut recs = Vec::new();
        let circles = if days == (TestDays::Ivanjko { with_circles: true }) {
            nearest_circles(&all, runs[0])
        } else {
            Vec::new()
        };
        for r in runs.iter().chain(&circles) {
            let (rb, rec) = load_run(dir, &r.folder)?;
            robot.get_or_insert(rb);
            recs.push((r.folder.clone(), rec));
        }
        let nominal = robot.ok_or("no run")?;
        let (ours, law) = train(&nominal, &recs, &session)?;
        let authors = if robot_name == "diff" {
            authors_diff_robot(&params, &nominal, &session, "square")
        } else {
            let key = format!("{robot_name}-sousa");
            authors_omni_robot(&params, &key, &nominal, &session, "square")
        }
        .ok_or_else(|| format!("no authors' parameters for square {session}"))?;
        let mut res = Vec::new();
        for t in tests {
            if !test_cache.contains_key(&t.folder) {
                let (rb, rec) = load_run(dir, &t.folder)?;
                let s = Series::new(&t.folder, &rb, &rec).map_err(|e| e.to_string())?;
                test_cache.insert(t.folder.clone(), s);
            }
            let s = &test_cache[&t.folder];
            let ours = dead_reckoning_rmse_law(&ours, &law, s).unwrap_or(f64::NAN);
            let authors = dead_reckoning_rmse(&authors, s).unwrap_or(f64::NAN);
            res.push((t.folder.clone(), ours, authors));
        }
        out.push(SessionResult {
            session,
            train_runs: runs.len(),
            tests: res,
        });
    }
    Ok(out)
}

/// One session left out of its month by [`laws_across_sessions`]: the mean dead-reckoned
/// RMS of its runs (m) with the geometry `calibrate` fitted on the month's other
/// sessions, by model.
#[derive(Debug, Clone, Serialize)]
pub struct LawFold {
    /// `"06"` or `"12"`.
    pub month: String,
    /// The left-out session (`diff-circular-250620202104`).
    pub session: String,
    /// Its runs.
    pub runs: usize,
    /// No law (`--turn-law 0`).
    pub none_m: f64,
    /// The turn law held at its value fitted on the other sessions (`law_tests`).
    pub turn_m: f64,
    /// The speed law held likewise.
    pub speed_m: f64,
    /// `calibrate`'s defaults (its own choice of law).
    pub chosen_m: f64,
    /// The turn and speed laws held (eb_arc / eb, per m/s).
    pub laws: (f64, f64),
}

/// Within each month of the differential robot's runs in `dir` (June, December), each
/// session left out in turn: `calibrate` on the month's other sessions with its defaults,
/// with the turn law and with the speed law each held at the value it fitted there on
/// its own (`law_tests`), and with none; each dead-reckons the left-out runs from their
/// first row, applying its law. The evidence across sessions for choosing between the
/// two rival laws (`examples/laws_across_sessions.rs` prints it).
pub fn laws_across_sessions(dir: &Path) -> Result<Vec<LawFold>, String> {
    use calibrate::{calibrate, CalOptions, Calibration};
    let mut out = Vec::new();
    for month in ["06", "12"] {
        let (robot, recs) = month_runs(dir, "diff", month)?;
        let series: Vec<Series> = recs
            .iter()
            .map(|(n, r)| Series::new(n, &robot, r).map_err(|e| e.to_string()))
            .collect::<Result<_, _>>()?;
        let mut sessions: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        for (i, (name, _)) in recs.iter().enumerate() {
            let session = name.rsplit_once("-run-").map_or(name.as_str(), |p| p.0);
            sessions.entry(session.to_string()).or_default().push(i);
        }
        for (session, held) in sessions {
            let train: Vec<(String, &Recording)> = recs
                .iter()
                .enumerate()
                .filter(|(i, _)| !held.contains(i))
                .map(|(_, (n, r))| (n.clone(), r))
                .collect();
            let run = |opts: &CalOptions| {
                calibrate(&robot, &train, None, opts).map_err(|e| format!("{session}: {e}"))
            };
            let chosen = run(&CalOptions::default())?;
            let tested = |law: &str| {
                chosen
                    .law_tests
                    .iter()
                    .find(|t| t.law == law)
                    .map_or(0.0, |t| t.value)
            };
            let laws = (tested("turn"), tested("speed"));
            let none = run(&CalOptions {
                turn_law: Some(0.0),
                ..Default::default()
            })?;
            let turn = run(&CalOptions {
                turn_law: Some(laws.0),
                ..Default::default()
            })?;
            let speed = run(&CalOptions {
                speed_law: Some(laws.1),
                ..Default::default()
            })?;
            let mean = |c: &Calibration| {
                held.iter()
                    .map(|&i| {
                        dead_reckoning_rmse_law(&c.law_base_robot, &c.turn_law, &series[i])
                            .unwrap_or(f64::NAN)
                    })
                    .sum::<f64>()
                    / held.len() as f64
            };
            out.push(LawFold {
                month: month.to_string(),
                session,
                runs: held.len(),
                none_m: mean(&none),
                turn_m: mean(&turn),
                speed_m: mean(&speed),
                chosen_m: mean(&chosen),
                laws,
            });
        }
    }
    Ok(out)
}

/// The geometric mean over `folds` of `model`'s error over no law's.
pub fn geometric_mean_over_none(folds: &[LawFold], model: impl Fn(&LawFold) -> f64) -> f64 {
    let n = folds.len().max(1) as f64;
    (folds
        .iter()
        .map(|f| (model(f) / f.none_m).ln())
        .sum::<f64>()
        / n)
        .exp()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(folder: &str) -> RunDir {
        let p: Vec<&str> = folder.split('-').collect();
        RunDir {
            robot: p[0].into(),
            path: p[1].into(),
            session: p[2].into(),
            folder: folder.into(),
        }
    }

    /// The sessions' own pairing: 23 June squares test on 25 June (the nearest day with
    /// circles or Ivanjko paths, not 22 December); with `OtherMonths`, on December's runs
    /// only; another robot's runs never; a robot without circles (omni4) on its other
    /// sessions' squares either way.
    #[test]
    fn test_days_pair_the_nearest_day_or_the_other_months() {
        let all: Vec<RunDir> = [
            "diff-square-230620202042-run-01",
            "diff-circular-250620202104-run-01",
            "diff-ivanjko-250620201618-run-01",
            "diff-circular-231220200121-run-01",
            "diff-ivanjko-221220200057-run-01",
            "omni3-circular-221220201643-run-01",
            "omni4-square-080920201715-run-01",
            "omni4-square-231220200521-run-01",
        ]
        .iter()
        .map(|f| run(f))
        .collect();
        let names = |v: Vec<&RunDir>| v.iter().map(|r| r.session.clone()).collect::<Vec<_>>();
        let june = &all[0];
        assert_eq!(
            names(test_runs(&all, june, TestDays::Nearest)),
            ["250620202104", "250620201618"]
        );
        assert_eq!(
            names(test_runs(&all, june, TestDays::OtherMonths)),
            ["231220200121", "221220200057"]
        );
        let dec = run("diff-square-231220200029-run-01");
        assert_eq!(
            names(test_runs(&all, &dec, TestDays::Nearest)),
            ["231220200121"]
        );
        assert_eq!(
            names(test_runs(&all, &dec, TestDays::OtherMonths)),
            ["250620202104", "250620201618"]
        );
        for days in [TestDays::Nearest, TestDays::OtherMonths] {
            assert_eq!(names(test_runs(&all, &all[6], days)), ["231220200521"]);
        }
    }
}

/// Every run of robot `robot` in `dir` whose kind of motion and session `keep` accepts
/// (`RunDir`), with the robot of the first.
pub fn robot_runs(
    dir: &Path,
    robot: &str,
    keep: impl Fn(&RunDir) -> bool,
) -> Result<(Robot, Vec<(String, Recording)>), String> {
    let mut nominal = None;
    let mut recs = Vec::new();
    for r in list_runs(dir).map_err(|e| e.to_string())? {
        if r.robot == robot && keep(&r) {
            let (rb, rec) = load_run(dir, &r.folder)?;
            nominal.get_or_insert(rb);
            recs.push((r.folder.clone(), rec));
        }
    }
    let nominal = nominal.ok_or(format!("no {robot} run"))?;
    Ok((nominal, recs))
}

/// One calibration dead-reckoning runs kept apart from it: the board as it applies the
/// calibration (its factors and laws, calib-core's odometry) and the same calibration's
/// constant geometry (the robot file), mean RMS over the runs (m).
#[derive(Debug, Clone, Serialize)]
pub struct KeptApart {
    /// What was trained on.
    pub training: String,
    /// What was kept apart and dead-reckoned.
    pub tested: String,
    /// Runs trained on and tested.
    pub train_runs: usize,
    pub test_runs: usize,
    /// The law kept (`law_tests`' name and value), if any.
    pub law: Option<(String, f64)>,
    /// Mean RMS of the board (laws included) and of the robot file, m.
    pub board_m: f64,
    pub constant_m: f64,
    /// Seconds calibrate took.
    pub seconds: f64,
}

impl KeptApart {
    /// The board's error over the constant geometry's.
    pub fn ratio(&self) -> f64 {
        self.board_m / self.constant_m
    }
}

/// The board a calibration's factors set: its factors and laws for a differential drive
/// (plain factors when no law is kept), an omni robot's per-wheel factors and turn law
/// (without the geometry no factor carries: `apply --factors-only`).
pub fn board_of(c: &calibrate::Calibration) -> calib_core::Corrections {
    match &c.factors {
        calibrate::Factors::Wheels {
            f_lat,
            f_lon,
            l_arc,
        } => calib_core::Corrections::omni(f_lat.iter().copied().collect(), *f_lon, *l_arc),
        calibrate::Factors::Diff { board: Some(b), .. } => b.corrections(),
        calibrate::Factors::Diff { c_l, c_r, e_b, .. } => calib_core::Corrections::DiffDrive {
            c_l: *c_l,
            c_r: *c_r,
            e_b: *e_b,
        },
    }
}

/// `calibrate` (defaults) on the differential robot's runs `train` accepts, its board and
/// its robot file dead-reckoning the runs `test` accepts, from their first row.
pub fn kept_apart(
    dir: &Path,
    training: &str,
    tested: &str,
    train: impl Fn(&RunDir) -> bool,
    test: impl Fn(&RunDir) -> bool,
) -> Result<(KeptApart, calibrate::Calibration), String> {
    use calibrate::{board_dead_reckoning_errors, calibrate, CalOptions};
    let (robot, recs) = robot_runs(dir, "diff", train)?;
    let (_, held) = robot_runs(dir, "diff", test)?;
    let t0 = std::time::Instant::now();
    let c = calibrate(&robot, &recs, None, &CalOptions::default()).map_err(|e| e.to_string())?;
    let seconds = t0.elapsed().as_secs_f64();
    let board = board_of(&c);
    let (mut b, mut k) = (0.0, 0.0);
    for (name, rec) in &held {
        let s = Series::new(name, &robot, rec).map_err(|e| e.to_string())?;
        b += board_dead_reckoning_errors(&robot, &board, &s)
            .ok_or(format!("{name}: the board cannot dead-reckon it"))?
            .0;
        k += dead_reckoning_rmse(&c.fitted_robot, &s).ok_or(format!("{name}: no path"))?;
    }
    let n = held.len().max(1) as f64;
    let law = c
        .law_tests
        .iter()
        .find(|t| t.kept && !t.law.contains("lead"))
        .map(|t| (t.law.to_string(), t.value));
    Ok((
        KeptApart {
            training: training.into(),
            tested: tested.into(),
            train_runs: recs.len(),
            test_runs: held.len(),
            law,
            board_m: b / n,
            constant_m: k / n,
            seconds,
        },
        c,
    ))
}

/// The training sets [`kept_apart`] is run on for the differential robot: each kind of
/// motion kept apart from the other two (all sessions of both months), and each month
/// kept apart from the other.
pub fn kept_apart_sets(dir: &Path) -> Result<Vec<(KeptApart, calibrate::Calibration)>, String> {
    let mut out = Vec::new();
    for kind in ["square", "circular", "ivanjko"] {
        out.push(kept_apart(
            dir,
            &format!("all but {kind}"),
            kind,
            |r| r.path != kind,
            |r| r.path == kind,
        )?);
    }
    for (train, test, a, b) in [
        ("06", "12", "June", "December"),
        ("12", "06", "December", "June"),
    ] {
        out.push(kept_apart(
            dir,
            a,
            b,
            |r| r.session.get(2..4) == Some(train),
            |r| r.session.get(2..4) == Some(test),
        )?);
    }
    Ok(out)
}

/// Mean, median and worst of `v`.
pub fn mean_median_worst(v: &[f64]) -> (f64, f64, f64) {
    let s = Spread::of(v.iter().copied());
    (s.mean_m, s.median_m, s.worst_m)
}

/// OptiOdom's objective re-implemented (issue 56): the differential drive's three
/// parameters (left and right wheel diameter, separation) by least squares on positions
/// dead-reckoned from each run's first pose with no resets, compared every
/// [`OPTIODOM_SAMPLE_M`] of the measured path's travel (the authors' MATLAB). Minimised by
/// Levenberg-Marquardt from the nominal geometry, forward-difference Jacobian.
pub const OPTIODOM_SAMPLE_M: f64 = 0.5;

/// One run prepared for [`optiodom_fit`]: its series and the measured positions every
/// [`OPTIODOM_SAMPLE_M`] of travel, `(t, x, y)`.
pub struct OptiOdomRun {
    series: Series,
    samples: Vec<(f64, f64, f64)>,
}

impl OptiOdomRun {
    /// `rec` of `robot`, named `name`.
    pub fn new(name: &str, robot: &Robot, rec: &Recording) -> Result<OptiOdomRun, String> {
        let series = Series::new(name, robot, rec).map_err(|e| e.to_string())?;
        let mut samples = Vec::new();
        let (mut travel, mut next) = (0.0, OPTIODOM_SAMPLE_M);
        let mut last: Option<(f64, f64)> = None;
        for i in 0..rec.t.len() {
            let (Some(x), Some(y)) = (rec.x[i], rec.y[i]) else {
                continue;
            };
            if let Some((lx, ly)) = last {
                travel += (x - lx).hypot(y - ly);
            }
            last = Some((x, y));
            if travel >= next {
                samples.push((rec.t[i], x, y));
                next += OPTIODOM_SAMPLE_M;
            }
        }
        Ok(OptiOdomRun { series, samples })
    }

    /// The position residuals (m) of `robot` dead-reckoning this run, x and y per sample.
    fn residuals(&self, robot: &Robot, out: &mut Vec<f64>) -> Option<()> {
        let poses = calibrate::dead_reckoned_poses(robot, &TurnLaw::default(), &self.series)?;
        let mut j = 0;
        for &(t, x, y) in &self.samples {
            while j + 1 < poses.len() && poses[j + 1].0 < t {
                j += 1;
            }
            let (a, b) = (poses[j], poses[(j + 1).min(poses.len() - 1)]);
            let f = if b.0 > a.0 {
                ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0)
            } else {
                0.0
            };
            out.push(a.1 + f * (b.1 - a.1) - x);
            out.push(a.2 + f * (b.2 - a.2) - y);
        }
        Some(())
    }
}

/// `nominal` with the left and right wheel radii and the separation scaled by `p`.
fn diff_with(nominal: &Robot, p: [f64; 3]) -> Robot {
    let mut r = nominal.clone();
    for w in r.wheels.iter_mut() {
        w.radius_m *= if w.is_left() { p[0] } else { p[1] };
        w.l_m *= p[2];
    }
    r
}

/// OptiOdom's fit of `nominal` (a differential drive) on `runs`: the robot with its
/// fitted diameters and separation.
pub fn optiodom_fit(nominal: &Robot, runs: &[OptiOdomRun]) -> Robot {
    let res = |p: [f64; 3]| {
        let r = diff_with(nominal, p);
        let mut out = Vec::new();
        for run in runs {
            run.residuals(&r, &mut out)?;
        }
        Some(out)
    };
    let cost = |v: &[f64]| v.iter().map(|e| e * e).sum::<f64>();
    let mut p = [1.0; 3];
    let Some(mut r0) = res(p) else {
        return nominal.clone();
    };
    let mut lambda = 1e-3;
    for _ in 0..50 {
        let h = 1e-6;
        let mut jac = [
            vec![0.0; r0.len()],
            vec![0.0; r0.len()],
            vec![0.0; r0.len()],
        ];
        for k in 0..3 {
            let mut q = p;
            q[k] += h;
            let Some(rk) = res(q) else {
                return diff_with(nominal, p);
            };
            for (j, (a, b)) in rk.iter().zip(&r0).enumerate() {
                jac[k][j] = (a - b) / h;
            }
        }
        let mut jtj = [[0.0; 3]; 3];
        let mut jtr = [0.0; 3];
        for a in 0..3 {
            for b in 0..3 {
                jtj[a][b] = jac[a].iter().zip(&jac[b]).map(|(x, y)| x * y).sum();
            }
            jtr[a] = jac[a].iter().zip(&r0).map(|(x, y)| x * y).sum();
        }
        let mut improved = false;
        for _ in 0..10 {
            let mut m = jtj;
            for (a, row) in m.iter_mut().enumerate() {
                row[a] *= 1.0 + lambda;
            }
            let Some(step) = solve3(m, jtr.map(|v| -v)) else {
                break;
            };
            let q = [p[0] + step[0], p[1] + step[1], p[2] + step[2]];
            if let Some(rq) = res(q).filter(|rq| cost(rq) < cost(&r0)) {
                let small = step.iter().all(|s| s.abs() < 1e-9);
                p = q;
                r0 = rq;
                lambda = (lambda / 10.0).max(1e-9);
                improved = !small;
                break;
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    diff_with(nominal, p)
}

/// `m x = b` for a 3x3 system (Cramer's rule), `None` when singular.
fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: [[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-300 || !d.is_finite() {
        return None;
    }
    let mut x = [0.0; 3];
    for (k, xk) in x.iter_mut().enumerate() {
        let mut mk = m;
        for r in 0..3 {
            mk[r][k] = b[r];
        }
        *xk = det(mk) / d;
    }
    Some(x)
}

/// One training set of issue 56's comparison: `calibrate`'s board (its factors and laws)
/// and the same calibration's constant geometry against OptiOdom's objective fitted on
/// the same runs, each dead-reckoning the runs not trained on; mean RMS, m.
#[derive(Debug, Clone, Serialize)]
pub struct AgainstOptiOdom {
    pub training: String,
    pub train_runs: usize,
    pub test_runs: usize,
    pub law: Option<(String, f64)>,
    pub board_m: f64,
    pub constant_m: f64,
    pub optiodom_m: f64,
}

/// Which runs a training set takes.
pub type Keep = Box<dyn Fn(&RunDir) -> bool>;

/// The 20 training sets of issue 56 §3 for the differential robot, as (name, keep):
/// each of the 8 square sessions, four circle sessions, six square + circle pairs,
/// December's squares, circles and Ivanjko paths, and all runs.
pub fn issue56_training_sets() -> Vec<(String, Keep)> {
    let mut out: Vec<(String, Keep)> = Vec::new();
    let sessions = |names: &[&'static str]| -> Keep {
        let names = names.to_vec();
        Box::new(move |r: &RunDir| names.contains(&r.session.as_str()))
    };
    for s in [
        "230620202042",
        "230620202144",
        "230620202258",
        "230620202317",
        "231220200029",
        "231220200040",
        "231220200045",
        "231220200048",
        "231220200121",
        "231220200134",
        "250620202104",
        "250620202251",
    ] {
        out.push((s.to_string(), sessions(&[s])));
    }
    for (a, b) in [
        ("231220200029", "231220200121"),
        ("231220200040", "231220200134"),
        ("231220200045", "231220200121"),
        ("231220200048", "231220200134"),
        ("230620202042", "250620202104"),
        ("230620202317", "250620202251"),
    ] {
        out.push((format!("{a} + {b}"), sessions(&[a, b])));
    }
    out.push((
        "December (squares, circles, Ivanjko)".into(),
        Box::new(|r: &RunDir| r.session.get(2..4) == Some("12")),
    ));
    out.push(("all runs".into(), Box::new(|_: &RunDir| true)));
    out
}

/// `calibrate` and OptiOdom's objective trained on the differential robot's runs that
/// `train` accepts, judged on the runs `test` accepts.
pub fn against_optiodom(
    dir: &Path,
    training: &str,
    train: &dyn Fn(&RunDir) -> bool,
    test: &dyn Fn(&RunDir) -> bool,
) -> Result<AgainstOptiOdom, String> {
    let (k, _) = kept_apart(dir, training, "the rest", train, test)?;
    let (robot, recs) = robot_runs(dir, "diff", train)?;
    let (_, held) = robot_runs(dir, "diff", test)?;
    let runs = recs
        .iter()
        .map(|(n, r)| OptiOdomRun::new(n, &robot, r))
        .collect::<Result<Vec<_>, _>>()?;
    let opti = optiodom_fit(&robot, &runs);
    let mut o = 0.0;
    for (name, rec) in &held {
        let s = Series::new(name, &robot, rec).map_err(|e| e.to_string())?;
        o += dead_reckoning_rmse(&opti, &s).ok_or(format!("{name}: no path"))?;
    }
    Ok(AgainstOptiOdom {
        training: k.training,
        train_runs: k.train_runs,
        test_runs: k.test_runs,
        law: k.law,
        board_m: k.board_m,
        constant_m: k.constant_m,
        optiodom_m: o / held.len().max(1) as f64,
    })
}
