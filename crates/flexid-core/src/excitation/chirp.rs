//! Logarithmic (exponential) swept sine in torque units [N m].

use std::f64::consts::PI;

use serde::{Deserialize, Serialize};

use super::stats::{
    check_length, check_limit, check_sample_rate, crest_factor, peak_abs, rms, scale_to_limits,
};
use super::{ExcitationError, ExcitationInfo, ExcitationKind};

/// Design of an exponential sweep `x(t) = a(t) sin(phi(t))` [N m] from `f0_hz` to `f1_hz`
/// over `duration_s`, sampled at `t_n = n / fs`, `n = 0 .. round(duration_s * fs)`.
///
/// The instantaneous frequency is `f(t) = f0 (f1 / f0)^(t / T)` \[Hz\] and the phase
/// `phi(t) = 2 pi f0 L (exp(t / L) - 1)` \[rad\] with `L = T / ln(f1 / f0)`. Downward sweeps
/// (`f1 < f0`) are allowed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChirpDesign {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Start frequency \[Hz\] (> 0, below Nyquist).
    pub f0_hz: f64,
    /// End frequency \[Hz\] (> 0, below Nyquist, != f0).
    pub f1_hz: f64,
    /// Sweep duration `T` \[s\].
    pub duration_s: f64,
    /// Length \[s\] of the raised-cosine fade-in and fade-out (0 = none, at most `T / 2`).
    pub taper_s: f64,
    /// Amplitude envelope `a(t) ∝ f(t)^exponent` (0 = constant amplitude).
    pub amplitude_exponent: f64,
    /// Largest allowed |torque| [N m] (> 0).
    pub peak_limit_nm: f64,
    /// Optional largest RMS torque [N m] (> 0) over the whole sweep.
    pub rms_limit_nm: Option<f64>,
}

impl ChirpDesign {
    /// Constant-amplitude sweep without taper and without RMS limit.
    pub fn new(
        sample_rate_hz: f64,
        f0_hz: f64,
        f1_hz: f64,
        duration_s: f64,
        peak_limit_nm: f64,
    ) -> Self {
        Self {
            sample_rate_hz,
            f0_hz,
            f1_hz,
            duration_s,
            taper_s: 0.0,
            amplitude_exponent: 0.0,
            peak_limit_nm,
            rms_limit_nm: None,
        }
    }

    /// Generates the sweep, scaled so the binding limit (peak, or RMS if given) is met.
    pub fn generate(&self) -> Result<Chirp, ExcitationError> {
        let fs = self.sample_rate_hz;
        check_sample_rate(fs)?;
        check_limit("peak", self.peak_limit_nm)?;
        if let Some(r) = self.rms_limit_nm {
            check_limit("rms", r)?;
        }
        let nyquist_hz = fs / 2.0;
        for f in [self.f0_hz, self.f1_hz] {
            if !(f.is_finite() && f > 0.0) {
                return Err(ExcitationError::InvalidFrequency { freq_hz: f });
            }
            if f >= nyquist_hz {
                return Err(ExcitationError::FrequencyAboveNyquist {
                    freq_hz: f,
                    nyquist_hz,
                });
            }
        }
        if self.f0_hz == self.f1_hz {
            return Err(ExcitationError::EmptySweep {
                freq_hz: self.f0_hz,
            });
        }
        let t_total = self.duration_s;
        let n_f = t_total * fs;
        if !(t_total.is_finite() && t_total > 0.0 && n_f.round() >= 2.0) {
            return Err(ExcitationError::InvalidDuration {
                duration_s: t_total,
            });
        }
        check_length(n_f.round())?;
        let taper = self.taper_s;
        if !(taper.is_finite() && taper >= 0.0 && taper <= 0.5 * t_total) {
            return Err(ExcitationError::InvalidTaper {
                taper_s: taper,
                duration_s: t_total,
            });
        }
        if !self.amplitude_exponent.is_finite() {
            return Err(ExcitationError::InvalidExponent {
                exponent: self.amplitude_exponent,
            });
        }

        let n = n_f.round() as usize;
        let l = t_total / (self.f1_hz / self.f0_hz).ln();
        let f_ref = self.f0_hz.min(self.f1_hz);
        let mut signal = Vec::with_capacity(n);
        for i in 0..n {
            let t = i as f64 / fs;
            let growth = (t / l).exp(); // f(t) / f0
            let phase = 2.0 * PI * self.f0_hz * l * (growth - 1.0);
            let mut a = (self.f0_hz * growth / f_ref).powf(self.amplitude_exponent);
            if taper > 0.0 {
                let edge = t.min(t_total - t);
                if edge < taper {
                    a *= 0.5 * (1.0 - (PI * edge / taper).cos());
                }
            }
            signal.push(a * phase.sin());
        }
        scale_to_limits(&mut signal, self.peak_limit_nm, self.rms_limit_nm);
        Ok(Chirp {
            sample_rate_hz: fs,
            f0_hz: self.f0_hz,
            f1_hz: self.f1_hz,
            duration_s: t_total,
            signal,
        })
    }
}

/// A generated exponential sweep [N m].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Chirp {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Start frequency \[Hz\].
    pub f0_hz: f64,
    /// End frequency \[Hz\].
    pub f1_hz: f64,
    /// Sweep duration `T` \[s\].
    pub duration_s: f64,
    /// The samples [N m], `signal[n]` at `t = n / fs`.
    pub signal: Vec<f64>,
}

impl Chirp {
    /// Instantaneous frequency `f0 (f1 / f0)^(t / T)` \[Hz\] at time `t` \[s\].
    pub fn instantaneous_frequency_hz(&self, t_s: f64) -> f64 {
        self.f0_hz * (self.f1_hz / self.f0_hz).powf(t_s / self.duration_s)
    }

    /// Sweep phase `phi(t)` \[rad\] at time `t` \[s\] (the signal is `a(t) sin(phi(t))`).
    pub fn phase_rad(&self, t_s: f64) -> f64 {
        let l = self.duration_s / (self.f1_hz / self.f0_hz).ln();
        2.0 * PI * self.f0_hz * l * ((t_s / l).exp() - 1.0)
    }

    /// Peak |torque| [N m].
    pub fn peak_nm(&self) -> f64 {
        peak_abs(&self.signal)
    }

    /// RMS torque [N m] over the sweep.
    pub fn rms_nm(&self) -> f64 {
        rms(&self.signal)
    }

    /// Crest factor (dimensionless).
    pub fn crest_factor(&self) -> f64 {
        crest_factor(&self.signal)
    }

    /// Description: kind Chirp, not periodic (`period_samples = 0`), band `[min, max]` of
    /// the two sweep ends, design `"log_sweep"`.
    pub fn info(&self) -> ExcitationInfo {
        ExcitationInfo {
            kind: ExcitationKind::Chirp,
            period_samples: 0,
            periods: 0,
            transient_periods: 0,
            excited_lines: Vec::new(),
            band_hz: Some([self.f0_hz.min(self.f1_hz), self.f0_hz.max(self.f1_hz)]),
            peak_nm: Some(self.peak_nm()),
            rms_nm: Some(self.rms_nm()),
            design: Some("log_sweep".to_string()),
            blocks: Vec::new(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Times \[s\] of the zero crossings of `x`, linearly interpolated.
    fn zero_crossings(x: &[f64], fs: f64) -> Vec<f64> {
        x.windows(2)
            .enumerate()
            .filter(|(_, w)| (w[0] < 0.0) != (w[1] < 0.0))
            .map(|(i, w)| (i as f64 + w[0] / (w[0] - w[1])) / fs)
            .collect()
    }

    #[test]
    fn instantaneous_frequency_follows_the_exponential_law() {
        let d = ChirpDesign::new(2000.0, 2.0, 100.0, 10.0, 4.0);
        let c = d.generate().unwrap();
        assert_eq!(c.signal.len(), 20000);
        assert!((c.peak_nm() - 4.0).abs() < 1e-12);
        // Naive reference: the samples are g sin(phi(t_n)), g scaling the sampled peak to 4.
        let s: Vec<f64> = (0..c.signal.len())
            .map(|i| c.phase_rad(i as f64 / 2000.0).sin())
            .collect();
        let g = 4.0 / peak_abs(&s);
        for (v, r) in c.signal.iter().zip(&s) {
            assert!((v - g * r).abs() < 1e-9);
        }
        let zc = zero_crossings(&c.signal, 2000.0);
        for t in [0.5, 2.0, 5.0, 7.5, 9.5] {
            let j = zc.iter().position(|&z| z > t).unwrap();
            let (a, b) = (zc[j - 1], zc[j]);
            let f_est = 0.5 / (b - a);
            let f_law = 2.0 * 50f64.powf(0.5 * (a + b) / 10.0);
            assert!(
                (f_est / f_law - 1.0).abs() < 5e-3,
                "t = {t}: {f_est} vs {f_law}"
            );
            assert!((c.instantaneous_frequency_hz(0.5 * (a + b)) / f_law - 1.0).abs() < 1e-12);
            // Analytic phase: d phi / dt / (2 pi) is the instantaneous frequency.
            let h = 1e-6;
            let f_phase = (c.phase_rad(t + h) - c.phase_rad(t - h)) / (2.0 * h * 2.0 * PI);
            assert!((f_phase / c.instantaneous_frequency_hz(t) - 1.0).abs() < 1e-6);
        }
        let info = c.info();
        assert_eq!(info.kind, ExcitationKind::Chirp);
        assert_eq!(info.band_hz, Some([2.0, 100.0]));
    }

    #[test]
    fn taper_shaping_and_limits() {
        let mut d = ChirpDesign::new(1000.0, 1.0, 50.0, 8.0, 2.0);
        d.taper_s = 0.5;
        d.amplitude_exponent = 0.5;
        let c = d.generate().unwrap();
        assert_eq!(c.signal[0], 0.0);
        assert!(c.signal[c.signal.len() - 1].abs() < 1e-4);
        assert!(c.peak_nm() <= 2.0 * (1.0 + 1e-12));
        assert!((c.peak_nm() - 2.0).abs() < 1e-12);
        // Envelope a(t) = a0 * (f(t) / f0)^0.5 outside the tapers, read where |sin phi| > 0.5.
        let env = |i: usize| {
            let t = i as f64 / 1000.0;
            c.signal[i] / c.phase_rad(t).sin()
        };
        let (mut a_ref, mut t_ref) = (0.0, 0.0);
        for i in (600..7400).step_by(13) {
            let t = i as f64 / 1000.0;
            if c.phase_rad(t).sin().abs() < 0.5 {
                continue;
            }
            if a_ref == 0.0 {
                (a_ref, t_ref) = (env(i), t);
                continue;
            }
            let want = a_ref
                * (c.instantaneous_frequency_hz(t) / c.instantaneous_frequency_hz(t_ref)).sqrt();
            assert!((env(i) / want - 1.0).abs() < 1e-9, "t = {t}");
        }
        // RMS limit binds when tight.
        d.rms_limit_nm = Some(0.3);
        let c = d.generate().unwrap();
        assert!((c.rms_nm() - 0.3).abs() < 1e-12);
        assert!(c.peak_nm() < 2.0);
    }

    #[test]
    fn bad_chirp_inputs() {
        use ExcitationError as E;
        let ok = ChirpDesign::new(1000.0, 1.0, 50.0, 8.0, 2.0);
        let with = |f: &dyn Fn(&mut ChirpDesign)| {
            let mut d = ok.clone();
            f(&mut d);
            d.generate().unwrap_err()
        };
        assert!(matches!(
            with(&|d| d.f0_hz = 0.0),
            E::InvalidFrequency { .. }
        ));
        assert!(matches!(
            with(&|d| d.f1_hz = 500.0),
            E::FrequencyAboveNyquist { .. }
        ));
        assert!(matches!(with(&|d| d.f1_hz = 1.0), E::EmptySweep { .. }));
        assert!(matches!(
            with(&|d| d.duration_s = 0.0),
            E::InvalidDuration { .. }
        ));
        assert!(matches!(
            with(&|d| d.duration_s = f64::INFINITY),
            E::InvalidDuration { .. }
        ));
        assert!(matches!(with(&|d| d.taper_s = 5.0), E::InvalidTaper { .. }));
        assert!(matches!(with(&|d| d.duration_s = 1e300), E::TooLong { .. }));
        assert!(matches!(
            with(&|d| d.peak_limit_nm = 0.0),
            E::NonPositiveLimit { .. }
        ));
        assert!(matches!(
            with(&|d| d.rms_limit_nm = Some(-1.0)),
            E::NonPositiveLimit { which: "rms", .. }
        ));
        assert!(matches!(
            with(&|d| d.amplitude_exponent = f64::NAN),
            E::InvalidExponent { .. }
        ));
        assert!(matches!(
            with(&|d| d.sample_rate_hz = 0.0),
            E::InvalidSampleRate { .. }
        ));
        // Downward sweeps are fine.
        assert!(ChirpDesign::new(1000.0, 50.0, 1.0, 8.0, 2.0)
            .generate()
            .is_ok());
    }
}
