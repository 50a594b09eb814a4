//! Formatting `REC.csv` and `REC.json` with full precision, onto any writer (the atomic
//! file pair on disk is written by `flexid-files`).

use super::error::RecordingError;
use super::read::COLUMNS;
use super::types::Recording;
use std::io::{self, Write};
use std::path::Path;

/// Write the CSV text of `rec` to `w`.
///
/// Numbers are written in Rust's shortest round-trip scientific form (`{:e}`, e.g.
/// `1.25e-3`), so reading them back gives bit-identical values. Columns: `time_s`,
/// `torque_cmd_nm`, then those motion columns that are present. Call [`validate`] first:
/// this writes what it is given.
pub fn write_csv(w: &mut dyn Write, rec: &Recording) -> io::Result<()> {
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
}

/// The sidecar JSON text of `rec` (pretty-printed, newline-terminated): `rec.sidecar` with
/// `sample_rate_hz` set to `rec.sample_rate_hz` (the in-memory rate is authoritative).
/// `path` only names the sidecar in errors.
pub fn sidecar_json(rec: &Recording, path: &Path) -> Result<String, RecordingError> {
    let mut sidecar = rec.sidecar.clone();
    sidecar.sample_rate_hz = Some(rec.sample_rate_hz);
    let mut json = serde_json::to_string_pretty(&sidecar).map_err(|e| RecordingError::Invalid {
        path: path.to_path_buf(),
        message: e.to_string(),
    })?;
    json.push('\n');
    Ok(json)
}

/// Check that `rec` can be written: columns of equal length, a motion column, finite
/// values, a positive rate. `path` only names the file in errors
/// ([`RecordingError::Invalid`]).
pub fn validate(path: &Path, rec: &Recording) -> Result<(), RecordingError> {
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
