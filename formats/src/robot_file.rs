//! Robot description files (docs/formats.md §1, TOML) on the host.
//!
//! Every error names the file, the line and column, and the field: a person edits these
//! by hand, so "wheel 2 ('right'): radius_m must be positive, got -0.05" at the right line
//! is the whole point.

use calib_core::robot::{
    Drive, DriveType, Legs, Problem, Robot, RobotError, RobotKind, Wheel, WheelName, MAX_WHEELS,
};
use serde::Deserialize;
use std::fmt;
use std::path::{Path, PathBuf};
use toml::Spanned;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RobotFile {
    name: Spanned<String>,
    kind: Spanned<String>,
    drive: Spanned<DriveFile>,
    wheels: Spanned<Vec<Spanned<WheelFile>>>,
    legs: Option<Spanned<LegsFile>>,
    /// Extension to docs/formats.md §1 (optional, see §5): how the calibration procedures
    /// run.
    procedure: Option<Spanned<ProcedureFile>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ProcedureFile {
    idle_wheels: Option<Spanned<String>>,
}

/// The robot file's optional `[procedure]` table (an extension to docs/formats.md §1, see
/// §5, which other tools may ignore): how the calibration procedures drive this robot.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Procedure {
    /// `idle_wheels = "held" | "released"`: what the wheels an omni path does not drive
    /// do (see `calib_core::omni_cal::IdleWheels`).
    pub idle_wheels: Option<calib_core::omni_cal::IdleWheels>,
}

/// Reads the `[procedure]` table of a robot file (the whole file is validated too).
pub fn load_procedure(path: &Path) -> Result<Procedure, RobotFileError> {
    let text = read(path)?;
    parse(&text, path)?;
    parse_procedure(&text, path)
}

/// The `[procedure]` table of robot TOML; `path` is only used in messages.
pub fn parse_procedure(text: &str, path: &Path) -> Result<Procedure, RobotFileError> {
    let file: RobotFile = toml::from_str(text).map_err(|e| {
        let (line, column) = e.span().map_or((None, None), |s| {
            let (l, c) = line_col(text, s.start);
            (Some(l), Some(c))
        });
        RobotFileError {
            path: path.to_path_buf(),
            line,
            column,
            message: e.message().trim().to_string(),
        }
    })?;
    let Some(idle) = file.procedure.and_then(|p| p.into_inner().idle_wheels) else {
        return Ok(Procedure::default());
    };
    let idle_wheels = match idle.get_ref().as_str() {
        "held" => calib_core::omni_cal::IdleWheels::Held,
        "released" => calib_core::omni_cal::IdleWheels::Released,
        other => {
            let (l, c) = line_col(text, idle.span().start);
            return Err(RobotFileError {
                path: path.to_path_buf(),
                line: Some(l),
                column: Some(c),
                message: format!(
                    "procedure.idle_wheels: \"{other}\" (expected \"held\" or \"released\")"
                ),
            });
        }
    };
    Ok(Procedure {
        idle_wheels: Some(idle_wheels),
    })
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct DriveFile {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    steps_per_rev: Option<Spanned<u32>>,
    microsteps: Option<Spanned<u32>>,
    gear_ratio: Option<Spanned<f64>>,
    encoder_counts_per_rev: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct WheelFile {
    name: Spanned<String>,
    radius_m: Spanned<f64>,
    alpha_deg: Spanned<f64>,
    l_m: Spanned<f64>,
    #[serde(default)]
    beta_deg: Option<Spanned<f64>>,
    #[serde(default)]
    gamma_deg: Option<Spanned<f64>>,
    #[serde(default)]
    driven: Option<bool>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LegsFile {
    length_m: f64,
    body_length_m: f64,
    body_mass_kg: f64,
    leg_mass_kg: f64,
}

/// A robot file that could not be read: where and why.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotFileError {
    /// The file.
    pub path: PathBuf,
    /// 1-based line and column, when known.
    pub line: Option<usize>,
    /// 1-based column, when known.
    pub column: Option<usize>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for RobotFileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.path.display())?;
        if let (Some(l), Some(c)) = (self.line, self.column) {
            write!(f, ":{l}:{c}")?;
        }
        write!(f, ": {}", self.message)
    }
}

impl std::error::Error for RobotFileError {}

/// 1-based (line, column) of a byte offset.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let col = before.rfind('\n').map_or(offset, |p| offset - p - 1) + 1;
    (line, col)
}

/// Largest robot file read (bytes). A description of eight wheels with comments is a few
/// KB; a 200 MB file is a mistake (it took 30 s and 8.4 GB of memory to refuse).
pub const MAX_FILE_BYTES: u64 = 1 << 20;

/// Reads and validates a robot file.
pub fn load(path: &Path) -> Result<Robot, RobotFileError> {
    parse(&read(path)?, path)
}

/// A robot file's text, refused before reading when it is too large to be one.
fn read(path: &Path) -> Result<String, RobotFileError> {
    crate::text_file::read_capped(path, MAX_FILE_BYTES, "robot description").map_err(|e| {
        RobotFileError {
            path: path.to_path_buf(),
            line: None,
            column: None,
            message: e.0,
        }
    })
}

/// Parses and validates robot TOML; `path` is only used in messages.
pub fn parse(text: &str, path: &Path) -> Result<Robot, RobotFileError> {
    let at = |span: Option<core::ops::Range<usize>>, message: String| {
        let (line, column) = match span {
            Some(s) => {
                let (l, c) = line_col(text, s.start);
                (Some(l), Some(c))
            }
            None => (None, None),
        };
        RobotFileError {
            path: path.to_path_buf(),
            line,
            column,
            message,
        }
    };
    if text.len() as u64 > MAX_FILE_BYTES {
        return Err(at(
            None,
            format!(
                "{} bytes is not a robot description (at most {MAX_FILE_BYTES} bytes)",
                text.len()
            ),
        ));
    }
    // Refuse a ninth wheel before the TOML parser builds them all.
    if let Some((offset, _)) = text.match_indices("[[wheels]]").nth(MAX_WHEELS) {
        return Err(at(
            Some(offset..offset + 10),
            format!("more than {MAX_WHEELS} wheels (the firmware drives at most {MAX_WHEELS})"),
        ));
    }
    let file: RobotFile =
        toml::from_str(text).map_err(|e| at(e.span(), e.message().trim().to_string()))?;

    let kind = match file.kind.get_ref().as_str() {
        "diff_drive" => RobotKind::DiffDrive,
        "omni" => RobotKind::Omni,
        "wheeled_legged" => RobotKind::WheeledLegged,
        "skid_steer" => RobotKind::SkidSteer,
        other => {
            return Err(at(
                Some(file.kind.span()),
                format!(
                    "kind: unknown kind \"{other}\" (expected diff_drive, omni, wheeled_legged or skid_steer)"
                ),
            ))
        }
    };
    let d = file.drive.get_ref();
    let drive_kind = match d.kind.get_ref().as_str() {
        "stepper" => DriveType::Stepper,
        "dc" => DriveType::Dc,
        other => {
            return Err(at(
                Some(d.kind.span()),
                format!("drive.type: unknown drive \"{other}\" (expected stepper or dc)"),
            ))
        }
    };
    if drive_kind == DriveType::Stepper && d.steps_per_rev.is_none() {
        return Err(at(
            Some(file.drive.span()),
            "drive.steps_per_rev: required for a stepper drive".into(),
        ));
    }
    let drive = Drive {
        kind: drive_kind,
        steps_per_rev: d.steps_per_rev.as_ref().map_or(200, |v| *v.get_ref()),
        microsteps: d.microsteps.as_ref().map_or(1, |v| *v.get_ref()),
        gear_ratio: d.gear_ratio.as_ref().map_or(1.0, |v| *v.get_ref()),
        encoder_counts_per_rev: d
            .encoder_counts_per_rev
            .as_ref()
            .map_or(calib_core::robot::DEFAULT_COUNTS_PER_REV, |v| *v.get_ref()),
    };
    let mut wheels = Vec::new();
    for (i, w) in file.wheels.get_ref().iter().enumerate() {
        let w = w.get_ref();
        let mut name = WheelName::new();
        if name.push_str(w.name.get_ref()).is_err() {
            return Err(at(
                Some(w.name.span()),
                format!(
                    "wheel {} : name \"{}\" is longer than 16 characters",
                    i + 1,
                    w.name.get_ref()
                ),
            ));
        }
        wheels.push(Wheel {
            name,
            radius_m: *w.radius_m.get_ref(),
            alpha_rad: w.alpha_deg.get_ref().to_radians(),
            l_m: *w.l_m.get_ref(),
            beta_rad: w
                .beta_deg
                .as_ref()
                .map_or(0.0, |v| v.get_ref().to_radians()),
            gamma_rad: w
                .gamma_deg
                .as_ref()
                .map_or(0.0, |v| v.get_ref().to_radians()),
            driven: w.driven.unwrap_or(true),
        });
    }
    let legs = file.legs.as_ref().map(|l| {
        let l = l.get_ref();
        Legs {
            length_m: l.length_m,
            body_length_m: l.body_length_m,
            body_mass_kg: l.body_mass_kg,
            leg_mass_kg: l.leg_mass_kg,
        }
    });
    Robot::new(file.name.get_ref(), kind, drive, &wheels, legs).map_err(|e| {
        let span = span_of(&file, &e);
        at(span, e.to_string())
    })
}

/// Where in the file the field a validation error names was written.
fn span_of(file: &RobotFile, e: &RobotError) -> Option<core::ops::Range<usize>> {
    use calib_core::robot::Field::*;
    if let Some((i, _)) = &e.wheel {
        let w = file.wheels.get_ref().get(*i)?;
        let wf = w.get_ref();
        return Some(match e.field {
            Name => wf.name.span(),
            RadiusM => wf.radius_m.span(),
            AlphaDeg => wf.alpha_deg.span(),
            LM => wf.l_m.span(),
            BetaDeg => wf.beta_deg.as_ref().map_or(w.span(), |v| v.span()),
            GammaDeg => wf.gamma_deg.as_ref().map_or(w.span(), |v| v.span()),
            _ => w.span(),
        });
    }
    let d = file.drive.get_ref();
    Some(match e.field {
        StepsPerRev => d
            .steps_per_rev
            .as_ref()
            .map_or(file.drive.span(), |v| v.span()),
        Microsteps => d
            .microsteps
            .as_ref()
            .map_or(file.drive.span(), |v| v.span()),
        GearRatio => d
            .gear_ratio
            .as_ref()
            .map_or(file.drive.span(), |v| v.span()),
        EncoderCountsPerRev => d
            .encoder_counts_per_rev
            .as_ref()
            .map_or(file.drive.span(), |v| v.span()),
        Legs => file.legs.as_ref().map_or(file.kind.span(), |l| l.span()),
        Kind => file.kind.span(),
        _ if matches!(
            e.problem,
            Problem::SingularJacobian
                | Problem::TooFewWheels(_)
                | Problem::TooManyWheels(_)
                | Problem::WrongWheelCount { .. }
        ) =>
        {
            file.wheels.span()
        }
        _ => file.name.span(),
    })
}

/// Writes a robot description back as TOML (for `--write-robot` and the simulator's
/// recordings), in docs/formats.md §1 layout.
pub fn to_toml(robot: &Robot) -> String {
    use std::fmt::Write;
    let mut s = String::new();
    let _ = writeln!(s, "name = \"{}\"", robot.name);
    let _ = writeln!(s, "kind = \"{}\"", robot.kind.as_str());
    let _ = writeln!(s, "\n[drive]");
    let d = &robot.drive;
    match d.kind {
        DriveType::Stepper => {
            let _ = writeln!(
                s,
                "type = \"stepper\"\nsteps_per_rev = {}\nmicrosteps = {}",
                d.steps_per_rev, d.microsteps
            );
        }
        DriveType::Dc => {
            let _ = writeln!(s, "type = \"dc\"");
        }
    }
    let _ = writeln!(
        s,
        "gear_ratio = {:?}\nencoder_counts_per_rev = {:?}",
        d.gear_ratio, d.encoder_counts_per_rev
    );
    for w in &robot.wheels {
        let _ = writeln!(s, "\n[[wheels]]\nname = \"{}\"\nradius_m = {:?}\nalpha_deg = {:?}\nl_m = {:?}\nbeta_deg = {:?}\ngamma_deg = {:?}\ndriven = {}",
            w.name, w.radius_m, w.alpha_rad.to_degrees(), w.l_m, w.beta_rad.to_degrees(), w.gamma_rad.to_degrees(), w.driven);
    }
    if let Some(l) = &robot.legs {
        let _ = writeln!(s, "\n[legs]\nlength_m = {:?}\nbody_length_m = {:?}\nbody_mass_kg = {:?}\nleg_mass_kg = {:?}",
            l.length_m, l.body_length_m, l.body_mass_kg, l.leg_mass_kg);
    }
    s
}

/// Writes the robot description `text` (a robot file's TOML, comments allowed) to
/// `path` under `safe_write`'s rule: never an input, and an existing file only when it
/// is a robot description (or with `--force`).
pub fn write(path: &Path, text: &str) -> std::io::Result<()> {
    crate::safe_write::write_file(path, text.as_bytes(), "robot description", is_robot_file)
}

/// Accepts an existing robot description: what `safe_write` may replace with a fitted
/// robot.
pub fn is_robot_file(head: &[u8]) -> bool {
    std::str::from_utf8(head)
        .ok()
        .is_some_and(|t| parse(t, Path::new("")).is_ok())
}

#[cfg(test)]
mod tests {
    use super::*;

    const MOBOLAB: &str = r#"name = "mobolab"
kind = "diff_drive"

[drive]
type = "stepper"
steps_per_rev = 200
microsteps = 1
gear_ratio = 4.875
encoder_counts_per_rev = 1920

[[wheels]]
name = "left"
radius_m = 0.05
alpha_deg = 90.0
l_m = 0.2
beta_deg = 0.0

[[wheels]]
name = "right"
radius_m = 0.05
alpha_deg = -90.0
l_m = 0.2
beta_deg = 180.0
"#;

    #[test]
    fn parses_and_round_trips() {
        let r = parse(MOBOLAB, Path::new("mobolab.toml")).unwrap();
        assert_eq!(r.wheels.len(), 2);
        assert!((r.wheels[1].beta_rad - core::f64::consts::PI).abs() < 1e-15);
        assert!(
            (r.drive.steps_per_wheel_rad() - 200.0 * 4.875 / core::f64::consts::TAU).abs() < 1e-9
        );
        let again = parse(&to_toml(&r), Path::new("x")).unwrap();
        assert_eq!(again.wheels[1].radius_m, r.wheels[1].radius_m);
        assert!((again.wheels[1].alpha_rad - r.wheels[1].alpha_rad).abs() < 1e-15);
    }

    #[test]
    fn negative_radius_names_file_line_wheel_and_field() {
        let bad = MOBOLAB.replacen(
            "radius_m = 0.05\nalpha_deg = -90.0",
            "radius_m = -0.05\nalpha_deg = -90.0",
            1,
        );
        let e = parse(&bad, Path::new("robots/bad.toml")).unwrap_err();
        let text = e.to_string();
        assert_eq!(e.line, Some(20), "{text}");
        assert!(
            text.starts_with("robots/bad.toml:20:12: wheel 2 ('right'): radius_m"),
            "{text}"
        );
    }

    #[test]
    fn unknown_kind_and_syntax_errors_have_positions() {
        let bad = MOBOLAB.replace("diff_drive", "tank");
        let e = parse(&bad, Path::new("r.toml")).unwrap_err();
        assert_eq!((e.line, e.column), (Some(2), Some(8)));
        assert!(e.message.contains("unknown kind \"tank\""));
        let e = parse("name = \"x\"\nkind = = 3\n", Path::new("r.toml")).unwrap_err();
        assert_eq!(e.line, Some(2));
        let e = parse(
            &MOBOLAB.replace(
                "l_m = 0.2\nbeta_deg = 0.0",
                "l_m = 0.2\nbeta_deg = 0.0\nwheel_colour = 3",
            ),
            Path::new("r.toml"),
        )
        .unwrap_err();
        assert!(e.message.contains("wheel_colour"), "{e}");
    }

    #[test]
    fn singular_geometry_points_at_wheels() {
        let bad = MOBOLAB.replace(
            "alpha_deg = -90.0\nl_m = 0.2\nbeta_deg = 180.0",
            "alpha_deg = 90.0\nl_m = 0.2\nbeta_deg = 0.0",
        );
        // Both wheels at the same place: the twist cannot be resolved.
        let e = parse(&bad, Path::new("r.toml")).unwrap_err();
        assert!(e.message.contains("rank < 3"), "{e}");
        assert!(e.line.is_some());
    }

    /// Issue 13.8: a 200 MB robot file took 30 s and 8.4 GB before it was refused.
    #[test]
    fn oversized_files_and_too_many_wheels_are_refused_early() {
        let dir = std::env::temp_dir().join(format!("wheelcal-robot-cap-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let big = dir.join("big.toml");
        std::fs::write(&big, "# padding\n".repeat(120_000)).unwrap();
        let e = load(&big).unwrap_err();
        assert!(e.message.contains("at most 1048576 bytes"), "{e}");
        assert!(e.to_string().starts_with(&big.display().to_string()));
        let wheel =
            "[[wheels]]\nname = \"w\"\nradius_m = 0.03\nalpha_deg = 0\nl_m = 0.1\nbeta_deg = 0\n";
        let text = format!("name = \"x\"\nkind = \"omni\"\n{}", wheel.repeat(9));
        let e = parse(&text, Path::new("nine.toml")).unwrap_err();
        assert!(e.message.contains("more than 8 wheels"), "{e}");
        // The ninth `[[wheels]]` header: after two lines and eight six-line wheels.
        assert_eq!((e.line, e.column), (Some(2 + 8 * 6 + 1), Some(1)));
        let _ = std::fs::remove_dir_all(&dir);
    }

    /// Issue 12: `[procedure] idle_wheels` in a robot file (an extension, docs/formats.md §5).
    #[test]
    fn procedure_table_says_how_idle_wheels_behave() {
        use calib_core::omni_cal::IdleWheels;
        let base = std::fs::read_to_string(
            Path::new(env!("CARGO_MANIFEST_DIR")).join("../robots/omni4.toml"),
        )
        .unwrap();
        let p = Path::new("omni4.toml");
        assert_eq!(parse_procedure(&base, p).unwrap().idle_wheels, None);
        for (v, want) in [
            ("held", IdleWheels::Held),
            ("released", IdleWheels::Released),
        ] {
            let text = format!("{base}\n[procedure]\nidle_wheels = \"{v}\"\n");
            assert_eq!(parse_procedure(&text, p).unwrap().idle_wheels, Some(want));
            // The robot itself still parses with the table present.
            assert_eq!(parse(&text, p).unwrap().wheel_count(), 4);
        }
        let text = format!("{base}\n[procedure]\nidle_wheels = \"hold\"\n");
        let e = parse_procedure(&text, p).unwrap_err();
        let line = text.lines().count();
        assert_eq!((e.line, e.column), (Some(line), Some(15)), "{e}");
        assert!(e.message.contains("\"held\" or \"released\""), "{e}");
    }
}
