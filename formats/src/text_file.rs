//! Reading a text input whatever the path names: only a regular file is opened (a FIFO
//! would wait for a writer forever, a device such as `/dev/zero` never ends), the read is
//! capped by the bytes actually read, and binary data is refused at its first NUL byte
//! instead of after reading it all.

use std::io::Read;
use std::path::Path;

/// Line numbers of byte offsets, counted on `\n` only: the csv crate's own count takes a
/// CR LF pair as two line ends' worth in places and named every line of an Excel or
/// Windows file one too low. Offsets must be asked in increasing order (one pass).
pub struct LineCounter<'a> {
    text: &'a [u8],
    at: usize,
    line: usize,
}

impl<'a> LineCounter<'a> {
    /// A counter over `text`, at line 1.
    pub fn new(text: &'a str) -> Self {
        LineCounter {
            text: text.as_bytes(),
            at: 0,
            line: 1,
        }
    }

    /// The 1-based line of the record starting at byte `offset` (not before the last
    /// offset asked). The csv crate ends a record at the CR of a CR LF pair and puts the
    /// next record's start on the LF: line-end bytes at the start are skipped.
    pub fn line_at(&mut self, offset: u64) -> usize {
        let mut to = (offset as usize).min(self.text.len());
        while to < self.text.len() && matches!(self.text[to], b'\r' | b'\n') {
            to += 1;
        }
        if to > self.at {
            self.line += self.text[self.at..to]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
            self.at = to;
        }
        self.line
    }
}

/// Why a text input could not be read; the message never names the path (the caller's
/// error does, with its line and column conventions).
#[derive(Debug, Clone, PartialEq)]
pub struct ReadError(pub String);

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ReadError {}

/// What a file system object that is not a regular file is, in words.
pub fn kind_of(meta: &std::fs::Metadata) -> &'static str {
    use std::os::unix::fs::FileTypeExt;
    let t = meta.file_type();
    if t.is_file() {
        "a regular file"
    } else if t.is_dir() {
        "a folder"
    } else if t.is_fifo() {
        "a FIFO (named pipe)"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// Reads at most `max_bytes` of UTF-8 text from `path`; `what` names the kind of file in
/// messages ("robot file"). More bytes, a NUL byte or invalid UTF-8 are errors, found
/// within the first 64 KiB read past the fault.
pub fn read_capped(path: &Path, max_bytes: u64, what: &str) -> Result<String, ReadError> {
    crate::safe_write::note_input(path);
    let meta =
        std::fs::metadata(path).map_err(|e| ReadError(format!("cannot read {what}: {e}")))?;
    if meta.is_dir() {
        return Err(ReadError(format!("is a folder, not a {what}")));
    }
    // A device, FIFO or socket is refused before it is opened: opening a FIFO waits for
    // a writer (forever), and a device such as /dev/zero never ends.
    if !meta.is_file() {
        return Err(ReadError(format!(
            "{}, not a regular file: a {what} is read from a regular file",
            kind_of(&meta)
        )));
    }
    let file =
        std::fs::File::open(path).map_err(|e| ReadError(format!("cannot read {what}: {e}")))?;
    let mut limited = file.take(max_bytes + 1);
    // The file's own size (a device says 0): no doubling slack held while it is parsed.
    let mut buf: Vec<u8> = Vec::with_capacity(meta.len().min(max_bytes) as usize + 1);
    let mut chunk = vec![0u8; 64 * 1024];
    loop {
        let n = match limited.read(&mut chunk) {
            Ok(0) => break,
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(ReadError(format!("cannot read {what}: {e}"))),
        };
        if let Some(i) = chunk[..n].iter().position(|&b| b == 0) {
            return Err(ReadError(format!(
                "binary data (a NUL byte at offset {}), not a {what}",
                buf.len() + i
            )));
        }
        buf.extend_from_slice(&chunk[..n]);
        if buf.len() as u64 > max_bytes {
            return Err(ReadError(format!(
                "more than {max_bytes} bytes: a {what} has at most {max_bytes} bytes"
            )));
        }
    }
    String::from_utf8(buf).map_err(|e| {
        ReadError(format!(
            "not UTF-8 text (invalid byte at offset {}), not a {what}",
            e.utf8_error().valid_up_to()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn devices_are_refused_and_files_stop_at_the_cap_or_the_first_nul() {
        for dev in ["/dev/zero", "/dev/full"] {
            if Path::new(dev).exists() {
                let e = read_capped(Path::new(dev), 1 << 20, "robot file").unwrap_err();
                assert!(
                    e.0.contains("a character device, not a regular file"),
                    "{e}"
                );
            }
        }
        let dir = std::env::temp_dir().join(format!("formats-capped-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let f = dir.join("big.txt");
        std::fs::write(&f, "a".repeat(1001)).unwrap();
        let e = read_capped(&f, 1000, "runs file").unwrap_err();
        assert!(e.0.contains("more than 1000 bytes"), "{e}");
        assert_eq!(read_capped(&f, 1001, "runs file").unwrap().len(), 1001);
        std::fs::write(&f, [b'a', 0xff, b'b']).unwrap();
        let e = read_capped(&f, 1000, "runs file").unwrap_err();
        assert!(e.0.contains("offset 1"), "{e}");
        std::fs::write(&f, [b'a', 0, b'b']).unwrap();
        let e = read_capped(&f, 1000, "runs file").unwrap_err();
        assert!(e.0.contains("NUL byte at offset 1"), "{e}");
        let e = read_capped(&dir, 1000, "runs file").unwrap_err();
        assert!(e.0.contains("folder"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
