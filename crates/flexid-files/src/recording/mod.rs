//! The recording's file pair on disk: `REC.csv` and its optional `REC.json` sidecar, read
//! through the core's parser and written atomically through its formatter.
//!
//! The types, the parser over any reader and the formatter over any writer are in
//! [`flexid_core::recording`]; this module opens and replaces the files.

pub use flexid_core::recording::*;

mod atomic;
mod read;
mod write;

pub use atomic::{writable_target, write_atomic, write_bytes_atomic};
pub use read::{read_recording, read_recording_report, MAX_SIDECAR_BYTES};
pub use write::write_recording;

#[cfg(test)]
mod tests;
