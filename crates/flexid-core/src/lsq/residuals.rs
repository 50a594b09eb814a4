//! Least squares on a residual closure `r(x)`: the normal equations by forward
//! differences, solved by the one Levenberg-Marquardt of [`super::lm`], and the covariance
//! of the result. The diagnosis's joint refits of the nominal chain with an effect's few
//! parameters use it.

use super::lm::{minimize, Damping, LmOptions, LmWorkspace, NormalEquations};
use nalgebra::DMatrix;

/// A step that lowers the cost by less than this fraction of it (actual and predicted)
/// ends the fit. The fits' costs are chi² of 1e3-1e6 over the lines, so what is left is at
/// most ~1, below every decision the ranking takes on them (an information-criterion
/// penalty of 2 and more per parameter).
pub const MIN_REL_IMPROVEMENT: f64 = 1e-6;

/// Result of [`minimise`].
#[derive(Debug, Clone)]
pub struct LmResult {
    /// The parameters at the end.
    pub x: Vec<f64>,
    /// Sum of squared residuals at `x`.
    pub cost: f64,
    /// Covariance `(JᵀJ)⁻¹ · max(1, cost/dof)` of `x`, row-major.
    pub cov: Vec<f64>,
}

/// A residual closure as a [`NormalEquations`] problem: the Jacobian column of parameter
/// `p` is `(r(x + h e_p) - r(x)) / h` with `h = 1e-6 max(|x_p|, 1)`.
pub struct Residuals<F> {
    r: F,
    theta: Vec<f64>,
    probe: Vec<f64>,
    res: Vec<f64>,
}

impl<F: FnMut(&[f64]) -> Option<Vec<f64>>> Residuals<F> {
    /// The problem of `r` with `np` parameters.
    pub fn new(r: F, np: usize) -> Self {
        Residuals {
            r,
            theta: vec![0.0; np],
            probe: vec![0.0; np],
            res: Vec::new(),
        }
    }

    /// Residuals at the parameters of the last cost.
    pub fn residuals(&self) -> &[f64] {
        &self.res
    }
}

impl<F: FnMut(&[f64]) -> Option<Vec<f64>>> NormalEquations for Residuals<F> {
    type Scratch = ();

    fn scratch(&self) {}

    fn set_theta(&mut self, theta: &[f64]) {
        self.theta.copy_from_slice(theta);
    }

    fn cost(&mut self, _: &mut ()) -> Option<f64> {
        let r = (self.r)(&self.theta)?;
        let cost: f64 = r.iter().map(|v| v * v).sum();
        self.res = r;
        cost.is_finite().then_some(cost)
    }

    fn normal_after_cost(&mut self, _: &mut (), jtj: &mut [f64], jtr: &mut [f64]) -> bool {
        let np = self.theta.len();
        let n = self.res.len();
        let mut jac = vec![0.0; n * np]; // column-major, once per accepted step
        for p in 0..np {
            let h = 1e-6 * self.theta[p].abs().max(1.0);
            self.probe.copy_from_slice(&self.theta);
            self.probe[p] += h;
            let Some(rp) = (self.r)(&self.probe) else {
                return false;
            };
            if rp.len() != n {
                return false;
            }
            for (i, (a, b)) in rp.iter().zip(&self.res).enumerate() {
                jac[p * n + i] = (a - b) / h;
            }
        }
        for a in 0..np {
            let ca = &jac[a * n..(a + 1) * n];
            jtr[a] = ca.iter().zip(&self.res).map(|(x, y)| x * y).sum();
            for b in a..np {
                let cb = &jac[b * n..(b + 1) * n];
                let v: f64 = ca.iter().zip(cb).map(|(x, y)| x * y).sum();
                jtj[a * np + b] = v;
                jtj[b * np + a] = v;
            }
        }
        jtj.iter().chain(jtr.iter()).all(|v| v.is_finite())
    }
}

/// Minimise `|r(x)|²` from `x0` with at most `max_iter` accepted steps (Marquardt's
/// damping schedule, [`Damping::Marquardt`]); `r` returns `None` where the model is
/// invalid. `None` when the cost is not finite at
/// `x0`.
pub fn minimise(
    x0: &[f64],
    max_iter: usize,
    r: impl FnMut(&[f64]) -> Option<Vec<f64>>,
) -> Option<LmResult> {
    let np = x0.len();
    let mut problem = Residuals::new(r, np);
    let mut ws = LmWorkspace::new(&problem, np);
    let opts = LmOptions {
        ftol: MIN_REL_IMPROVEMENT,
        xtol: 0.0,
        gtol: 0.0,
        max_evals: usize::MAX,
        damping: Damping::Marquardt {
            max_steps: max_iter,
        },
    };
    let out = minimize(&mut problem, x0, &opts, &mut ws).ok()?;
    let n = problem.residuals().len();
    let jtj = DMatrix::from_row_slice(np, np, &ws.jtj);
    let dof = (n as f64 - np as f64).max(1.0);
    let scale = (out.cost / dof).max(1.0);
    let cov = (super::covariance_of_information(&jtj) * scale)
        .as_slice()
        .to_vec();
    Some(LmResult {
        x: ws.theta.clone(),
        cost: out.cost,
        cov,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fits_an_exponential() {
        let t: Vec<f64> = (0..20).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (-1.5 * t).exp()).collect();
        let r = minimise(&[1.0, -0.5], 50, |x| {
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

    /// The covariance against a direct computation: for a linear model `r = A x - y` it
    /// is `(AᵀA)⁻¹ max(1, cost/dof)` exactly.
    #[test]
    fn covariance_of_a_linear_fit_is_the_inverse_normal_matrix() {
        let a: Vec<[f64; 2]> = (0..30).map(|i| [1.0, i as f64 * 0.1]).collect();
        let y: Vec<f64> = (0..30)
            .map(|i| 0.5 + 2.0 * i as f64 * 0.1 + if i % 2 == 0 { 0.3 } else { -0.3 })
            .collect();
        let r = minimise(&[0.0, 0.0], 50, |x| {
            Some(
                a.iter()
                    .zip(&y)
                    .map(|(row, y)| row[0] * x[0] + row[1] * x[1] - y)
                    .collect(),
            )
        })
        .unwrap();
        let ata = DMatrix::from_fn(2, 2, |i, j| a.iter().map(|row| row[i] * row[j]).sum());
        let scale = (r.cost / 28.0).max(1.0);
        let want = ata.try_inverse().unwrap() * scale;
        for k in 0..4 {
            let w = want.as_slice()[k];
            assert!(
                (r.cov[k] - w).abs() <= 1e-5 * w.abs().max(1e-9),
                "{k}: {} vs {w}",
                r.cov[k]
            );
        }
    }
}
