//! Whole runs to recordings (formats.md §2). Placeholder until the API settles.
