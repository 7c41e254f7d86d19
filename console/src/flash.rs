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
}

impl NorFlashError for FlashError {
    fn kind(&self) -> NorFlashErrorKind {
        match self {
            FlashError::OutOfBounds => NorFlashErrorKind::OutOfBounds,
            FlashError::NotAligned => NorFlashErrorKind::NotAligned,
        }
    }
}

/// NOR semantics: erase sets bytes to 0xFF, writes can only clear bits.
pub struct RamFlash {
    data: Vec<u8>,
    file: Option<PathBuf>,
}

impl RamFlash {
    /// `pages` erase pages, all erased.
    pub fn new(pages: usize) -> Self {
        RamFlash {
            data: vec![0xFF; pages * PAGE],
            file: None,
        }
    }

    /// Loads from `file` when it exists (and has the right size), and writes every change
    /// back to it.
    pub fn with_file(pages: usize, file: PathBuf) -> std::io::Result<Self> {
        let mut f = RamFlash::new(pages);
        match std::fs::read(&file) {
            Ok(bytes) if bytes.len() == f.data.len() => f.data = bytes,
            Ok(_) => {} // wrong size: start erased (the store reports Missing)
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
            Err(e) => return Err(e),
        }
        f.file = Some(file);
        Ok(f)
    }

    /// Size of the flash, bytes.
    pub fn len(&self) -> usize {
        self.data.len()
    }

    /// Whether the flash has no bytes at all (zero pages).
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    fn sync(&self) {
        if let Some(p) = &self.file {
            // Best effort: a failed mirror write only loses persistence across restarts.
            let _ = std::fs::write(p, &self.data);
        }
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
        self.sync();
        Ok(())
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
        self.sync();
        Ok(())
    }
}
