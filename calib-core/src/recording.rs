//! Recordings (formats.md §2): placeholder, written next.
