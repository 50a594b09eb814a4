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
    /// Several realisations of one multisine design (the same excited lines, other random
    /// phases), one steady period of `period_samples` each, in the order recorded; each
    /// preceded by its own lead-in. With them the FRF is the best linear approximation
    /// over the realisations ([`crate::frf::estimate_realisations`]) and `periods` counts
    /// the realisations. Empty for every other excitation.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub realisations: Vec<Realisation>,
    /// The input column is the excitation as an ADC measured it from an analogue generator
    /// (band-limited between the samples, e.g. the Silverbox's input voltage), not a
    /// command held over each sample (the zero-order hold of a drive, the default): the
    /// diagnosis compares models on the continuous system's response at the lines
    /// ([`crate::diagnose::lti::Discrete::band_limited`]). `false` when absent.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub band_limited: bool,
}

/// One realisation of a multisine within a recording ([`ExcitationInfo::realisations`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Realisation {
    /// Row of the first sample of its steady period (the period runs over `start ..
    /// start + period_samples`).
    pub start: usize,
    /// Samples played before the steady period that repeat the period's last `lead_in`
    /// samples (the generator ran the period from a point before its start): the
    /// system's transient settles over them, and on their second half the output's
    /// difference to the same samples one period later is noise alone (the noise
    /// estimate of [`crate::frf::estimate_realisations`]). 0 when not known.
    #[serde(default)]
    pub lead_in: usize,
}
