//! A small Levenberg-Marquardt on a residual closure (forward-difference Jacobian), for
//! the joint refits of the nominal chain with an effect's few parameters.

use nalgebra::{DMatrix, DVector};

/// Result of [`minimise`].
#[derive(Debug, Clone)]
pub struct LmResult {
    pub x: Vec<f64>,
    /// Sum of squared residuals at `x`.
    pub cost: f64,
    /// Covariance `(JᵀJ)⁻¹ · max(1, cost/dof)` of `x`.
    pub cov: Vec<f64>,
}

/// A step that lowers the cost by less than this fraction of it ends the fit. The fits'
/// costs are chi² of 1e3-1e6 over the lines, so what is left is at most ~1, below every
/// decision the ranking takes on them (an information-criterion penalty of 2 and more per
/// parameter); at 1e-9 the last iterations bought nothing visible and cost ~15 % of a
/// diagnosis (`benches/withheld_effect.rs`, README "Timing").
pub const MIN_REL_IMPROVEMENT: f64 = 1e-6;

fn cost_of(r: &[f64]) -> f64 {
    r.iter().map(|v| v * v).sum()
}

/// Minimise `|r(x)|²` from `x0`; `r` returns `None` where the model is invalid.
pub fn minimise(
    x0: &[f64],
    max_iter: usize,
    mut r: impl FnMut(&[f64]) -> Option<Vec<f64>>,
) -> Option<LmResult> {
    let np = x0.len();
    let mut x = x0.to_vec();
    let mut res = r(&x)?;
    let mut cost = cost_of(&res);
    if !cost.is_finite() {
        return None;
    }
    let mut lambda = 1e-3;
    let mut jac = DMatrix::<f64>::zeros(res.len(), np);
    let jacobian = |x: &[f64],
                    res: &[f64],
                    jac: &mut DMatrix<f64>,
                    r: &mut dyn FnMut(&[f64]) -> Option<Vec<f64>>|
     -> bool {
        for p in 0..np {
            let h = 1e-6 * x[p].abs().max(1.0);
            let mut xp = x.to_vec();
            xp[p] += h;
            let Some(rp) = r(&xp) else { return false };
            for (i, (a, b)) in rp.iter().zip(res).enumerate() {
                jac[(i, p)] = (a - b) / h;
            }
        }
        true
    };
    if !jacobian(&x, &res, &mut jac, &mut r) {
        return None;
    }
    for _ in 0..max_iter {
        let jtj = jac.tr_mul(&jac);
        let g = jac.tr_mul(&DVector::from_column_slice(&res));
        let mut improved = false;
        for _ in 0..8 {
            let mut a = jtj.clone();
            for i in 0..np {
                a[(i, i)] += lambda * jtj[(i, i)].max(1e-12);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            if let Some(rn) = r(&xn) {
                let cn = cost_of(&rn);
                if cn.is_finite() && cn < cost {
                    let rel = (cost - cn) / cost.max(1e-300);
                    x = xn;
                    res = rn;
                    cost = cn;
                    lambda = (lambda * 0.3).max(1e-9);
                    improved = rel > MIN_REL_IMPROVEMENT;
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
        if !jacobian(&x, &res, &mut jac, &mut r) {
            break;
        }
    }
    let jtj = jac.tr_mul(&jac);
    let dof = (res.len() as f64 - np as f64).max(1.0);
    let scale = (cost / dof).max(1.0);
    let cov = jtj
        .pseudo_inverse(1e-12)
        .map(|c| (c * scale).as_slice().to_vec())
        .unwrap_or_else(|_| vec![f64::NAN; np * np]);
    Some(LmResult { x, cost, cov })
}

#[cfg(test)]
mod tests {
    #[test]
    fn diagnose_lm_fits_an_exponential() {
        let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-1.5 * t).exp()).collect();
        let r = super::minimise(&[1.0, -0.5], 50, |x| {
            Some(
                t.iter()
                    .zip(&y)
                    .map(|(t, y)| x[0] * (x[1] * t).exp() - y)
                    .collect(),
            )
        })
        .unwrap();
        assert!(
            (r.x[0] - 2.0).abs() < 1e-6 && (r.x[1] + 1.5).abs() < 1e-6,
            "{:?}",
            r.x
        );
    }
}
