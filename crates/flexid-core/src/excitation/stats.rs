//! Signal statistics and limit scaling shared by all generators.

use super::ExcitationError;

/// Largest number of samples any generator produces (a period, a sweep, a stepped-sine
/// record), about 8.6 GB of `f64`; longer requests fail with [`ExcitationError::TooLong`].
pub const MAX_SIGNAL_SAMPLES: usize = 1 << 30;

/// Checks that `samples` does not exceed [`MAX_SIGNAL_SAMPLES`].
pub(crate) fn check_length(samples: f64) -> Result<(), ExcitationError> {
    if samples <= MAX_SIGNAL_SAMPLES as f64 {
        Ok(())
    } else {
        Err(ExcitationError::TooLong {
            samples,
            max_samples: MAX_SIGNAL_SAMPLES,
        })
    }
}

/// Root mean square of `x` (same unit as `x`, e.g. N m). Returns 0 for an empty slice.
pub fn rms(x: &[f64]) -> f64 {
    if x.is_empty() {
        return 0.0;
    }
    (x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64).sqrt()
}

/// Largest absolute value of `x` (same unit as `x`). Returns 0 for an empty slice.
pub fn peak_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0_f64, |m, v| m.max(v.abs()))
}

/// Crest factor `max |x| / rms(x)` (dimensionless, >= 1 for any non-zero signal; a single
/// sine has sqrt(2)). Returns NaN for an empty or all-zero slice.
pub fn crest_factor(x: &[f64]) -> f64 {
    let r = rms(x);
    if r > 0.0 {
        peak_abs(x) / r
    } else {
        f64::NAN
    }
}

/// Checks that a torque limit [N m] is positive and finite.
pub(crate) fn check_limit(which: &'static str, value_nm: f64) -> Result<(), ExcitationError> {
    if value_nm.is_finite() && value_nm > 0.0 {
        Ok(())
    } else {
        Err(ExcitationError::NonPositiveLimit { which, value_nm })
    }
}

/// Checks that a sample rate \[Hz\] is positive and finite.
pub(crate) fn check_sample_rate(sample_rate_hz: f64) -> Result<(), ExcitationError> {
    if sample_rate_hz.is_finite() && sample_rate_hz > 0.0 {
        Ok(())
    } else {
        Err(ExcitationError::InvalidSampleRate { sample_rate_hz })
    }
}

/// Scales `x` in place by the single largest gain for which `peak <= peak_limit` and (if
/// given) `rms <= rms_limit`; the binding limit is met with equality up to rounding.
/// Returns the gain applied. `x` must not be all zero (then it is left untouched, gain 1).
pub(crate) fn scale_to_limits(x: &mut [f64], peak_limit_nm: f64, rms_limit_nm: Option<f64>) -> f64 {
    let p = peak_abs(x);
    let r = rms(x);
    if p <= 0.0 || r <= 0.0 {
        return 1.0;
    }
    let mut g = peak_limit_nm / p;
    if let Some(rl) = rms_limit_nm {
        g = g.min(rl / r);
    }
    x.iter_mut().for_each(|v| *v *= g);
    g
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stats_of_a_sine_and_edge_cases() {
        let n = 1000;
        let x: Vec<f64> = (0..n)
            .map(|i| 3.0 * (2.0 * std::f64::consts::PI * 7.0 * i as f64 / n as f64).sin())
            .collect();
        assert!((rms(&x) - 3.0 / 2f64.sqrt()).abs() < 1e-12);
        assert!((crest_factor(&x) - 2f64.sqrt()).abs() < 1e-3);
        assert_eq!(rms(&[]), 0.0);
        assert!(crest_factor(&[]).is_nan());
        assert!(crest_factor(&[0.0, 0.0]).is_nan());
        assert_eq!(crest_factor(&[-2.0, 2.0]), 1.0);
    }

    #[test]
    fn scaling_meets_the_binding_limit() {
        // Square-ish signal: crest 1, so the rms limit binds when rms_limit < peak_limit.
        let mut x = vec![1.0, -1.0, 1.0, -1.0];
        let g = scale_to_limits(&mut x, 5.0, Some(2.0));
        assert!((g - 2.0).abs() < 1e-15);
        assert!((rms(&x) - 2.0).abs() < 1e-15);
        let mut y = vec![4.0, 0.0, 0.0, 0.0];
        scale_to_limits(&mut y, 1.0, Some(10.0));
        assert!((peak_abs(&y) - 1.0).abs() < 1e-15);
    }
}
