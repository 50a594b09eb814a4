//! The band an FRF estimate supports: where its lines carry information.
//!
//! A line carries information about the response when the response stands out of its own
//! scatter: `SNR = |H| / sigma_H`, with `sigma_H` the estimator's per-line standard
//! deviation. A line that holds noise only has an estimate `|H|` of the order of its own
//! sigma: for complex Gaussian noise `|H| / sigma` is Rayleigh distributed with median
//! 0.83, and it exceeds [`MIN_SNR`] = 2 on 1.8 % of such lines (`exp(-4)`). An SNR of 1, the
//! point where the scatter equals the response, is therefore no boundary: half of the noise
//! lines reach it. Single lines scatter, and an anti-resonance dips for a few lines where
//! the motor barely moves, so the line SNR is judged over a window: the median of the
//! window of `WINDOW_FRACTION` of the lines (at least `MIN_WINDOW`) around each line; the
//! median of even 5 noise-only lines exceeds 2 with a probability below 1e-4. The supported
//! band runs from the first to the last line whose windowed SNR is at least [`MIN_SNR`].

use super::Frf;

/// The windowed SNR a line needs to carry information (see the module's derivation).
pub const MIN_SNR: f64 = 2.0;

/// The window of the running median, as a fraction of the lines.
pub const WINDOW_FRACTION: f64 = 0.02;
/// The smallest window of the running median [lines].
pub const MIN_WINDOW: usize = 5;

/// The lines an estimate supports and why the others are left out.
#[derive(Debug, Clone, PartialEq)]
pub struct SupportedBand {
    /// The supported band [Hz]: its lowest and highest line.
    pub band_hz: [f64; 2],
    /// Lines inside the band.
    pub lines: usize,
    /// Lines of the estimate in all.
    pub total_lines: usize,
    /// The windowed SNR of every line (`|H| / sigma_H`, median over the window) [1].
    pub snr: Vec<f64>,
}

impl SupportedBand {
    /// Whether lines were left out at either end.
    pub fn trims(&self) -> bool {
        self.lines < self.total_lines
    }
}

/// The band of `frf` whose lines carry information (windowed SNR >= [`MIN_SNR`]); `None`
/// when no line does. Lines with an unknown variance (0: a modelled response) count as informative.
pub fn supported_band(frf: &Frf) -> Option<SupportedBand> {
    let n = frf.len();
    if n == 0 {
        return None;
    }
    let snr_line: Vec<f64> = (0..n)
        .map(|i| {
            let (h, v) = (frf.h[i].norm(), frf.var[i]);
            if v == 0.0 {
                f64::INFINITY
            } else if v.is_finite() && h.is_finite() {
                h / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let half = ((WINDOW_FRACTION * n as f64).round() as usize).max(MIN_WINDOW) / 2;
    let mut buf: Vec<f64> = Vec::with_capacity(2 * half + 1);
    let snr: Vec<f64> = (0..n)
        .map(|i| {
            let (a, b) = (i.saturating_sub(half), (i + half + 1).min(n));
            buf.clear();
            buf.extend_from_slice(&snr_line[a..b]);
            buf.sort_by(f64::total_cmp);
            buf[buf.len() / 2]
        })
        .collect();
    let first = snr.iter().position(|s| *s >= MIN_SNR)?;
    let last = snr.iter().rposition(|s| *s >= MIN_SNR)?;
    Some(SupportedBand {
        band_hz: [frf.freq_hz[first], frf.freq_hz[last]],
        lines: last - first + 1,
        total_lines: n,
        snr,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::FrfKind;
    use num_complex::Complex64;

    fn frf(h: &[f64], sigma: &[f64]) -> Frf {
        Frf {
            freq_hz: (1..=h.len()).map(|k| k as f64).collect(),
            h: h.iter().map(|v| Complex64::new(*v, 0.0)).collect(),
            var: sigma.iter().map(|s| s * s).collect(),
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: 1000.0,
        }
    }

    #[test]
    fn the_band_ends_where_the_uncertainty_exceeds_the_response() {
        // |H| falls as 1/f, the noise floor is flat at 0.005: SNR = 2 at f = 100
        let h: Vec<f64> = (1..=400).map(|k| 1.0 / k as f64).collect();
        let s = vec![0.005; 400];
        let b = supported_band(&frf(&h, &s)).unwrap();
        assert_eq!(b.band_hz[0], 1.0);
        assert!((b.band_hz[1] - 100.0).abs() <= 1.0, "{:?}", b.band_hz);
        assert!(b.trims());
    }

    #[test]
    fn a_narrow_notch_does_not_cut_the_band_and_a_clean_estimate_is_kept_whole() {
        let mut h = vec![1.0; 500];
        for v in &mut h[200..203] {
            *v = 1e-4; // an anti-resonance three lines wide
        }
        let s = vec![0.01; 500];
        let b = supported_band(&frf(&h, &s)).unwrap();
        assert_eq!((b.lines, b.total_lines), (500, 500));
        assert!(!b.trims());
    }

    #[test]
    fn no_line_with_information_gives_none() {
        assert!(supported_band(&frf(&[1.0; 50], &[0.6; 50])).is_none());
        assert!(supported_band(&frf(&[], &[])).is_none());
    }

    /// Lines of pure noise (`H` complex Gaussian with the variance the estimator reports)
    /// carry no information: no band; a response 10 sigma above the noise floor on the
    /// lower half is found and the noise half left out.
    #[test]
    fn pure_noise_lines_give_no_band_and_a_noise_half_is_left_out() {
        use rand::SeedableRng;
        use rand_distr::{Distribution, Normal};
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let g = Normal::new(0.0, std::f64::consts::FRAC_1_SQRT_2).unwrap();
        let n = 2000;
        let noise: Vec<Complex64> = (0..n)
            .map(|_| Complex64::new(g.sample(&mut rng), g.sample(&mut rng)))
            .collect();
        let mut f = frf(&vec![0.0; n], &vec![1.0; n]);
        f.h = noise.clone();
        assert!(
            supported_band(&f).is_none(),
            "{:?}",
            supported_band(&f).map(|b| b.band_hz)
        );
        for h in &mut f.h[..n / 2] {
            *h += Complex64::new(10.0, 0.0);
        }
        let b = supported_band(&f).unwrap();
        assert_eq!(b.band_hz[0], 1.0);
        assert!(
            (b.band_hz[1] - (n / 2) as f64).abs() <= 0.02 * n as f64,
            "{:?}",
            b.band_hz
        );
    }
}
