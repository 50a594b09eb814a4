//! Errors of Bode plotting.

use std::path::PathBuf;

/// Why a plot could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// A response has no lines (or none with a finite variance).
    #[error("{what}: nothing to plot ({reason})")]
    Empty {
        /// Which curve ("measured" or the model's label).
        what: String,
        /// Why, e.g. "no lines".
        reason: String,
    },
    /// A per-line vector has a different length than `freq_hz`.
    #[error("{what}: `{field}` has {got} entries, `freq_hz` has {expected}")]
    LengthMismatch {
        /// Which curve.
        what: String,
        /// Which field (`h`, `var`, `coherence`).
        field: &'static str,
        /// Length of `freq_hz`.
        expected: usize,
        /// Length of the field.
        got: usize,
    },
    /// A frequency is not finite and positive, or frequencies do not increase (a log axis
    /// needs positive increasing frequencies).
    #[error("{what}: line {index}: frequency {freq_hz} Hz is not positive, finite and increasing")]
    InvalidFrequency {
        /// Which curve.
        what: String,
        /// 0-based line index.
        index: usize,
        /// The frequency [Hz].
        freq_hz: f64,
    },
    /// A response value is not finite or is zero (not representable in dB).
    #[error("{what}: line {index} ({freq_hz} Hz): response is zero or not finite")]
    InvalidResponse {
        /// Which curve.
        what: String,
        /// 0-based line index.
        index: usize,
        /// The frequency [Hz].
        freq_hz: f64,
    },
    /// A measured variance is zero, negative or NaN (`+inf` marks an unusable line and is
    /// allowed).
    #[error("measured: line {index} ({freq_hz} Hz): variance {var} is not positive")]
    InvalidVariance {
        /// 0-based line index.
        index: usize,
        /// The frequency [Hz].
        freq_hz: f64,
        /// The variance.
        var: f64,
    },
    /// A coherence value is NaN or outside [0, 1].
    #[error("measured: line {index}: coherence {value} is outside [0, 1]")]
    InvalidCoherence {
        /// 0-based line index.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A marker frequency is not finite and positive.
    #[error("marker frequency {freq_hz} Hz is not finite and positive")]
    InvalidMarker {
        /// The frequency [Hz].
        freq_hz: f64,
    },
    /// The picture size is too small to lay out the panels.
    #[error("picture size {width_px} x {height_px} px is too small (at least 400 x 300)")]
    InvalidSize {
        /// Width [px].
        width_px: u32,
        /// Height [px].
        height_px: u32,
    },
    /// The drawing library failed.
    #[error("rendering failed: {0}")]
    Render(String),
    /// The SVG file could not be written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating-system error.
        #[source]
        source: std::io::Error,
    },
}
