//! The policy the board's links share (a UART and a USB CDC-ACM link, each with its own
//! [`crate::Server`], on one application): where telemetry goes, and how saves reach the
//! storage task one at a time. Kept here, not in the embassy glue, so the host tests
//! cover it (`tests/two_links.rs`).

use crate::app::PersistItem;
use core::sync::atomic::{AtomicU8, Ordering};
use embassy_sync::blocking_mutex::raw::RawMutex;
use embassy_sync::channel::Channel;
use embassy_sync::mutex::Mutex;
use embassy_sync::signal::Signal;

/// Which link receives telemetry: the last one that received a valid frame. The
/// application has one telemetry schedule; split between two links, each would see half
/// the rate, and a link nobody listens to would take frames from the one that does.
pub struct TelemetryRoute {
    last: AtomicU8,
}

/// No link has spoken yet: telemetry goes nowhere.
const NO_LINK: u8 = 0;

impl TelemetryRoute {
    /// A route to no link.
    pub const fn new() -> Self {
        TelemetryRoute {
            last: AtomicU8::new(NO_LINK),
        }
    }

    /// Link `link` (1, 2, ...; 0 is reserved for "none") received a valid frame.
    pub fn spoke(&self, link: u8) {
        self.last.store(link, Ordering::Relaxed);
    }

    /// Whether telemetry goes to `link` now.
    pub fn gets_telemetry(&self, link: u8) -> bool {
        link != NO_LINK && self.last.load(Ordering::Relaxed) == link
    }
}

impl Default for TelemetryRoute {
    fn default() -> Self {
        Self::new()
    }
}

/// Hands flash saves from the links to the storage task, one at a time: a link holds the
/// turn from handing its item over until it has the result, so two links saving at once
/// can never take each other's result (the storage task signals one `bool` per save).
pub struct SaveQueue<M: RawMutex> {
    turn: Mutex<M, ()>,
    item: Channel<M, PersistItem, 1>,
    done: Signal<M, bool>,
}

impl<M: RawMutex> SaveQueue<M> {
    /// An empty queue (usable in a `static`).
    pub const fn new() -> Self {
        SaveQueue {
            turn: Mutex::new(()),
            item: Channel::new(),
            done: Signal::new(),
        }
    }

    /// A link: saves `item` through the storage task, waiting for its turn, and returns
    /// whether the write worked.
    pub async fn save(&self, item: PersistItem) -> bool {
        let _turn = self.turn.lock().await;
        self.item.send(item).await;
        self.done.wait().await
    }

    /// The storage task: the next item to write.
    pub async fn next(&self) -> PersistItem {
        self.item.receive().await
    }

    /// The storage task: the item from [`SaveQueue::next`] was written (`ok`) or not.
    pub fn finished(&self, ok: bool) {
        self.done.signal(ok);
    }
}

impl<M: RawMutex> Default for SaveQueue<M> {
    fn default() -> Self {
        Self::new()
    }
}
