//! The recording format: `REC.csv` (one row per sample at a uniform rate) and the optional
//! `REC.json` sidecar.
//!
//! This is a stable contract other tools call:
//!
//! * [`read_recording`] / [`read_recording_report`] read a file pair, [`parse_recording`]
//!   reads from strings and [`read_recording_from`] from any reader;
//! * [`write_recording`] writes both files atomically with round-trip precision;
//! * [`infer_excitation`] / [`find_period`] describe a torque signal that came without a
//!   description;
//! * [`write_atomic`] is the atomic file replacement used by the writers (and by
//!   [`crate::plot`]).
//!
//! Errors are [`RecordingError`]s naming the file, the 1-based line and the column.

mod atomic;
mod error;
mod json_exact;
mod period;
mod read;
mod types;
mod write;

pub use atomic::{write_atomic, write_bytes_atomic};
pub use error::RecordingError;
pub use period::{
    find_period, infer_excitation, Periodicity, EXCITED_LINE_THRESHOLD, PERIOD_TOLERANCE,
};
pub use read::{
    parse_recording, parse_sidecar, read_recording, read_recording_from, read_recording_report,
    sidecar_path, ReadReport, COLUMNS, TIME_STEP_TOLERANCE,
};
pub use types::{
    CycleCounters, CycleTiming, DriveInfo, MotionSignal, Recording, RecordingEnd, Sidecar,
};
pub use write::write_recording;

#[cfg(test)]
mod tests;
