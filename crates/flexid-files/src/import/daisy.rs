//! DaISy-style ASCII files: whitespace-separated numeric columns, one row per sample.

use super::spec::{build_recording, file_name, motion_column_name, MatSpec};
use super::ImportError;
use crate::recording::{MotionSignal, Recording};
use std::path::Path;

/// Reads the numeric rows of a whitespace-separated text file. Empty lines and lines
/// starting with `%` or `#` are skipped; every other row must hold the same number of
/// numbers.
pub fn read_columns(path: &Path) -> Result<Vec<Vec<f64>>, ImportError> {
    let text = std::fs::read(path).map_err(|source| ImportError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let text = String::from_utf8_lossy(&text);
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('%') || line.starts_with('#') {
            continue;
        }
        let err = |reason: String| ImportError::Text {
            path: path.to_path_buf(),
            line: i + 1,
            reason,
        };
        let row = line
            .split(|c: char| c.is_whitespace() || c == ',')
            .filter(|s| !s.is_empty())
            .map(|s| {
                s.parse::<f64>()
                    .map_err(|_| err(format!("`{s}` is not a number")))
            })
            .collect::<Result<Vec<f64>, _>>()?;
        if let Some(first) = rows.first() {
            if first.len() != row.len() {
                return Err(err(format!(
                    "{} columns, the first row has {}",
                    row.len(),
                    first.len()
                )));
            }
        }
        rows.push(row);
    }
    Ok(rows)
}

/// Builds a [`Recording`] from a column text file: column `spec.input_column` (default 0)
/// is the input, `spec.output_column` (default 1) the output; `spec.sample_rate_hz` is
/// required (text files carry no rate). Names in `spec` are labels only.
pub fn text_to_recording(path: &Path, spec: &MatSpec) -> Result<Recording, ImportError> {
    let rows = read_columns(path)?;
    let fs = spec.sample_rate_hz.ok_or_else(|| ImportError::Spec {
        path: path.to_path_buf(),
        reason: "a text file has no sample rate: give one".into(),
    })?;
    let ci = spec.input_column.unwrap_or(0);
    let co = spec.output_column.unwrap_or(1);
    let width = rows.first().map_or(0, |r| r.len());
    if ci >= width || co >= width {
        return Err(ImportError::Spec {
            path: path.to_path_buf(),
            reason: format!(
                "{} rows of {width} columns: no column {}",
                rows.len(),
                ci.max(co) + 1
            ),
        });
    }
    let input = rows.iter().map(|r| r[ci]).collect();
    let output = rows.iter().map(|r| r[co]).collect();
    let source = format!(
        "{} (ASCII columns): torque_cmd_nm <- column {} ({}), {} <- column {} ({}); fs {fs} Hz (given)",
        file_name(path),
        ci + 1,
        spec.input,
        motion_column_name(spec.output_kind),
        co + 1,
        spec.output,
    );
    build_recording(path, spec, source, input, output, None, fs)
}

/// Reads a 2-column DaISy file (column 1 input, column 2 output) sampled at
/// `sample_rate_hz` [Hz]; the output fills the `kind` column. Not periodic.
pub fn daisy_to_recording(
    path: &Path,
    sample_rate_hz: f64,
    kind: MotionSignal,
) -> Result<Recording, ImportError> {
    let spec = MatSpec {
        sample_rate_hz: Some(sample_rate_hz),
        ..MatSpec::new("u", "y", kind)
    };
    text_to_recording(path, &spec)
}
