//! Errors of reading and writing recordings.

use std::path::PathBuf;

/// Why a recording could not be read or written.
///
/// Every variant names the file; variants about file content name the line (1-based, as a
/// text editor shows it, counting comment and blank lines) and, where it applies, the column
/// (by its header name).
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be opened, read, written or renamed.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
    /// A line is not valid UTF-8 text.
    #[error("{}: line {line}: not valid UTF-8 text", path.display())]
    NotUtf8 {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
    },
    /// A line is longer than [`MAX_LINE_BYTES`](super::MAX_LINE_BYTES) (not a recording,
    /// or a file without line ends: refused before it fills the memory).
    #[error("{}: line {line}: longer than {max_bytes} bytes (not a recording row)", path.display())]
    LineTooLong {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The limit [bytes].
        max_bytes: usize,
    },
    /// The file holds no header line, or a header but no data rows.
    #[error("{}: no data rows (a header line and at least one row are needed)", path.display())]
    Empty {
        /// The file concerned.
        path: PathBuf,
    },
    /// A required column is missing from the header.
    #[error("{}: line {line}: the header has no column `{column}`", path.display())]
    MissingColumn {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number of the header.
        line: usize,
        /// Name of the missing column.
        column: String,
    },
    /// A column name appears twice in the header.
    #[error("{}: line {line}: column `{column}` appears more than once in the header", path.display())]
    DuplicateColumn {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number of the header.
        line: usize,
        /// The repeated column name.
        column: String,
    },
    /// The header has none of `position_rad`, `velocity_rad_s`, `acceleration_rad_s2`.
    #[error(
        "{}: line {line}: the header has no motion column (one of `position_rad`, \
         `velocity_rad_s`, `acceleration_rad_s2` is needed)",
        path.display()
    )]
    NoMotionColumn {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number of the header.
        line: usize,
    },
    /// A field is not a number.
    #[error("{}: line {line}, column {column}: cannot parse \"{text}\" as a number", path.display())]
    Parse {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Header name of the column.
        column: String,
        /// The offending text (trimmed, shortened to 40 characters).
        text: String,
    },
    /// A field is a number but NaN or infinite.
    #[error("{}: line {line}, column {column}: value \"{text}\" is not finite", path.display())]
    NonFinite {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Header name of the column.
        column: String,
        /// The offending text.
        text: String,
    },
    /// A row has a different number of fields than the header.
    #[error("{}: line {line}: expected {expected} comma-separated fields (as in the header), got {got}", path.display())]
    RowLength {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Number of header columns.
        expected: usize,
        /// Number of fields in the row.
        got: usize,
    },
    /// `time_s` does not increase from the previous row to this one.
    #[error(
        "{}: line {line}, column time_s: time {time_s} s does not increase (previous row: {previous_s} s)",
        path.display()
    )]
    TimeNotIncreasing {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// Time on this line [s].
        time_s: f64,
        /// Time on the previous data row [s].
        previous_s: f64,
    },
    /// The time step ending at this line differs from the median step by more than 1 %.
    #[error(
        "{}: line {line}, column time_s: time step {step_s} s differs from the median step \
         {expected_s} s by more than 1 % (samples must be uniform)",
        path.display()
    )]
    NotUniform {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The step from the previous row [s].
        step_s: f64,
        /// The median step [s].
        expected_s: f64,
    },
    /// The sidecar's `sample_rate_hz` contradicts the `time_s` column (its median step
    /// means another rate, by more than 1 %).
    #[error(
        "{}: column time_s: the median time step {median_step_s} s means {time_hz} Hz, but the \
         sidecar's sample_rate_hz is {sidecar_hz} Hz (more than 1 % apart)",
        path.display()
    )]
    RateContradiction {
        /// The file concerned.
        path: PathBuf,
        /// The sidecar's rate [Hz].
        sidecar_hz: f64,
        /// The rate the median `time_s` step means [Hz].
        time_hz: f64,
        /// The median `time_s` step [s].
        median_step_s: f64,
    },
    /// With the sidecar's rate, a `time_s` step that is not `1 / sample_rate_hz` (a gap, a
    /// jump or a repeated stretch of time).
    #[error(
        "{}: line {line}, column time_s: time step {step_s} s, but the sidecar's \
         sample_rate_hz {sidecar_hz} Hz means {expected_s} s (a gap or jump in time_s)",
        path.display()
    )]
    TimeGap {
        /// The file concerned.
        path: PathBuf,
        /// 1-based line number of the row after the step.
        line: usize,
        /// The step from the previous row [s].
        step_s: f64,
        /// `1 / sample_rate_hz` [s].
        expected_s: f64,
        /// The sidecar's rate [Hz].
        sidecar_hz: f64,
    },
    /// Neither the sidecar nor `time_s` (with at least two rows) gives the sample rate.
    #[error(
        "{}: cannot determine the sample rate: no `sample_rate_hz` in the sidecar and {reason}",
        path.display()
    )]
    NoSampleRate {
        /// The file concerned.
        path: PathBuf,
        /// What is missing, e.g. "no `time_s` column".
        reason: String,
    },
    /// The JSON sidecar is malformed or holds an invalid value.
    #[error("{}: {message}", path.display())]
    Sidecar {
        /// The sidecar file.
        path: PathBuf,
        /// What is wrong (from the JSON parser, with its line and column).
        message: String,
    },
    /// A recording to be written is inconsistent (e.g. columns of different lengths).
    #[error("{}: cannot write recording: {message}", path.display())]
    Invalid {
        /// The file that was to be written.
        path: PathBuf,
        /// What is wrong.
        message: String,
    },
}
