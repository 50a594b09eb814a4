//! The recording format: `REC.csv` (one row per sample at a uniform rate) and the optional
//! `REC.json` sidecar.
//!
//! This is a stable contract other tools call:
//!
//! * [`parse_recording`] reads from strings and [`read_recording_from`] from any reader
//!   (`flexid_files::recording::read_recording` opens the file pair);
//! * [`write_csv`] and [`sidecar_json`] format both files with round-trip precision
//!   (`flexid_files::recording::write_recording` replaces them atomically);
//! * [`infer_excitation`] / [`find_period`] describe a torque signal that came without a
//!   description;
//!
//! Errors are [`RecordingError`]s naming the file, the 1-based line and the column.

mod error;
mod json_exact;
mod period;
mod read;
mod types;
mod write;

pub use error::RecordingError;
pub use period::{
    find_period, infer_excitation, Periodicity, EXCITED_LINE_THRESHOLD, PERIOD_TOLERANCE,
};
pub use read::{
    check_excitation_fits, parse_recording, parse_sidecar, read_recording_from, sidecar_path,
    ReadReport, COLUMNS, MAX_LINE_BYTES, TIME_STEP_TOLERANCE,
};
pub use types::{
    CycleCounters, CycleTiming, DriveInfo, LatencySummary, MotionSignal, Recording, RecordingEnd,
    Sidecar,
};
pub use write::{sidecar_json, validate, write_csv};
