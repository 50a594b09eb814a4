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
//! computed by forward-mode jets (`super::jet`). The poles are then grouped in conjugate
//! (or real) pairs, each pair a real-coefficient second-order section in `w = z - 1`, so
//! that per line and section the Jacobian costs one complex reciprocal and four
//! complex-times-real multiply-adds per parameter.

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
    /// `z - 1` per line, computed without cancellation.
    pub(crate) zm1: Vec<Complex64>,
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

/// Model quantities at one parameter vector. The flexible poles are grouped in pairs
/// (conjugate, or both real) so that each pair is one real-coefficient second-order section
/// `(n1 w + n0) / (w^2 + b1 w + b0)` in `w = z - 1` (no cancellation at low frequency,
/// where `z` and the sampled poles all crowd near 1).
#[derive(Debug, Clone, Default)]
struct ModelState {
    j_total: f64,
    /// `d J_total / d theta_j`.
    dj: Vec<f64>,
    /// `[n1, n0, b1, b0]` per section.
    sec: Vec<[f64; 4]>,
    /// Derivatives of `[n1, n0, b1, b0]` at `[s * P + j]`.
    dsec: Vec<[f64; 4]>,
    /// Flexible poles of the continuous chain at the current parameters (the Newton start
    /// of the next update).
    poles: Vec<Complex64>,
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

/// One pole of the sampled response with its derivatives in every log-parameter.
struct PoleTerm {
    /// `q = e^{p Ts}`.
    q: Complex64,
    /// `q - 1`, without cancellation.
    m: Complex64,
    /// `r a` with `a = (q - 1)/p`.
    ra: Complex64,
    /// `d q / d theta_j`.
    dq: Vec<Complex64>,
    /// `d (r a) / d theta_j`.
    dra: Vec<Complex64>,
}

fn pole_term(chain: &Chain, p: Complex64, ts: f64, np: usize) -> Option<PoleTerm> {
    let base = impedance_jet(chain, p, None);
    let zs = base.0[1];
    let zss = 2.0 * base.0[2];
    let r = 1.0 / (p * zs);
    let q = (p * ts).exp();
    let m = expm1(p * ts);
    let a = m / p;
    // d a / d p = a b
    let b = ts * q / m - 1.0 / p;
    if !(r.is_finite() && a.is_finite() && b.is_finite()) {
        return None;
    }
    let mut t = PoleTerm {
        q,
        m,
        ra: r * a,
        dq: Vec::with_capacity(np),
        dra: Vec::with_capacity(np),
    };
    for j in 0..np {
        let jet = impedance_jet(chain, p, Some(j));
        let dp = -jet.0[3] / zs;
        let df = dp * zs + p * (zss * dp + jet.0[4]);
        let dr = -r * r * df;
        t.dq.push(ts * q * dp);
        t.dra.push(a * dr + r * a * b * dp);
    }
    Some(t)
}

/// `e^x - 1` for complex `x` without cancellation for small `|x|`.
pub(crate) fn expm1(x: Complex64) -> Complex64 {
    let half = (0.5 * x.im).sin();
    Complex64::new(
        x.re.exp_m1() * x.im.cos() - 2.0 * half * half,
        x.re.exp() * x.im.sin(),
    )
}

fn conj_term(t: &PoleTerm) -> PoleTerm {
    PoleTerm {
        q: t.q.conj(),
        m: t.m.conj(),
        ra: t.ra.conj(),
        dq: t.dq.iter().map(|v| v.conj()).collect(),
        dra: t.dra.iter().map(|v| v.conj()).collect(),
    }
}

/// Polish `poles` (the flexible poles of nearby parameters) into the flexible poles of
/// `chain` by Newton's method on the ladder impedance, in place. `true` only when every
/// pole converged and the result is a complete set: `2(n-1)` distinct, non-zero poles
/// (the impedance has exactly that many flexible zeros, so distinct converged roots are
/// all of them). Otherwise the caller computes them from scratch.
fn newton_poles(chain: &Chain, poles: &mut [Complex64]) -> bool {
    if poles.len() != 2 * (chain.masses() - 1) {
        return false;
    }
    let mut scale: f64 = 0.0;
    for p in poles.iter_mut() {
        let mut done = false;
        for _ in 0..12 {
            let (z, dz) = chain.impedance_and_derivative(*p);
            let step = z / dz;
            if !(step.re.is_finite() && step.im.is_finite()) {
                return false;
            }
            *p -= step;
            if step.norm() <= 1e-14 * p.norm() {
                done = true;
                break;
            }
        }
        if !done {
            return false;
        }
        scale = scale.max(p.norm());
    }
    for (i, p) in poles.iter().enumerate() {
        if !(p.norm() > 1e-6 * scale) {
            return false;
        }
        if poles[..i].iter().any(|q| (p - q).norm() <= 1e-6 * p.norm()) {
            return false;
        }
    }
    true
}

/// Group poles into conjugate pairs and pairs of real poles.
fn pair_poles(poles: &[Complex64]) -> Option<Vec<(Complex64, Option<Complex64>)>> {
    let tiny = |p: &Complex64| p.im.abs() <= 1e-12 * p.norm();
    let mut out = Vec::new();
    let mut real: Vec<Complex64> = Vec::new();
    for p in poles {
        if tiny(p) {
            real.push(Complex64::new(p.re, 0.0));
        } else if p.im > 0.0 {
            out.push((*p, None));
        }
    }
    let upper = out.len();
    let lower = poles.iter().filter(|p| !tiny(p) && p.im < 0.0).count();
    if upper != lower || real.len() % 2 != 0 {
        return None;
    }
    for c in real.chunks(2) {
        out.push((c[0], Some(c[1])));
    }
    Some(out)
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
        st.sec.clear();
        st.dsec.clear();
        if self.theta.iter().any(|t| !t.is_finite() || t.abs() > 700.0) {
            return;
        }
        let chain = chain_of_theta(self.theta.as_slice(), n);
        st.j_total = chain.total_inertia();
        st.dj.clear();
        st.dj
            .extend((0..np).map(|j| if j < n { chain.inertia_kgm2[j] } else { 0.0 }));
        if n > 1 {
            // the poles of the previous parameters, polished by Newton, when they are still
            // the complete set; the eigenvalues of the chain otherwise
            if !newton_poles(&chain, &mut st.poles) {
                let Ok(sc) = SampledChain::new(&chain, d.fs_hz, 0) else {
                    st.poles.clear();
                    return;
                };
                st.poles.clear();
                st.poles.extend_from_slice(sc.poles());
            }
            let Some(groups) = pair_poles(&st.poles) else {
                return;
            };
            for (p1, p2) in groups {
                let Some(t1) = pole_term(&chain, p1, d.ts, np) else {
                    return;
                };
                let t2 = match p2 {
                    None => conj_term(&t1),
                    Some(p2) => match pole_term(&chain, p2, d.ts, np) {
                        Some(t) => t,
                        None => return,
                    },
                };
                // (ra1 (w - m2) + ra2 (w - m1)) / ((w - m1)(w - m2)), w = z - 1, m = q - 1
                st.sec.push([
                    (t1.ra + t2.ra).re,
                    -(t1.ra * t2.m + t2.ra * t1.m).re,
                    -(t1.m + t2.m).re,
                    (t1.m * t2.m).re,
                ]);
                for j in 0..np {
                    st.dsec.push([
                        (t1.dra[j] + t2.dra[j]).re,
                        -(t1.dra[j] * t2.m
                            + t1.ra * t2.dq[j]
                            + t2.dra[j] * t1.m
                            + t2.ra * t1.dq[j])
                            .re,
                        -(t1.dq[j] + t2.dq[j]).re,
                        (t1.dq[j] * t2.m + t1.m * t2.dq[j]).re,
                    ]);
                }
            }
            if 2 * st.sec.len() != st.poles.len() {
                return;
            }
        }
        st.ok = true;
    }

    /// Position response `P(z)` on line `i`; fills `e[s] = 1/D_s(z)` and `g[s] = N_s/D_s`.
    #[inline]
    fn position(&self, i: usize, e: &mut [Complex64], g: &mut [Complex64]) -> Complex64 {
        let d = self.data;
        let st = &self.state;
        let w = d.zm1[i];
        let mut p = d.gamma[i] / st.j_total;
        for (s, c) in st.sec.iter().enumerate() {
            let den = w * (w + c[2]) + c[3];
            let es = den.inv();
            let gs = (w * c[0] + c[1]) * es;
            e[s] = es;
            g[s] = gs;
            p += gs;
        }
        p
    }

    /// Complex log-ratio `ln(H_model/H_meas)` per line (unweighted).
    pub(crate) fn log_ratios(&self) -> Option<Vec<Complex64>> {
        if !self.state.ok {
            return None;
        }
        let ns = self.state.sec.len();
        let mut e = vec![Complex64::new(0.0, 0.0); ns];
        let mut g = vec![Complex64::new(0.0, 0.0); ns];
        Some(
            (0..self.data.z.len())
                .map(|i| {
                    let v = self.position(i, &mut e, &mut g) * self.data.k[i];
                    Complex64::new(0.5 * v.norm_sqr().ln(), v.im.atan2(v.re))
                })
                .collect(),
        )
    }
}

/// Scratch of the line passes, sized once per fit ([`ChainProblem::scratch`]): nothing is
/// allocated per evaluation. The cost pass ([`ChainProblem::cost`]) leaves its per-line
/// quantities here, so that the Jacobian pass ([`ChainProblem::normal_after_cost`]) of an
/// accepted step does not compute the response again.
#[derive(Debug, Clone, Default)]
pub(crate) struct LineScratch {
    /// Weighted complex residual per line.
    res: Vec<Complex64>,
    /// Position response `P(z)` per line.
    pz: Vec<Complex64>,
    /// Per line the section terms `[e_0..e_(ns-1), g_0..g_(ns-1)]` of [`ChainProblem::position`].
    eg: Vec<Complex64>,
    /// One block of basis rows (see [`ChainProblem::normal_after_cost`]): per basis
    /// function `BLOCK` real parts, then `BLOCK` imaginary parts.
    basis: Vec<f64>,
    /// The block's residuals, real parts then imaginary parts.
    rblock: Vec<f64>,
    /// Gram matrix of the basis over all lines (`nb x nb`, upper triangle).
    gram: Vec<f64>,
    /// Basis times residual, summed over all lines (`nb`).
    gres: Vec<f64>,
    /// `G M` (`nb x P`).
    gm: Vec<f64>,
}

/// Lines per block of the Jacobian pass.
const BLOCK: usize = 32;

/// Add one block's Gram matrix (upper triangle) and basis-times-residual to `gram` and
/// `gres` (see [`ChainProblem::normal_after_cost`]).
#[inline(always)]
fn gram_block_body(basis: &[f64], rb: &[f64], nb: usize, gram: &mut [f64], gres: &mut [f64]) {
    for a in 0..nb {
        let ba = &basis[a * 2 * BLOCK..(a + 1) * 2 * BLOCK];
        gres[a] += dot4(ba, rb);
        for b in a..nb {
            gram[a * nb + b] += dot4(ba, &basis[b * 2 * BLOCK..(b + 1) * 2 * BLOCK]);
        }
    }
}

/// [`gram_block_body`] compiled for AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn gram_block_avx2(
    basis: &[f64],
    rb: &[f64],
    nb: usize,
    gram: &mut [f64],
    gres: &mut [f64],
) {
    gram_block_body(basis, rb, nb, gram, gres)
}

/// [`gram_block_body`] with AVX2 and FMA where the CPU has them (checked once).
fn gram_block(basis: &[f64], rb: &[f64], nb: usize, gram: &mut [f64], gres: &mut [f64]) {
    #[cfg(target_arch = "x86_64")]
    {
        if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU supports the features the function is compiled for.
            unsafe { gram_block_avx2(basis, rb, nb, gram, gres) };
            return;
        }
    }
    gram_block_body(basis, rb, nb, gram, gres)
}

/// `sum a_i b_i` with four independent partial sums (vectorisable; `a.len()` a multiple of 4).
#[inline(always)]
fn dot4(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 4];
    for (x, y) in a.chunks_exact(4).zip(b.chunks_exact(4)) {
        for k in 0..4 {
            acc[k] += x[k] * y[k];
        }
    }
    (acc[0] + acc[2]) + (acc[1] + acc[3])
}

impl FitData {
    /// Every `stride`-th line (from the first): the coarse problem of the multi-start fit.
    pub(crate) fn decimated(&self, stride: usize) -> FitData {
        let stride = stride.max(1);
        let pick = |v: &Vec<Complex64>| v.iter().step_by(stride).copied().collect();
        FitData {
            fs_hz: self.fs_hz,
            ts: self.ts,
            masses: self.masses,
            z: pick(&self.z),
            zm1: pick(&self.zm1),
            k: pick(&self.k),
            gamma: pick(&self.gamma),
            w: self.w.iter().step_by(stride).copied().collect(),
        }
    }
}

impl<'a> ChainProblem<'a> {
    /// A problem on `data` with no parameters set yet (invalid until [`Self::set_theta`]).
    pub(crate) fn unset(data: &'a FitData) -> Self {
        ChainProblem {
            data,
            theta: DVector::zeros(0),
            state: ModelState::default(),
        }
    }

    /// Scratch buffers for [`Self::cost`] and [`Self::normal_equations`].
    pub(crate) fn scratch(&self) -> LineScratch {
        let np = self.data.params();
        let ns = self.data.masses.saturating_sub(1);
        let nb = 1 + 4 * ns;
        let lines = self.data.z.len();
        let zero = Complex64::new(0.0, 0.0);
        LineScratch {
            res: vec![zero; lines],
            pz: vec![zero; lines],
            eg: vec![zero; 2 * ns.max(1) * lines],
            basis: vec![0.0; 2 * BLOCK * nb],
            rblock: vec![0.0; 2 * BLOCK],
            gram: vec![0.0; nb * nb],
            gres: vec![0.0; nb],
            gm: vec![0.0; nb * np],
        }
    }

    /// Move to the log-parameters `theta` (same length as before), without allocating the
    /// parameter vector.
    pub(crate) fn set_theta(&mut self, theta: &[f64]) {
        if self.theta.len() == theta.len() {
            self.theta.as_mut_slice().copy_from_slice(theta);
        } else {
            self.theta = DVector::from_column_slice(theta);
        }
        self.update();
    }

    /// The cost `sum r^2` at the current parameters: the response and the weighted
    /// residual of every line, kept in `s` for [`Self::normal_after_cost`]. `None` where
    /// the model is invalid or the cost is not finite.
    pub(crate) fn cost(&self, s: &mut LineScratch) -> Option<f64> {
        if !self.state.ok {
            return None;
        }
        let d = self.data;
        let ns = self.state.sec.len();
        let mut cost = 0.0;
        for (i, ((res, pz), eg)) in s
            .res
            .iter_mut()
            .zip(s.pz.iter_mut())
            .zip(s.eg.chunks_exact_mut(2 * ns.max(1)))
            .enumerate()
        {
            let (e, g) = eg.split_at_mut(ns);
            let p = self.position(i, e, g);
            let v = p * d.k[i];
            let w = d.w[i];
            let r = Complex64::new(w * 0.5 * v.norm_sqr().ln(), w * v.im.atan2(v.re));
            cost += r.norm_sqr();
            *res = r;
            *pz = p;
        }
        cost.is_finite().then_some(cost)
    }

    /// The normal equations `J^T J` (`jtj`, `P x P` row-major, both triangles) and `J^T r`
    /// (`jtr`) at the current parameters, from the per-line quantities the last
    /// [`Self::cost`] pass at these same parameters left in `s`. `false` where anything is
    /// not finite.
    ///
    /// The `2 lines x P` Jacobian is never formed. Per line, `d ln H / d theta_j` is
    /// `sum_k B_k M_kj`: the `nb = 1 + 4 (n-1)` complex basis functions `B` (the rigid term
    /// `-gamma/J^2` and, per section, `w e`, `e`, `w g e`, `g e`, all times `weight / P`)
    /// combined by the real `nb x P` matrix `M` of the parameter derivatives (`dJ`, and per
    /// section `dn1, dn0, -db1, -db0`), which is the same on every line. So
    /// `J^T J = M^T G M` and `J^T r = M^T (B^T r)` with the basis' Gram matrix `G`, which
    /// is accumulated over blocks of lines by vectorisable dot products.
    pub(crate) fn normal_after_cost(
        &self,
        s: &mut LineScratch,
        jtj: &mut [f64],
        jtr: &mut [f64],
    ) -> bool {
        if !self.state.ok {
            return false;
        }
        let d = self.data;
        let st = &self.state;
        let np = d.params();
        let ns = st.sec.len();
        let nb = 1 + 4 * ns;
        let lines = d.z.len();
        let gram = &mut s.gram[..nb * nb];
        let gres = &mut s.gres[..nb];
        gram.fill(0.0);
        gres.fill(0.0);
        let inv_j2 = 1.0 / (st.j_total * st.j_total);
        let basis = &mut s.basis[..2 * BLOCK * nb];
        let rb = &mut s.rblock[..];
        for start in (0..lines).step_by(BLOCK) {
            let len = BLOCK.min(lines - start);
            if len < BLOCK {
                basis.fill(0.0);
                rb.fill(0.0);
            }
            for l in 0..len {
                let i = start + l;
                let wip = d.w[i] * s.pz[i].inv();
                let z = d.zm1[i];
                let mut put = |k: usize, c: Complex64| {
                    basis[k * 2 * BLOCK + l] = c.re;
                    basis[k * 2 * BLOCK + BLOCK + l] = c.im;
                };
                put(0, -d.gamma[i] * inv_j2 * wip);
                let eg = &s.eg[i * 2 * ns..(i + 1) * 2 * ns];
                for k in 0..ns {
                    let e = eg[k] * wip;
                    let ge = eg[ns + k] * e;
                    put(1 + 4 * k, z * e);
                    put(2 + 4 * k, e);
                    put(3 + 4 * k, z * ge);
                    put(4 + 4 * k, ge);
                }
                let r = s.res[i];
                rb[l] = r.re;
                rb[BLOCK + l] = r.im;
            }
            gram_block(basis, rb, nb, gram, gres);
        }
        for a in 0..nb {
            for b in 0..a {
                gram[a * nb + b] = gram[b * nb + a];
            }
        }
        // M (nb x P): row 0 dJ, then per section dn1, dn0, -db1, -db0
        let m = |k: usize, j: usize| -> f64 {
            if k == 0 {
                st.dj[j]
            } else {
                let (sec, c) = ((k - 1) / 4, (k - 1) % 4);
                let v = st.dsec[sec * np + j][c];
                if c < 2 {
                    v
                } else {
                    -v
                }
            }
        };
        let gm = &mut s.gm[..nb * np];
        for a in 0..nb {
            for j in 0..np {
                gm[a * np + j] = (0..nb).map(|b| gram[a * nb + b] * m(b, j)).sum();
            }
        }
        for i in 0..np {
            jtr[i] = (0..nb).map(|a| m(a, i) * gres[a]).sum();
            for j in i..np {
                let v: f64 = (0..nb).map(|a| m(a, i) * gm[a * np + j]).sum();
                jtj[i * np + j] = v;
                jtj[j * np + i] = v;
            }
        }
        jtr.iter().all(|v| v.is_finite()) && jtj.iter().all(|v| v.is_finite())
    }

    /// The cost `sum r^2` together with the normal equations `J^T J` (`jtj`, `P x P`
    /// row-major, both triangles) and `J^T r` (`jtr`): [`Self::cost`] then
    /// [`Self::normal_after_cost`]. `None` where the model is invalid or anything is not
    /// finite.
    pub(crate) fn normal_equations(
        &self,
        s: &mut LineScratch,
        jtj: &mut [f64],
        jtr: &mut [f64],
    ) -> Option<f64> {
        let cost = self.cost(s)?;
        self.normal_after_cost(s, jtj, jtr).then_some(cost)
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
        let ns = st.sec.len();
        let lines = d.z.len();
        let mut jac = DMatrix::zeros(2 * lines, np);
        let mut e = vec![Complex64::new(0.0, 0.0); ns];
        let mut g = vec![Complex64::new(0.0, 0.0); ns];
        let mut dpd = vec![Complex64::new(0.0, 0.0); np];
        for i in 0..lines {
            let z = d.zm1[i];
            let pz = self.position(i, &mut e, &mut g);
            let inv_p = pz.inv();
            let rigid = -d.gamma[i] / (st.j_total * st.j_total);
            for (j, v) in dpd.iter_mut().enumerate() {
                *v = rigid * st.dj[j];
            }
            for s in 0..ns {
                // d(N/D) = (dn1 w + dn0 - G (db1 w + db0)) / D
                let ze = z * e[s];
                let ge = g[s] * e[s];
                let gze = ge * z;
                let ds = &st.dsec[s * np..(s + 1) * np];
                for (v, c) in dpd.iter_mut().zip(ds) {
                    *v += ze * c[0] + e[s] * c[1] - gze * c[2] - ge * c[3];
                }
            }
            let w = d.w[i];
            for (j, v) in dpd.iter().enumerate() {
                let gj = v * inv_p;
                jac[(2 * i, j)] = w * gj.re;
                jac[(2 * i + 1, j)] = w * gj.im;
            }
        }
        if jac.iter().all(|v| v.is_finite()) {
            Some(jac)
        } else {
            None
        }
    }
}

/// The chain fit as the shared solver sees it ([`crate::lsq::lm`]).
impl crate::lsq::NormalEquations for ChainProblem<'_> {
    type Scratch = LineScratch;

    fn scratch(&self) -> LineScratch {
        ChainProblem::scratch(self)
    }

    fn set_theta(&mut self, theta: &[f64]) {
        ChainProblem::set_theta(self, theta)
    }

    fn cost(&mut self, s: &mut LineScratch) -> Option<f64> {
        ChainProblem::cost(self, s)
    }

    fn normal_after_cost(&mut self, s: &mut LineScratch, jtj: &mut [f64], jtr: &mut [f64]) -> bool {
        ChainProblem::normal_after_cost(self, s, jtj, jtr)
    }

    fn normal_equations(
        &mut self,
        s: &mut LineScratch,
        jtj: &mut [f64],
        jtr: &mut [f64],
    ) -> Option<f64> {
        ChainProblem::normal_equations(self, s, jtj, jtr)
    }
}
