//! Writing `REC.csv` and `REC.json` atomically with full precision.

use super::atomic::write_atomic;
use flexid_core::recording::{sidecar_json, sidecar_path, validate, write_csv};
use flexid_core::recording::{Recording, RecordingError};
use std::io::Write;
use std::path::Path;

/// Write `rec` to `path` (CSV) and the sidecar beside it (see [`sidecar_path`]).
///
/// Each file is replaced atomically (temporary file in the same directory, fsync, rename,
/// fsync of the directory); the pair is written CSV first, then sidecar. Numbers are written
/// in Rust's shortest round-trip scientific form (`{:e}`, e.g. `1.25e-3`), so reading the
/// files back gives bit-identical values. Columns: `time_s`, `torque_cmd_nm`, then those
/// motion columns that are present. The sidecar is `rec.sidecar` with `sample_rate_hz` set to
/// `rec.sample_rate_hz` (the in-memory rate is authoritative).
///
/// Errors: [`RecordingError::Invalid`] when columns differ in length, no motion column is
/// present, a value is not finite or the rate is not positive; [`RecordingError::Io`].
pub fn write_recording(path: impl AsRef<Path>, rec: &Recording) -> Result<(), RecordingError> {
    let path = path.as_ref();
    validate(path, rec)?;
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| RecordingError::Io { path: p, source }
    };
    let side = sidecar_path(path);
    // both targets checked before either is written (a refused sidecar target must not
    // leave a new CSV beside an old sidecar)
    for p in [path, side.as_path()] {
        super::atomic::writable_target(p).map_err(io(p))?;
    }
    write_atomic(path, |w: &mut dyn Write| write_csv(w, rec)).map_err(io(path))?;
    let json = sidecar_json(rec, &side)?;
    write_atomic(&side, |w: &mut dyn Write| w.write_all(json.as_bytes())).map_err(io(&side))
}
