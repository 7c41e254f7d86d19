//! Persistence of corrections and robot parameters in flash through `sequential-storage`'s
//! map, generic over any async `NorFlash` (the STM32's sectors 10-11 on the board,
//! sequential-storage's mock flash in tests).
//!
//! sequential-storage writes a new item before it invalidates the old one and repairs an
//! interrupted write on the next access, so a power cut during a save leaves either the old
//! or the new value (tested by cutting the power at every flash operation of a save). On
//! top of that each value carries a format byte and its own CRC-32 and is validated again
//! at boot (finite, in range, fits the robot): anything else is reported and replaced by
//! the defaults, never used.

use crate::app::PersistItem;
use crate::defaults;
use calib_core::protocol::{BootReport, Params, Stored};
use calib_core::Corrections;
use core::ops::Range;
use embedded_storage_async::nor_flash::NorFlash;
use sequential_storage::cache::{Cache, Uncached};
use sequential_storage::map::{MapConfig, MapStorage};

const KEY_CORRECTIONS: u8 = 1;
const KEY_PARAMS: u8 = 2;
/// One byte, a bit per item key that has ever been saved. sequential-storage skips an
/// item whose CRC fails as if it were absent; with this record boot tells "never saved"
/// from "saved, now unreadable" (a lost calibration the user must hear about).
const KEY_SAVED: u8 = 3;
/// Bumped when an item's stored layout changes; older values are then reported invalid.
/// Per item, so a new parameter layout does not throw away a saved calibration.
const FORMAT_CORRECTIONS: u8 = 1;
/// 2: `Safety::arena_m` added.
const FORMAT_PARAMS: u8 = 2;
/// Largest stored value (params with eight wheels are ~600 bytes) plus key and alignment.
const BUF: usize = 1024;
const CRC32: crc::Crc<u32> = crc::Crc::<u32>::new(&crc::CRC_32_ISO_HDLC);

/// Why the store could not be used.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// The flash range does not suit the flash (alignment, fewer than two pages).
    Config,
    /// Reading, writing or erasing failed, or the flash is full or corrupted.
    Flash,
    /// The value does not fit the buffer.
    TooBig,
}

/// What boot found: values to run with and how they were obtained.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    /// Parameters to run with (stored or defaults).
    pub params: Params,
    /// Corrections to run with (stored or none).
    pub corrections: Corrections,
    /// What was found for each item.
    pub boot: BootReport,
}

type Map<F> = MapStorage<u8, F, Cache<Uncached, Uncached, Uncached, u8>>;

/// The persisted settings of one board.
pub struct Store<F: NorFlash> {
    /// `None` only while [`Store::load`] reads the raw flash under it.
    map: Option<Map<F>>,
    range: Range<u32>,
    buf: [u8; BUF],
}

impl<F: NorFlash> Store<F> {
    /// A store on `range` (byte offsets within `flash`, whole erase pages, at least two).
    pub fn new(flash: F, range: Range<u32>) -> Result<Self, StoreError> {
        let config = MapConfig::try_new(range.clone()).map_err(|_| StoreError::Config)?;
        Ok(Store {
            map: Some(MapStorage::new(flash, config, Cache::new_uncached())),
            range,
            buf: [0; BUF],
        })
    }

    /// Gives the flash back (tests reboot a board on the same flash).
    pub fn into_flash(self) -> F {
        match self.map {
            Some(m) => m.destroy().0,
            None => unreachable!("the map is only taken inside load"),
        }
    }

    /// One item's bytes; on failure, what boot reports for it: data sequential-storage
    /// finds corrupted is a lost value (`Invalid`), anything else a flash fault.
    async fn fetch(&mut self, key: u8) -> Result<Option<&[u8]>, Stored> {
        let Some(map) = self.map.as_mut() else {
            return Err(Stored::StorageError);
        };
        match map.fetch_item::<&[u8]>(&mut self.buf, &key).await {
            Ok(v) => Ok(v),
            Err(sequential_storage::Error::Corrupted { .. }) => Err(Stored::Invalid),
            Err(_) => Err(Stored::StorageError),
        }
    }

    /// Whether any byte of the store's range differs from the erased state (0xFF): a
    /// flash that was never written is "none saved"; one with data but no readable
    /// record of what was saved lost it (flipped bits, a damaged image).
    async fn holds_data(&mut self) -> bool {
        let Some(map) = self.map.take() else {
            return false;
        };
        let (mut flash, cache) = map.destroy();
        let mut chunk = [0u8; 64];
        let mut written = false;
        let mut at = self.range.start;
        while at < self.range.end && !written {
            let n = (chunk.len() as u32).min(self.range.end - at) as usize;
            match flash.read(at, &mut chunk[..n]).await {
                Ok(()) => written = chunk[..n].iter().any(|&b| b != 0xFF),
                // An unreadable flash holds something we cannot use.
                Err(_) => written = true,
            }
            at += n as u32;
        }
        if let Ok(config) = MapConfig::try_new(self.range.clone()) {
            self.map = Some(MapStorage::new(flash, config, cache));
        }
        written
    }

    /// The keys ever saved (bit `1 << key`); 0 when the record is absent or unreadable.
    async fn saved_mask(&mut self) -> u8 {
        match self.fetch(KEY_SAVED).await {
            Ok(Some(&[m])) => m,
            _ => 0,
        }
    }

    /// Reads and validates both items; anything unusable becomes the defaults, and the
    /// report says which. An item that was saved once but is now gone is `Invalid`
    /// (corrupted), not `Missing`.
    pub async fn load(&mut self) -> Loaded {
        let saved = self.saved_mask().await;
        // No readable record of saves on a flash that holds data: whatever was saved is
        // lost, not absent (flipped bits and random bytes read "none saved").
        let lost = saved == 0 && self.holds_data().await;
        let absent = |key: u8| {
            if saved & (1 << key) != 0 || lost {
                Stored::Invalid
            } else {
                Stored::Missing
            }
        };
        let (params, params_state) = match self.fetch(KEY_PARAMS).await {
            Ok(None) => (defaults::params(), absent(KEY_PARAMS)),
            Err(state) => (defaults::params(), state),
            Ok(Some(b)) => {
                match unpack::<Params>(b, FORMAT_PARAMS).filter(|p| p.validate().is_ok()) {
                    Some(p) => (p, Stored::Loaded),
                    None => (defaults::params(), Stored::Invalid),
                }
            }
        };
        let (corrections, corr_state) = match self.fetch(KEY_CORRECTIONS).await {
            Ok(None) => (Corrections::None, absent(KEY_CORRECTIONS)),
            Err(state) => (Corrections::None, state),
            Ok(Some(b)) => {
                match unpack::<Corrections>(b, FORMAT_CORRECTIONS)
                    .filter(|c| c.validate(&params.robot).is_ok())
                {
                    Some(c) => (c, Stored::Loaded),
                    None => (Corrections::None, Stored::Invalid),
                }
            }
        };
        Loaded {
            params,
            corrections,
            boot: BootReport {
                corrections: corr_state,
                params: params_state,
            },
        }
    }

    /// Writes one item (power-fail safe: old or new survives).
    pub async fn save(&mut self, item: &PersistItem) -> Result<(), StoreError> {
        let mut value = [0u8; BUF - 8];
        let (key, len) = match item {
            PersistItem::Corrections(c) => {
                (KEY_CORRECTIONS, pack(FORMAT_CORRECTIONS, c, &mut value)?)
            }
            PersistItem::Params(p) => (KEY_PARAMS, pack(FORMAT_PARAMS, p, &mut value)?),
        };
        // The "ever saved" bit goes first: a save cut short after it reads as corrupted
        // (the save was lost), never as "nothing saved".
        let saved = self.saved_mask().await;
        let Store { map, buf, .. } = self;
        let map = map.as_mut().ok_or(StoreError::Flash)?;
        if saved & (1 << key) == 0 {
            map.store_item(buf, &KEY_SAVED, &&[saved | (1 << key)][..])
                .await
                .map_err(|_| StoreError::Flash)?;
        }
        map.store_item(buf, &key, &&value[..len])
            .await
            .map_err(|_| StoreError::Flash)
    }
}

/// `format | postcard | crc32(format | postcard)`.
fn pack<T: serde::Serialize>(format: u8, v: &T, out: &mut [u8]) -> Result<usize, StoreError> {
    let body = out.len().checked_sub(4).ok_or(StoreError::TooBig)?;
    out[0] = format;
    let n = 1 + postcard::to_slice(v, &mut out[1..body])
        .map_err(|_| StoreError::TooBig)?
        .len();
    let crc = CRC32.checksum(&out[..n]);
    out[n..n + 4].copy_from_slice(&crc.to_le_bytes());
    Ok(n + 4)
}

fn unpack<'a, T: serde::Deserialize<'a>>(b: &'a [u8], format: u8) -> Option<T> {
    let n = b.len().checked_sub(4)?;
    let (data, crc) = b.split_at(n);
    if data.first() != Some(&format) || CRC32.checksum(data).to_le_bytes() != crc {
        return None;
    }
    postcard::from_bytes(&data[1..]).ok()
}
