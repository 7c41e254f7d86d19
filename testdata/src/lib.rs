//! Where the tests find real recordings (a dev-dependency only).
//!
//! - The seven real runs the tests need (six UMBmark squares of the OptiOdom differential
//!   robot and one omni3 square, under 1 MB) are in the repository, `data/real/`, with their
//!   licence and provenance: a clone with nothing beside it tests on real data.
//! - The OptiOdom evaluation sessions (about 300 runs, 83 MB) stay outside. Tests that need
//!   them are `#[ignore]`d with a message naming [`SESSIONS_VAR`]; run them with the variable
//!   naming the folder (`data/real/README.md`). When asked to run without it they fail,
//!   naming what is missing: no test passes by skipping.

use std::path::{Path, PathBuf};

/// The environment variable naming the converted OptiOdom sessions folder.
pub const SESSIONS_VAR: &str = "WHEELCAL_SESSIONS";

/// The repository's root (this crate sits one level below it).
pub fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map(Path::to_path_buf)
        .unwrap_or_else(|| PathBuf::from("."))
}

/// `data/real/`: the real runs kept in the repository.
pub fn real_dir() -> PathBuf {
    repo_root().join("data/real")
}

/// One run folder of `data/real/` (`diff-square-run-01` .. `-06`, `omni3-square-run-01`),
/// checked to exist: a missing folder is a broken checkout, said by name.
pub fn real(folder: &str) -> PathBuf {
    let d = real_dir().join(folder);
    assert!(
        d.join("recording.csv").is_file() && d.join("robot.toml").is_file(),
        "{} is not a real run folder (recording.csv and robot.toml): the checkout is incomplete",
        d.display()
    );
    d
}

/// The six real UMBmark squares (runs 01-03 clockwise, 04-06 counter-clockwise).
pub fn real_squares() -> Vec<PathBuf> {
    (1..=6)
        .map(|i| real(&format!("diff-square-run-{i:02}")))
        .collect()
}

/// The OptiOdom sessions folder named by [`SESSIONS_VAR`]. Panics with what to do when it
/// is not set or not a sessions folder: call it only from `#[ignore]`d tests, which run
/// when asked for.
pub fn sessions_dir() -> PathBuf {
    match sessions_dir_if_set() {
        Ok(d) => d,
        Err(why) => panic!("{why}"),
    }
}

/// [`sessions_dir`] as a result, for harnesses (examples, benches) that print the reason.
pub fn sessions_dir_if_set() -> Result<PathBuf, String> {
    let Some(v) = std::env::var_os(SESSIONS_VAR) else {
        return Err(format!(
            "{SESSIONS_VAR} is not set: this needs the OptiOdom sessions (see data/real/README.md, \
             'The larger evaluation sets'; scripts/fetch-sessions.sh)"
        ));
    };
    let d = PathBuf::from(v);
    if !d.join("authors_params.json").is_file() {
        return Err(format!(
            "{SESSIONS_VAR}={} is not the OptiOdom sessions folder (no authors_params.json in it)",
            d.display()
        ));
    }
    Ok(d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_seven_real_runs_are_in_the_repository() {
        assert_eq!(real_squares().len(), 6);
        let omni = real("omni3-square-run-01");
        // 51 s at 25 Hz: about 1,280 rows plus the header.
        let rows = std::fs::read_to_string(omni.join("recording.csv"))
            .unwrap()
            .lines()
            .count();
        assert!((1200..1400).contains(&rows), "{rows} rows");
        assert!(real_dir().join("LICENSE").is_file());
    }

    #[test]
    fn an_unset_sessions_variable_names_what_to_do() {
        if std::env::var_os(SESSIONS_VAR).is_some() {
            assert!(
                sessions_dir_if_set().is_ok(),
                "{SESSIONS_VAR} is set but wrong"
            );
        } else {
            let e = sessions_dir_if_set().unwrap_err();
            assert!(
                e.contains(SESSIONS_VAR) && e.contains("data/real/README.md"),
                "{e}"
            );
        }
    }
}
