use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// Which quantity the FRF relates to the torque command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrfKind {
    /// Torque [N m] -> velocity obtained as the backward difference of the sampled
    /// position, `(p[k] - p[k-1]) * fs` [rad/s]. The difference quotient's own response is
    /// part of what was measured; compare models with
    /// [`crate::model::SampledChain::frf`] which includes it exactly.
    DifferencedVelocity,
    /// Torque [N m] -> a velocity signal measured directly (e.g. the drive's own estimate).
    Velocity,
    /// Torque [N m] -> position [rad].
    Position,
    /// Anything else (e.g. acceleration in the DaISy robot-arm data); units are the user's.
    Other,
}

/// A measured (or modelled) frequency response on a set of lines.
///
/// `h[i]` is the complex response at `freq_hz[i]`; `var[i]` is the variance of `h[i]` as an
/// estimate, i.e. `E|h_est - h_true|^2` (the variance of the *mean*, not of one period).
/// A variance of `f64::INFINITY` marks a line without a usable estimate; `0.0` means "not
/// known" only for modelled responses.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Frf {
    /// Line frequencies [Hz], strictly increasing.
    pub freq_hz: Vec<f64>,
    /// Complex response at each line (units depend on `kind`, e.g. (rad/s)/(N m)).
    pub h: Vec<Complex64>,
    /// Variance of each `h` estimate [(unit)^2].
    pub var: Vec<f64>,
    /// Magnitude-squared coherence in [0, 1], if the estimator provides it.
    pub coherence: Option<Vec<f64>>,
    /// What the response relates.
    pub kind: FrfKind,
    /// Sample rate of the underlying recording [Hz] (needed to evaluate sampled models).
    pub sample_rate_hz: f64,
}

impl Frf {
    /// Number of lines.
    pub fn len(&self) -> usize {
        self.freq_hz.len()
    }

    /// True when there are no lines.
    pub fn is_empty(&self) -> bool {
        self.freq_hz.is_empty()
    }

    /// Indices of the lines a weighted fit can use: a finite, positive variance and a
    /// response that is not zero.
    pub fn usable_lines(&self) -> Vec<usize> {
        (0..self.len())
            .filter(|&k| {
                let v = self.var[k];
                v.is_finite() && v > 0.0 && self.h[k].norm() > 0.0
            })
            .collect()
    }

    /// Standard deviation of `h[i]` relative to its magnitude (a dimensionless number; 0.01
    /// means about 0.086 dB / 0.57 degrees of one-sigma scatter).
    pub fn relative_std(&self, i: usize) -> f64 {
        self.var[i].sqrt() / self.h[i].norm()
    }

    /// Magnitude in dB at each line.
    pub fn magnitude_db(&self) -> Vec<f64> {
        self.h.iter().map(|h| 20.0 * h.norm().log10()).collect()
    }

    /// Phase in degrees at each line, unwrapped along frequency.
    pub fn phase_deg_unwrapped(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(self.h.len());
        let mut prev = 0.0_f64;
        let mut offset = 0.0_f64;
        for (i, h) in self.h.iter().enumerate() {
            let p = h.arg();
            if i > 0 {
                let d = p - prev;
                if d > std::f64::consts::PI {
                    offset -= 2.0 * std::f64::consts::PI;
                } else if d < -std::f64::consts::PI {
                    offset += 2.0 * std::f64::consts::PI;
                }
            }
            prev = p;
            out.push((p + offset).to_degrees());
        }
        out
    }

    /// Keep only the lines for which `keep(freq_hz)` is true.
    pub fn retain_band(&mut self, mut keep: impl FnMut(f64) -> bool) {
        let idx: Vec<usize> = (0..self.len()).filter(|&i| keep(self.freq_hz[i])).collect();
        self.freq_hz = idx.iter().map(|&i| self.freq_hz[i]).collect();
        self.h = idx.iter().map(|&i| self.h[i]).collect();
        self.var = idx.iter().map(|&i| self.var[i]).collect();
        if let Some(c) = &self.coherence {
            self.coherence = Some(idx.iter().map(|&i| c[i]).collect());
        }
    }
}
