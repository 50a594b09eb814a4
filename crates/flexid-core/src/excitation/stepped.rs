//! Stepped sine in torque units [N m]: one exactly periodic dwell block per spot frequency.

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::lines::MIN_PERIOD_SAMPLES;
use super::stats::{check_length, check_limit, check_sample_rate, peak_abs, rms, scale_to_limits};
use super::{ExcitationError, ExcitationInfo, ExcitationKind};

/// Most extra cycles tried when a spot frequency near Nyquist rounds onto the Nyquist line.
const MAX_LINE_TRIES: usize = 1000;

/// Design of a stepped sine.
///
/// For every spot frequency `f` a period of `P` samples holding exactly `line` sine cycles is
/// chosen: `line = max(1, ceil(f * min_period_samples / fs))`, `P = round(line * fs / f)`, so
/// the played frequency `line * fs / P` (DFT line `line` of the period) is within a quarter
/// line spacing of `f`. The block of that frequency is `settle_periods + periods` such
/// periods, starting and ending at zero torque (`x = A sin(2 pi line n / P)`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedSineDesign {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Spot frequencies \[Hz\], played in the given order (each > 0 and below Nyquist).
    pub frequencies_hz: Vec<f64>,
    /// Lower bound on the period length `P` \[samples\] (>= 4); sets the line spacing
    /// `fs / P` and so the frequency resolution of each block.
    pub min_period_samples: usize,
    /// Steady-state periods per block (>= 1), processed by the estimator.
    pub periods: usize,
    /// Leading periods per block to let the transient settle (discarded).
    pub settle_periods: usize,
    /// Largest allowed |torque| [N m] (> 0).
    pub peak_limit_nm: f64,
    /// Largest allowed RMS torque [N m] (> 0).
    pub rms_limit_nm: f64,
}

impl SteppedSineDesign {
    /// Generates the blocks one after the other. Each block's sine is scaled by the largest
    /// gain meeting both limits (so the binding one holds with equality).
    pub fn generate(&self) -> Result<SteppedSine, ExcitationError> {
        let fs = self.sample_rate_hz;
        check_sample_rate(fs)?;
        check_limit("peak", self.peak_limit_nm)?;
        check_limit("rms", self.rms_limit_nm)?;
        if self.frequencies_hz.is_empty() {
            return Err(ExcitationError::NoFrequencies);
        }
        if self.periods == 0 {
            return Err(ExcitationError::ZeroCount { which: "periods" });
        }
        if self.min_period_samples < MIN_PERIOD_SAMPLES {
            return Err(ExcitationError::PeriodTooShort {
                period_samples: self.min_period_samples,
                min_samples: MIN_PERIOD_SAMPLES,
            });
        }
        let nyquist_hz = fs / 2.0;
        let mut grid = Vec::with_capacity(self.frequencies_hz.len());
        for &f in &self.frequencies_hz {
            if !(f.is_finite() && f > 0.0) {
                return Err(ExcitationError::InvalidFrequency { freq_hz: f });
            }
            let too_high = ExcitationError::FrequencyAboveNyquist {
                freq_hz: f,
                nyquist_hz,
            };
            if f >= nyquist_hz {
                return Err(too_high);
            }
            // Reject absurdly low frequencies before rounding the period to usize.
            check_length(self.min_period_samples as f64 + fs / f)?;
            grid.push(snap(fs, f, self.min_period_samples).ok_or(too_high)?);
        }

        let reps_f = self.settle_periods as f64 + self.periods as f64;
        check_length(grid.iter().map(|&(_, p)| p as f64 * reps_f).sum())?;
        let reps = self.settle_periods + self.periods;
        let total: usize = grid.iter().map(|&(_, p)| p * reps).sum();
        let mut signal = Vec::with_capacity(total);
        let mut blocks = Vec::with_capacity(grid.len());
        let mut one = Vec::new();
        for (&requested_hz, &(line, p)) in self.frequencies_hz.iter().zip(&grid) {
            one.clear();
            one.extend((0..p).map(|n| (2.0 * PI * (line * n % p) as f64 / p as f64).sin()));
            let amplitude_nm =
                scale_to_limits(&mut one, self.peak_limit_nm, Some(self.rms_limit_nm));
            let start = signal.len();
            for _ in 0..reps {
                signal.extend_from_slice(&one);
            }
            blocks.push(SteppedBlock {
                requested_hz,
                frequency_hz: line as f64 * fs / p as f64,
                start,
                period_samples: p,
                line,
                settle_periods: self.settle_periods,
                periods: self.periods,
                amplitude_nm,
                peak_nm: peak_abs(&one),
                rms_nm: rms(&one),
            });
        }
        Ok(SteppedSine {
            sample_rate_hz: fs,
            signal,
            blocks,
        })
    }
}

/// `(line, period_samples)` for frequency `f`: `line` cycles in `P >= min_p` samples, `2 line < P`.
fn snap(fs: f64, f: f64, min_p: usize) -> Option<(usize, usize)> {
    let line0 = ((f * min_p as f64 / fs).ceil() as usize).max(1);
    (line0..line0 + MAX_LINE_TRIES).find_map(|line| {
        let p = (line as f64 * fs / f).round() as usize;
        (2 * line < p && p >= min_p).then_some((line, p))
    })
}

/// One dwell block of a stepped sine: `settle_periods + periods` repetitions of a period of
/// `period_samples` samples holding exactly `line` cycles of `amplitude_nm * sin(.)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedBlock {
    /// Requested spot frequency \[Hz\].
    pub requested_hz: f64,
    /// Played frequency `line * fs / period_samples` \[Hz\].
    pub frequency_hz: f64,
    /// Index of the block's first sample in [`SteppedSine::signal`] (settle periods included).
    pub start: usize,
    /// Samples per period `P`.
    pub period_samples: usize,
    /// Excited DFT line of one period (cycles per period).
    pub line: usize,
    /// Leading periods to discard.
    pub settle_periods: usize,
    /// Steady-state periods after the settle ones.
    pub periods: usize,
    /// Sine amplitude [N m].
    pub amplitude_nm: f64,
    /// Peak |torque| of the samples [N m].
    pub peak_nm: f64,
    /// RMS torque [N m].
    pub rms_nm: f64,
}

impl SteppedBlock {
    /// Block length \[samples\], settle periods included.
    pub fn len(&self) -> usize {
        (self.settle_periods + self.periods) * self.period_samples
    }

    /// Always false: a block holds at least one period.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Index of the first steady-state sample (after the settle periods).
    pub fn steady_start(&self) -> usize {
        self.start + self.settle_periods * self.period_samples
    }

    /// Description of this block as a periodic excitation (kind SteppedSine, one excited
    /// line), valid for the slice `signal[start .. start + len()]`.
    pub fn info(&self) -> ExcitationInfo {
        ExcitationInfo {
            kind: ExcitationKind::SteppedSine,
            period_samples: self.period_samples,
            periods: self.periods,
            transient_periods: self.settle_periods,
            excited_lines: vec![self.line],
            band_hz: Some([self.frequency_hz, self.frequency_hz]),
            peak_nm: Some(self.peak_nm),
            rms_nm: Some(self.rms_nm),
            design: Some("stepped_sine".to_string()),
            blocks: Vec::new(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }
}

/// A generated stepped sine [N m]: the blocks back to back.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SteppedSine {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// All blocks back to back [N m].
    pub signal: Vec<f64>,
    /// The blocks, in playing order.
    pub blocks: Vec<SteppedBlock>,
}

impl SteppedSine {
    /// `(start, len, line)` per block: first sample, length in samples (settle included) and
    /// excited line of the block's period.
    pub fn segments(&self) -> Vec<(usize, usize, usize)> {
        self.blocks
            .iter()
            .map(|b| (b.start, b.len(), b.line))
            .collect()
    }

    /// Description of the whole record: kind SteppedSine, not one period
    /// (`period_samples = 0`), band `[lowest, highest]` played frequency, overall peak and
    /// RMS, and the blocks (so that each is estimated on its own). Per-block periodic
    /// descriptions are in [`SteppedSine::infos`].
    pub fn info(&self) -> ExcitationInfo {
        let lo = self
            .blocks
            .iter()
            .map(|b| b.frequency_hz)
            .fold(f64::INFINITY, f64::min);
        let hi = self
            .blocks
            .iter()
            .map(|b| b.frequency_hz)
            .fold(0.0, f64::max);
        ExcitationInfo {
            kind: ExcitationKind::SteppedSine,
            period_samples: 0,
            periods: 0,
            transient_periods: 0,
            excited_lines: Vec::new(),
            band_hz: (!self.blocks.is_empty()).then_some([lo, hi]),
            peak_nm: Some(peak_abs(&self.signal)),
            rms_nm: Some(rms(&self.signal)),
            design: Some("stepped_sine".to_string()),
            blocks: self.blocks.clone(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }

    /// Per-block descriptions, in playing order.
    pub fn infos(&self) -> Vec<ExcitationInfo> {
        self.blocks.iter().map(SteppedBlock::info).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::excitation::test_util::naive_line_spectrum;

    fn design() -> SteppedSineDesign {
        SteppedSineDesign {
            sample_rate_hz: 1000.0,
            frequencies_hz: vec![0.7, 3.3, 17.0, 123.4, 333.3, 499.0],
            min_period_samples: 200,
            periods: 3,
            settle_periods: 2,
            peak_limit_nm: 2.0,
            rms_limit_nm: 1.0,
        }
    }

    #[test]
    fn blocks_are_exactly_periodic_on_the_grid() {
        let d = design();
        let s = d.generate().unwrap();
        assert_eq!(s.blocks.len(), 6);
        let mut next = 0;
        for ((start, len, line), b) in s.segments().into_iter().zip(&s.blocks) {
            assert_eq!(start, next);
            next = start + len;
            let p = b.period_samples;
            assert!(p >= 200 && 2 * line < p);
            assert_eq!(len, 5 * p);
            assert_eq!(b.steady_start(), start + 2 * p);
            let x = &s.signal[start..start + len];
            // Exactly periodic (bitwise), starting at zero torque.
            assert_eq!(x[0], 0.0);
            for i in 0..len - p {
                assert_eq!(x[i], x[i + p], "block at {start}, sample {i}");
            }
            // Played frequency on the grid of the period, near the requested one.
            let df = 1000.0 / p as f64;
            assert!((b.frequency_hz - line as f64 * df).abs() < 1e-12);
            assert!((b.frequency_hz - b.requested_hz).abs() <= 0.25 * df + 1e-12);
            // Naive DFT of one period: energy at `line` only.
            let (amp, _) = naive_line_spectrum(&x[..p]);
            for (k, &a) in amp.iter().enumerate() {
                if k == line {
                    assert!((a - b.amplitude_nm).abs() < 1e-9 * b.amplitude_nm);
                } else {
                    assert!(a < 1e-9 * b.amplitude_nm, "block {start}: line {k} has {a}");
                }
            }
            // Limits: rms 1 binds (amplitude sqrt 2 < peak limit 2).
            assert!((b.rms_nm - 1.0).abs() < 1e-12);
            assert!(b.peak_nm <= 2.0);
            let info = b.info();
            assert_eq!(info.kind, ExcitationKind::SteppedSine);
            assert_eq!(info.excited_lines, vec![line]);
            assert_eq!(
                (info.period_samples, info.periods, info.transient_periods),
                (p, 3, 2)
            );
        }
        assert_eq!(next, s.signal.len());
        assert_eq!(s.infos().len(), 6);
        let all = s.info();
        assert_eq!(all.kind, ExcitationKind::SteppedSine);
        assert!((all.rms_nm.unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(all.band_hz.unwrap()[0], s.blocks[0].frequency_hz);
    }

    #[test]
    fn peak_limit_can_bind() {
        let mut d = design();
        d.rms_limit_nm = 10.0;
        let s = d.generate().unwrap();
        for b in &s.blocks {
            assert!((b.peak_nm - 2.0).abs() < 1e-12);
            assert!(b.rms_nm < 10.0);
        }
    }

    #[test]
    fn bad_stepped_inputs() {
        use ExcitationError as E;
        let with = |f: &dyn Fn(&mut SteppedSineDesign)| {
            let mut d = design();
            f(&mut d);
            d.generate().unwrap_err()
        };
        assert!(matches!(
            with(&|d| d.frequencies_hz.clear()),
            E::NoFrequencies
        ));
        assert!(matches!(
            with(&|d| d.frequencies_hz[2] = 500.0),
            E::FrequencyAboveNyquist { .. }
        ));
        assert!(matches!(
            with(&|d| d.frequencies_hz[0] = -1.0),
            E::InvalidFrequency { .. }
        ));
        assert!(matches!(
            with(&|d| d.frequencies_hz[0] = f64::NAN),
            E::InvalidFrequency { .. }
        ));
        assert!(matches!(
            with(&|d| d.periods = 0),
            E::ZeroCount { which: "periods" }
        ));
        assert!(matches!(
            with(&|d| d.min_period_samples = 2),
            E::PeriodTooShort { .. }
        ));
        assert!(matches!(
            with(&|d| d.peak_limit_nm = 0.0),
            E::NonPositiveLimit { .. }
        ));
        assert!(matches!(
            with(&|d| d.sample_rate_hz = f64::NAN),
            E::InvalidSampleRate { .. }
        ));
        assert!(matches!(
            with(&|d| d.frequencies_hz[0] = 1e-300),
            E::TooLong { .. }
        ));
        assert!(matches!(
            with(&|d| d.periods = usize::MAX),
            E::TooLong { .. }
        ));
    }
}
