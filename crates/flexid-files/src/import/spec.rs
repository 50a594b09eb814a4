//! [`MatSpec`]: which variables of a measurement file make a [`Recording`], and the
//! conversion itself ([`mat_to_recording`]).

use super::lines::{excited_lines, mean_period};
use super::mat5::{dims_text, MatFile, MatValue};
use super::ImportError;
use crate::recording::{MotionSignal, Recording, Sidecar};
use flexid_core::excitation::{ExcitationInfo, ExcitationKind};
use std::path::Path;

/// Variable names tried for the sample rate [Hz] when neither
/// [`MatSpec::sample_rate_hz`] nor [`MatSpec::sample_rate_var`] is given.
pub const SAMPLE_RATE_NAMES: &[&str] = &["fs", "Fs", "FS", "ms.harm.fs"];
/// Variable names tried for the sample period [s] after [`SAMPLE_RATE_NAMES`].
pub const SAMPLE_PERIOD_NAMES: &[&str] = &["Ts", "ts", "dt"];

/// How to turn a measurement file into a [`Recording`].
///
/// A signal is a numeric vector, or one channel of a matrix: samples run along the longer
/// dimension (singleton dimensions are ignored, so `3x1xN` is `3xN`) and the channel is
/// picked by the 0-based `*_column` index along the shorter one. For text (DaISy) files the
/// names are only labels and the columns are the file's columns.
#[derive(Debug, Clone, PartialEq)]
pub struct MatSpec {
    /// Input variable, stored in `torque_cmd_nm` (e.g. `iq_adx`, the motor current [A]).
    pub input: String,
    /// Channel of the input when it is a matrix (text files: column, default 0).
    pub input_column: Option<usize>,
    /// Factor applied to the input (e.g. a torque constant [N m/A]); 1 keeps the file's units.
    pub input_scale: f64,
    /// A scalar variable of the file whose value also multiplies the input (e.g. a drive
    /// gain `gtau` [N/V] stored beside a controller output in volts); `None`: none.
    pub input_scale_var: Option<String>,
    /// Output variable (e.g. `theta_mx`).
    pub output: String,
    /// Channel of the output when it is a matrix (text files: column, default 1).
    pub output_column: Option<usize>,
    /// Which motion column the output fills.
    pub output_kind: MotionSignal,
    /// Factor applied to the output (e.g. -1 for a flipped encoder).
    pub output_scale: f64,
    /// Sample rate [Hz]; when `None` it is read from the file ([`Self::sample_rate_var`] or
    /// one of [`SAMPLE_RATE_NAMES`] / [`SAMPLE_PERIOD_NAMES`]).
    pub sample_rate_hz: Option<f64>,
    /// Variable (dotted struct path allowed) holding the sample rate [Hz].
    pub sample_rate_var: Option<String>,
    /// Samples per period for periodic excitation; `None` for non-periodic data.
    pub period_samples: Option<usize>,
    /// Leading periods to discard as transient.
    pub transient_periods: usize,
    /// Variable holding the designed excitation (one period, or a periodic signal) from
    /// which the excited lines are computed; `None` uses the input.
    pub excitation_reference: Option<String>,
    /// A DFT line is excited when its amplitude exceeds this fraction of the largest one
    /// (1e-6 for a designed signal; about 1e-2 for a measured one).
    pub line_threshold: f64,
    /// Excitation design name for the sidecar (e.g. "schroeder").
    pub design: Option<String>,
    /// Free text appended to the sidecar's `source` (units caveats and the like).
    pub notes: String,
    /// The record holds several realisations of a flat multisine of `period_samples`, one
    /// steady period each after its own lead-in ([`super::realisations`]): they are found
    /// by the input's periodicity, the record is cut from the first lead-in to the last
    /// period's end, and the sidecar lists them (`transient_periods` is not used).
    pub realisations: bool,
    /// Subtract each signal's mean over the whole file first (offset errors of the
    /// acquisition, e.g. the Silverbox's README asks for it).
    pub remove_mean: bool,
    /// The input is a measured analogue signal, band-limited between the samples, not a
    /// command held over each sample ([`ExcitationInfo::band_limited`]; realisations only).
    pub band_limited: bool,
}

impl Default for MatSpec {
    fn default() -> Self {
        MatSpec {
            input: String::new(),
            input_column: None,
            input_scale: 1.0,
            input_scale_var: None,
            output: String::new(),
            output_column: None,
            output_kind: MotionSignal::Position,
            output_scale: 1.0,
            sample_rate_hz: None,
            sample_rate_var: None,
            period_samples: None,
            transient_periods: 0,
            excitation_reference: None,
            line_threshold: 1e-6,
            design: None,
            notes: String::new(),
            realisations: false,
            remove_mean: false,
            band_limited: false,
        }
    }
}

impl MatSpec {
    /// A spec reading `input` -> `output` (as `output_kind`) with the defaults: scales 1,
    /// sample rate from the file, not periodic.
    pub fn new(input: &str, output: &str, output_kind: MotionSignal) -> MatSpec {
        MatSpec {
            input: input.into(),
            output: output.into(),
            output_kind,
            ..MatSpec::default()
        }
    }
}

/// Reads a MAT v5 file and builds a [`Recording`] as `spec` says: `time_s[k] = k / fs`,
/// `torque_cmd_nm = input_scale * input`, the `output_kind` column `= output_scale * output`,
/// and a sidecar with the sample rate, the source text and, for periodic data, the
/// [`ExcitationInfo`] (kind `Multisine`, excited lines from the DFT of one period of the
/// excitation reference). Periodic records are cut to whole periods.
pub fn mat_to_recording(path: &Path, spec: &MatSpec) -> Result<Recording, ImportError> {
    let mat = MatFile::read(path)?;
    let input = signal(&mat, path, &spec.input, spec.input_column)?;
    let output = signal(&mat, path, &spec.output, spec.output_column)?;
    let (fs, fs_from) = match spec.sample_rate_hz {
        Some(fs) => (fs, "given".to_string()),
        None => sample_rate_from_file(&mat, path, spec.sample_rate_var.as_deref())?,
    };
    let reference = match &spec.excitation_reference {
        Some(name) => Some(signal(&mat, path, name, None)?),
        None => None,
    };
    let file = file_name(path);
    let mut spec = spec.clone();
    let mut scaled_by = String::new();
    if let Some(name) = &spec.input_scale_var {
        let g = scalar(&mat, path, name, "input scale")?;
        if !(g.is_finite() && g != 0.0) {
            return Err(ImportError::BadVariable {
                path: path.to_path_buf(),
                name: name.clone(),
                reason: format!("is {g}, not a usable input scale"),
            });
        }
        spec.input_scale *= g;
        scaled_by = format!(" x `{name}` = {g}");
    }
    let spec = &spec;
    let what = format!(
        "{file} (MAT v5: {}): torque_cmd_nm <- `{}`{}{scaled_by}, {} <- `{}`{}; fs {fs} Hz ({fs_from})",
        mat.header_text.split(',').next().unwrap_or(""),
        spec.input,
        column_text(spec.input_column),
        motion_column_name(spec.output_kind),
        spec.output,
        column_text(spec.output_column),
    );
    build_recording(path, spec, what, input, output, reference, fs)
}

/// Shared tail of the importers: checks, periodic cut, excitation info, sidecar.
pub(crate) fn build_recording(
    path: &Path,
    spec: &MatSpec,
    mut source: String,
    mut input: Vec<f64>,
    mut output: Vec<f64>,
    reference: Option<Vec<f64>>,
    fs: f64,
) -> Result<Recording, ImportError> {
    let spec_err = |reason: String| ImportError::Spec {
        path: path.to_path_buf(),
        reason,
    };
    if !(fs.is_finite() && fs > 0.0) {
        return Err(spec_err(format!("sample rate {fs} Hz is not positive")));
    }
    if input.len() != output.len() {
        return Err(spec_err(format!(
            "input `{}` has {} samples, output `{}` has {}",
            spec.input,
            input.len(),
            spec.output,
            output.len()
        )));
    }
    if input.is_empty() {
        return Err(spec_err("no samples".into()));
    }
    input.iter_mut().for_each(|v| *v *= spec.input_scale);
    output.iter_mut().for_each(|v| *v *= spec.output_scale);
    if spec.input_scale != 1.0 {
        source += &format!("; input scaled by {}", spec.input_scale);
    }
    if spec.output_scale != 1.0 {
        source += &format!("; output scaled by {}", spec.output_scale);
    }
    if spec.remove_mean {
        let (mu, my) = (mean(&input), mean(&output));
        input.iter_mut().for_each(|v| *v -= mu);
        output.iter_mut().for_each(|v| *v -= my);
        source += &format!("; means removed (input {mu:.6e}, output {my:.6e})");
    }
    if let (true, Some(period)) = (spec.realisations, spec.period_samples) {
        return realisations_recording(path, spec, source, input, output, period, fs);
    }

    let excitation = match spec.period_samples {
        Some(period) => {
            let n_periods = input.len().checked_div(period).unwrap_or(0);
            if n_periods <= spec.transient_periods {
                return Err(spec_err(format!(
                    "{} samples hold {n_periods} whole periods of {period}, need more than the {} transient ones",
                    input.len(),
                    spec.transient_periods
                )));
            }
            let used = n_periods * period;
            if used < input.len() {
                source += &format!(
                    "; cut to {n_periods} whole periods (dropped {} trailing samples)",
                    input.len() - used
                );
                input.truncate(used);
                output.truncate(used);
            }
            let (ref_signal, ref_name) = match &reference {
                Some(r) => (
                    r.as_slice(),
                    spec.excitation_reference.clone().unwrap_or_default(),
                ),
                None => (input.as_slice(), spec.input.clone()),
            };
            let one = mean_period(ref_signal, period, spec.transient_periods).ok_or_else(|| {
                spec_err(format!(
                    "excitation reference `{ref_name}` ({} samples) holds no steady-state period of {period}",
                    ref_signal.len()
                ))
            })?;
            let lines = excited_lines(&one, spec.line_threshold);
            source += &format!(
                "; {n_periods} periods of {period} samples ({} transient), {} excited lines from the DFT of one period of `{ref_name}` (threshold {:e} of the largest)",
                spec.transient_periods,
                lines.len(),
                spec.line_threshold
            );
            let steady = &input[spec.transient_periods * period..];
            let df = fs / period as f64;
            Some(ExcitationInfo {
                kind: ExcitationKind::Multisine,
                period_samples: period,
                periods: n_periods - spec.transient_periods,
                transient_periods: spec.transient_periods,
                band_hz: match (lines.first(), lines.last()) {
                    (Some(&lo), Some(&hi)) => Some([lo as f64 * df, hi as f64 * df]),
                    _ => None,
                },
                excited_lines: lines,
                peak_nm: Some(steady.iter().fold(0.0, |m, v| f64::max(m, v.abs()))),
                rms_nm: Some(rms(steady)),
                design: spec.design.clone(),
                blocks: Vec::new(),
                realisations: Vec::new(),
                band_limited: false,
            })
        }
        None => {
            source += "; not periodic (estimate with Welch H1)";
            Some(ExcitationInfo {
                kind: ExcitationKind::Other,
                period_samples: 0,
                periods: 0,
                transient_periods: 0,
                excited_lines: Vec::new(),
                band_hz: None,
                peak_nm: Some(input.iter().fold(0.0, |m, v| f64::max(m, v.abs()))),
                rms_nm: Some(rms(&input)),
                design: spec.design.clone(),
                blocks: Vec::new(),
                realisations: Vec::new(),
                band_limited: false,
            })
        }
    };
    if !spec.notes.is_empty() {
        source += ". ";
        source += &spec.notes;
    }

    Ok(assemble(spec, source, input, output, excitation, fs))
}

/// The recording: `time_s[k] = k / fs`, the input in the torque column, the output in the
/// spec's motion column, the sidecar with the rate, the excitation and the source.
fn assemble(
    spec: &MatSpec,
    source: String,
    input: Vec<f64>,
    output: Vec<f64>,
    excitation: Option<ExcitationInfo>,
    fs: f64,
) -> Recording {
    let time_s = (0..input.len()).map(|k| k as f64 / fs).collect();
    let mut rec = Recording {
        time_s,
        torque_cmd_nm: input,
        sample_rate_hz: fs,
        sidecar: Sidecar {
            sample_rate_hz: Some(fs),
            excitation,
            source: Some(source),
            ..Sidecar::default()
        },
        ..Recording::default()
    };
    match spec.output_kind {
        MotionSignal::Position => rec.position_rad = Some(output),
        MotionSignal::Velocity => rec.velocity_rad_s = Some(output),
        MotionSignal::Acceleration => rec.acceleration_rad_s2 = Some(output),
    }
    rec
}

fn mean(x: &[f64]) -> f64 {
    x.iter().sum::<f64>() / x.len().max(1) as f64
}

/// A record of several multisine realisations ([`MatSpec::realisations`]): found, cut and
/// described.
fn realisations_recording(
    path: &Path,
    spec: &MatSpec,
    mut source: String,
    input: Vec<f64>,
    output: Vec<f64>,
    period: usize,
    fs: f64,
) -> Result<Recording, ImportError> {
    let found = super::realisations::find(&input, period);
    if found.len() < 2 {
        return Err(ImportError::Spec {
            path: path.to_path_buf(),
            reason: format!(
                "input `{}`: {} realisation(s) of a {period}-sample period found by its periodicity (a lead-in of at least {} samples repeating one period later), need at least 2",
                spec.input,
                found.len(),
                super::realisations::MIN_RUN
            ),
        });
    }
    let steady: Vec<usize> = found.iter().map(|f| f.1).collect();
    let lines = super::realisations::flat_lines(&input, period, &steady);
    if lines.is_empty() {
        return Err(ImportError::Spec {
            path: path.to_path_buf(),
            reason: format!(
                "input `{}`: no excited line common to the realisations",
                spec.input
            ),
        });
    }
    let (from, to) = (found[0].0, found[found.len() - 1].1 + period);
    let realisations = super::realisations::described(&found, from);
    source += &format!(
        "; {} realisations of a {period}-sample multisine found by the input's periodicity: steady periods at rows {} of the file (0-based), lead-ins of {}-{} samples; cut to rows {from}..{to} of the file; {} excited lines (at least half the median line amplitude in every realisation)",
        found.len(),
        steady.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(", "),
        realisations.iter().map(|r| r.lead_in).min().unwrap_or(0),
        realisations.iter().map(|r| r.lead_in).max().unwrap_or(0),
        lines.len(),
    );
    if !spec.notes.is_empty() {
        source += ". ";
        source += &spec.notes;
    }
    let input = input[from..to].to_vec();
    let output = output[from..to].to_vec();
    let df = fs / period as f64;
    let periods: Vec<f64> = realisations
        .iter()
        .flat_map(|r| input[r.start..r.start + period].iter().copied())
        .collect();
    let excitation = ExcitationInfo {
        kind: ExcitationKind::Multisine,
        period_samples: period,
        periods: realisations.len(),
        transient_periods: 0,
        band_hz: match (lines.first(), lines.last()) {
            (Some(&lo), Some(&hi)) => Some([lo as f64 * df, hi as f64 * df]),
            _ => None,
        },
        excited_lines: lines,
        peak_nm: Some(periods.iter().fold(0.0, |m, v| f64::max(m, v.abs()))),
        rms_nm: Some(rms(&periods)),
        design: spec.design.clone(),
        blocks: Vec::new(),
        realisations,
        band_limited: spec.band_limited,
    };
    Ok(assemble(spec, source, input, output, Some(excitation), fs))
}

fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        0.0
    } else {
        (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
    }
}

pub(crate) fn file_name(path: &Path) -> String {
    path.file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

fn column_text(c: Option<usize>) -> String {
    c.map(|c| format!("[channel {c}]")).unwrap_or_default()
}

pub(crate) fn motion_column_name(kind: MotionSignal) -> &'static str {
    match kind {
        MotionSignal::Position => "position_rad",
        MotionSignal::Velocity => "velocity_rad_s",
        MotionSignal::Acceleration => "acceleration_rad_s2",
    }
}

fn missing(mat: &MatFile, path: &Path, name: &str) -> ImportError {
    ImportError::MissingVariable {
        path: path.to_path_buf(),
        name: name.to_string(),
        available: mat.names(),
    }
}

/// The value of scalar variable `name` (`what` it is for, in the error).
fn scalar(mat: &MatFile, path: &Path, name: &str, what: &str) -> Result<f64, ImportError> {
    let v = mat.get(name).ok_or_else(|| missing(mat, path, name))?;
    v.as_scalar().ok_or_else(|| ImportError::BadVariable {
        path: path.to_path_buf(),
        name: name.to_string(),
        reason: format!("is {}, not a scalar {what}", v.describe()),
    })
}

/// The sample rate [Hz] from the file, and the variable it came from.
fn sample_rate_from_file(
    mat: &MatFile,
    path: &Path,
    var: Option<&str>,
) -> Result<(f64, String), ImportError> {
    let scalar = |name: &str| scalar(mat, path, name, "sample rate");
    if let Some(name) = var {
        return Ok((scalar(name)?, format!("from `{name}`")));
    }
    for name in SAMPLE_RATE_NAMES {
        if mat.get(name).is_some() {
            return Ok((scalar(name)?, format!("from `{name}`")));
        }
    }
    for name in SAMPLE_PERIOD_NAMES {
        if mat.get(name).is_some() {
            return Ok((1.0 / scalar(name)?, format!("1 / `{name}`")));
        }
    }
    Err(ImportError::Spec {
        path: path.to_path_buf(),
        reason: format!(
            "no sample rate given and none of {:?} / {:?} in the file",
            SAMPLE_RATE_NAMES, SAMPLE_PERIOD_NAMES
        ),
    })
}

/// One signal (a vector, or channel `column` of a matrix) of variable `name`.
pub fn signal(
    mat: &MatFile,
    path: &Path,
    name: &str,
    column: Option<usize>,
) -> Result<Vec<f64>, ImportError> {
    let bad = |reason: String| ImportError::BadVariable {
        path: path.to_path_buf(),
        name: name.to_string(),
        reason,
    };
    let value = mat.get(name).ok_or_else(|| missing(mat, path, name))?;
    let (dims, data) = match value {
        MatValue::Numeric {
            dims,
            data,
            imag: None,
        } => (dims, data),
        other => {
            return Err(bad(format!(
                "is {}, not a real numeric array",
                other.describe()
            )))
        }
    };
    let shape: Vec<usize> = dims.iter().cloned().filter(|&d| d != 1).collect();
    match shape.as_slice() {
        [] | [_] => match column {
            None | Some(0) => Ok(data.clone()),
            Some(c) => Err(bad(format!(
                "is a vector ({}), has no channel {c}",
                dims_text(dims)
            ))),
        },
        &[rows, cols] => {
            let c = column.ok_or_else(|| {
                bad(format!(
                    "is a {} matrix: say which channel (column) to use",
                    dims_text(dims)
                ))
            })?;
            if rows >= cols {
                if c >= cols {
                    return Err(bad(format!(
                        "{} matrix has no channel {c}",
                        dims_text(dims)
                    )));
                }
                Ok(data[c * rows..(c + 1) * rows].to_vec())
            } else {
                if c >= rows {
                    return Err(bad(format!(
                        "{} matrix has no channel {c}",
                        dims_text(dims)
                    )));
                }
                Ok((0..cols).map(|j| data[c + j * rows]).collect())
            }
        }
        _ => Err(bad(format!(
            "has {} dimensions, need a vector or matrix",
            dims_text(dims)
        ))),
    }
}
