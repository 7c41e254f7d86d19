//! A calibration as `wheelcal calibrate` saves it (its `--json` output, or the
//! `calibration.json` of a `--report` folder), read back by the commands that reuse it:
//! `calibrate --laws-from` takes its laws, `evaluate --board` the factors a board gets.
//! Refused, naming the file: unreadable, not JSON (with its line and column), a
//! calibration of another kind of robot, or without the numbers asked for.

use anyhow::{anyhow, bail, Context, Result};
use calib_core::correction::{Corrections, DiffLaws};
use calib_core::robot::{Robot, RobotKind};
use calibrate::{BoardFactors, Candidate};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Options that take a saved calibration say so in their errors.
const TAKES: &str = "takes calibrate's --json output or a --report folder";

/// A saved calibration, checked to be of `robot`'s kind.
pub struct SavedCalibration {
    /// The JSON file read.
    pub file: PathBuf,
    /// The option that named it, for the errors.
    flag: &'static str,
    json: Value,
}

/// The laws a saved calibration kept (a zero is a law it did not keep: `None`).
#[derive(Debug)]
pub struct KnownLaws {
    /// The turn law, eb_arc / eb.
    pub turn: Option<f64>,
    /// The speed law, per m/s.
    pub speed: Option<f64>,
    /// Where they came from and what each is, for the report's notes.
    pub note: String,
}

impl SavedCalibration {
    /// Reads `path` (a JSON file, or a folder holding `calibration.json`) for option
    /// `flag`, and checks it calibrated a robot of `robot`'s kind.
    pub fn read(path: &Path, robot: &Robot, flag: &'static str) -> Result<SavedCalibration> {
        let file = if path.is_dir() {
            path.join("calibration.json")
        } else {
            path.to_path_buf()
        };
        let text = crate::input::read_text(
            &file,
            crate::input::MAX_CALIBRATION_BYTES,
            "calibration JSON",
        )
        .with_context(|| flag.to_string())?;
        Self::parse(&text, file, robot, flag)
    }

    /// [`SavedCalibration::read`] of `text`, read from `file`.
    fn parse(
        text: &str,
        file: PathBuf,
        robot: &Robot,
        flag: &'static str,
    ) -> Result<SavedCalibration> {
        let shown = file.display();
        let json: Value = serde_json::from_str(text).map_err(|e| {
            anyhow!(
                "{shown}:{}:{}: not a calibration's JSON ({flag} {TAKES}): {e}",
                e.line(),
                e.column()
            )
        })?;
        // `umbmark compute`'s result (a differential drive's, without a kind) carries the
        // circle test's law.
        let kind = match json["kind"].as_str() {
            None if is_umbmark(&json) => "diff_drive",
            None if is_omni_compute(&json) => "omni",
            k => k.unwrap_or("unknown"),
        };
        if kind != robot.kind.as_str() {
            bail!(
                "{shown}: a calibration of a robot of kind {kind} ('{}'); --robot '{}' is of kind {}: {flag} takes a calibration of the same kind of robot",
                json["robot"].as_str().unwrap_or("?"),
                robot.name,
                robot.kind.as_str()
            );
        }
        Ok(SavedCalibration { file, flag, json })
    }

    /// The calibrated robot's name as the calibration gives it.
    pub fn robot_name(&self) -> &str {
        self.json["robot"].as_str().unwrap_or("?")
    }

    /// `apply --board-robot`: refuses a board robot (`robot`, read from `file`) that is
    /// not this calibration's robot, naming both files and what differs: another robot's
    /// name, other wheels, or a wheel's radius, distance or mounting angle outside the
    /// calibration's plausible range around the geometry it fitted (its `geometry`;
    /// for a calibration that carries none, around `board`, the robot the board holds,
    /// whose name the calibration's must already be). The range of each quantity is
    /// its fitted parameters' (`params[].plausible`: a diff drive's radius `scale` and
    /// `ed` together, ±8 %; its `eb`, ±8 %), or the catalogue's when none was fitted
    /// (radius ±5 %, distance ±8 %, angle ±3 degrees).
    pub fn check_board_robot(&self, robot: &Robot, file: &Path, board: &Robot) -> Result<()> {
        let (shown, cal) = (file.display(), self.file.display());
        if robot.name.as_str() != self.robot_name() {
            bail!(
                "{shown}: robot '{}'; {cal} is a calibration of robot '{}': --board-robot takes the calibrated robot's board robot (`calibrate --write-board-robot`); nothing was sent",
                robot.name,
                self.robot_name()
            );
        }
        // (name, radius_m, l_m, alpha_rad) of the reference geometry.
        let (reference, what): (Vec<(String, f64, f64, f64)>, String) =
            match self.json["geometry"].as_array() {
                Some(ws) => (
                    ws.iter()
                        .map(|w| {
                            (
                                w["name"].as_str().unwrap_or("?").to_string(),
                                w["radius_m"].as_f64().unwrap_or(f64::NAN),
                                w["l_m"].as_f64().unwrap_or(f64::NAN),
                                w["alpha_deg"].as_f64().unwrap_or(f64::NAN).to_radians(),
                            )
                        })
                        .collect(),
                    format!("that {cal} fitted"),
                ),
                None => (
                    board
                        .wheels
                        .iter()
                        .map(|w| (w.name.to_string(), w.radius_m, w.l_m, w.alpha_rad))
                        .collect(),
                    format!("of the board's robot ({cal} carries no geometry)"),
                ),
            };
        let names: Vec<&str> = robot.wheels.iter().map(|w| w.name.as_str()).collect();
        let want: Vec<&str> = reference.iter().map(|w| w.0.as_str()).collect();
        if names != want {
            bail!(
                "{shown}: wheels {}; the robot {what} has wheels {}: not the calibrated robot; nothing was sent",
                names.join(", "),
                want.join(", ")
            );
        }
        let (radius, distance, angle) = self.plausible_spans();
        for (w, (name, r, l, alpha)) in robot.wheels.iter().zip(&reference) {
            let off = |got: f64, of: f64| (got / of - 1.0).abs();
            let rel = [
                ("radius_m", w.radius_m, *r, radius),
                ("l_m", w.l_m, *l, distance),
            ];
            for (q, got, of, span) in rel {
                if off(got, of).is_nan() || off(got, of) > span {
                    bail!(
                        "{shown}: wheel '{name}' {q} = {got} m is {:.1} % from the {of:.5} m {what}, outside the calibration's plausible ±{:.1} %: not the calibrated robot's geometry; nothing was sent",
                        off(got, of) * 100.0,
                        span * 100.0
                    );
                }
            }
            let turned = (w.alpha_rad - alpha + std::f64::consts::PI)
                .rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            if turned.is_nan() || turned.abs() > angle {
                bail!(
                    "{shown}: wheel '{name}' alpha = {:.3} degrees is {:.3} degrees from the {:.3} degrees {what}, outside the calibration's plausible ±{:.1} degrees: not the calibrated robot's geometry; nothing was sent",
                    w.alpha_rad.to_degrees(),
                    turned.abs().to_degrees(),
                    alpha.to_degrees(),
                    angle.to_degrees()
                );
            }
        }
        Ok(())
    }

    /// The relative half-widths of a wheel's radius and distance and the half-width
    /// (rad) of its mounting angle that this calibration's fitted parameters allow:
    /// radius parameters of different effects add (a diff drive's `scale` and `ed`),
    /// the widest of one effect counts (per-wheel `radius_scale_w*`); the catalogue's
    /// range where none was fitted.
    fn plausible_spans(&self) -> (f64, f64, f64) {
        use calibrate::{ALPHA_RANGE, BASE_RANGE, RADIUS_RANGE};
        let mut by_effect: std::collections::BTreeMap<String, f64> = Default::default();
        let (mut distance, mut angle) = (0.0f64, 0.0f64);
        for p in self.json["params"].as_array().into_iter().flatten() {
            let (Some(lo), Some(hi)) = (p["plausible"][0].as_f64(), p["plausible"][1].as_f64())
            else {
                continue;
            };
            let half = (hi - lo).abs() / 2.0;
            let name = p["name"].as_str().unwrap_or("");
            let effect = p["effect"].as_str().unwrap_or("").to_string();
            if name == "scale" || name == "ed" || name.starts_with("radius_scale") {
                let e = by_effect.entry(effect).or_default();
                *e = e.max(half);
            } else if name == "eb" || name.starts_with("l_scale") {
                distance = distance.max(half);
            } else if name.starts_with("alpha_offset") {
                angle = angle.max(half);
            }
        }
        let radius: f64 = by_effect.values().sum();
        let or = |v: f64, d: f64| if v > 0.0 && v.is_finite() { v } else { d };
        (
            or(radius, RADIUS_RANGE),
            or(distance, BASE_RANGE),
            or(angle, ALPHA_RANGE),
        )
    }

    /// The turn and speed laws it kept, with a note saying so.
    pub fn laws(&self) -> Result<KnownLaws> {
        if is_umbmark(&self.json) {
            return self.circle_test_law();
        }
        if is_omni_compute(&self.json) {
            let l_arc = self.json["l_arc"].as_f64().unwrap_or(0.0);
            return Ok(KnownLaws {
                turn: (l_arc != 0.0).then_some(l_arc),
                speed: None,
                note: format!(
                    "turn law from the omni circle test of {} (omni compute, robot '{}'): {}",
                    self.file.display(),
                    self.robot_name(),
                    if l_arc == 0.0 {
                        "none kept there, tested here".to_string()
                    } else {
                        format!("l_arc {l_arc:+.5}, held")
                    }
                ),
            });
        }
        let law = |k: &str| self.json["turn_law"][k].as_f64();
        let (Some(arc), Some(speed)) = (law("arc_rel"), law("speed_rel")) else {
            bail!(
                "{}: no turn_law.arc_rel and turn_law.speed_rel numbers: {} {TAKES}",
                self.file.display(),
                self.flag
            );
        };
        let said = |v: f64, unit: &str| {
            if v == 0.0 {
                "not kept there, tested here".to_string()
            } else {
                format!("{v:+}{unit}, held")
            }
        };
        let omni = self.json["kind"].as_str() == Some("omni");
        Ok(KnownLaws {
            turn: (arc != 0.0).then_some(arc),
            speed: (speed != 0.0).then_some(speed),
            note: if omni {
                format!(
                    "laws from {} (robot '{}'): turn law l_arc {}",
                    self.file.display(),
                    self.robot_name(),
                    said(arc, "")
                )
            } else {
                format!(
                    "laws from {} (robot '{}'): turn law eb_arc / eb {}; speed law {}",
                    self.file.display(),
                    self.robot_name(),
                    said(arc, ""),
                    said(speed, " per m/s")
                )
            },
        })
    }

    /// The law of `umbmark compute`'s circle test (no speed law: circles at one speed
    /// cannot show one).
    fn circle_test_law(&self) -> Result<KnownLaws> {
        let c = &self.json["circles"];
        let (Some(k), Some(sigma), Some(kept)) = (
            c["e_b_arc"].as_f64(),
            c["e_b_arc_sigma"].as_f64(),
            c["kept"].as_bool(),
        ) else {
            bail!(
                "{}: a UMBmark result without circles, so without a law: {} takes calibrate's --json output, or umbmark compute's with circle rows (umbmark run --circle-radius)",
                self.file.display(),
                self.flag
            );
        };
        let what = if kept {
            format!("e_b_arc {k:+.5} ± {sigma:.5}, held")
        } else {
            format!("not kept there ({k:+.5} ± {sigma:.5}), tested here")
        };
        Ok(KnownLaws {
            turn: kept.then_some(k),
            speed: None,
            note: format!(
                "turn law from the circle test of {} (umbmark compute, robot '{}'): {what}; speed law tested here",
                self.file.display(),
                self.robot_name()
            ),
        })
    }

    /// Whether `robot` has the calibration's fitted geometry (every wheel's radius,
    /// distance, mounting and roller angle, as its JSON's `geometry` gives them, to 1e-9
    /// relative): the robot file it wrote, not the one it was fitted from.
    fn is_fitted_robot(&self, robot: &Robot) -> bool {
        let Some(g) = self.json["geometry"].as_array() else {
            return false;
        };
        let close = |a: f64, b: Option<f64>| {
            b.is_some_and(|b| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-3))
        };
        g.len() == robot.wheels.len()
            && robot.wheels.iter().zip(g).all(|(w, j)| {
                j["name"].as_str() == Some(w.name.as_str())
                    && close(w.radius_m, j["radius_m"].as_f64())
                    && close(w.l_m, j["l_m"].as_f64())
                    && close(w.alpha_rad.to_degrees(), j["alpha_deg"].as_f64())
                    && close(w.gamma_rad.to_degrees(), j["gamma_deg"].as_f64())
            })
    }

    /// The fitted parameters no board factor carries (an omni robot's factors are its
    /// wheels' sizes, f_lat and f_lon, and its turn law, l_arc; wheel distances, angles,
    /// the centre and the roller angle need the robot file). None on a differential drive, whose every parameter
    /// has a factor or a law.
    pub fn without_factor(&self) -> Vec<String> {
        if is_omni_compute(&self.json) {
            // The circle test's wheel distance goes in the board robot only.
            return match self.json["circles"]["wheel_distance_scale"].as_f64() {
                Some(_) => vec!["wheel_distance_scale".into()],
                None => Vec::new(),
            };
        }
        if self.json["factors"].get("f_lat").is_none() {
            return Vec::new();
        }
        self.json["params"]
            .as_array()
            .into_iter()
            .flatten()
            .filter_map(|p| p["name"].as_str())
            .filter(|n| *n != "scale" && *n != "l_arc" && !n.starts_with("radius_scale"))
            .map(str::to_string)
            .collect()
    }

    /// The geometry a board holding `board` takes from this calibration when its factors
    /// cannot carry what was fitted ([`SavedCalibration::without_factor`] not empty: an
    /// omni robot's wheel distances, mounting angles, centre or roller angle): `board`
    /// with each wheel's radius, distance, angles and roller angle from the JSON's
    /// `board_geometry` (the geometry of `calibrate --write-board-robot`; `geometry` in
    /// calibrations written before it, when they kept no law). `None` when the factors
    /// carry everything, and for results that carry no geometry (`omni compute`'s, and
    /// older calibrations with a law: those go without, as the notes say). Refused,
    /// naming the file, when the wheels are not `board`'s.
    pub fn board_geometry(&self, board: &Robot) -> Result<Option<Robot>> {
        if self.without_factor().is_empty() || is_omni_compute(&self.json) {
            return Ok(None);
        }
        let shown = self.file.display();
        let law = self.json["factors"]["l_arc"].as_f64().unwrap_or(0.0) != 0.0;
        let wheels = match (
            self.json["board_geometry"].as_array(),
            self.json["geometry"].as_array(),
        ) {
            (Some(w), _) => w,
            (None, Some(w)) if !law => w,
            _ => return Ok(None),
        };
        let names: Vec<&str> = wheels
            .iter()
            .map(|w| w["name"].as_str().unwrap_or("?"))
            .collect();
        let want: Vec<&str> = board.wheels.iter().map(|w| w.name.as_str()).collect();
        if names != want {
            bail!(
                "{shown}: a geometry of wheels {}; the board's robot has wheels {}: not the calibrated robot",
                names.join(", "),
                want.join(", ")
            );
        }
        let mut robot = board.clone();
        for (w, j) in robot.wheels.iter_mut().zip(wheels) {
            let num = |k: &str| {
                j[k].as_f64().filter(|v| v.is_finite()).ok_or_else(|| {
                    anyhow!(
                        "{shown}: board_geometry: wheel '{}' has no number {k}",
                        w.name
                    )
                })
            };
            w.radius_m = num("radius_m")?;
            w.l_m = num("l_m")?;
            w.alpha_rad = num("alpha_deg")?.to_radians();
            // Calibrations written before `beta_deg` never moved it.
            if j.get("beta_deg").is_some() {
                w.beta_rad = num("beta_deg")?.to_radians();
            }
            w.gamma_rad = num("gamma_deg")?.to_radians();
        }
        Ok(Some(robot))
    }

    /// The factors a board gets from it (`factors set` in full): a differential drive's
    /// with every law kept (the board's E_b is that of a turn in place, its c_L and c_R
    /// at standstill), an omni robot's f_lat and f_lon (and its turn law l_arc).
    pub fn board_corrections(&self) -> Result<Corrections> {
        // `omni compute` gives its factors (and a circle test's law) at the top.
        let f = if is_omni_compute(&self.json) {
            &self.json
        } else {
            &self.json["factors"]
        };
        let shown = self.file.display();
        let missing =
            |what: &str| anyhow!("{shown}: no factors.{what} numbers: {} {TAKES}", self.flag);
        if f.get("f_lat").is_some() {
            let hint = format!(": {} {TAKES}", self.flag);
            return super::omni::corrections_from_value(f, &shown, &hint);
        }
        if let Some(b) = f.get("board") {
            let b: BoardFactors = serde_json::from_value(b.clone())
                .map_err(|e| anyhow!("{shown}: factors.board: {e}"))?;
            return Ok(b.corrections());
        }
        // `umbmark compute` gives its factors at the top, E_b as `eb`.
        let (top, e_b_key) = if is_umbmark(&self.json) {
            (&self.json, "eb")
        } else {
            (f, "e_b")
        };
        let num = |k: &str| top[k].as_f64().ok_or_else(|| missing("c_l, c_r and e_b"));
        let (c_l, c_r, e_b) = (num("c_l")?, num("c_r")?, num(e_b_key)?);
        Ok(Corrections::diff_drive(c_l, c_r, e_b, DiffLaws::default()))
    }

    /// The factors of a board holding this calibration's board robot
    /// (`calibrate --write-board-robot`, with `n` wheels): ones, and the laws it kept.
    pub fn law_corrections(&self, n: usize) -> Result<Corrections> {
        Ok(self.board_corrections()?.laws_only(n))
    }

    /// The factors a board holding `robot` gets ([`SavedCalibration::board_corrections`]);
    /// refused when `robot` is this calibration's fitted geometry (the robot file it
    /// wrote) and the factors change the geometry: they correct the robot they were
    /// fitted from, so they would count twice.
    pub fn factors_for(&self, robot: &Robot) -> Result<Corrections> {
        let factors = self.board_corrections()?;
        if self.is_fitted_robot(robot) && !self.is_fitted_robot(&factors.apply_to(robot)) {
            bail!(
                "{}: the robot has this calibration's fitted geometry (the robot file it wrote), and its factors would count twice",
                self.file.display()
            );
        }
        Ok(factors)
    }

    /// `evaluate --board --board-robot`: the board holding the robot geometry `geometry`
    /// (the file `file`, given with `wheelcal robot set`) with factors of one and this
    /// calibration's laws. Refused, naming the files, when the board would refuse them.
    pub fn laws_candidate(&self, geometry: &Robot, file: &Path) -> Result<Candidate> {
        let laws = self.law_corrections(geometry.wheels.len())?;
        let board = Candidate::board(
            format!(
                "{} on the board holding {}",
                self.file.display(),
                file.display()
            ),
            geometry.clone(),
            laws,
        );
        board
            .check()
            .map_err(|e| anyhow!("{e} (--board-robot {})", file.display()))?;
        Ok(board)
    }

    /// `evaluate --board`: the board holding its factors for `robot` (the file at
    /// `robot_path`), labelled with what no factor carries. Refused, naming the files:
    /// factors the board itself refuses for `robot`, and a `robot` that is the fitted
    /// robot file this calibration wrote when the factors change the geometry (they
    /// correct the robot they were fitted from, so they would count twice).
    pub fn board_candidate(&self, robot: &Robot, robot_path: &Path) -> Result<Candidate> {
        if let Some(geometry) = self
            .board_geometry(robot)
            .map_err(|e| anyhow!("{e} (--robot {})", robot_path.display()))?
        {
            let laws = self.law_corrections(geometry.wheels.len())?;
            let board = Candidate::board(
                format!(
                    "{} on the board holding its fitted geometry (no firmware factor carries {}: apply puts the geometry there)",
                    self.file.display(),
                    self.without_factor().join(", ")
                ),
                geometry,
                laws,
            );
            board
                .check()
                .map_err(|e| anyhow!("{e} (--robot {})", robot_path.display()))?;
            return Ok(board);
        }
        let factors = self.factors_for(robot).map_err(|e| {
            anyhow!(
                "{e}: --board applies the calibration's factors to the robot it was fitted from; give that robot (the nominal) as --robot {}, and the fitted file as --against",
                robot_path.display()
            )
        })?;
        let lost = self.without_factor();
        let lost = if lost.is_empty() {
            String::new()
        } else {
            format!(
                " (no firmware factor for {}: the board's odometry goes without)",
                lost.join(", ")
            )
        };
        let board = Candidate::board(
            format!("{} on the board{lost}", self.file.display()),
            robot.clone(),
            factors,
        );
        board
            .check()
            .map_err(|e| anyhow!("{e} (--robot {})", robot_path.display()))?;
        Ok(board)
    }
}

/// Whether `json` is `umbmark compute`'s result.
/// `omni compute`'s result: its factors at the top, beside the idle-wheel mode.
fn is_omni_compute(json: &Value) -> bool {
    json["kind"].is_null() && json["f_lat"].is_array() && json["idle_wheels"].is_string()
}

fn is_umbmark(json: &Value) -> bool {
    json["recommended"].as_str() == Some("exact") && json["exact"].is_object()
}

/// `--laws-from`: known turn and speed laws are a differential drive's; an omni robot has
/// a turn law (l_arc) too.
pub fn laws_from(path: &Path, robot: &Robot) -> Result<KnownLaws> {
    if !matches!(robot.kind, RobotKind::DiffDrive | RobotKind::Omni) {
        bail!(
            "--laws-from: known laws are for differential drives and omni robots; --robot '{}' is of kind {} (a skid-steer robot's turn law is fitted from its recordings)",
            robot.name,
            robot.kind.as_str()
        );
    }
    SavedCalibration::read(path, robot, "--laws-from")?.laws()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mobolab() -> Robot {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/mobolab.toml");
        formats::robot_file::load(&p).unwrap()
    }

    /// A differential drive's calibration with a turn law, as calibrate writes its JSON
    /// (the fields these readers take).
    const GOOD: &str = r#"{"robot": "mobolab", "kind": "diff_drive",
 "factors": {"c_l": 1.01, "c_r": 0.99, "e_b": 1.0225,
  "board": {"c_l": 1.01, "c_r": 0.99, "e_b": 1.02, "e_b_arc": 0.005, "speed_rel": 0.0, "accel_slip_s": 0.0}},
 "turn_law": {"arc_rel": 0.005, "icr_x_m": 0.0, "speed_rel": 0.0, "accel_slip_s": 0.0},
 "geometry": [{"name": "left", "radius_m": 0.0505, "l_m": 0.204, "alpha_deg": 90.0, "gamma_deg": 0.0},
  {"name": "right", "radius_m": 0.0495, "l_m": 0.204, "alpha_deg": -90.0, "gamma_deg": 0.0}]}"#;

    fn parse(text: &str) -> Result<SavedCalibration> {
        SavedCalibration::parse(text, PathBuf::from("cal.json"), &mobolab(), "--board")
    }

    /// The board gets E_b of a turn in place and the law, exactly as written; the laws
    /// read back as kept (turn) and not kept (speed); nominal mobolab is not the robot
    /// file it wrote.
    #[test]
    fn a_calibration_gives_the_board_its_factors_and_laws() {
        let s = parse(GOOD).unwrap();
        assert_eq!(
            s.board_corrections().unwrap(),
            Corrections::DiffDriveTurnLaw {
                c_l: 1.01,
                c_r: 0.99,
                e_b: 1.02,
                e_b_arc: 0.005
            }
        );
        let l = s.laws().unwrap();
        assert_eq!((l.turn, l.speed), (Some(0.005), None));
        assert!(!s.is_fitted_robot(&mobolab()));
        assert!(s.without_factor().is_empty());
    }

    /// `umbmark compute`'s result: its circle test's law is held when kept, tested when
    /// not; without circles it has no law to give. A board judged with it (`evaluate
    /// --board`) gets UMBmark's factors, and the law when the circle test kept one.
    #[test]
    fn an_umbmark_results_circle_test_gives_its_law() {
        let laws = |circles: &str| {
            let text = format!(
                r#"{{"robot": "mobolab", "recommended": "exact", "exact": {{"eb": 1.02}},
                "c_l": 1.0, "c_r": 1.0, "eb": 1.02, "circles": {circles}}}"#
            );
            SavedCalibration::parse(&text, PathBuf::from("umb.json"), &mobolab(), "--laws-from")
                .unwrap()
                .laws()
        };
        let l = laws(r#"{"e_b_arc": 0.0064, "e_b_arc_sigma": 0.0003, "kept": true}"#).unwrap();
        assert_eq!((l.turn, l.speed), (Some(0.0064), None));
        assert!(l.note.contains("circle test of umb.json"), "{}", l.note);
        let l = laws(r#"{"e_b_arc": 0.0002, "e_b_arc_sigma": 0.0003, "kept": false}"#).unwrap();
        assert_eq!(l.turn, None);
        let board = |extra: &str| {
            let text = format!(
                r#"{{"robot": "mobolab", "recommended": "exact", "exact": {{"eb": 1.02}},
                "c_l": 1.001, "c_r": 0.999, "eb": 1.02, "circles": null{extra}}}"#
            );
            SavedCalibration::parse(&text, PathBuf::from("umb.json"), &mobolab(), "--board")
                .unwrap()
                .board_corrections()
                .unwrap()
        };
        assert_eq!(
            board(""),
            Corrections::DiffDrive {
                c_l: 1.001,
                c_r: 0.999,
                e_b: 1.02
            }
        );
        let with_law = r#", "factors": {"board": {"c_l": 1.001, "c_r": 0.999, "e_b": 1.02,
            "e_b_arc": 0.0064, "speed_rel": 0.0, "accel_slip_s": 0.0}}"#;
        assert_eq!(board(with_law).laws().e_b_arc, 0.0064);
        let e = laws("null").unwrap_err().to_string();
        assert!(
            e.starts_with("umb.json: a UMBmark result without circles"),
            "{e}"
        );
    }

    /// An omni calibration's wheel distance and centre have no board factor; its radii do.
    #[test]
    fn an_omni_calibrations_distances_and_centre_are_named_as_without_a_factor() {
        let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/omni3.toml");
        let omni = formats::robot_file::load(&p).unwrap();
        let text = r#"{"robot": "omni3", "kind": "omni",
            "factors": {"f_lat": [1.02, 1.04, 1.03], "f_lon": 1.0},
            "params": [{"name": "radius_scale_w1"}, {"name": "radius_scale_w2"},
              {"name": "radius_scale_w3"}, {"name": "l_scale"}, {"name": "centre_x_m"}]}"#;
        let s = SavedCalibration::parse(text, PathBuf::from("o.json"), &omni, "--board").unwrap();
        assert_eq!(s.without_factor(), ["l_scale", "centre_x_m"]);
        match s.board_corrections().unwrap() {
            Corrections::Omni { f_lat, f_lon } => {
                assert_eq!((f_lat.as_slice(), f_lon), (&[1.02, 1.04, 1.03][..], 1.0))
            }
            c => panic!("{c:?}"),
        }
        // With a turn law: the board gets it too, so it is not named as without a factor,
        // and `--laws-from` holds it (an omni robot has no speed law).
        let text = r#"{"robot": "omni3", "kind": "omni",
            "factors": {"f_lat": [1.02, 1.04, 1.03], "f_lon": 1.0, "l_arc": 0.019},
            "turn_law": {"arc_rel": 0.019, "icr_x_m": 0.0, "speed_rel": 0.0, "accel_slip_s": 0.0},
            "params": [{"name": "scale"}, {"name": "l_scale"}, {"name": "l_arc"}]}"#;
        let s = SavedCalibration::parse(text, PathBuf::from("o.json"), &omni, "--board").unwrap();
        assert_eq!(s.without_factor(), ["l_scale"]);
        let l = s.laws().unwrap();
        assert_eq!((l.turn, l.speed), (Some(0.019), None));
        assert!(l.note.contains("turn law l_arc +0.019, held"), "{}", l.note);
        let c = s.board_corrections().unwrap();
        assert!(
            matches!(c, Corrections::OmniTurnLaw { l_arc, .. } if l_arc == 0.019),
            "{c:?}"
        );
    }

    /// Every prefix of a good file and every byte of it replaced by each of a few bytes
    /// JSON cares about: nothing panics, and every error names the file (3,928 cases).
    #[test]
    fn truncated_or_mangled_calibrations_are_refused_by_name_never_a_panic() {
        let check = |text: &str| {
            let errors: Vec<anyhow::Error> = match parse(text) {
                Err(e) => vec![e],
                Ok(s) => [s.board_corrections().err(), s.laws().err()]
                    .into_iter()
                    .flatten()
                    .collect(),
            };
            for e in errors {
                assert!(format!("{e:#}").contains("cal.json"), "{e:#} for {text}");
            }
        };
        let bytes = GOOD.as_bytes();
        let mut cases = 0;
        for n in 0..bytes.len() {
            check(&String::from_utf8_lossy(&bytes[..n]));
            for b in [b'"', b'}', b']', b'9', b'-', b'x', b' '] {
                let mut m = bytes.to_vec();
                m[n] = b;
                check(&String::from_utf8_lossy(&m));
                cases += 1;
            }
            cases += 1;
        }
        assert_eq!(cases, 8 * bytes.len());
    }
}
