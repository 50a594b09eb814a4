use serde::{Deserialize, Serialize};

/// The kind of excitation signal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ExcitationKind {
    /// Periodic multisine (any phase design).
    Multisine,
    /// Logarithmic (exponential) swept sine.
    Chirp,
    /// Stepped sine: a sequence of single-frequency dwell blocks.
    SteppedSine,
    /// Anything else (noise, unknown); estimated with the Welch H1 estimator.
    Other,
}

/// Description of an excitation signal, written beside every recording (the `excitation`
/// object of the `REC.json` sidecar).
///
/// For periodic signals the recording holds `transient_periods + periods` periods of
/// `period_samples` samples each; the first `transient_periods` are discarded by the
/// estimators.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ExcitationInfo {
    /// Signal kind; selects the estimator.
    pub kind: ExcitationKind,
    /// Samples per period (periodic signals) or per block (stepped sine). 0 if not periodic.
    #[serde(default)]
    pub period_samples: usize,
    /// Number of steady-state periods recorded after the transient ones.
    #[serde(default)]
    pub periods: usize,
    /// Number of leading periods to discard (transient).
    #[serde(default)]
    pub transient_periods: usize,
    /// Excited DFT line indices within one period (line k is at k * fs / period_samples Hz).
    /// Empty when not known: the estimator then infers them from the input spectrum.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub excited_lines: Vec<usize>,
    /// Lowest and highest excited frequency \[Hz\], for information.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub band_hz: Option<[f64; 2]>,
    /// Peak |torque| [N m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub peak_nm: Option<f64>,
    /// RMS torque [N m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_nm: Option<f64>,
    /// Free-form design name, e.g. "schroeder", "random_phase", "odd_random_phase".
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub design: Option<String>,
    /// The dwell blocks of a stepped sine over the whole record (`period_samples = 0`):
    /// with them each block is estimated as its own periodic experiment, one line each
    /// ([`crate::frf::estimate_stepped`]). Empty for every other kind.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub blocks: Vec<super::SteppedBlock>,
}
