//! Writing without losing a user's file. Every command that writes follows
//! one rule:
//!
//! - a folder is written into only when it is new, empty, or one wheelcal made (it holds
//!   the marker file [`MARKER`]), and never when it holds one of the command's inputs;
//! - an existing file is replaced only when it is of the kind about to be written (the
//!   caller says how to tell), unless `--force` ([`set_force`]);
//! - a path that is one of the command's own inputs is never written, `--force` or not
//!   (the loaders of this crate note every file they read: [`note_input`]);
//! - the bytes go to a temporary file beside the target, then a rename, so a failed write
//!   leaves the old file whole; a write that did not happen is an error naming the path.

use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// The file that marks a folder as made by wheelcal (its outputs may be replaced).
pub const MARKER: &str = ".wheelcal-output";

static FORCE: AtomicBool = AtomicBool::new(false);
static INPUTS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// `--force`: replace existing files of another kind and write into folders wheelcal did
/// not make. Inputs stay protected.
pub fn set_force(force: bool) {
    FORCE.store(force, Ordering::Relaxed);
}

/// Whether `--force` was given.
pub fn force() -> bool {
    FORCE.load(Ordering::Relaxed)
}

/// Records `path` as an input of this process: no safe write will replace it, and no
/// folder holding it is claimed for output.
pub fn note_input(path: &Path) {
    if let Ok(p) = std::fs::canonicalize(path) {
        if let Ok(mut v) = INPUTS.lock() {
            if !v.contains(&p) {
                v.push(p);
            }
        }
    }
}

fn inputs() -> Vec<PathBuf> {
    INPUTS.lock().map(|v| v.clone()).unwrap_or_default()
}

/// The canonical form of a path that may not exist yet (its folder canonicalised).
fn canonical_target(path: &Path) -> Option<PathBuf> {
    if let Ok(p) = std::fs::canonicalize(path) {
        return Some(p);
    }
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    Some(std::fs::canonicalize(parent).ok()?.join(path.file_name()?))
}

fn refuse(msg: String) -> io::Error {
    io::Error::other(msg)
}

/// The input `path` is, if it is one.
fn is_input(path: &Path) -> bool {
    match canonical_target(path) {
        Some(p) => inputs().contains(&p),
        None => false,
    }
}

/// Makes `dir` ready for output: created with its marker when missing; an empty folder or
/// one with the marker is taken as is; a folder with other files is refused (naming a
/// few) unless `--force`; a folder holding one of the inputs is always refused.
pub fn claim_dir(dir: &Path) -> io::Result<()> {
    let shown = dir.display();
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => {
            std::fs::create_dir_all(dir)
                .map_err(|e| refuse(format!("cannot create the folder {shown}: {e}")))?;
            return mark(dir);
        }
        Err(e) => return Err(refuse(format!("cannot use the folder {shown}: {e}"))),
        Ok(m) if !m.is_dir() => {
            return Err(refuse(format!(
                "{shown} is a file, not a folder: nothing written (give a new folder name)"
            )))
        }
        Ok(_) => {}
    }
    if let Ok(canon) = std::fs::canonicalize(dir) {
        if let Some(i) = inputs().iter().find(|i| i.starts_with(&canon)) {
            return Err(refuse(format!(
                "{shown} holds {}, an input of this command: nothing written (write the output into another folder)",
                i.display()
            )));
        }
    }
    if dir.join(MARKER).exists() {
        return Ok(());
    }
    let mut others: Vec<String> = std::fs::read_dir(dir)
        .map_err(|e| refuse(format!("cannot read the folder {shown}: {e}")))?
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    if !others.is_empty() && !force() {
        others.sort();
        let n = others.len();
        others.truncate(4);
        let more = if n > 4 {
            format!(" and {} more", n - 4)
        } else {
            String::new()
        };
        return Err(refuse(format!(
            "{shown} holds files wheelcal did not make ({}{more}): nothing written (give a new folder, or --force to write into it)",
            others.join(", ")
        )));
    }
    mark(dir)
}

fn mark(dir: &Path) -> io::Result<()> {
    replace_file(
        &dir.join(MARKER),
        b"This folder was made by wheelcal; it may replace the files it wrote here.\n",
    )
}

/// Writes `bytes` to `path` under the rule: never an input; an existing file only when
/// `same_kind` accepts its first MiB (or with `--force`); `what` names the kind in the
/// message ("robot description").
pub fn write_file(
    path: &Path,
    bytes: &[u8],
    what: &str,
    same_kind: impl Fn(&[u8]) -> bool,
) -> io::Result<()> {
    check_target(path, what, same_kind)?;
    replace_file(path, bytes)
}

/// The checks of [`write_file`] without writing: for writers that stream (open the path
/// afterwards with [`replace_file`] or their own temporary file).
pub fn check_target(path: &Path, what: &str, same_kind: impl Fn(&[u8]) -> bool) -> io::Result<()> {
    let shown = path.display();
    if is_input(path) {
        return Err(refuse(format!(
            "{shown} is an input of this command: not overwritten (write to another file)"
        )));
    }
    match std::fs::symlink_metadata(path) {
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(refuse(format!("cannot use {shown}: {e}"))),
        Ok(m) if m.is_dir() => Err(refuse(format!(
            "{shown} is a folder: nothing written (give a file name)"
        ))),
        Ok(m) if !m.is_file() => Err(refuse(format!(
            "{shown} is not a regular file: nothing written"
        ))),
        Ok(_) => {
            if force() {
                return Ok(());
            }
            let mut head = Vec::new();
            std::fs::File::open(path)
                .and_then(|f| {
                    use std::io::Read;
                    f.take(1 << 20).read_to_end(&mut head)
                })
                .map_err(|e| refuse(format!("cannot read {shown}: {e}")))?;
            if same_kind(&head) {
                Ok(())
            } else {
                Err(refuse(format!(
                    "{shown} exists and is not a {what}: not overwritten (give a new file name, or --force to replace it)"
                )))
            }
        }
    }
}

/// Replaces `path` with `bytes` through a temporary file in the same folder and a rename
/// (no checks: for files the caller owns, such as a virtual board's flash image).
pub fn replace_file(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let shown = path.display();
    let name = path
        .file_name()
        .ok_or_else(|| refuse(format!("{shown}: not a file name")))?;
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(".tmp-{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = (|| {
        let mut f = std::fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(refuse(format!("cannot write {shown}: {e}")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("formats-safe-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn folders_are_claimed_only_when_new_empty_or_marked() {
        let d = scratch("claim");
        let new = d.join("new");
        claim_dir(&new).unwrap();
        assert!(new.join(MARKER).exists());
        claim_dir(&new).unwrap();
        let user = d.join("user");
        std::fs::create_dir_all(&user).unwrap();
        std::fs::write(user.join("notes.txt"), "mine").unwrap();
        let e = claim_dir(&user).unwrap_err().to_string();
        assert!(e.contains("notes.txt") && e.contains("--force"), "{e}");
        assert!(!user.join(MARKER).exists());
        let file = d.join("file");
        std::fs::write(&file, "x").unwrap();
        assert!(claim_dir(&file)
            .unwrap_err()
            .to_string()
            .contains("not a folder"));
    }

    #[test]
    fn files_of_another_kind_and_inputs_are_not_replaced() {
        let d = scratch("files");
        let f = d.join("out.toml");
        std::fs::write(&f, "my notes").unwrap();
        let e = write_file(
            &f,
            b"x",
            "robot description",
            crate::robot_file::is_robot_file,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("not a robot description"), "{e}");
        assert_eq!(std::fs::read_to_string(&f).unwrap(), "my notes");
        let g = d.join("new.txt");
        write_file(&g, b"hello", "text", |_| false).unwrap();
        assert_eq!(std::fs::read_to_string(&g).unwrap(), "hello");
        note_input(&g);
        let e = write_file(&g, b"x", "text", |_| true)
            .unwrap_err()
            .to_string();
        assert!(e.contains("input"), "{e}");
        assert!(claim_dir(&d).unwrap_err().to_string().contains("input"));
        // No temporary file left behind.
        let left: Vec<_> = std::fs::read_dir(&d).unwrap().flatten().collect();
        assert_eq!(left.len(), 2, "{left:?}");
    }
}
