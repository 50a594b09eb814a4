//! Reading `REC.csv` and, if present, `REC.json` from disk.

use flexid_core::recording::{
    parse_sidecar, read_recording_from, sidecar_path, ReadReport, Recording, RecordingError,
};
use std::fs::File;
use std::io::{BufReader, ErrorKind, Read};
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
    let sidecar = match read_sidecar_text(&side)? {
        Some(text) => Some(parse_sidecar(&text, &side)?),
        None => None,
    };
    let file = File::open(path).map_err(|source| RecordingError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_recording_from(BufReader::with_capacity(1 << 20, file), path, sidecar)
}

/// Largest sidecar [bytes]: a sidecar is a few hundred bytes to a few MB (the excited lines
/// of a long period); a larger one is refused before it is read into memory.
pub const MAX_SIDECAR_BYTES: u64 = 16 * 1024 * 1024;

/// The sidecar's text, `None` when there is none. Only a regular file is read (a FIFO
/// would block the reader, a device such as `/dev/zero` would fill the memory), and at
/// most [`MAX_SIDECAR_BYTES`] of it.
fn read_sidecar_text(side: &Path) -> Result<Option<String>, RecordingError> {
    let refuse = |message: String| RecordingError::Sidecar {
        path: side.to_path_buf(),
        message,
    };
    let meta = match std::fs::metadata(side) {
        Ok(m) => m,
        Err(e) if e.kind() == ErrorKind::NotFound => return Ok(None),
        Err(source) => {
            return Err(RecordingError::Io {
                path: side.to_path_buf(),
                source,
            })
        }
    };
    if !meta.is_file() {
        return Err(refuse(
            "not a regular file (a sidecar is a JSON file; a FIFO, device or directory is \
             not read)"
                .to_string(),
        ));
    }
    if meta.len() > MAX_SIDECAR_BYTES {
        return Err(refuse(format!(
            "{} bytes, more than a sidecar holds (at most {MAX_SIDECAR_BYTES})",
            meta.len()
        )));
    }
    let io = |source| RecordingError::Io {
        path: side.to_path_buf(),
        source,
    };
    let mut text = String::new();
    File::open(side)
        .map_err(io)?
        .take(MAX_SIDECAR_BYTES + 1)
        .read_to_string(&mut text)
        .map_err(|source| {
            if source.kind() == ErrorKind::InvalidData {
                refuse("not valid UTF-8 text".to_string())
            } else {
                io(source)
            }
        })?;
    if text.len() as u64 > MAX_SIDECAR_BYTES {
        return Err(refuse(format!(
            "grew beyond {MAX_SIDECAR_BYTES} bytes while it was read"
        )));
    }
    Ok(Some(text))
}
