//! The weighted log-complex least-squares problem on the exact sampled chain response, with
//! its analytic Jacobian, as a [`levenberg_marquardt::LeastSquaresProblem`].
//!
//! Model. The sampled position response is the ZOH image of the pole/residue form of the
//! continuous position transfer (see [`crate::model::SampledChain`]):
//! `P(z) = Ts^2 (z+1) / (2 J (z-1)^2) + sum_k r_k a_k / (z - q_k)`, `q_k = e^{p_k Ts}`,
//! `a_k = (q_k - 1)/p_k`. The measured quantity is `G(z) P(z)` with the known factor `G`
//! (backward difference and delay).
//!
//! Jacobian. With `theta` the logs of all parameters, `d ln H / d theta = (dP/d theta)/P`
//! and `dP/d theta` follows from the chain rule through `J`, `p_k` and `r_k`. The pole and
//! residue derivatives come from the implicit-function theorem on the ladder impedance
//! `Z(p_k) = 0`: `dp = -Z_theta / Z_s`, `r = 1/(p Z_s)`,
//! `dr = -r^2 (dp Z_s + p (Z_ss dp + Z_s,theta))`, the partial derivatives of `Z` being
//! computed by forward-mode jets (`super::jet`). Per line and pole this costs one complex
//! division and two complex multiply-adds per parameter.

use super::jet::impedance_jet;
use crate::model::{Chain, SampledChain};
use levenberg_marquardt::LeastSquaresProblem;
use nalgebra::{DMatrix, DVector, Dyn, Owned};
use num_complex::Complex64;

/// The measured lines, prepared once per fit.
#[derive(Debug, Clone)]
pub(crate) struct FitData {
    pub(crate) fs_hz: f64,
    pub(crate) ts: f64,
    /// Number of bodies of the model.
    pub(crate) masses: usize,
    /// `z = e^{j w Ts}` per line.
    pub(crate) z: Vec<Complex64>,
    /// `G(z) / H_meas` per line: the model's ratio to the measurement is `P(z) k`.
    pub(crate) k: Vec<Complex64>,
    /// `Ts^2 (z+1) / (2 (z-1)^2)`: rigid-body position response times `J`.
    pub(crate) gamma: Vec<Complex64>,
    /// `1/sigma` per line (sigma: standard deviation of each of `ln|H|`, `arg H`).
    pub(crate) w: Vec<f64>,
}

impl FitData {
    pub(crate) fn params(&self) -> usize {
        3 * self.masses - 2
    }
}

/// Model quantities at one parameter vector.
#[derive(Debug, Clone, Default)]
struct ModelState {
    j_total: f64,
    /// `d J_total / d theta_j`.
    dj: Vec<f64>,
    /// `r_k a_k` per pole.
    ra: Vec<Complex64>,
    q: Vec<Complex64>,
    a: Vec<Complex64>,
    /// `r_k (Ts q/(q-1) - 1/p)` per pole.
    rb: Vec<Complex64>,
    r: Vec<Complex64>,
    /// `dp_k/dtheta_j` at `[k * P + j]`.
    dp: Vec<Complex64>,
    /// `dr_k/dtheta_j` at `[k * P + j]`.
    dr: Vec<Complex64>,
    ok: bool,
}

/// The problem handed to the Levenberg-Marquardt solver.
pub(crate) struct ChainProblem<'a> {
    data: &'a FitData,
    theta: DVector<f64>,
    state: ModelState,
}

/// Chain from log-parameters `[ln J1..ln Jn, ln c1.., ln d1..]`.
pub(crate) fn chain_of_theta(theta: &[f64], n: usize) -> Chain {
    Chain {
        inertia_kgm2: theta[..n].iter().map(|t| t.exp()).collect(),
        stiffness_nm_per_rad: theta[n..2 * n - 1].iter().map(|t| t.exp()).collect(),
        damping_nms_per_rad: theta[2 * n - 1..].iter().map(|t| t.exp()).collect(),
    }
}

impl<'a> ChainProblem<'a> {
    pub(crate) fn new(data: &'a FitData, theta: DVector<f64>) -> Self {
        let mut p = ChainProblem {
            data,
            theta: DVector::zeros(0),
            state: ModelState::default(),
        };
        p.set_params(&theta);
        p
    }

    fn update(&mut self) {
        let d = self.data;
        let n = d.masses;
        let np = d.params();
        let st = &mut self.state;
        st.ok = false;
        if self.theta.iter().any(|t| !t.is_finite() || t.abs() > 700.0) {
            return;
        }
        let chain = chain_of_theta(self.theta.as_slice(), n);
        st.j_total = chain.total_inertia();
        st.dj = (0..np)
            .map(|j| if j < n { chain.inertia_kgm2[j] } else { 0.0 })
            .collect();
        let poles: Vec<Complex64> = if n > 1 {
            match SampledChain::new(&chain, d.fs_hz, 0) {
                Ok(sc) => sc.poles().to_vec(),
                Err(_) => return,
            }
        } else {
            Vec::new()
        };
        let m = poles.len();
        st.ra.clear();
        st.q.clear();
        st.a.clear();
        st.rb.clear();
        st.r.clear();
        st.dp.clear();
        st.dr.clear();
        for &p in &poles {
            let base = impedance_jet(&chain, p, None);
            let zs = base.0[1];
            let zss = 2.0 * base.0[2];
            let r = 1.0 / (p * zs);
            let q = (p * d.ts).exp();
            let a = (q - 1.0) / p;
            let b = d.ts * q / (q - 1.0) - 1.0 / p;
            if !(r.is_finite() && a.is_finite() && b.is_finite()) {
                return;
            }
            st.r.push(r);
            st.q.push(q);
            st.a.push(a);
            st.ra.push(r * a);
            st.rb.push(r * b);
            for j in 0..np {
                let jet = impedance_jet(&chain, p, Some(j));
                let dp = -jet.0[3] / zs;
                let df = dp * zs + p * (zss * dp + jet.0[4]);
                st.dp.push(dp);
                st.dr.push(-r * r * df);
            }
        }
        debug_assert_eq!(st.dp.len(), m * np);
        st.ok = true;
    }

    /// Position response `P(z)` times `k` on line `i`, and the `1/(z - q_k)` per pole.
    #[inline]
    fn ratio(&self, i: usize, u: &mut [Complex64]) -> Complex64 {
        let d = self.data;
        let st = &self.state;
        let z = d.z[i];
        let mut p = d.gamma[i] / st.j_total;
        for (k, (&ra, &q)) in st.ra.iter().zip(&st.q).enumerate() {
            let uk = 1.0 / (z - q);
            u[k] = uk;
            p += ra * uk;
        }
        p
    }

    /// Complex log-ratio `ln(H_model/H_meas)` per line (unweighted).
    pub(crate) fn log_ratios(&self) -> Option<Vec<Complex64>> {
        if !self.state.ok {
            return None;
        }
        let mut u = vec![Complex64::new(0.0, 0.0); self.state.q.len()];
        Some(
            (0..self.data.z.len())
                .map(|i| (self.ratio(i, &mut u) * self.data.k[i]).ln())
                .collect(),
        )
    }
}

impl LeastSquaresProblem<f64, Dyn, Dyn> for ChainProblem<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, Dyn>;
    type ParameterStorage = Owned<f64, Dyn>;

    fn set_params(&mut self, x: &DVector<f64>) {
        self.theta.clone_from(x);
        self.update();
    }

    fn params(&self) -> DVector<f64> {
        self.theta.clone()
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let l = self.log_ratios()?;
        let mut r = DVector::zeros(2 * l.len());
        for (i, li) in l.iter().enumerate() {
            let w = self.data.w[i];
            r[2 * i] = w * li.re;
            r[2 * i + 1] = w * li.im;
        }
        if r.iter().all(|v| v.is_finite()) {
            Some(r)
        } else {
            None
        }
    }

    fn jacobian(&self) -> Option<DMatrix<f64>> {
        if !self.state.ok {
            return None;
        }
        let d = self.data;
        let st = &self.state;
        let np = d.params();
        let m = st.q.len();
        let lines = d.z.len();
        let mut jac = DMatrix::zeros(2 * lines, np);
        let mut u = vec![Complex64::new(0.0, 0.0); m];
        let mut phi = vec![Complex64::new(0.0, 0.0); m];
        let mut psi = vec![Complex64::new(0.0, 0.0); m];
        let mut dpd = vec![Complex64::new(0.0, 0.0); np];
        let ts = d.ts;
        for i in 0..lines {
            let pz = self.ratio(i, &mut u);
            let inv_p = 1.0 / pz;
            for k in 0..m {
                // phi = dg/dr, psi = dg/dp
                phi[k] = st.a[k] * u[k];
                psi[k] = phi[k] * (st.rb[k] + st.r[k] * ts * st.q[k] * u[k]);
            }
            let rigid = -d.gamma[i] / (st.j_total * st.j_total);
            for (j, v) in dpd.iter_mut().enumerate() {
                *v = rigid * st.dj[j];
            }
            for k in 0..m {
                let (f, s) = (phi[k], psi[k]);
                let dr = &st.dr[k * np..(k + 1) * np];
                let dp = &st.dp[k * np..(k + 1) * np];
                for j in 0..np {
                    dpd[j] += f * dr[j] + s * dp[j];
                }
            }
            let w = d.w[i];
            for (j, v) in dpd.iter().enumerate() {
                let g = v * inv_p;
                jac[(2 * i, j)] = w * g.re;
                jac[(2 * i + 1, j)] = w * g.im;
            }
        }
        if jac.iter().all(|v| v.is_finite()) {
            Some(jac)
        } else {
            None
        }
    }
}
