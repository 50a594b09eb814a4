//! DFT line grid of one period: which lines a band holds, and the odd random-phase
//! selection with detection lines.
//!
//! Line `k` of a period of `N` samples at sample rate `fs` lies at `k * fs / N` Hz. Usable
//! lines are `1 <= k` and `2 k < N` (DC and the Nyquist line are never excited: they cannot
//! carry an arbitrary phase).

use rand::Rng;

use super::stats::{check_length, check_sample_rate};
use super::ExcitationError;

/// Smallest accepted number of samples per period.
pub const MIN_PERIOD_SAMPLES: usize = 4;

/// Relative tolerance (in units of one line spacing) when snapping band edges to lines.
const EDGE_TOL: f64 = 1e-9;

/// All usable DFT lines of an `period_samples`-sample period whose frequency lies in
/// `band_hz = [lo, hi]` (inclusive, Hz), in increasing order.
///
/// Errors: bad sample rate, period shorter than [`MIN_PERIOD_SAMPLES`], malformed band,
/// period longer than [`MAX_SIGNAL_SAMPLES`](super::MAX_SIGNAL_SAMPLES), band above
/// Nyquist, band below one line spacing, or no line in the band.
pub fn band_lines(
    sample_rate_hz: f64,
    period_samples: usize,
    band_hz: [f64; 2],
) -> Result<Vec<usize>, ExcitationError> {
    check_sample_rate(sample_rate_hz)?;
    if period_samples < MIN_PERIOD_SAMPLES {
        return Err(ExcitationError::PeriodTooShort {
            period_samples,
            min_samples: MIN_PERIOD_SAMPLES,
        });
    }
    check_length(period_samples as f64)?;
    let [lo_hz, hi_hz] = band_hz;
    if !(lo_hz.is_finite() && hi_hz.is_finite() && lo_hz >= 0.0 && lo_hz <= hi_hz) {
        return Err(ExcitationError::InvalidBand { lo_hz, hi_hz });
    }
    let nyquist_hz = sample_rate_hz / 2.0;
    let spacing_hz = sample_rate_hz / period_samples as f64;
    if hi_hz > nyquist_hz * (1.0 + EDGE_TOL) {
        return Err(ExcitationError::BandAboveNyquist { hi_hz, nyquist_hz });
    }
    if hi_hz < spacing_hz * (1.0 - EDGE_TOL) {
        return Err(ExcitationError::BandBelowLineSpacing { hi_hz, spacing_hz });
    }
    let k_lo = ((lo_hz / spacing_hz - EDGE_TOL).ceil() as usize).max(1);
    let k_max_usable = (period_samples - 1) / 2; // largest k with 2k < N
    let k_hi = ((hi_hz / spacing_hz + EDGE_TOL).floor() as usize).min(k_max_usable);
    if k_lo > k_hi {
        return Err(ExcitationError::NoLineInBand {
            lo_hz,
            hi_hz,
            spacing_hz,
        });
    }
    Ok((k_lo..=k_hi).collect())
}

/// Odd random-phase line selection from the usable lines of a band (`candidates`, increasing).
///
/// Even lines are dropped. The odd lines are cut, from the lowest, into groups of `group`
/// consecutive odd lines; in every full group one line, drawn uniformly with `rng`, becomes a
/// detection line (left unexcited). A trailing partial group is excited entirely.
/// Returns `(excited, detection)`, both increasing.
pub(crate) fn odd_random_lines<R: Rng>(
    candidates: &[usize],
    group: usize,
    rng: &mut R,
) -> (Vec<usize>, Vec<usize>) {
    let odd: Vec<usize> = candidates.iter().copied().filter(|k| k % 2 == 1).collect();
    let mut excited = Vec::with_capacity(odd.len());
    let mut detection = Vec::with_capacity(odd.len() / group.max(1) + 1);
    for chunk in odd.chunks(group) {
        if chunk.len() == group {
            let skip = rng.random_range(0..group);
            for (i, &k) in chunk.iter().enumerate() {
                if i == skip {
                    detection.push(k);
                } else {
                    excited.push(k);
                }
            }
        } else {
            excited.extend_from_slice(chunk);
        }
    }
    (excited, detection)
}

/// The band `[lowest, highest]` [Hz] of the excited `lines` (DFT bins, increasing) at the
/// line spacing `df_hz`; `None` without lines.
pub fn band_of(lines: &[usize], df_hz: f64) -> Option<[f64; 2]> {
    match (lines.first(), lines.last()) {
        (Some(&a), Some(&b)) => Some([a as f64 * df_hz, b as f64 * df_hz]),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{rngs::StdRng, SeedableRng};

    #[test]
    fn band_edges_snap_to_lines() {
        // fs = 1000, N = 1000: spacing 1 Hz.
        assert_eq!(
            band_lines(1000.0, 1000, [2.0, 5.0]).unwrap(),
            vec![2, 3, 4, 5]
        );
        assert_eq!(band_lines(1000.0, 1000, [0.0, 1.5]).unwrap(), vec![1]);
        // The Nyquist line (k = 500) is never used.
        assert_eq!(
            *band_lines(1000.0, 1000, [498.0, 500.0])
                .unwrap()
                .last()
                .unwrap(),
            499
        );
    }

    #[test]
    fn band_errors() {
        use ExcitationError as E;
        assert!(matches!(
            band_lines(1000.0, 1000, [1.0, 600.0]),
            Err(E::BandAboveNyquist { .. })
        ));
        assert!(matches!(
            band_lines(1000.0, 100, [0.0, 5.0]),
            Err(E::BandBelowLineSpacing { .. })
        ));
        assert!(matches!(
            band_lines(1000.0, 100, [11.0, 19.0]),
            Err(E::NoLineInBand { .. })
        ));
        assert!(matches!(
            band_lines(1000.0, 100, [30.0, 20.0]),
            Err(E::InvalidBand { .. })
        ));
        assert!(matches!(
            band_lines(1000.0, 100, [f64::NAN, 20.0]),
            Err(E::InvalidBand { .. })
        ));
        assert!(matches!(
            band_lines(1000.0, 3, [0.0, 400.0]),
            Err(E::PeriodTooShort { .. })
        ));
        assert!(matches!(
            band_lines(0.0, 100, [0.0, 400.0]),
            Err(E::InvalidSampleRate { .. })
        ));
    }

    #[test]
    fn odd_random_groups() {
        let cand: Vec<usize> = (4..=40).collect();
        let mut rng = StdRng::seed_from_u64(7);
        let (exc, det) = odd_random_lines(&cand, 3, &mut rng);
        assert!(exc.iter().chain(&det).all(|k| k % 2 == 1));
        // Odd lines 5..=39: 18 lines, 6 full groups of 3.
        assert_eq!(det.len(), 6);
        assert_eq!(exc.len(), 12);
    }
}
