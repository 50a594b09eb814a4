//! Writing `REC.csv` and `REC.json` atomically with full precision.

use super::atomic::write_atomic;
use super::error::RecordingError;
use super::read::{sidecar_path, COLUMNS};
use super::types::Recording;
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
    let cols: Vec<(&str, &[f64])> = [
        Some((COLUMNS[0], rec.time_s.as_slice())),
        Some((COLUMNS[1], rec.torque_cmd_nm.as_slice())),
        rec.position_rad.as_deref().map(|v| (COLUMNS[2], v)),
        rec.velocity_rad_s.as_deref().map(|v| (COLUMNS[3], v)),
        rec.acceleration_rad_s2.as_deref().map(|v| (COLUMNS[4], v)),
        rec.torque_actual_nm.as_deref().map(|v| (COLUMNS[5], v)),
    ]
    .into_iter()
    .flatten()
    .collect();
    let io = |p: &Path| {
        let p = p.to_path_buf();
        move |source| RecordingError::Io { path: p, source }
    };
    write_atomic(path, |w: &mut dyn Write| {
        let names: Vec<&str> = cols.iter().map(|c| c.0).collect();
        writeln!(w, "{}", names.join(","))?;
        let mut line = String::with_capacity(128);
        for k in 0..rec.len() {
            line.clear();
            for (i, (_, v)) in cols.iter().enumerate() {
                if i > 0 {
                    line.push(',');
                }
                use std::fmt::Write as _;
                let _ = write!(line, "{:e}", v[k]);
            }
            line.push('\n');
            w.write_all(line.as_bytes())?;
        }
        Ok(())
    })
    .map_err(io(path))?;
    let side = sidecar_path(path);
    let mut sidecar = rec.sidecar.clone();
    sidecar.sample_rate_hz = Some(rec.sample_rate_hz);
    let json = serde_json::to_string_pretty(&sidecar).map_err(|e| RecordingError::Invalid {
        path: side.clone(),
        message: e.to_string(),
    })?;
    write_atomic(&side, |w: &mut dyn Write| {
        w.write_all(json.as_bytes())?;
        w.write_all(b"\n")
    })
    .map_err(io(&side))
}

fn validate(path: &Path, rec: &Recording) -> Result<(), RecordingError> {
    let bad = |message: String| RecordingError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let n = rec.len();
    if !(rec.sample_rate_hz.is_finite() && rec.sample_rate_hz > 0.0) {
        return Err(bad(format!(
            "sample_rate_hz must be finite and positive, got {}",
            rec.sample_rate_hz
        )));
    }
    if rec.preferred_motion().is_none() {
        return Err(bad(
            "no motion column (position, velocity or acceleration)".into()
        ));
    }
    let cols = [
        (COLUMNS[0], Some(&rec.time_s)),
        (COLUMNS[1], Some(&rec.torque_cmd_nm)),
        (COLUMNS[2], rec.position_rad.as_ref()),
        (COLUMNS[3], rec.velocity_rad_s.as_ref()),
        (COLUMNS[4], rec.acceleration_rad_s2.as_ref()),
        (COLUMNS[5], rec.torque_actual_nm.as_ref()),
    ];
    for (name, col) in cols {
        let Some(col) = col else { continue };
        if col.len() != n {
            return Err(bad(format!(
                "column {name} has {} samples, torque_cmd_nm has {n}",
                col.len()
            )));
        }
        if let Some(k) = col.iter().position(|v| !v.is_finite()) {
            return Err(bad(format!(
                "column {name}, sample {k}: {} is not finite",
                col[k]
            )));
        }
    }
    Ok(())
}
