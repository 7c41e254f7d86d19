//! Serial protocol messages and framing (placeholder: the firmware/protocol work fills this in).
