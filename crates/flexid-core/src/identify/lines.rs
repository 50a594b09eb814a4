//! Line selection and the rigid-body reference shared by the identification steps.

use super::error::IdentifyError;
use crate::frf::{Frf, FrfKind};
use crate::model::{Chain, SampledChain};
use num_complex::Complex64;

/// Indices of the lines of `frf` that carry information: frequency inside `band_hz`
/// (inclusive, [Hz]), finite positive variance (or zero, "unknown", for modelled responses),
/// finite non-zero response.
pub(crate) fn usable_lines(frf: &Frf, band_hz: Option<[f64; 2]>) -> Vec<usize> {
    let [lo, hi] = band_hz.unwrap_or([0.0, f64::INFINITY]);
    (0..frf.len())
        .filter(|&i| {
            let f = frf.freq_hz[i];
            let h = frf.h[i];
            let v = frf.var[i];
            f > 0.0
                && f >= lo
                && f <= hi
                && f.is_finite()
                && v.is_finite()
                && v >= 0.0
                && h.re.is_finite()
                && h.im.is_finite()
                && h.norm() > 0.0
        })
        .collect()
}

/// Relative standard deviation of each of `ln|h|` and `arg h` [1, rad] on line `i`:
/// `sqrt(var/2)/|h|`. Lines with an unknown (zero) variance get `fallback`.
pub(crate) fn sigma_log(frf: &Frf, i: usize, fallback: f64) -> f64 {
    let v = frf.var[i];
    if v > 0.0 {
        (v / 2.0).sqrt() / frf.h[i].norm()
    } else {
        fallback
    }
}

/// Median of the known relative standard deviations on `idx`, or 1e-2 when none is known.
pub(crate) fn fallback_sigma(frf: &Frf, idx: &[usize]) -> f64 {
    let mut s: Vec<f64> = idx
        .iter()
        .filter(|&&i| frf.var[i] > 0.0)
        .map(|&i| sigma_log(frf, i, 0.0))
        .collect();
    if s.is_empty() {
        return 1e-2;
    }
    s.sort_by(|a, b| a.total_cmp(b));
    s[s.len() / 2]
}

/// Check the sample rate of an FRF.
pub(crate) fn sample_rate(frf: &Frf) -> Result<f64, IdentifyError> {
    let fs = frf.sample_rate_hz;
    if fs.is_finite() && fs > 0.0 {
        Ok(fs)
    } else {
        Err(IdentifyError::SampleRate { fs_hz: fs })
    }
}

/// The sampled response of a rigid body of unit inertia (1 kg m^2) as measured by `kind`
/// (differenced velocity or position) at `f_hz`, including `delay_samples`: the footing
/// against which the measured FRF is normalised (`H_meas / H_rigid` is `1/J_eff`).
pub(crate) struct RigidReference {
    sc: SampledChain,
    kind: FrfKind,
}

impl RigidReference {
    pub(crate) fn new(frf: &Frf, delay_samples: u32) -> Result<Self, IdentifyError> {
        let fs = sample_rate(frf)?;
        match frf.kind {
            FrfKind::DifferencedVelocity | FrfKind::Position => {}
            kind => {
                return Err(IdentifyError::UnsupportedKind {
                    what: "sampled chain models",
                    kind,
                })
            }
        }
        let unit = Chain::new(vec![1.0], vec![], vec![])?;
        Ok(RigidReference {
            sc: SampledChain::new(&unit, fs, delay_samples)?,
            kind: frf.kind,
        })
    }

    /// Response of the unit rigid body at `f_hz`.
    pub(crate) fn at(&self, f_hz: f64) -> Complex64 {
        match self.kind {
            FrfKind::Position => self.sc.position_frf(f_hz),
            _ => self.sc.frf(f_hz),
        }
    }
}
