//! Local second-order rational fit used to refine anti-resonance and resonance frequencies.
//!
//! Around one pair the normalised response `R = H_meas / H_rigid,J=1` (the inverse effective
//! inertia) is, to a good approximation, `(b0 + b1 s + b2 s^2) / (a0 + a1 s + s^2)` in the
//! scaled Laplace variable `s = j w / w_c`: exact for a two-mass chain, locally accurate for
//! longer chains. The coefficients are found by Sanathanan-Koerner iterations (linear least
//! squares re-weighted by the previous denominator), each line weighted by its standard
//! deviation; the zero gives the anti-resonance, the pole the resonance.

use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// A refined frequency with its standard deviation [Hz].
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Refined {
    pub(crate) hz: f64,
    pub(crate) std_hz: f64,
}

/// Result of the local fit: the zero pair (anti-resonance) and the pole pair (resonance),
/// each `None` when the fitted quadratic has no positive natural frequency.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LocalFit {
    pub(crate) zero: Option<Refined>,
    pub(crate) pole: Option<Refined>,
}

/// Fit `(b0 + b1 s + b2 s^2)/(a0 + a1 s + s^2)` to `r` at `f_hz` (`sigma`: absolute standard
/// deviation of each of the real and imaginary parts of `r`), scaled about `fc_hz`.
pub(crate) fn fit_second_order(
    f_hz: &[f64],
    r: &[Complex64],
    sigma: &[f64],
    fc_hz: f64,
) -> Option<LocalFit> {
    let m = f_hz.len();
    if m < 3 {
        return None;
    }
    let s: Vec<Complex64> = f_hz
        .iter()
        .map(|f| Complex64::new(0.0, f / fc_hz))
        .collect();
    let mut den_prev = vec![1.0_f64; m];
    let mut x = DVector::<f64>::zeros(5);
    let mut cov = DMatrix::<f64>::zeros(5, 5);
    for _ in 0..12 {
        let mut a = DMatrix::<f64>::zeros(2 * m, 5);
        let mut b = DVector::<f64>::zeros(2 * m);
        for i in 0..m {
            let w = 1.0 / (sigma[i] * den_prev[i]);
            let si = s[i];
            // N(s) - R (a0 + a1 s) = R s^2
            let cols = [Complex64::new(1.0, 0.0), si, si * si, -r[i], -r[i] * si];
            let rhs = r[i] * si * si;
            for (j, c) in cols.iter().enumerate() {
                a[(2 * i, j)] = w * c.re;
                a[(2 * i + 1, j)] = w * c.im;
            }
            b[2 * i] = w * rhs.re;
            b[2 * i + 1] = w * rhs.im;
        }
        // column scaling for conditioning
        let scale: Vec<f64> = (0..5)
            .map(|j| {
                let n = a.column(j).norm();
                if n > 0.0 {
                    n
                } else {
                    1.0
                }
            })
            .collect();
        for (j, sc) in scale.iter().enumerate() {
            a.column_mut(j).scale_mut(1.0 / sc);
        }
        let svd = a.clone().svd(true, true);
        let smax = svd.singular_values.max();
        let y = svd.solve(&b, 1e-13 * smax).ok()?;
        let xn = DVector::from_fn(5, |j, _| y[j] / scale[j]);
        // residual scale and covariance of the scaled solution
        let res = &a * &y - &b;
        let dof = (2 * m).saturating_sub(5).max(1) as f64;
        let s2 = (res.norm_squared() / dof).max(1.0);
        let ata = a.transpose() * &a;
        let inv = ata
            .svd(true, true)
            .pseudo_inverse(1e-14 * smax * smax)
            .ok()?;
        cov = DMatrix::from_fn(5, 5, |i, j| inv[(i, j)] * s2 / (scale[i] * scale[j]));
        let change = (&xn - &x).norm() / xn.norm().max(1e-300);
        x = xn;
        for i in 0..m {
            den_prev[i] = (x[3] + x[4] * s[i] + s[i] * s[i]).norm().max(1e-12);
        }
        if change < 1e-10 {
            break;
        }
    }
    let (b0, b2, a0) = (x[0], x[2], x[3]);
    let pole = (a0 > 0.0).then(|| {
        let w = a0.sqrt();
        let sd = (cov[(3, 3)].max(0.0)).sqrt() / (2.0 * w);
        Refined {
            hz: fc_hz * w,
            std_hz: fc_hz * sd,
        }
    });
    let zero = (b2 != 0.0 && b0 / b2 > 0.0).then(|| {
        let w = (b0 / b2).sqrt();
        // d ln w = 0.5 (db0/b0 - db2/b2)
        let g0 = 0.5 / b0;
        let g2 = -0.5 / b2;
        let v = g0 * g0 * cov[(0, 0)] + g2 * g2 * cov[(2, 2)] + 2.0 * g0 * g2 * cov[(0, 2)];
        Refined {
            hz: fc_hz * w,
            std_hz: fc_hz * w * v.max(0.0).sqrt(),
        }
    });
    Some(LocalFit { zero, pole })
}
