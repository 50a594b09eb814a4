//! A local modal fit: a few second-order modes plus residual terms fitted to one
//! measured FRF in a band, weighted by the measured per-line variances, with each mode's
//! natural frequency and damping ratio and their standard deviations.
//!
//! The model, on the receptance `H(s)` (`s = j ω`; the caller divides out the FRF's
//! kinematic factor, [`receptance`]):
//!
//! ```text
//! H(s) = sum_i [ r_i / (s - p_i) + conj(r_i) / (s - conj(p_i)) ] + R0 + R2 / s²
//! p_i = -ζ_i ω_i + j ω_i sqrt(1 - ζ_i²),   ω_i = 2π f_i
//! ```
//!
//! with complex residues `r_i` (general viscous damping) and complex residual terms `R0`
//! (the modes above the band: a constant) and `R2` (those below it: a mass line `1/s²`);
//! their imaginary parts take the small phase the sampling and the measurement chain add.
//! The residues and residual terms enter linearly and are solved by weighted linear least
//! squares at every trial `(f_i, ζ_i)` (variable projection); the `(f_i, ζ_i)` by
//! flexid's one Levenberg-Marquardt ([`crate::lsq::minimise`]).
//!
//! **Uncertainty.** The residual of line `k` is `(H_k - M_k) sqrt(2 / var_k)` in its real
//! and imaginary parts, each of unit variance under the noise alone (`var_k = E|ΔH_k|²`).
//! The covariance of all parameters (nonlinear and linear, the Jacobian by central
//! differences) is `(JᵀJ)⁻¹ s²` with `s² = max(1, chi² / (2L - P))`: a model that leaves
//! more than noise (stochastic nonlinear distortion at a high level, a mode left out)
//! widens every uncertainty by its own excess, never narrows it. The standard deviations
//! are checked against a Monte-Carlo of noisy synthetic FRFs in the tests.

use crate::frf::FrfKind;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;
use std::f64::consts::PI;

/// Damping ratios outside `(0, ZETA_MAX)` are no mode of a structure (the fit is invalid
/// there).
pub const ZETA_MAX: f64 = 0.5;

/// Most modes tried in one band.
pub const MAX_MODES: usize = 6;

/// Complex residual terms (`R0`, `R2`): 4 real parameters.
const RESIDUAL_PARAMS: usize = 4;

/// One FRF on a set of lines: frequency [Hz], response, variance of the response
/// `E|ΔH|²` (of the mean over the periods).
#[derive(Debug, Clone)]
pub struct Lines {
    pub f: Vec<f64>,
    pub h: Vec<Complex64>,
    pub var: Vec<f64>,
}

impl Lines {
    /// The lines within `[lo, hi]` Hz with a positive finite variance.
    pub fn within(&self, lo: f64, hi: f64) -> Lines {
        let idx: Vec<usize> = (0..self.f.len())
            .filter(|&k| {
                self.f[k] >= lo
                    && self.f[k] <= hi
                    && self.var[k].is_finite()
                    && self.var[k] > 0.0
                    && self.h[k].re.is_finite()
                    && self.h[k].im.is_finite()
            })
            .collect();
        Lines {
            f: idx.iter().map(|&k| self.f[k]).collect(),
            h: idx.iter().map(|&k| self.h[k]).collect(),
            var: idx.iter().map(|&k| self.var[k]).collect(),
        }
    }
}

/// The FRF of `kind` (sampled at `fs` Hz) as a receptance (position per input): divided by
/// the backward difference's `(1 - e^{-jωT}) f_s` or the velocity's `j ω`, the variance by
/// its squared modulus. `None` for a kind whose factor is not known.
pub fn receptance(kind: FrfKind, fs: f64, l: &Lines) -> Option<Lines> {
    let factor = |f: f64| -> Complex64 {
        let w = 2.0 * PI * f;
        match kind {
            FrfKind::DifferencedVelocity => {
                (Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -w / fs)) * fs
            }
            FrfKind::Velocity => Complex64::new(0.0, w),
            _ => Complex64::new(1.0, 0.0),
        }
    };
    if kind == FrfKind::Other {
        return None;
    }
    let d: Vec<Complex64> = l.f.iter().map(|&f| factor(f)).collect();
    Some(Lines {
        f: l.f.clone(),
        h: l.h.iter().zip(&d).map(|(h, d)| h / d).collect(),
        var: l
            .var
            .iter()
            .zip(&d)
            .map(|(v, d)| v / d.norm_sqr())
            .collect(),
    })
}

/// One fitted mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mode {
    /// Natural frequency `ω_i / 2π` [Hz] and its standard deviation [Hz].
    pub f_hz: f64,
    pub f_std_hz: f64,
    /// Damping ratio [-] and its standard deviation.
    pub zeta: f64,
    pub zeta_std: f64,
}

/// A local modal fit of one FRF.
#[derive(Debug, Clone)]
pub struct ModalFit {
    /// The modes, by frequency.
    pub modes: Vec<Mode>,
    /// `sum_k |H_k - M_k|² / var_k` over the lines (noise alone: about `L - P/2`).
    pub chi2: f64,
    /// Lines fitted.
    pub lines: usize,
    /// Real parameters (2 per mode for `(f, ζ)`, 2 per mode for the residue, 4 residual).
    pub params: usize,
    /// The covariance's scale `s² = max(1, 2 chi² / (2L - P))`.
    pub scale: f64,
    /// The linear parameters: per mode `Re r_i, Im r_i`, then `R0` and `R2` (re, im).
    pub linear: Vec<f64>,
}

impl ModalFit {
    /// Reduced chi² per real residual (1 = the noise alone).
    pub fn reduced_chi2(&self) -> f64 {
        2.0 * self.chi2 / (2 * self.lines).saturating_sub(self.params).max(1) as f64
    }
    /// The Bayesian information criterion on the unit-variance residuals.
    pub fn bic(&self) -> f64 {
        2.0 * self.chi2 + self.params as f64 * ((2 * self.lines) as f64).ln()
    }
}

/// The pole of a mode at `f` Hz with damping ratio `zeta`.
fn pole(f: f64, zeta: f64) -> Complex64 {
    let w = 2.0 * PI * f;
    Complex64::new(-zeta * w, w * (1.0 - zeta * zeta).sqrt())
}

/// The model's basis functions at `f` Hz for the modes `nl = [f_1, ζ_1, f_2, ζ_2, ...]`: per
/// mode the responses to `Re r` and `Im r`, then `R0` (re, im) and `R2` (re, im).
fn basis(nl: &[f64], f: f64) -> Vec<Complex64> {
    let s = Complex64::new(0.0, 2.0 * PI * f);
    let j = Complex64::new(0.0, 1.0);
    let mut b = Vec::with_capacity(nl.len() + RESIDUAL_PARAMS);
    for m in nl.chunks(2) {
        let p = pole(m[0], m[1]);
        let a = 1.0 / (s - p);
        let c = 1.0 / (s - p.conj());
        b.push(a + c);
        b.push(j * a - j * c);
    }
    let inv_s2 = 1.0 / (s * s);
    b.extend([Complex64::new(1.0, 0.0), j, inv_s2, j * inv_s2]);
    b
}

/// The frequency range a mode may take: the band `[lo, hi]` stretched by half its width
/// each side (at least 0) [Hz].
fn f_range(lo: f64, hi: f64) -> [f64; 2] {
    let w = hi - lo;
    [(lo - 0.5 * w).max(0.0), hi + 0.5 * w]
}

/// `(f, ζ)` of the modes from the unbounded coordinates the optimiser moves: each a
/// logistic onto its open range ([`f_range`], `(0, ZETA_MAX)`), so that a step never
/// leaves the admissible region (a bound the fit presses against leaves a flat
/// coordinate; [`super::amplitude_mode::identified`] then rejects the mode).
fn from_free(u: &[f64], range: [f64; 2]) -> Vec<f64> {
    let logistic = |x: f64| 1.0 / (1.0 + (-x).exp());
    u.chunks(2)
        .flat_map(|m| {
            [
                range[0] + (range[1] - range[0]) * logistic(m[0]),
                ZETA_MAX * logistic(m[1]),
            ]
        })
        .collect()
}

/// The inverse of [`from_free`]; `None` outside the open ranges.
fn to_free(nl: &[f64], range: [f64; 2]) -> Option<Vec<f64>> {
    let logit = |p: f64| (p > 0.0 && p < 1.0).then(|| (p / (1.0 - p)).ln());
    let mut u = Vec::with_capacity(nl.len());
    for m in nl.chunks(2) {
        u.push(logit((m[0] - range[0]) / (range[1] - range[0]))?);
        u.push(logit(m[1] / ZETA_MAX)?);
    }
    Some(u)
}

/// The weighted residuals (real and imaginary parts, unit variance under noise) of the
/// full parameter vector `[nl..., linear...]`.
fn residuals_full(l: &Lines, nl: &[f64], lin: &[f64]) -> Vec<f64> {
    let mut r = Vec::with_capacity(2 * l.f.len());
    for k in 0..l.f.len() {
        let b = basis(nl, l.f[k]);
        let m: Complex64 = b.iter().zip(lin).map(|(b, x)| b * x).sum();
        let e = (l.h[k] - m) * (2.0 / l.var[k]).sqrt();
        r.push(e.re);
        r.push(e.im);
    }
    r
}

/// The linear parameters at the modes `nl` (weighted least squares) and the residuals.
fn project(l: &Lines, nl: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let np = nl.len() + RESIDUAL_PARAMS;
    let n = 2 * l.f.len();
    if n <= np {
        return None;
    }
    let mut a = DMatrix::<f64>::zeros(n, np);
    let mut y = DVector::<f64>::zeros(n);
    for k in 0..l.f.len() {
        let w = (2.0 / l.var[k]).sqrt();
        for (c, b) in basis(nl, l.f[k]).iter().enumerate() {
            a[(2 * k, c)] = b.re * w;
            a[(2 * k + 1, c)] = b.im * w;
        }
        y[2 * k] = l.h[k].re * w;
        y[2 * k + 1] = l.h[k].im * w;
    }
    // columns scaled to unit norm: the residual terms and the modes differ by decades
    let norms: Vec<f64> = (0..np).map(|c| a.column(c).norm().max(1e-300)).collect();
    for (c, s) in norms.iter().enumerate() {
        a.column_mut(c).scale_mut(1.0 / s);
    }
    let x = a.clone().svd(true, true).solve(&y, 1e-12).ok()?;
    let lin: Vec<f64> = x.iter().zip(&norms).map(|(x, s)| x / s).collect();
    if !lin.iter().all(|v| v.is_finite()) {
        return None;
    }
    let r = residuals_full(l, nl, &lin);
    Some((lin, r))
}

/// Fit the modes started at `starts` (`(f [Hz], ζ)`, any order) to `l`, within the band
/// `[lo, hi]` Hz the lines were taken from. `None` when the fit cannot be made (too few
/// lines, a mode leaving the band or its damping range) or its covariance is singular.
pub fn fit(l: &Lines, starts: &[(f64, f64)], lo: f64, hi: f64) -> Option<ModalFit> {
    if starts.is_empty() {
        return None;
    }
    let mut s: Vec<(f64, f64)> = starts.to_vec();
    s.sort_by(|a, b| a.0.total_cmp(&b.0));
    let x0: Vec<f64> = s.iter().flat_map(|&(f, z)| [f, z]).collect();
    let range = f_range(lo, hi);
    let u0 = to_free(&x0, range)?;
    let res = crate::lsq::minimise(&u0, 200, |u| project(l, &from_free(u, range)).map(|p| p.1))?;
    let nl = from_free(&res.x, range);
    let (lin, r) = project(l, &nl)?;
    let chi2 = 0.5 * r.iter().map(|v| v * v).sum::<f64>();
    let np = nl.len() + lin.len();
    let n = r.len();
    // the covariance of every parameter, the Jacobian of the full residual by central
    // differences (the projection's own Jacobian would drop a term proportional to the
    // residual, which a distorted level's is not small)
    let mut full: Vec<f64> = nl.iter().chain(&lin).copied().collect();
    let mut jac = DMatrix::<f64>::zeros(n, np);
    for p in 0..np {
        let h = if p < nl.len() {
            1e-6 * full[p].abs().max(1e-3)
        } else {
            1e-6 * full[p].abs().max(1e-300)
        };
        let x = full[p];
        full[p] = x + h;
        let rp = residuals_full(l, &full[..nl.len()], &full[nl.len()..]);
        full[p] = x - h;
        let rm = residuals_full(l, &full[..nl.len()], &full[nl.len()..]);
        full[p] = x;
        for i in 0..n {
            jac[(i, p)] = (rp[i] - rm[i]) / (2.0 * h);
        }
    }
    // scaled columns for a well-conditioned inverse
    let norms: Vec<f64> = (0..np).map(|c| jac.column(c).norm().max(1e-300)).collect();
    for (c, s) in norms.iter().enumerate() {
        jac.column_mut(c).scale_mut(1.0 / s);
    }
    let jtj = jac.transpose() * &jac;
    let inv = jtj.try_inverse()?;
    let dof = n.saturating_sub(np).max(1) as f64;
    let scale = (2.0 * chi2 / dof).max(1.0);
    let sd = |p: usize| (inv[(p, p)] * scale).max(0.0).sqrt() / norms[p];
    let modes: Vec<Mode> = (0..nl.len() / 2)
        .map(|i| Mode {
            f_hz: nl[2 * i],
            f_std_hz: sd(2 * i),
            zeta: nl[2 * i + 1],
            zeta_std: sd(2 * i + 1),
        })
        .collect();
    if !modes
        .iter()
        .all(|m| m.f_std_hz.is_finite() && m.zeta_std.is_finite())
    {
        return None;
    }
    Some(ModalFit {
        modes,
        chi2,
        lines: l.f.len(),
        params: np,
        scale,
        linear: lin,
    })
}

impl ModalFit {
    /// The fitted receptance at `f` Hz with the modes' `(f_i, ζ_i)` replaced by `modes`
    /// (the residues and residual terms kept): the response the structure would have if
    /// only its natural frequencies and damping ratios changed.
    pub fn response_with(&self, modes: &[Mode], f: f64) -> Complex64 {
        let nl: Vec<f64> = modes.iter().flat_map(|m| [m.f_hz, m.zeta]).collect();
        basis(&nl, f)
            .iter()
            .zip(&self.linear)
            .map(|(b, x)| b * x)
            .sum()
    }
}

/// Starting modes from the peaks of `|H|` (a line larger than its two neighbours on each
/// side, on the 3-line running mean), the largest first, each with the damping ratio of
/// its half-power width where it can be read (else 2 %).
pub fn peak_starts(l: &Lines) -> Vec<(f64, f64)> {
    let n = l.f.len();
    if n < 5 {
        return Vec::new();
    }
    let mag: Vec<f64> = (0..n)
        .map(|k| {
            let a = k.saturating_sub(1);
            let b = (k + 1).min(n - 1);
            (a..=b).map(|i| l.h[i].norm()).sum::<f64>() / (b - a + 1) as f64
        })
        .collect();
    let mut peaks: Vec<(f64, f64, f64)> = Vec::new();
    for k in 2..n - 2 {
        if (k - 2..=k + 2).all(|i| i == k || mag[i] < mag[k]) {
            let half = mag[k] / std::f64::consts::SQRT_2;
            let lo = (0..k).rev().find(|&i| mag[i] < half);
            let hi = (k + 1..n).find(|&i| mag[i] < half);
            let zeta = match (lo, hi) {
                (Some(a), Some(b)) => ((l.f[b] - l.f[a]) / (2.0 * l.f[k])).clamp(0.002, 0.2),
                _ => 0.02,
            };
            peaks.push((mag[k], l.f[k], zeta));
        }
    }
    peaks.sort_by(|a, b| b.0.total_cmp(&a.0));
    peaks.into_iter().map(|(_, f, z)| (f, z)).collect()
}

/// The modal fit of `l` in `[lo, hi]` Hz with the number of modes chosen by the Bayesian
/// information criterion: 1 to [`MAX_MODES`] modes started at the largest peaks
/// ([`peak_starts`]), and each order also from the fit of one order less with a mode added
/// at the line where that fit's error is largest.
pub fn fit_order(l: &Lines, lo: f64, hi: f64) -> Option<ModalFit> {
    let peaks = peak_starts(l);
    let mut best: Option<ModalFit> = None;
    let mut prev: Option<ModalFit> = None;
    for n in 1..=MAX_MODES {
        let mut tries: Vec<Vec<(f64, f64)>> = Vec::new();
        if peaks.len() >= n {
            tries.push(peaks[..n].to_vec());
        }
        if let Some(p) = &prev {
            let mut s: Vec<(f64, f64)> = p.modes.iter().map(|m| (m.f_hz, m.zeta)).collect();
            if let Some(f) = worst_line(l, p) {
                s.push((f, 0.02));
                tries.push(s);
            }
        }
        let fit_n = tries
            .iter()
            .filter_map(|s| fit(l, s, lo, hi))
            .filter(distinct)
            .min_by(|a, b| a.chi2.total_cmp(&b.chi2));
        // an order that cannot be fitted (a singular covariance: a mode without a residue)
        // does not end the search: the next order has other starts
        let Some(fit_n) = fit_n else { continue };
        if best.as_ref().is_none_or(|b| fit_n.bic() < b.bic()) {
            best = Some(fit_n.clone());
        }
        prev = Some(fit_n);
    }
    best
}

/// Whether the fit's modes are distinct (no two closer than the sum of their
/// half-power half-widths `ζ f`, the same resonance fitted twice).
fn distinct(fit: &ModalFit) -> bool {
    fit.modes
        .windows(2)
        .all(|w| w[1].f_hz - w[0].f_hz > w[0].zeta * w[0].f_hz + w[1].zeta * w[1].f_hz)
}

/// The frequency of the line where `fit` leaves the largest error (on the 3-line running
/// mean of `|e|²/var`).
fn worst_line(l: &Lines, fit: &ModalFit) -> Option<f64> {
    let nl: Vec<f64> = fit.modes.iter().flat_map(|m| [m.f_hz, m.zeta]).collect();
    let (_, r) = project(l, &nl)?;
    let z: Vec<f64> = r.chunks(2).map(|c| c[0] * c[0] + c[1] * c[1]).collect();
    let n = z.len();
    (1..n.saturating_sub(1))
        .max_by(|&a, &b| {
            let s = |k: usize| z[k - 1] + z[k] + z[k + 1];
            s(a).total_cmp(&s(b))
        })
        .map(|k| l.f[k])
}

/// Synthetic receptance of the modes `(f [Hz], ζ, residue)` plus `r0` on the lines `f`.
pub fn synthetic(modes: &[(f64, f64, Complex64)], r0: Complex64, f: &[f64]) -> Vec<Complex64> {
    f.iter()
        .map(|&f| {
            let s = Complex64::new(0.0, 2.0 * PI * f);
            modes
                .iter()
                .map(|&(fm, z, r)| {
                    let p = pole(fm, z);
                    r / (s - p) + r.conj() / (s - p.conj())
                })
                .sum::<Complex64>()
                + r0
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn noisy(h: &[Complex64], var: &[f64], rng: &mut rand::rngs::StdRng) -> Vec<Complex64> {
        let n = Normal::new(0.0, 1.0).unwrap();
        h.iter()
            .zip(var)
            .map(|(h, v)| {
                let s = (v / 2.0).sqrt();
                h + Complex64::new(s * n.sample(rng), s * n.sample(rng))
            })
            .collect()
    }

    fn three_modes() -> (Vec<(f64, f64, Complex64)>, Vec<f64>) {
        let modes = vec![
            (6.6, 0.015, Complex64::new(0.0, -2e-3)),
            (7.3, 0.02, Complex64::new(1e-4, -4e-3)),
            (9.2, 0.012, Complex64::new(0.0, -1.5e-3)),
        ];
        let f: Vec<f64> = (0..100).map(|k| 5.8 + 0.0488 * k as f64).collect();
        (modes, f)
    }

    /// The fit recovers known modes from a noisy synthetic FRF within its stated
    /// uncertainty, and its standard deviations match the scatter of the estimates over a
    /// Monte-Carlo of noise realisations (the covariance is honest, not just small).
    #[test]
    fn modes_and_their_uncertainty_against_a_monte_carlo() {
        let (modes, f) = three_modes();
        let h0 = synthetic(&modes, Complex64::new(2e-6, 0.0), &f);
        // 1 % of the largest response as one-sigma everywhere
        let big = h0.iter().map(|h| h.norm()).fold(0.0, f64::max);
        let var = vec![(0.01 * big).powi(2); f.len()];
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        let (lo, hi) = (f[0], *f.last().unwrap());
        let runs = 200;
        let mut est: Vec<[f64; 2]> = Vec::new();
        let mut sd: Vec<[f64; 2]> = Vec::new();
        let mut orders = 0;
        for run in 0..runs {
            let l = Lines {
                f: f.clone(),
                h: noisy(&h0, &var, &mut rng),
                var: var.clone(),
            };
            let fit = if run < 20 {
                // the order is chosen right from the peaks alone
                let fit = fit_order(&l, lo, hi).expect("fit");
                orders += usize::from(fit.modes.len() == 3);
                fit
            } else {
                let s: Vec<(f64, f64)> = modes.iter().map(|m| (m.0 * 1.01, 0.03)).collect();
                fit(&l, &s, lo, hi).expect("fit")
            };
            assert_eq!(fit.modes.len(), 3);
            let m = fit.modes[1];
            est.push([m.f_hz, m.zeta]);
            sd.push([m.f_std_hz, m.zeta_std]);
            if run == 0 {
                for (m, t) in fit.modes.iter().zip(&modes) {
                    assert!((m.f_hz - t.0).abs() < 4.0 * m.f_std_hz, "{m:?} vs {t:?}");
                    assert!((m.zeta - t.1).abs() < 4.0 * m.zeta_std, "{m:?} vs {t:?}");
                }
                assert!(fit.reduced_chi2() < 1.5, "{}", fit.reduced_chi2());
            }
        }
        assert!(orders >= 18, "three modes chosen {orders} times of 20");
        for q in 0..2 {
            let mean = est.iter().map(|e| e[q]).sum::<f64>() / runs as f64;
            let scatter =
                (est.iter().map(|e| (e[q] - mean).powi(2)).sum::<f64>() / (runs - 1) as f64).sqrt();
            let stated = sd.iter().map(|s| s[q]).sum::<f64>() / runs as f64;
            let truth = [modes[1].0, modes[1].1][q];
            eprintln!(
                "{}: stated sd {stated:.4e}, Monte-Carlo scatter {scatter:.4e} (ratio {:.3}), mean {mean:.6} vs {truth}",
                ["f_hz", "zeta"][q],
                stated / scatter
            );
            assert!(
                (stated / scatter - 1.0).abs() < 0.2,
                "q {q}: stated {stated:.3e}, Monte-Carlo scatter {scatter:.3e}"
            );
            assert!(
                (mean - truth).abs() < 4.0 * scatter / (runs as f64).sqrt() + 1e-3 * scatter,
                "q {q}: mean {mean} vs truth {truth} (scatter {scatter:.2e})"
            );
        }
    }

    #[test]
    fn too_few_lines_or_bad_starts_are_no_fit() {
        let l = Lines {
            f: vec![1.0, 2.0, 3.0],
            h: vec![Complex64::new(1.0, 0.0); 3],
            var: vec![1.0; 3],
        };
        assert!(fit(&l, &[(2.0, 0.02)], 1.0, 3.0).is_none());
        assert!(fit(&l, &[], 1.0, 3.0).is_none());
        assert!(fit_order(&l, 1.0, 3.0).is_none());
    }

    #[test]
    fn receptance_divides_out_the_backward_difference() {
        let fs = 400.0;
        let f = vec![5.0, 7.0];
        let h: Vec<Complex64> = f
            .iter()
            .map(|&f| {
                let w = 2.0 * PI * f;
                (Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -w / fs)) * fs * 3.0
            })
            .collect();
        let l = Lines {
            f: f.clone(),
            h,
            var: vec![1.0; 2],
        };
        let r = receptance(FrfKind::DifferencedVelocity, fs, &l).unwrap();
        for h in &r.h {
            assert!((h - Complex64::new(3.0, 0.0)).norm() < 1e-12);
        }
        assert!(receptance(FrfKind::Other, fs, &l).is_none());
    }
}
