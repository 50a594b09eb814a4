//! Errors of the FRF estimators.

use thiserror::Error;

/// Why an FRF could not be estimated. Every variant carries the numbers needed to act on it.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FrfError {
    /// Input (torque) and output signals have different lengths \[samples\].
    #[error("input and output lengths differ: u has {u} samples, y has {y}")]
    LengthMismatch {
        /// Length of the input signal \[samples\].
        u: usize,
        /// Length of the output signal \[samples\].
        y: usize,
    },
    /// Not enough data for one estimate: `needed` and `got` are samples (or periods/segments,
    /// as stated by `unit`).
    #[error("too short: need at least {needed} {unit}, got {got}")]
    TooShort {
        /// Minimum amount required.
        needed: usize,
        /// Amount available.
        got: usize,
        /// What is counted: "samples", "periods" or "segments".
        unit: &'static str,
    },
    /// A requested DFT line lies above the Nyquist line of the period (`max` = N/2).
    #[error("DFT line {line} out of range: the highest line of the period is {max}")]
    LineOutOfRange {
        /// The offending line index.
        line: usize,
        /// Highest valid line index (`period_samples / 2`).
        max: usize,
    },
    /// No excited line was given and none could be inferred from the input spectrum.
    #[error("no excited lines (none given and none found in the input spectrum)")]
    NoExcitedLines,
    /// A parameter has an invalid value (zero period, overlap >= segment length,
    /// non-positive sample rate, ...).
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
}

impl FrfError {
    pub(crate) fn invalid(name: &'static str, reason: impl Into<String>) -> Self {
        FrfError::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }
}

/// Check that a sample rate is positive and finite.
pub(crate) fn check_fs(fs: f64) -> Result<(), FrfError> {
    if fs.is_finite() && fs > 0.0 {
        Ok(())
    } else {
        Err(FrfError::invalid(
            "sample_rate_hz",
            format!("must be positive and finite, got {fs}"),
        ))
    }
}
