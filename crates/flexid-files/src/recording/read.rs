//! Reading `REC.csv` and, if present, `REC.json` from disk.

use flexid_core::recording::{
    parse_sidecar, read_recording_from, sidecar_path, ReadReport, Recording, RecordingError,
};
use std::fs::File;
use std::io::{BufReader, ErrorKind};
use std::path::Path;

/// Read `REC.csv` and, if present, the sidecar `REC.json` beside it.
///
/// Warnings (see [`ReadReport::warnings`]) are logged with `tracing::warn!`; use
/// [`read_recording_report`] to get them.
pub fn read_recording(path: impl AsRef<Path>) -> Result<Recording, RecordingError> {
    let report = read_recording_report(path)?;
    for w in &report.warnings {
        tracing::warn!("{w}");
    }
    Ok(report.recording)
}

/// Like [`read_recording`], returning the warnings instead of logging them.
pub fn read_recording_report(path: impl AsRef<Path>) -> Result<ReadReport, RecordingError> {
    let path = path.as_ref();
    let side = sidecar_path(path);
    let sidecar = match std::fs::read_to_string(&side) {
        Ok(text) => Some(parse_sidecar(&text, &side)?),
        Err(e) if e.kind() == ErrorKind::NotFound => None,
        Err(source) => return Err(RecordingError::Io { path: side, source }),
    };
    let file = File::open(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_recording_from(BufReader::with_capacity(1 << 20, file), path, sidecar)
}
