//! Stepped-sine FRF: each dwell block is a periodic experiment with one excited line, so
//! each block gives one line of the FRF with the period-to-period variance of
//! [`PeriodicEstimator`] (unbiased, with a known number of averages), where a Welch
//! estimate over the whole record would mix blocks and transients.

use super::error::FrfError;
use super::periodic::PeriodicEstimator;
use super::types::{Frf, FrfKind};
use crate::excitation::SteppedBlock;

/// The FRF of a stepped-sine record, one line per block (sorted by frequency; of two
/// blocks at the same played frequency the one with the smaller variance is kept).
///
/// `u` is the torque command [N m] and `y` the motion signal of the whole record (block
/// `start` indices refer to them). Errors: `TooShort` when a block runs past the end of the
/// record or holds no steady period, `NoExcitedLines` without blocks, and the periodic
/// estimator's own errors. `grid` is the grid step of the recorded motion signal with that
/// signal (the position for a differenced velocity): each block's repeating quantisation
/// error, from its own period-to-period scatter, is added to its line's variance
/// ([`super::quantisation`]).
pub fn estimate_stepped(
    blocks: &[SteppedBlock],
    u: &[f64],
    y: &[f64],
    sample_rate_hz: f64,
    kind: FrfKind,
    grid: Option<(f64, &[f64])>,
) -> Result<Frf, FrfError> {
    if blocks.is_empty() {
        return Err(FrfError::NoExcitedLines);
    }
    let mut lines: Vec<(f64, num_complex::Complex64, f64, Option<f64>)> = Vec::new();
    for b in blocks {
        let end = b.start + b.len();
        if end > u.len().min(y.len()) {
            return Err(FrfError::TooShort {
                needed: end,
                got: u.len().min(y.len()),
                unit: "samples",
            });
        }
        let mut est = PeriodicEstimator::from_info(&b.info(), sample_rate_hz, kind)?
            .excited_lines_only()
            .with_quantum(grid.map(|(q, x)| repeating_power(b, q, x)));
        est.push(&u[b.start..end], &y[b.start..end])?;
        let one = est.estimate()?;
        for i in 0..one.len() {
            let c = one.coherence.as_ref().map(|c| c[i]);
            lines.push((one.freq_hz[i], one.h[i], one.var[i], c));
        }
    }
    lines.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.2.total_cmp(&b.2)));
    lines.dedup_by(|later, kept| later.0 == kept.0);
    let with_coherence = lines.iter().all(|l| l.3.is_some());
    Ok(Frf {
        freq_hz: lines.iter().map(|l| l.0).collect(),
        h: lines.iter().map(|l| l.1).collect(),
        var: lines.iter().map(|l| l.2).collect(),
        coherence: with_coherence.then(|| lines.iter().map(|l| l.3.unwrap_or(0.0)).collect()),
        kind,
        sample_rate_hz,
    })
}

/// The repeating quantisation power of block `b` of the recorded signal `x` (grid step
/// `q`), as the white-error power that gives the same variance at the block's line: the
/// larger of the white floor ([`super::quantisation::repeating_variance`] at the noise
/// behind the counts, [`super::quantisation::noise_std_from_scatter`]) and the
/// single tone's own ([`super::quantisation::tone_error_power_bound`], whose fundamental
/// of mean square `E[E₁²]` is `E[E₁²]/4` on the `1/N`-scaled line: `N E[E₁²]/4` as a white
/// power). A stepped sine plays one tone per block: its count error sits on the tone's
/// harmonics, not spread over the period's lines.
fn repeating_power(b: &SteppedBlock, q: f64, x: &[f64]) -> f64 {
    use super::quantisation as qz;
    let steady = &x[b.steady_start().min(x.len())..];
    let scatter = qz::scatter_std(steady, b.period_samples, b.periods).unwrap_or(0.0);
    let sigma = qz::noise_std_from_scatter(q, scatter);
    let white = qz::repeating_variance(q, sigma);
    let n = (b.period_samples * b.periods).min(steady.len());
    if n == 0 {
        return white;
    }
    // the tone's amplitude in the recorded signal: its line over the steady periods
    let w = 2.0 * std::f64::consts::PI * b.line as f64 / b.period_samples as f64;
    let line: num_complex::Complex64 = steady[..n]
        .iter()
        .enumerate()
        .map(|(i, v)| v * num_complex::Complex64::from_polar(1.0, -w * i as f64))
        .sum();
    let amplitude = 2.0 * line.norm() / n as f64;
    let tone = qz::tone_error_power_bound(q, amplitude, sigma);
    white.max(b.period_samples as f64 * tone / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::excitation::SteppedSineDesign;
    use num_complex::Complex64;

    /// A first-order system y[k] = a y[k-1] + b u[k] driven by a stepped sine: each line
    /// equals the exact response b / (1 - a e^{-j w}) within its variance, and the variance
    /// shrinks with the number of periods.
    #[test]
    fn each_block_gives_the_exact_line_of_a_filter() {
        let fs = 1000.0;
        let d = SteppedSineDesign {
            sample_rate_hz: fs,
            frequencies_hz: vec![5.0, 20.0, 80.0, 200.0],
            min_period_samples: 200,
            periods: 4,
            settle_periods: 3,
            peak_limit_nm: 2.0,
            rms_limit_nm: 1.0,
        };
        let s = d.generate().unwrap();
        let (a, b) = (0.9, 0.1);
        let mut y = vec![0.0; s.signal.len()];
        let mut prev = 0.0;
        // deterministic small noise (a different LCG per sample)
        let mut state = 12345u64;
        for (k, u) in s.signal.iter().enumerate() {
            prev = a * prev + b * u;
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            let noise = ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 1e-3;
            y[k] = prev + noise;
        }
        let frf = estimate_stepped(&s.blocks, &s.signal, &y, fs, FrfKind::Other, None).unwrap();
        assert_eq!(frf.len(), 4);
        let mut z2 = 0.0;
        for i in 0..frf.len() {
            let w = 2.0 * std::f64::consts::PI * frf.freq_hz[i] / fs;
            let exact = b / (Complex64::new(1.0, 0.0) - a * Complex64::from_polar(1.0, -w));
            let err = (frf.h[i] - exact).norm_sqr();
            assert!(frf.var[i] > 0.0 && frf.var[i].is_finite());
            assert!((frf.h[i] - exact).norm() < 1e-2 * exact.norm(), "line {i}");
            z2 += err / frf.var[i];
        }
        // four lines of F(2, 6): a mean beyond 10 would be a biased estimate
        assert!(z2 / 4.0 < 10.0, "mean z2 {}", z2 / 4.0);
        assert!(frf.freq_hz.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn a_block_past_the_record_is_an_error() {
        let d = SteppedSineDesign {
            sample_rate_hz: 1000.0,
            frequencies_hz: vec![10.0, 50.0],
            min_period_samples: 100,
            periods: 2,
            settle_periods: 1,
            peak_limit_nm: 1.0,
            rms_limit_nm: 1.0,
        };
        let s = d.generate().unwrap();
        let short = &s.signal[..s.signal.len() - 10];
        let r = estimate_stepped(&s.blocks, short, short, 1000.0, FrfKind::Other, None);
        assert!(matches!(r, Err(FrfError::TooShort { .. })), "{r:?}");
        let r = estimate_stepped(&[], short, short, 1000.0, FrfKind::Other, None);
        assert!(matches!(r, Err(FrfError::NoExcitedLines)));
    }
}
