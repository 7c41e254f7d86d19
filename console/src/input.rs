//! Reading the files a user names: only regular files, and at most a stated size, so
//! that `/dev/zero`, a FIFO or a terminal given where a file belongs is refused by name
//! at once instead of being read until memory runs out (or forever: opening a FIFO
//! waits for a writer). Every whole-file read of a user's file in the console goes
//! through [`read_text`].

use anyhow::{anyhow, Result};
use std::path::Path;

/// A saved calibration (`calibrate --json`, a report's `calibration.json`): one is about
/// 5 KB for a few recordings and grows with their number (per-recording results,
/// leave-one-out rows); 16 MiB is thousands of recordings' worth, far beyond any real
/// one, and small enough to parse without strain.
pub const MAX_CALIBRATION_BYTES: u64 = 16 << 20;

/// A one-line sidecar or a small JSON record the console itself wrote (a procedure's
/// idle-wheel mode, its previous factors): under a kilobyte; 64 KiB leaves room for
/// hand edits and comments.
pub const MAX_SIDECAR_BYTES: u64 = 64 << 10;

pub use formats::text_file::kind_of;

/// `Ok(())` if `path` is a regular file (links followed); otherwise an error naming it
/// and saying what it is, for a `what` ("calibration JSON"). A missing file is left to
/// the caller's own message (`None` of the metadata).
pub fn check_regular(path: &Path, what: &str) -> Result<Option<std::fs::Metadata>> {
    let meta = match std::fs::metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(anyhow!("{}: cannot read the {what}: {e}", path.display())),
    };
    if !meta.is_file() {
        return Err(anyhow!(
            "{}: {}, not a regular file: a {what} is read from a regular file",
            path.display(),
            kind_of(&meta)
        ));
    }
    Ok(Some(meta))
}

/// Reads the UTF-8 text of the regular file `path`, at most `max_bytes` of it; `what`
/// names the kind of file in the errors, which name the path. A device, FIFO, socket or
/// folder is refused before it is opened; a larger file, binary data or invalid UTF-8
/// is refused after reading at most `max_bytes` + 64 KiB
/// ([`formats::text_file::read_capped`]). `NotFound` stays an `std::io::Error` in the
/// chain so callers can tell a missing file apart.
pub fn read_text(path: &Path, max_bytes: u64, what: &str) -> Result<String> {
    if check_regular(path, what)?.is_none() {
        return Err(
            anyhow::Error::new(std::io::Error::from(std::io::ErrorKind::NotFound))
                .context(format!("{}: no such {what}", path.display())),
        );
    }
    formats::text_file::read_capped(path, max_bytes, what)
        .map_err(|e| anyhow!("{}: {e}", path.display()))
}

/// Whether `e` (from [`read_text`]) is a missing file.
pub fn is_not_found(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_regular_files_within_the_cap_are_read() {
        let e = read_text(Path::new("/dev/zero"), 1 << 20, "calibration JSON").unwrap_err();
        assert!(
            e.to_string()
                .contains("/dev/zero: a character device, not a regular file"),
            "{e}"
        );
        let d = std::env::temp_dir().join(format!("wheelcal-input-{}", std::process::id()));
        std::fs::create_dir_all(&d).unwrap();
        let e = read_text(&d, 10, "calibration JSON").unwrap_err();
        assert!(
            e.to_string().contains("a folder, not a regular file"),
            "{e}"
        );
        let f = d.join("x.json");
        std::fs::write(&f, "12345678901").unwrap();
        let e = read_text(&f, 10, "calibration JSON").unwrap_err();
        assert!(e.to_string().contains("more than 10 bytes"), "{e}");
        assert_eq!(read_text(&f, 11, "x").unwrap(), "12345678901");
        let e = read_text(&d.join("none"), 10, "calibration JSON").unwrap_err();
        assert!(is_not_found(&e), "{e}");
        let _ = std::fs::remove_dir_all(&d);
    }
}
