//! Total inertia from the low-frequency gain (paper step 1).
//!
//! Below the first anti-resonance a free chain moves as one body: the measured response is
//! that of a rigid inertia `J = J1 + .. + Jn` seen through the sampling. Each line gives
//! `J_i = |H_rigid,J=1(f_i)| / |H_meas(f_i)|` with the sampled unit-inertia response
//! `H_rigid,J=1` (so the hold and the differencing are removed exactly), and the lines are
//! combined by inverse-variance weighting of `ln J_i` (whose standard deviation is the
//! relative standard deviation `sqrt(var/2)/|H|` of the line).
//!
//! The compliance bends the gain slightly even well below the anti-resonance:
//! `ln J_eff(f) = ln J + b f^2 + O(f^4)`. When the band shows a significant `b` (> 3 sigma),
//! it is fitted together with `ln J` so that `J` is the `f -> 0` extrapolation.

use super::detect::ArRPair;
use super::error::IdentifyError;
use super::lines::{fallback_sigma, sigma_log, usable_lines, RigidReference};
use crate::frf::Frf;
use serde::{Deserialize, Serialize};

/// Total inertia estimated from the low-frequency lines.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InertiaEstimate {
    /// Total inertia `J1 + .. + Jn` [kg m^2].
    pub j_kgm2: f64,
    /// One-sigma standard deviation of `j_kgm2` [kg m^2] (inflated by `sqrt(chi2/dof)` when
    /// the lines scatter more than their variances say).
    pub std_kgm2: f64,
    /// Band actually used [Hz] (lowest and highest line used).
    pub band_hz: [f64; 2],
    /// Number of lines combined.
    pub lines_used: usize,
    /// Weighted scatter of the per-line estimates about the fit, per degree of freedom
    /// (about 1 when the lines agree within their variances).
    pub chi2_per_dof: f64,
    /// True when the `f^2` bending of the gain was fitted and extrapolated away.
    pub curvature_corrected: bool,
}

/// Total inertia from the lines of `frf` inside `band_hz` ([Hz], inclusive), with
/// `delay_samples` whole samples of command delay in the measurement.
///
/// Supports differenced-velocity and position FRFs.
pub fn estimate_inertia(
    frf: &Frf,
    band_hz: [f64; 2],
    delay_samples: u32,
) -> Result<InertiaEstimate, IdentifyError> {
    if band_hz[0].partial_cmp(&band_hz[1]) != Some(std::cmp::Ordering::Less) {
        return Err(IdentifyError::InvalidArgument(format!(
            "inertia band {band_hz:?} Hz is empty"
        )));
    }
    let reference = RigidReference::new(frf, delay_samples)?;
    let idx = usable_lines(frf, Some(band_hz));
    if idx.is_empty() {
        return Err(IdentifyError::NoUsableLines {
            band_hz,
            total: frf.len(),
        });
    }
    let fb = fallback_sigma(frf, &idx);
    // per line: x = f^2 (scaled), y = ln J_i, w = 1/sigma^2
    let fmax = idx.iter().map(|&i| frf.freq_hz[i]).fold(0.0, f64::max);
    let pts: Vec<(f64, f64, f64)> = idx
        .iter()
        .map(|&i| {
            let f = frf.freq_hz[i];
            let y = (reference.at(f).norm() / frf.h[i].norm()).ln();
            let s = sigma_log(frf, i, fb);
            ((f / fmax).powi(2), y, 1.0 / (s * s))
        })
        .collect();
    let (mean, var_mean, chi2_0) = weighted_mean(&pts);
    let n = pts.len();
    let mut est = (mean, var_mean, chi2_0, n.saturating_sub(1), false);
    if n >= 3 {
        if let Some((a, var_a, b, var_b, chi2_1)) = weighted_line(&pts) {
            let dof = n - 2;
            let infl = (chi2_1 / dof as f64).max(1.0);
            if b.abs() > 3.0 * (var_b * infl).sqrt() {
                est = (a, var_a, chi2_1, dof, true);
            }
        }
    }
    let (ln_j, var_ln_j, chi2, dof, corrected) = est;
    let chi2_per_dof = if dof > 0 { chi2 / dof as f64 } else { 1.0 };
    let j = ln_j.exp();
    let std_ln = (var_ln_j * chi2_per_dof.max(1.0)).sqrt();
    Ok(InertiaEstimate {
        j_kgm2: j,
        std_kgm2: j * std_ln,
        band_hz: [frf.freq_hz[idx[0]], frf.freq_hz[*idx.last().unwrap()]],
        lines_used: n,
        chi2_per_dof,
        curvature_corrected: corrected,
    })
}

/// Total inertia on the lines below half the first detected anti-resonance (or below
/// `fallback_limit_hz` [Hz] when no pair was detected).
///
/// Fails when the first pair's anti-resonance lies below the measured band: the lowest lines
/// then already show a compliant chain and the total inertia is not observable.
pub fn estimate_inertia_below_pairs(
    frf: &Frf,
    pairs: &[ArRPair],
    fallback_limit_hz: f64,
    delay_samples: u32,
) -> Result<InertiaEstimate, IdentifyError> {
    let limit = match pairs.first() {
        Some(p) if p.ar_below_band => {
            return Err(IdentifyError::InvalidArgument(format!(
                "the first anti-resonance lies below the lowest line ({:.4} Hz): the total \
                 inertia is not visible in the low-frequency gain",
                p.ar_hz
            )))
        }
        Some(p) => 0.5 * p.ar_hz,
        None => fallback_limit_hz,
    };
    estimate_inertia(frf, [0.0, limit], delay_samples)
}

/// Weighted mean of `y`: (mean, variance of the mean, chi2 about it).
fn weighted_mean(pts: &[(f64, f64, f64)]) -> (f64, f64, f64) {
    let sw: f64 = pts.iter().map(|p| p.2).sum();
    let m = pts.iter().map(|p| p.2 * p.1).sum::<f64>() / sw;
    let chi2 = pts.iter().map(|p| p.2 * (p.1 - m).powi(2)).sum();
    (m, 1.0 / sw, chi2)
}

/// Weighted straight line `y = a + b x`: (a, var a, b, var b, chi2).
fn weighted_line(pts: &[(f64, f64, f64)]) -> Option<(f64, f64, f64, f64, f64)> {
    let (mut s, mut sx, mut sxx, mut sy, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, y, w) in pts {
        s += w;
        sx += w * x;
        sxx += w * x * x;
        sy += w * y;
        sxy += w * x * y;
    }
    let det = s * sxx - sx * sx;
    if det.partial_cmp(&(1e-12 * s * sxx)) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    let a = (sxx * sy - sx * sxy) / det;
    let b = (s * sxy - sx * sy) / det;
    let chi2 = pts
        .iter()
        .map(|&(x, y, w)| w * (y - a - b * x).powi(2))
        .sum();
    Some((a, sxx / det, b, s / det, chi2))
}
