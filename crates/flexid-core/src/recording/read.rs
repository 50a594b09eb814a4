//! Parsing `REC.csv` and its optional `REC.json` sidecar from any reader (the files on
//! disk are opened by `flexid-files`).

use super::error::RecordingError;
use super::period::infer_excitation;
use super::types::{Recording, Sidecar};
use crate::excitation::ExcitationKind;
use std::io::{BufRead, Read};
use std::path::{Path, PathBuf};

/// Relative tolerance on the uniformity of `time_s` steps (1 %).
pub const TIME_STEP_TOLERANCE: f64 = 0.01;

/// Longest line of `REC.csv` [bytes]: a row of six round-trip numbers takes about 150; a
/// longer line is refused before it is held in memory (a file without line ends, or
/// `/dev/zero`, would otherwise grow one line without bound).
pub const MAX_LINE_BYTES: usize = 64 * 1024;

/// Column names of `REC.csv`, in the order the writer uses.
pub const COLUMNS: [&str; 6] = [
    "time_s",
    "torque_cmd_nm",
    "position_rad",
    "velocity_rad_s",
    "acceleration_rad_s2",
    "torque_actual_nm",
];
const TIME: usize = 0;
const TORQUE: usize = 1;
const POS: usize = 2;
const VEL: usize = 3;
const ACC: usize = 4;
const TACT: usize = 5;

/// A recording as read, with the warnings collected on the way.
#[derive(Debug, Clone, PartialEq)]
pub struct ReadReport {
    /// The recording. Its sidecar is the effective one: `sample_rate_hz` is always set and
    /// `excitation` is inferred from the torque when the file did not give it.
    pub recording: Recording,
    /// Things the reader tolerated or inferred (unknown columns ignored, excitation inferred,
    /// sidecar rate disagreeing with `time_s`, ...), one sentence each.
    pub warnings: Vec<String>,
}

/// The sidecar path of a recording: same directory and stem, extension `.json`.
pub fn sidecar_path(csv_path: &Path) -> PathBuf {
    csv_path.with_extension("json")
}

/// Parse a recording held in memory (`csv` text and optional sidecar JSON text); errors name
/// the file `<memory>`.
pub fn parse_recording(
    csv: &str,
    sidecar_json: Option<&str>,
) -> Result<ReadReport, RecordingError> {
    let path = Path::new("<memory>");
    let sidecar = sidecar_json
        .map(|s| parse_sidecar(s, Path::new("<memory>.json")))
        .transpose()?;
    read_recording_from(csv.as_bytes(), path, sidecar)
}

/// Parse and check a sidecar: JSON per [`Sidecar`], `sample_rate_hz` finite and positive.
/// `path` only names the file in errors.
pub fn parse_sidecar(json: &str, path: &Path) -> Result<Sidecar, RecordingError> {
    let err = |message: String| RecordingError::Sidecar {
        path: path.to_path_buf(),
        message,
    };
    let mut s: Sidecar = serde_json::from_str(json).map_err(|e| err(e.to_string()))?;
    // Re-read with exact float parsing (see `json_exact`); the structure is already valid.
    if let Some(exact) = super::json_exact::parse_exact(json) {
        if let Ok(e) = serde_json::from_value::<Sidecar>(exact) {
            s = e;
        }
    }
    if let Some(fs) = s.sample_rate_hz {
        if !(fs.is_finite() && fs > 0.0) {
            return Err(err(format!(
                "sample_rate_hz must be finite and positive, got {fs}"
            )));
        }
    }
    Ok(s)
}

/// Parse CSV text from `reader` with an already parsed sidecar; `path` names the file in
/// errors and warnings.
///
/// Format: lines starting with `#` (after optional spaces) and blank lines are skipped; the
/// first other line is the header; every further line is a row of comma-separated numbers
/// with as many fields as the header. Fields and names may have surrounding spaces, lines
/// may end in CRLF. Columns are matched by name: `torque_cmd_nm` and one motion column are
/// required; `time_s` is required unless the sidecar gives `sample_rate_hz` (then time is
/// `k / fs`). Unknown columns are ignored with a warning.
///
/// The sample rate is the sidecar's when given (a warning if the median `time_s` step
/// disagrees by more than 1 %); otherwise `time_s` must increase with uniform steps (each
/// within 1 % of the median step) and the rate is `(N-1) / (t_last - t_first)` [Hz].
pub fn read_recording_from<R: BufRead>(
    mut reader: R,
    path: &Path,
    sidecar: Option<Sidecar>,
) -> Result<ReadReport, RecordingError> {
    let p = || path.to_path_buf();
    let mut warnings = Vec::new();
    let mut buf: Vec<u8> = Vec::with_capacity(256);
    let mut line_no = 0usize;
    let mut ncols = 0usize;
    let mut slot_of_field: Vec<Option<usize>> = Vec::new();
    let mut present = [false; 6];
    let mut cols: [Vec<f64>; 6] = Default::default();
    let mut lines: Vec<usize> = Vec::new();
    let mut have_header = false;

    loop {
        buf.clear();
        let n = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|source| RecordingError::Io { path: p(), source })?;
        if n == 0 {
            break;
        }
        line_no += 1;
        if n > MAX_LINE_BYTES {
            return Err(RecordingError::LineTooLong {
                path: p(),
                line: line_no,
                max_bytes: MAX_LINE_BYTES,
            });
        }
        let text = std::str::from_utf8(&buf).map_err(|_| RecordingError::NotUtf8 {
            path: p(),
            line: line_no,
        })?;
        let mut t = text.trim();
        if line_no == 1 {
            t = t.trim_start_matches('\u{feff}').trim();
        }
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        if !have_header {
            have_header = true;
            for (i, name) in t.split(',').enumerate() {
                let name = name.trim();
                match COLUMNS.iter().position(|c| *c == name) {
                    Some(s) => {
                        if present[s] {
                            return Err(RecordingError::DuplicateColumn {
                                path: p(),
                                line: line_no,
                                column: name.to_string(),
                            });
                        }
                        present[s] = true;
                        slot_of_field.push(Some(s));
                    }
                    None => {
                        warnings.push(format!(
                            "{}: line {line_no}: ignoring unknown column `{name}` (field {})",
                            path.display(),
                            i + 1
                        ));
                        slot_of_field.push(None);
                    }
                }
            }
            ncols = slot_of_field.len();
            if !present[TORQUE] {
                return Err(RecordingError::MissingColumn {
                    path: p(),
                    line: line_no,
                    column: COLUMNS[TORQUE].to_string(),
                });
            }
            if !(present[POS] || present[VEL] || present[ACC]) {
                return Err(RecordingError::NoMotionColumn {
                    path: p(),
                    line: line_no,
                });
            }
            let rate_known = sidecar.as_ref().and_then(|s| s.sample_rate_hz).is_some();
            if !present[TIME] && !rate_known {
                return Err(RecordingError::MissingColumn {
                    path: p(),
                    line: line_no,
                    column: COLUMNS[TIME].to_string(),
                });
            }
            continue;
        }
        // Data row.
        let mut vals = [0.0_f64; 6];
        let mut got = 0usize;
        let mut first_err: Option<RecordingError> = None;
        for field in t.split(',') {
            if let Some(Some(s)) = slot_of_field.get(got) {
                if first_err.is_none() {
                    match parse_field(field) {
                        Ok(v) => vals[*s] = v,
                        Err(bad) => {
                            first_err = Some(field_error(bad, field, p(), line_no, COLUMNS[*s]))
                        }
                    }
                }
            }
            got += 1;
        }
        if got != ncols {
            return Err(RecordingError::RowLength {
                path: p(),
                line: line_no,
                expected: ncols,
                got,
            });
        }
        if let Some(e) = first_err {
            return Err(e);
        }
        for s in 0..6 {
            if present[s] {
                cols[s].push(vals[s]);
            }
        }
        lines.push(line_no);
    }
    if !have_header || lines.is_empty() {
        return Err(RecordingError::Empty { path: p() });
    }
    let n = lines.len();
    let mut sidecar = sidecar.unwrap_or_default();
    check_excitation_fits(&sidecar, n, path)?;
    let [time, torque, pos, vel, acc, tact] = cols;
    let time = if present[TIME] {
        check_increasing(&time, &lines, path)?;
        time
    } else {
        let fs = sidecar.sample_rate_hz.expect("checked with the header");
        warnings.push(format!(
            "{}: no `time_s` column; time is k / {fs} Hz",
            path.display()
        ));
        (0..n).map(|k| k as f64 / fs).collect()
    };
    let fs = match sidecar.sample_rate_hz {
        Some(fs) => {
            if present[TIME] && n >= 2 {
                check_against_rate(&time, &lines, fs, path)?;
            }
            fs
        }
        None => {
            if n < 2 {
                return Err(RecordingError::NoSampleRate {
                    path: p(),
                    reason: "time_s has a single row".to_string(),
                });
            }
            let med = median_step(&time);
            check_uniform(&time, &lines, med, path)?;
            let fs = (n - 1) as f64 / (time[n - 1] - time[0]);
            sidecar.sample_rate_hz = Some(fs);
            fs
        }
    };
    if sidecar.excitation.is_none() {
        let info = infer_excitation(&torque, fs);
        warnings.push(format!(
            "{}: no excitation in the sidecar; inferred from torque_cmd_nm: {:?}, \
             period {} samples, {} + {} periods, {} excited lines",
            path.display(),
            info.kind,
            info.period_samples,
            info.transient_periods,
            info.periods,
            info.excited_lines.len()
        ));
        sidecar.excitation = Some(info);
    }
    let opt = |on: bool, v: Vec<f64>| if on { Some(v) } else { None };
    Ok(ReadReport {
        recording: Recording {
            time_s: time,
            torque_cmd_nm: torque,
            position_rad: opt(present[POS], pos),
            velocity_rad_s: opt(present[VEL], vel),
            acceleration_rad_s2: opt(present[ACC], acc),
            torque_actual_nm: opt(present[TACT], tact),
            sample_rate_hz: fs,
            sidecar,
        },
        warnings,
    })
}

/// The sidecar's excitation against the `rows` read (also used for an excitation file and
/// its description): a period or a dwell block that the
/// record cannot hold is a contradiction, refused before anything is sized by it (issue
/// 16: `period_samples` of 1.5e9 made the estimator allocate 24 GB and abort); unless the
/// sidecar says the sweep ended early (`end.complete: false` or `ended_because`), whose rows are kept
/// whatever their number (the estimators then refuse the record as too short).
pub fn check_excitation_fits(
    sidecar: &Sidecar,
    rows: usize,
    path: &Path,
) -> Result<(), RecordingError> {
    let Some(e) = &sidecar.excitation else {
        return Ok(());
    };
    // an interrupted measurement: `end.complete: false`, or `ended_because` (the daemon's
    // store after a crash, and sweeps stopped early before `end` existed)
    if sidecar.end.as_ref().is_some_and(|end| !end.complete) || sidecar.ended_because.is_some() {
        return Ok(());
    }
    let err = |message: String| RecordingError::Sidecar {
        path: path.to_path_buf(),
        message,
    };
    if e.kind == ExcitationKind::Multisine && e.period_samples < 2 {
        // issue 16: `period_samples: 0` silently lost a mode
        return Err(err(format!(
            "excitation.period_samples {}: a multisine is periodic, its period needs at least 2 samples",
            e.period_samples
        )));
    }
    if e.period_samples > rows {
        return Err(err(format!(
            "excitation.period_samples {} is longer than the recording ({rows} rows)",
            e.period_samples
        )));
    }
    if e.period_samples > 0 {
        let claimed = e
            .transient_periods
            .checked_add(e.periods)
            .and_then(|p| p.checked_mul(e.period_samples));
        if claimed.is_none_or(|c| c > rows) {
            return Err(err(format!(
                "excitation: transient_periods {} + periods {} of period_samples {} need {} rows, \
                 but the recording has {rows} (a truncated file, or the wrong sidecar)",
                e.transient_periods,
                e.periods,
                e.period_samples,
                claimed.map_or("more than 2^64".to_string(), |c| c.to_string())
            )));
        }
        let nyquist_line = e.period_samples / 2;
        if let Some(&line) = e.excited_lines.iter().find(|&&l| l > nyquist_line) {
            return Err(err(format!(
                "excitation.excited_lines: line {line} is above the Nyquist line {nyquist_line} \
                 of a {}-sample period",
                e.period_samples
            )));
        }
    }
    for (i, r) in e.realisations.iter().enumerate() {
        let end = r.start.checked_add(e.period_samples);
        if e.period_samples == 0 || end.is_none_or(|end| end > rows) || r.lead_in > r.start {
            return Err(err(format!(
                "excitation.realisations[{i}]: start {} (lead-in {}) with period_samples {} does not fit the recording ({rows} rows)",
                r.start, r.lead_in, e.period_samples
            )));
        }
    }
    for (i, b) in e.blocks.iter().enumerate() {
        if b.period_samples == 0 || b.period_samples > rows || b.start >= rows {
            return Err(err(format!(
                "excitation.blocks[{i}]: start {} and period_samples {} do not fit the recording ({rows} rows)",
                b.start, b.period_samples
            )));
        }
    }
    Ok(())
}

enum BadField {
    Parse,
    NonFinite,
}

#[inline]
fn parse_field(field: &str) -> Result<f64, BadField> {
    match field.trim().parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        Ok(_) => Err(BadField::NonFinite),
        Err(_) => Err(BadField::Parse),
    }
}

fn field_error(
    bad: BadField,
    field: &str,
    path: PathBuf,
    line: usize,
    col: &str,
) -> RecordingError {
    let text: String = field.trim().chars().take(40).collect();
    let column = col.to_string();
    match bad {
        BadField::Parse => RecordingError::Parse {
            path,
            line,
            column,
            text,
        },
        BadField::NonFinite => RecordingError::NonFinite {
            path,
            line,
            column,
            text,
        },
    }
}

fn check_increasing(t: &[f64], lines: &[usize], path: &Path) -> Result<(), RecordingError> {
    for k in 1..t.len() {
        if t[k] <= t[k - 1] {
            return Err(RecordingError::TimeNotIncreasing {
                path: path.to_path_buf(),
                line: lines[k],
                time_s: t[k],
                previous_s: t[k - 1],
            });
        }
    }
    Ok(())
}

/// `time_s` against the sidecar's rate (issue 16: a 10 ms gap gave a wrong model and exit
/// 0; twice the rate was only a warning): the median step must mean the sidecar's rate,
/// and every step must be `1 / fs` within [`TIME_STEP_TOLERANCE`].
fn check_against_rate(
    t: &[f64],
    lines: &[usize],
    fs: f64,
    path: &Path,
) -> Result<(), RecordingError> {
    let med = median_step(t);
    if ((med * fs) - 1.0).abs() > TIME_STEP_TOLERANCE {
        return Err(RecordingError::RateContradiction {
            path: path.to_path_buf(),
            sidecar_hz: fs,
            time_hz: 1.0 / med,
            median_step_s: med,
        });
    }
    for k in 1..t.len() {
        let step = t[k] - t[k - 1];
        if ((step * fs) - 1.0).abs() > TIME_STEP_TOLERANCE {
            return Err(RecordingError::TimeGap {
                path: path.to_path_buf(),
                line: lines[k],
                step_s: step,
                expected_s: 1.0 / fs,
                sidecar_hz: fs,
            });
        }
    }
    Ok(())
}

fn median_step(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t.windows(2).map(|w| w[1] - w[0]).collect();
    let mid = d.len() / 2;
    let (_, m, _) = d.select_nth_unstable_by(mid, f64::total_cmp);
    *m
}

fn check_uniform(t: &[f64], lines: &[usize], med: f64, path: &Path) -> Result<(), RecordingError> {
    for k in 1..t.len() {
        let step = t[k] - t[k - 1];
        if (step - med).abs() > TIME_STEP_TOLERANCE * med {
            return Err(RecordingError::NotUniform {
                path: path.to_path_buf(),
                line: lines[k],
                step_s: step,
                expected_s: med,
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const CSV: &str =
        "time_s,torque_cmd_nm,position_rad\n0,0,0\n0.001,1,0\n0.002,0,0.001\n0.003,-1,0\n";

    /// Issue 16: an absurd `period_samples` made the estimator allocate 24 GB and abort; the
    /// reader refuses a period or a block the record cannot hold, naming the key.
    #[test]
    fn a_period_longer_than_the_record_is_refused() {
        let sidecar = |period: &str| {
            format!(
                r#"{{"sample_rate_hz": 1000.0, "excitation": {{"kind": "multisine", "period_samples": {period}, "periods": 1, "transient_periods": 0, "excited_lines": [1]}}}}"#
            )
        };
        let e = parse_recording(CSV, Some(&sidecar("1500000000"))).unwrap_err();
        assert!(matches!(e, RecordingError::Sidecar { .. }), "{e}");
        assert!(e.to_string().contains("period_samples 1500000000"), "{e}");
        // a period the record holds is read
        assert!(parse_recording(CSV, Some(&sidecar("2"))).is_ok());
        // an interrupted sweep keeps its rows, whole period or not
        let cut = sidecar("2000").replace(
            r#""sample_rate_hz""#,
            r#""end": {"complete": false, "reason": "drive fault", "cycle": 4}, "sample_rate_hz""#,
        );
        assert!(parse_recording(CSV, Some(&cut)).is_ok(), "{cut}");
        // so does one the daemon's store closed after a crash (`ended_because`)
        let crashed = sidecar("2000").replace(
            r#""sample_rate_hz""#,
            r#""ended_because": "interrupted: the daemon stopped during the sweep", "sample_rate_hz""#,
        );
        assert!(parse_recording(CSV, Some(&crashed)).is_ok(), "{crashed}");
    }
}
