//! Errors of the excitation generators.

use thiserror::Error;

/// Invalid excitation design, reported by the generators instead of panicking.
///
/// Frequencies are in Hz, torques in N m, sample counts in samples.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ExcitationError {
    /// The sample rate is not a positive finite number.
    #[error("sample rate must be positive and finite, got {sample_rate_hz} Hz")]
    InvalidSampleRate {
        /// The offending sample rate \[Hz\].
        sample_rate_hz: f64,
    },
    /// The period (or block) is too short to hold any excited line.
    #[error("period of {period_samples} samples is too short (need at least {min_samples})")]
    PeriodTooShort {
        /// Requested samples per period.
        period_samples: usize,
        /// Smallest accepted number of samples per period.
        min_samples: usize,
    },
    /// The band is malformed: negative, non-finite or `lo > hi`.
    #[error("invalid band [{lo_hz}, {hi_hz}] Hz (need finite 0 <= lo <= hi)")]
    InvalidBand {
        /// Lower band edge \[Hz\].
        lo_hz: f64,
        /// Upper band edge \[Hz\].
        hi_hz: f64,
    },
    /// The band reaches above the Nyquist frequency `fs / 2`.
    #[error("band upper edge {hi_hz} Hz is above the Nyquist frequency {nyquist_hz} Hz")]
    BandAboveNyquist {
        /// Upper band edge \[Hz\].
        hi_hz: f64,
        /// Nyquist frequency `fs / 2` \[Hz\].
        nyquist_hz: f64,
    },
    /// The band lies entirely below the first DFT line of the period (`fs / N`).
    #[error(
        "band upper edge {hi_hz} Hz is below one line spacing {spacing_hz} Hz; use a longer period"
    )]
    BandBelowLineSpacing {
        /// Upper band edge \[Hz\].
        hi_hz: f64,
        /// DFT line spacing `fs / period_samples` \[Hz\].
        spacing_hz: f64,
    },
    /// No usable DFT line (for the odd design: no odd line) falls inside the band.
    #[error("no usable line in band [{lo_hz}, {hi_hz}] Hz with line spacing {spacing_hz} Hz")]
    NoLineInBand {
        /// Lower band edge \[Hz\].
        lo_hz: f64,
        /// Upper band edge \[Hz\].
        hi_hz: f64,
        /// DFT line spacing \[Hz\].
        spacing_hz: f64,
    },
    /// A peak or RMS limit is not a positive finite number.
    #[error("{which} limit must be positive and finite, got {value_nm} N m")]
    NonPositiveLimit {
        /// `"peak"` or `"rms"`.
        which: &'static str,
        /// The offending limit [N m].
        value_nm: f64,
    },
    /// A custom amplitude list does not have one entry per excited line.
    #[error("custom amplitude list has {got} entries but the design excites {expected} lines")]
    AmplitudeLengthMismatch {
        /// Number of excited lines.
        expected: usize,
        /// Number of amplitudes given.
        got: usize,
    },
    /// An amplitude is negative or non-finite, or all amplitudes are zero.
    #[error(
        "invalid amplitude {value} at excited line index {index} (need finite >= 0, not all zero)"
    )]
    InvalidAmplitude {
        /// Index into the excited-line list.
        index: usize,
        /// The offending (relative) amplitude.
        value: f64,
    },
    /// A shaping exponent is not finite.
    #[error("amplitude exponent must be finite, got {exponent}")]
    InvalidExponent {
        /// The offending exponent.
        exponent: f64,
    },
    /// The odd random-phase group size is below 2.
    #[error("odd random-phase group size must be at least 2, got {group}")]
    InvalidGroup {
        /// The offending group size.
        group: usize,
    },
    /// A spot or sweep frequency is not positive and finite.
    #[error("frequency must be positive and finite, got {freq_hz} Hz")]
    InvalidFrequency {
        /// The offending frequency \[Hz\].
        freq_hz: f64,
    },
    /// A spot or sweep frequency is at or above the Nyquist frequency.
    #[error("frequency {freq_hz} Hz is not below the Nyquist frequency {nyquist_hz} Hz")]
    FrequencyAboveNyquist {
        /// The offending frequency \[Hz\].
        freq_hz: f64,
        /// Nyquist frequency `fs / 2` \[Hz\].
        nyquist_hz: f64,
    },
    /// The sweep start and end frequencies are equal.
    #[error("sweep start and end frequency are equal ({freq_hz} Hz)")]
    EmptySweep {
        /// The common frequency \[Hz\].
        freq_hz: f64,
    },
    /// A duration is not positive and finite, or yields fewer than two samples.
    #[error("invalid duration {duration_s} s (need finite > 0 and at least two samples)")]
    InvalidDuration {
        /// The offending duration \[s\].
        duration_s: f64,
    },
    /// The taper length is negative, non-finite or longer than half the duration.
    #[error(
        "invalid taper {taper_s} s for duration {duration_s} s (need 0 <= taper <= duration / 2)"
    )]
    InvalidTaper {
        /// The taper length \[s\].
        taper_s: f64,
        /// The sweep duration \[s\].
        duration_s: f64,
    },
    /// The signal would exceed [`MAX_SIGNAL_SAMPLES`](super::MAX_SIGNAL_SAMPLES) samples.
    #[error("signal of {samples} samples is too long (at most {max_samples})")]
    TooLong {
        /// Requested number of samples (as f64, it may not fit a usize).
        samples: f64,
        /// Largest accepted number of samples.
        max_samples: usize,
    },
    /// The stepped-sine frequency list is empty.
    #[error("no spot frequency given")]
    NoFrequencies,
    /// A count that must be at least one is zero.
    #[error("{which} must be at least 1")]
    ZeroCount {
        /// Name of the count, e.g. `"periods"`.
        which: &'static str,
    },
    /// A multi-axis design gives a number of per-axis amplitudes other than its axes.
    #[error("{got} per-axis amplitudes given for {axes} axes")]
    AxisCountMismatch {
        /// Number of axes of the design.
        axes: usize,
        /// Number of per-axis amplitudes given.
        got: usize,
    },
    /// A per-axis RMS torque is not positive and finite.
    #[error("RMS torque of axis {axis} must be positive and finite, got {value_nm} N m")]
    InvalidAxisAmplitude {
        /// Index of the axis (0-based).
        axis: usize,
        /// The offending RMS torque [N m].
        value_nm: f64,
    },
    /// The FFT backend rejected its buffers (an internal invariant; should not happen).
    #[error("internal FFT error: {detail}")]
    Fft {
        /// The backend's message.
        detail: String,
    },
}
