//! A NOR flash in RAM, optionally mirrored to a file, for the virtual board: the same
//! sequential-storage code that runs on the STM32's sectors 10-11 runs on it, so saved
//! factors survive a virtual board restart (`--flash FILE`).

use embedded_storage_async::nor_flash::{
    ErrorType, NorFlash, NorFlashError, NorFlashErrorKind, ReadNorFlash,
};
use std::path::PathBuf;

/// Erase page size (small, so the virtual board's store is quick to scan).
pub const PAGE: usize = 4096;

/// Why a flash access was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlashError {
    /// The access runs past the end of the flash.
    OutOfBounds,
    /// The offset or length is not a multiple of the read, write or erase size.
    NotAligned,
    /// The file mirroring the flash could not be written.
    Io,
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
            FlashError::Io => NorFlashErrorKind::Other,
        }
    }
}

/// NOR semantics: erase sets bytes to 0xFF, writes can only clear bits.
pub struct RamFlash {
    data: Vec<u8>,
    file: Option<PathBuf>,
    /// Why the file is only read, never written (a damaged image): saves then fail.
    damaged: Option<String>,
}

impl RamFlash {
    /// `pages` erase pages, all erased.
    pub fn new(pages: usize) -> Self {
        RamFlash {
            data: vec![0xFF; pages * PAGE],
            file: None,
            damaged: None,
        }
    }

    /// Loads from `file` when it exists, and writes every change back to it. A file that
    /// is not a regular file or not exactly the flash's size is refused, not read to the
    /// end (a device never ends) nor overwritten (it may be someone's file); a missing
    /// file is created erased at once, so a folder that does not exist is an error now
    /// instead of saves that silently go nowhere.
    pub fn with_file(pages: usize, file: PathBuf) -> Result<Self, String> {
        let mut f = RamFlash::new(pages);
        let shown = file.display().to_string();
        match std::fs::metadata(&file) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                f.file = Some(file);
                f.try_sync()
                    .map_err(|e| format!("cannot create the flash file {shown}: {e}"))?;
                return Ok(f);
            }
            Err(e) => return Err(format!("cannot read the flash file {shown}: {e}")),
            Ok(m) if !m.is_file() => {
                return Err(format!(
                    "{shown} is not a regular file: a flash image is a file of {} bytes",
                    f.data.len()
                ))
            }
            Ok(_) => {}
        }
        let mut bytes = Vec::with_capacity(f.data.len() + 1);
        std::fs::File::open(&file)
            .and_then(|h| {
                use std::io::Read;
                h.take(f.data.len() as u64 + 1).read_to_end(&mut bytes)
            })
            .map_err(|e| format!("cannot read the flash file {shown}: {e}"))?;
        if bytes.len() != f.data.len() {
            let size = if bytes.len() > f.data.len() {
                format!("more than {}", f.data.len())
            } else {
                bytes.len().to_string()
            };
            // Text is somebody's file, not a flash image: refused, untouched.
            if !bytes.contains(&0) && std::str::from_utf8(&bytes).is_ok() {
                return Err(format!(
                    "{shown} is a text file ({size} bytes), not a flash image of this board ({} bytes): not used, not touched (give a new file name)",
                    f.data.len()
                ));
            }
            // A truncated or oversized image: the board reads what fits as damaged flash
            // (its missing end as written bytes, so it is not taken for a blank flash)
            // and reports the loss at boot; the file is never written.
            let n = bytes.len().min(f.data.len());
            f.data[..n].copy_from_slice(&bytes[..n]);
            f.data[n..].fill(0);
            f.damaged = Some(format!(
                "{shown} has {size} bytes, a flash image {}: read as damaged flash (`info` says corrupted) and never written; saves fail until it is moved away",
                f.data.len()
            ));
            f.file = Some(file);
            return Ok(f);
        }
        f.data = bytes;
        f.file = Some(file);
        Ok(f)
    }

    /// Why the flash file is read only, if it is (a damaged image).
    pub fn damaged(&self) -> Option<&str> {
        self.damaged.as_deref()
    }

    /// Size of the flash, bytes.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the flash has no bytes at all (zero pages).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Writes the image to its file through a temporary file and a rename, so a failed
    /// write leaves the old image whole.
    fn try_sync(&self) -> std::io::Result<()> {
        if let Some(why) = &self.damaged {
            return Err(std::io::Error::other(why.clone()));
        }
        match &self.file {
            Some(p) => formats::safe_write::replace_file(p, &self.data),
            None => Ok(()),
        }
    }

    fn sync(&mut self) -> Result<(), FlashError> {
        // A mirror that cannot be written is a failed flash operation: the board then
        // says the save failed instead of "saved to flash".
        self.try_sync().map_err(|_| FlashError::Io)
    }
}

impl ErrorType for RamFlash {
    type Error = FlashError;
}

impl ReadNorFlash for RamFlash {
    const READ_SIZE: usize = 1;

    async fn read(&mut self, offset: u32, bytes: &mut [u8]) -> Result<(), FlashError> {
        let o = offset as usize;
        let src = self
            .data
            .get(o..o + bytes.len())
            .ok_or(FlashError::OutOfBounds)?;
        bytes.copy_from_slice(src);
        Ok(())
    }

    fn capacity(&self) -> usize {
        self.data.len()
    }
}

impl NorFlash for RamFlash {
    const WRITE_SIZE: usize = 4;
    const ERASE_SIZE: usize = PAGE;

    async fn erase(&mut self, from: u32, to: u32) -> Result<(), FlashError> {
        let (f, t) = (from as usize, to as usize);
        if !f.is_multiple_of(PAGE) || !t.is_multiple_of(PAGE) {
            return Err(FlashError::NotAligned);
        }
        self.data
            .get_mut(f..t)
            .ok_or(FlashError::OutOfBounds)?
            .fill(0xFF);
        self.sync()
    }

    async fn write(&mut self, offset: u32, bytes: &[u8]) -> Result<(), FlashError> {
        let o = offset as usize;
        if !o.is_multiple_of(Self::WRITE_SIZE) || !bytes.len().is_multiple_of(Self::WRITE_SIZE) {
            return Err(FlashError::NotAligned);
        }
        let dst = self
            .data
            .get_mut(o..o + bytes.len())
            .ok_or(FlashError::OutOfBounds)?;
        for (d, s) in dst.iter_mut().zip(bytes) {
            *d &= *s;
        }
        self.sync()
    }
}
