//! Errors of the identification steps, each with the context needed to act on it.

use crate::frf::FrfKind;
use crate::model::ModelError;

/// Why an identification step could not produce a result.
#[derive(Debug, PartialEq, thiserror::Error)]
pub enum IdentifyError {
    /// The FRF has no line with a finite variance, a finite non-zero response and a
    /// frequency inside the requested band.
    #[error("no usable lines in {band_hz:?} Hz ({total} lines in the FRF)")]
    NoUsableLines {
        /// Band that was searched [Hz].
        band_hz: [f64; 2],
        /// Number of lines in the FRF.
        total: usize,
    },
    /// Fewer usable lines than the step needs.
    #[error("{what}: {usable} usable lines, at least {needed} needed")]
    TooFewLines {
        /// The step that needed them.
        what: &'static str,
        /// Usable lines found.
        usable: usize,
        /// Lines needed.
        needed: usize,
    },
    /// The FRF relates a quantity this step cannot model.
    #[error("FRF kind {kind:?} is not supported by {what}")]
    UnsupportedKind {
        /// The step.
        what: &'static str,
        /// The FRF's kind.
        kind: FrfKind,
    },
    /// The FRF's sample rate is missing or invalid.
    #[error("sample rate {fs_hz} Hz must be positive and finite")]
    SampleRate {
        /// The offending sample rate [Hz].
        fs_hz: f64,
    },
    /// A chain given to or produced by the step is invalid.
    #[error("invalid chain: {0}")]
    Model(#[from] ModelError),
    /// No start of the multi-start fit produced a finite cost.
    #[error("fit of a {masses}-mass chain failed on all {starts} starts: {reason}")]
    FitFailed {
        /// Model order.
        masses: usize,
        /// Starts tried.
        starts: usize,
        /// Last failure reason.
        reason: String,
    },
    /// The arguments are inconsistent.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}
