//! Trajectories in the TUM RGB-D format, which evo (`evo_ape tum REF EST`), the TUM
//! benchmark tools and most SLAM evaluators read: one pose per line,
//! `timestamp tx ty tz qx qy qz qw`, space separated, the timestamp in seconds, the
//! position in metres, the orientation a unit quaternion. wheelcal's poses are planar:
//! `tz = 0` and the quaternion is a rotation about z (`qx = qy = 0`, `qz = sin(yaw/2)`,
//! `qw = cos(yaw/2)`). Numbers are written in Rust's shortest form that reads back to the
//! same `f64`, so a file holds exactly the values computed.
//!
//! `--tum DIR` writes one file per trajectory into a folder wheelcal owns
//! (`formats::safe_write::claim_dir`): `log pull` the board's odometry, `diagnose` the
//! measured, nominal and fitted paths, `evaluate` each recording's measured poses and each
//! robot file's dead reckoning.

use anyhow::{bail, Context, Result};
use std::fmt::Write as _;
use std::path::Path;

/// One planar pose at a time: (t s, x m, y m, yaw rad).
pub type Stamped = (f64, f64, f64, f64);

/// The TUM text of `poses` (one line each; non-finite poses are left out, as a reader
/// would refuse them).
pub fn to_text(poses: &[Stamped]) -> String {
    let mut s = String::with_capacity(poses.len() * 96);
    for &(t, x, y, yaw) in poses {
        if ![t, x, y, yaw].iter().all(|v| v.is_finite()) {
            continue;
        }
        let h = 0.5 * yaw;
        let _ = writeln!(s, "{t} {x} {y} 0 0 0 {} {}", h.sin(), h.cos());
    }
    s
}

/// A file name for a trajectory label: ASCII letters, digits, `.`, `-` and `_` kept,
/// anything else `_`, at most 100 characters, never empty or hidden; `.txt` appended.
pub fn file_name(label: &str) -> String {
    let mut s: String = label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '.' | '-' | '_') {
                c
            } else {
                '_'
            }
        })
        .take(100)
        .collect();
    if s.is_empty() || s.starts_with('.') {
        s.insert(0, '_');
    }
    s.push_str(".txt");
    s
}

/// Writes `files` (name, trajectory) into `dir`, which must be new, empty or a wheelcal
/// output folder; names given twice get `_2`, `_3`... before `.txt`. Returns the paths
/// written.
pub fn write_dir(dir: &Path, files: &[(String, Vec<Stamped>)]) -> Result<Vec<String>> {
    formats::safe_write::claim_dir(dir)
        .with_context(|| format!("--tum {}: cannot use it", dir.display()))?;
    let mut used = std::collections::BTreeSet::new();
    let mut written = Vec::with_capacity(files.len());
    for (label, poses) in files {
        let base = file_name(label);
        let stem = base.trim_end_matches(".txt").to_string();
        let mut name = base;
        let mut k = 2;
        while !used.insert(name.clone()) {
            name = format!("{stem}_{k}.txt");
            k += 1;
        }
        let path = dir.join(&name);
        formats::safe_write::replace_file(&path, to_text(poses).as_bytes())
            .with_context(|| format!("cannot write {}", path.display()))?;
        written.push(path.display().to_string());
    }
    Ok(written)
}

/// One line of a TUM file: `[t, tx, ty, tz, qx, qy, qz, qw]`.
pub type Line = [f64; 8];

/// Reads TUM text: blank lines and lines starting with `#` are skipped; every other line
/// must hold exactly eight finite numbers separated by spaces (or tabs, or commas, as
/// evo also accepts). Errors name the line.
pub fn parse(text: &str) -> Result<Vec<Line>> {
    let mut out = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let l = line.trim();
        if l.is_empty() || l.starts_with('#') {
            continue;
        }
        let v: Vec<&str> = l
            .split([' ', '\t', ','])
            .filter(|s| !s.is_empty())
            .collect();
        if v.len() != 8 {
            bail!("line {}: {} values, a TUM pose has 8", i + 1, v.len());
        }
        let mut p = [0.0; 8];
        for (o, s) in p.iter_mut().zip(&v) {
            *o = s
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .with_context(|| format!("line {}: '{s}' is not a finite number", i + 1))?;
        }
        out.push(p);
    }
    Ok(out)
}

/// The absolute position error's RMS (m) of `est` against `reference`, pose by pose, as
/// `evo_ape tum REF EST` reports it without alignment (its default: translation part,
/// poses associated by timestamp): the files must hold the same timestamps (within
/// 1e-9 s) in the same order. `None` when they do not or are empty.
pub fn ape_rmse(reference: &[Line], est: &[Line]) -> Option<f64> {
    if reference.len() != est.len() || reference.is_empty() {
        return None;
    }
    let mut acc = 0.0;
    for (a, b) in reference.iter().zip(est) {
        if (a[0] - b[0]).abs() > 1e-9 {
            return None;
        }
        let (dx, dy, dz) = (a[1] - b[1], a[2] - b[2], a[3] - b[3]);
        acc += dx * dx + dy * dy + dz * dz;
    }
    Some((acc / reference.len() as f64).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn poses_read_back_exactly() {
        let poses = vec![
            (0.0, 0.0, 0.0, 0.0),
            (0.1, 1.0 / 3.0, -2e-7, 3.0),
            (0.2, 1e3, 5.5, -3.1),
        ];
        let back = parse(&to_text(&poses)).unwrap();
        assert_eq!(back.len(), 3);
        for (p, l) in poses.iter().zip(&back) {
            assert_eq!((l[0], l[1], l[2], l[3]), (p.0, p.1, p.2, 0.0));
            let yaw = 2.0 * l[6].atan2(l[7]);
            assert!((yaw - p.3).abs() < 1e-12, "{yaw} vs {}", p.3);
        }
        assert!(parse("1 2 3").is_err());
        assert!(parse("1 2 3 4 5 6 7 nan").is_err());
        assert_eq!(file_name("a/b c"), "a_b_c.txt");
        assert_eq!(file_name(".."), "_...txt");
    }
}
