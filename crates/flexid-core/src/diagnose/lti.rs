//! The nominal chain and its linear extensions on the exact sampled footing, as one
//! continuous state space discretised under zero-order hold with an exact fractional delay:
//! ground stiffness on the last body (gravity), ground damping on the motor (viscous
//! friction), a current loop (order 1 or 2) between command and torque, a pure delay.
//!
//! Independent of [`crate::model::SampledChain`] (which it reproduces for the plain chain):
//! `x[k+1] = Ad x[k] + G1 u[k-m] + G0 u[k-m-1]`, `G1 = int_0^(T-δ) e^(Aσ) dσ B`,
//! `G0 = e^(A(T-δ)) int_0^δ e^(Aσ) dσ B`, with the delay `m T + δ`.

use crate::frf::FrfKind;
use crate::model::Chain;
use nalgebra::{DMatrix, DVector};
use num_complex::Complex64;

/// Current loop between the command and the motor torque.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loop {
    /// 1: `1/(1+s/wc)`; 2: `wc²/(s²+2ζ wc s+wc²)`.
    pub order: u8,
    /// Corner / natural frequency [Hz].
    pub bandwidth_hz: f64,
    /// Damping ratio (order 2).
    pub zeta: f64,
}

/// The chain with its linear extensions (all off = the nominal model).
#[derive(Debug, Clone, PartialEq)]
pub struct LinExt {
    pub chain: Chain,
    /// Restoring stiffness from the last body to the ground [N m/rad] (gravity, small angles).
    pub ground_k: f64,
    /// Viscous damping from the motor to the ground [N m s/rad].
    pub motor_b: f64,
    /// Viscous damping from the last body to the ground [N m s/rad]: the bearing of a load
    /// that swings under `ground_k` (gravity's own damper: a pendulum is damped at its
    /// pivot, on the load side of the gear, not at the motor).
    pub ground_b: f64,
    pub current_loop: Option<Loop>,
    /// Delay [s] beyond the recording's whole-sample `io_delay`.
    pub delay_s: f64,
    /// The nominal model has a spring from the last body to the ground (`ground_k`, the
    /// user's `--ground-spring`: a Duffing oscillator's linear spring, a structure on its
    /// suspension): `ground_k` is then a parameter of the nominal model, fitted with the
    /// chain by every fit ([`super::effects::theta`]), and not an effect (`gravity` is not
    /// a candidate).
    pub ground_spring: bool,
}

impl LinExt {
    pub fn nominal(chain: Chain) -> Self {
        LinExt {
            chain,
            ground_k: 0.0,
            motor_b: 0.0,
            ground_b: 0.0,
            current_loop: None,
            delay_s: 0.0,
            ground_spring: false,
        }
    }

    /// Continuous `(A, B)`; `B` has one column per input: the command, then (with
    /// `extra_inputs`) a torque on the motor and a torque pair `(+1, -1)` on the bodies of
    /// coupling `coupling` (used by the time-domain simulation).
    pub fn continuous(&self, coupling: Option<usize>) -> (DMatrix<f64>, DMatrix<f64>) {
        let ch = &self.chain;
        let n = ch.masses();
        let lo = match self.current_loop {
            None => 0,
            Some(l) => l.order.clamp(1, 2) as usize,
        };
        let ns = 2 * n + lo;
        let ni = if coupling.is_some() { 3 } else { 1 };
        let mut a = DMatrix::zeros(ns, ns);
        let mut b = DMatrix::zeros(ns, ni);
        let j = &ch.inertia_kgm2;
        for i in 0..n {
            a[(i, n + i)] = 1.0;
        }
        for i in 0..n - 1 {
            let (c, d) = (ch.stiffness_nm_per_rad[i], ch.damping_nms_per_rad[i]);
            for (row, s) in [(i, 1.0), (i + 1, -1.0)] {
                a[(n + row, i)] -= s * c / j[row];
                a[(n + row, i + 1)] += s * c / j[row];
                a[(n + row, n + i)] -= s * d / j[row];
                a[(n + row, n + i + 1)] += s * d / j[row];
            }
        }
        a[(2 * n - 1, n - 1)] -= self.ground_k / j[n - 1];
        a[(2 * n - 1, 2 * n - 1)] -= self.ground_b / j[n - 1];
        a[(n, n)] -= self.motor_b / j[0];
        match self.current_loop {
            None => b[(n, 0)] = 1.0 / j[0],
            Some(l) => {
                let wc = 2.0 * std::f64::consts::PI * l.bandwidth_hz;
                let t = 2 * n;
                a[(n, t)] = 1.0 / j[0];
                if lo == 1 {
                    a[(t, t)] = -wc;
                    b[(t, 0)] = wc;
                } else {
                    a[(t, t + 1)] = 1.0;
                    a[(t + 1, t)] = -wc * wc;
                    a[(t + 1, t + 1)] = -2.0 * l.zeta * wc;
                    b[(t + 1, 0)] = wc * wc;
                }
            }
        }
        if let Some(k) = coupling {
            b[(n, 1)] = 1.0 / j[0];
            b[(n + k, 2)] = 1.0 / j[k];
            b[(n + k + 1, 2)] = -1.0 / j[k + 1];
        }
        (a, b)
    }
}

/// Largest entry of `A t` [1] [`zoh`] discretises: `e^(1e12)` is far past any mode a
/// sampled axis can have (a rate of 1e12 per sample), and well inside what the matrix
/// exponential handles.
pub const ZOH_MAX_NORM: f64 = 1e12;

/// `(e^(A t), int_0^t e^(Aσ) dσ B)`.
///
/// A model no physical axis has (an entry of `A t` beyond [`ZOH_MAX_NORM`], or not finite:
/// a trial step of a fit far outside the plausible) gives NaN matrices at once, which the
/// fits reject: nalgebra's scaling-and-squaring exponential does not return for such
/// matrices (a held-out diagnosis case hung in it for minutes).
pub fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, t: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (ns, ni) = (a.nrows(), b.ncols());
    let mut aug = DMatrix::<f64>::zeros(ns + ni, ns + ni);
    aug.view_mut((0, 0), (ns, ns)).copy_from(&(a * t));
    aug.view_mut((0, ns), (ns, ni)).copy_from(&(b * t));
    let norm = aug.amax();
    if !(norm.is_finite() && norm <= ZOH_MAX_NORM) {
        return (
            DMatrix::from_element(ns, ns, f64::NAN),
            DMatrix::from_element(ns, ni, f64::NAN),
        );
    }
    let e = aug.exp();
    (
        e.view((0, 0), (ns, ns)).into_owned(),
        e.view((0, ns), (ns, ni)).into_owned(),
    )
}

/// The discretised model, ready to give its FRF on any line.
///
/// `Ad` is reduced once to upper Hessenberg form `Ad = Q H Qᵀ` (orthogonal `Q`), so that
/// every line solves `(z I - H) y = Qᵀ (g1 + g0/z)` in `O(ns²)` (one sub-diagonal to
/// eliminate) instead of a dense `O(ns³)` elimination; the response is a row of `Q` times `y`.
#[derive(Debug, Clone)]
pub struct Discrete {
    /// `Ad`, `g1`, `g0` as discretised (kept for the dense reference of the tests).
    #[cfg(test)]
    ad: DMatrix<f64>,
    #[cfg(test)]
    g1: DVector<f64>,
    #[cfg(test)]
    g0: DVector<f64>,
    /// `H` row-major.
    h: Vec<f64>,
    /// `Qᵀ g1`, `Qᵀ g0`.
    qg1: Vec<f64>,
    qg0: Vec<f64>,
    /// Rows of `Q` giving the motor position and the motor velocity.
    q_pos: Vec<f64>,
    q_vel: Vec<f64>,
    whole: i32,
    /// Bodies of the chain (the motor velocity is state `n`).
    #[cfg(test)]
    n: usize,
    ts: f64,
    /// A band-limited input ([`Discrete::band_limited`]): the continuous `(A, B)`, the
    /// motor's state index and the whole delay [s].
    continuous: Option<Continuous>,
}

/// The continuous model behind [`Discrete::band_limited`].
#[derive(Debug, Clone)]
struct Continuous {
    a: DMatrix<f64>,
    b: DVector<f64>,
    n: usize,
    delay_s: f64,
}

impl Discrete {
    /// `io_delay_samples`: the recording's whole-sample delay, added to `m.delay_s`.
    pub fn new(m: &LinExt, fs: f64, io_delay_samples: u32) -> Self {
        let ts = 1.0 / fs;
        let (a, b) = m.continuous(None);
        let total = m.delay_s.max(0.0) + io_delay_samples as f64 * ts;
        let mut whole = (total / ts).floor();
        let mut delta = total - whole * ts;
        if delta > ts * (1.0 - 1e-12) {
            whole += 1.0;
            delta = 0.0;
        }
        let (ad, phi_all) = zoh(&a, &b, ts);
        let (g1, g0) = if delta <= 1e-15 * ts {
            (phi_all.column(0).into_owned(), DVector::zeros(a.nrows()))
        } else {
            let (e1, phi1) = zoh(&a, &b, ts - delta);
            let (_, phid) = zoh(&a, &b, delta);
            (
                phi1.column(0).into_owned(),
                (e1 * phid).column(0).into_owned(),
            )
        };
        let ns = ad.nrows();
        let n = m.chain.masses();
        let (q, h) = nalgebra::linalg::Hessenberg::new(ad.clone()).unpack();
        let (qg1, qg0) = (q.tr_mul(&g1), q.tr_mul(&g0));
        Discrete {
            h: (0..ns * ns).map(|i| h[(i / ns, i % ns)]).collect(),
            qg1: qg1.as_slice().to_vec(),
            qg0: qg0.as_slice().to_vec(),
            q_pos: (0..ns).map(|c| q[(0, c)]).collect(),
            q_vel: (0..ns).map(|c| q[(n, c)]).collect(),
            #[cfg(test)]
            ad,
            #[cfg(test)]
            g1,
            #[cfg(test)]
            g0,
            whole: whole as i32,
            #[cfg(test)]
            n,
            ts,
            continuous: None,
        }
    }

    /// The model of a measurement whose input is band-limited between the samples (an
    /// analogue excitation sampled like the output, [`crate::excitation::ExcitationInfo::band_limited`]):
    /// the continuous system's response at the line's frequency, `x = (jωI - A)⁻¹ B
    /// e^{-jωτ}`, the output measured as the sampled output is (a differenced position:
    /// times `(1 - e^{-jωT})/T`). Exact for band-limited signals: their samples' DFT is the
    /// continuous spectrum's.
    pub fn band_limited(m: &LinExt, fs: f64, io_delay_samples: u32) -> Self {
        let mut d = Self::new(m, fs, io_delay_samples);
        let (a, b) = m.continuous(None);
        d.continuous = Some(Continuous {
            b: b.column(0).into_owned(),
            a,
            n: m.chain.masses(),
            delay_s: m.delay_s.max(0.0) + io_delay_samples as f64 / fs,
        });
        d
    }

    /// [`Discrete::new`] or [`Discrete::band_limited`].
    pub fn with_input(m: &LinExt, fs: f64, io_delay_samples: u32, band_limited: bool) -> Self {
        if band_limited {
            Self::band_limited(m, fs, io_delay_samples)
        } else {
            Self::new(m, fs, io_delay_samples)
        }
    }

    /// The continuous response of [`Discrete::band_limited`] at `f_hz` (`None` for a held
    /// input), or NaN when `jωI - A` is singular.
    fn continuous_frf(&self, f_hz: f64, kind: FrfKind) -> Option<Complex64> {
        let c = self.continuous.as_ref()?;
        let w = 2.0 * std::f64::consts::PI * f_hz;
        let ns = c.a.nrows();
        let m = DMatrix::from_fn(ns, ns, |r, k| {
            let v = Complex64::new(-c.a[(r, k)], 0.0);
            if r == k {
                v + Complex64::new(0.0, w)
            } else {
                v
            }
        });
        let rhs = DVector::from_fn(ns, |r, _| Complex64::new(c.b[r], 0.0));
        let nan = Complex64::new(f64::NAN, f64::NAN);
        let Some(x) = m.lu().solve(&rhs) else {
            return Some(nan);
        };
        let late = Complex64::from_polar(1.0, -w * c.delay_s);
        let zi = Complex64::from_polar(1.0, -w * self.ts);
        let (pos, vel) = (x[0] * late, x[c.n] * late);
        Some(match kind {
            FrfKind::Position => pos,
            FrfKind::Velocity => vel,
            _ => pos * (1.0 - zi) / self.ts,
        })
    }

    /// Response at `f_hz` for the FRF kind of the measurement.
    pub fn frf(&self, f_hz: f64, kind: FrfKind) -> Complex64 {
        self.frf_with(f_hz, kind, &mut Vec::new())
    }

    /// [`Discrete::frf`] in the caller's scratch space (resized once, then reused). The
    /// state sizes of the fits (a 2- to 4-mass chain, with a current loop of order 1 or 2)
    /// are solved on the stack with the size known at compile time ([`Discrete::solve_fixed`],
    /// the same operations in the same order as [`Discrete::solve_rows`], so the same result
    /// to the bit); other sizes in `scratch`.
    fn frf_with(&self, f_hz: f64, kind: FrfKind, scratch: &mut Vec<Complex64>) -> Complex64 {
        if let Some(h) = self.continuous_frf(f_hz, kind) {
            return h;
        }
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * self.ts);
        let zi = 1.0 / z;
        let (pos, vel) = self
            .solve_sized(z, zi)
            .unwrap_or_else(|| self.solve_rows(z, zi, scratch));
        self.output(pos, vel, zi, kind)
    }

    /// [`Discrete::solve_fixed`] for the state sizes it is compiled for; `None` otherwise.
    fn solve_sized(&self, z: Complex64, zi: Complex64) -> Option<(Complex64, Complex64)> {
        Some(match self.qg1.len() {
            4 => self.solve_fixed::<4>(z, zi),
            5 => self.solve_fixed::<5>(z, zi),
            6 => self.solve_fixed::<6>(z, zi),
            7 => self.solve_fixed::<7>(z, zi),
            8 => self.solve_fixed::<8>(z, zi),
            9 => self.solve_fixed::<9>(z, zi),
            10 => self.solve_fixed::<10>(z, zi),
            _ => return None,
        })
    }

    /// The FRF kind from the motor position and velocity responses (whole-sample delay
    /// applied here).
    fn output(&self, pos: Complex64, vel: Complex64, zi: Complex64, kind: FrfKind) -> Complex64 {
        let d = zi.powi(self.whole);
        match kind {
            FrfKind::Position => pos * d,
            FrfKind::Velocity => vel * d,
            _ => pos * d * (1.0 - zi) / self.ts,
        }
    }

    /// `(z I - H) y = Qᵀ(g1 + g0/z)` for any state size, in `scratch`; the motor position
    /// and velocity rows of `Q y`. The reference of [`Discrete::solve_fixed`].
    fn solve_rows(
        &self,
        z: Complex64,
        zi: Complex64,
        scratch: &mut Vec<Complex64>,
    ) -> (Complex64, Complex64) {
        let ns = self.qg1.len();
        let w = ns + 1;
        if scratch.len() < ns * w {
            scratch.resize(ns * w, Complex64::new(0.0, 0.0));
        }
        let m = &mut scratch[..ns * w];
        // [z I - H | Qᵀ(g1 + g0/z)], upper Hessenberg
        for r in 0..ns {
            for c in r.saturating_sub(1)..ns {
                m[r * w + c] = Complex64::new(-self.h[r * ns + c], 0.0);
            }
            m[r * w + r] += z;
            m[r * w + ns] = self.qg1[r] + self.qg0[r] * zi;
        }
        // elimination of the sub-diagonal, partial pivoting between the two candidate rows
        for col in 0..ns.saturating_sub(1) {
            let (p, q) = (col * w, (col + 1) * w);
            if m[q + col].norm_sqr() > m[p + col].norm_sqr() {
                for c in col..w {
                    m.swap(p + c, q + c);
                }
            }
            let f = m[q + col] / m[p + col];
            if f.norm_sqr() == 0.0 || !f.is_finite() {
                continue;
            }
            for c in col + 1..w {
                let v = m[p + c];
                m[q + c] -= f * v;
            }
        }
        // back substitution into the last column (y), then the output rows of Q
        for r in (0..ns).rev() {
            let mut s = m[r * w + ns];
            for c in r + 1..ns {
                s -= m[r * w + c] * m[c * w + ns];
            }
            m[r * w + ns] = s / m[r * w + r];
        }
        let out = |row: &[f64]| -> Complex64 {
            row.iter().enumerate().map(|(c, q)| m[c * w + ns] * q).sum()
        };
        (out(&self.q_pos), out(&self.q_vel))
    }

    /// [`Discrete::solve_rows`] with `N` states known at compile time: the matrix and the
    /// right-hand side on the stack, loops unrolled. Rows are swapped whole (the entries
    /// left of the pivot column are never read again), every used entry sees the same
    /// operations in the same order.
    #[inline(always)]
    fn solve_fixed<const N: usize>(&self, z: Complex64, zi: Complex64) -> (Complex64, Complex64) {
        let zero = Complex64::new(0.0, 0.0);
        let h: &[f64] = &self.h[..N * N];
        let (qg1, qg0): (&[f64; N], &[f64; N]) = (
            self.qg1[..].try_into().expect("state size"),
            self.qg0[..].try_into().expect("state size"),
        );
        let mut a = [[zero; N]; N];
        let mut y = [zero; N];
        for r in 0..N {
            for c in r.saturating_sub(1)..N {
                a[r][c] = Complex64::new(-h[r * N + c], 0.0);
            }
            a[r][r] += z;
            y[r] = qg1[r] + qg0[r] * zi;
        }
        for col in 0..N - 1 {
            if a[col + 1][col].norm_sqr() > a[col][col].norm_sqr() {
                a.swap(col, col + 1);
                y.swap(col, col + 1);
            }
            let f = a[col + 1][col] / a[col][col];
            if f.norm_sqr() == 0.0 || !f.is_finite() {
                continue;
            }
            let (top, bottom) = a.split_at_mut(col + 1);
            let (p, q) = (&top[col], &mut bottom[0]);
            for c in col + 1..N {
                q[c] -= f * p[c];
            }
            let v = y[col];
            y[col + 1] -= f * v;
        }
        for r in (0..N).rev() {
            let mut s = y[r];
            for c in r + 1..N {
                s -= a[r][c] * y[c];
            }
            y[r] = s / a[r][r];
        }
        let out =
            |row: &[f64]| -> Complex64 { row.iter().enumerate().map(|(c, q)| y[c] * q).sum() };
        (out(&self.q_pos), out(&self.q_vel))
    }

    pub fn frf_lines(&self, f: &[f64], kind: FrfKind) -> Vec<Complex64> {
        let mut scratch = Vec::new();
        f.iter()
            .map(|&f| self.frf_with(f, kind, &mut scratch))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_absurd_model_is_refused_at_once_not_exponentiated() {
        let mut a = DMatrix::<f64>::zeros(4, 4);
        a[(0, 2)] = 1.0;
        a[(2, 0)] = -1e100;
        let b = DMatrix::<f64>::from_element(4, 1, 1.0);
        let t = std::time::Instant::now();
        let (ad, phi) = zoh(&a, &b, 5e-4);
        assert!(ad.iter().all(|v| v.is_nan()) && phi.iter().all(|v| v.is_nan()));
        assert!(t.elapsed().as_secs_f64() < 1.0);
        a[(2, 0)] = f64::INFINITY;
        assert!(zoh(&a, &b, 5e-4).0[(0, 0)].is_nan());
        // a plausible stiff axis still discretises
        a[(2, 0)] = -1e9;
        assert!(zoh(&a, &b, 5e-4).0.iter().all(|v| v.is_finite()));
    }
    use crate::model::SampledChain;

    fn chain3() -> Chain {
        Chain::new(
            vec![3.614e-3, 5.098e-3, 17.188e-3],
            vec![2.906e4, 5.706],
            vec![0.47, 0.018],
        )
        .unwrap()
    }

    /// The naive reference of [`Discrete::frf`]: `(z I - Ad) x = g1 + g0/z` solved densely
    /// (Gaussian elimination with partial pivoting over all rows).
    fn frf_dense(d: &Discrete, f_hz: f64, kind: FrfKind) -> Complex64 {
        let ns = d.ad.nrows();
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * d.ts);
        let zi = 1.0 / z;
        let mut m = nalgebra::DMatrix::<Complex64>::zeros(ns, ns);
        let mut rhs = nalgebra::DVector::<Complex64>::zeros(ns);
        for r in 0..ns {
            for c in 0..ns {
                m[(r, c)] = Complex64::new(-d.ad[(r, c)], 0.0);
            }
            m[(r, r)] += z;
            rhs[r] = d.g1[r] + d.g0[r] * zi;
        }
        let x = m.lu().solve(&rhs).expect("regular");
        let dl = zi.powi(d.whole);
        match kind {
            FrfKind::Position => x[0] * dl,
            FrfKind::Velocity => x[d.n] * dl,
            _ => x[0] * dl * (1.0 - zi) / d.ts,
        }
    }

    /// The Hessenberg solve gives the dense solve's response on every line, for the chain
    /// with each linear extension (loops of order 1 and 2, fractional delay, gravity,
    /// viscous friction) and every FRF kind; to 1e-7 (near the anti-resonances both carry
    /// the round-off of an ill-conditioned solve: 1.5e-9 apart there).
    #[test]
    fn hessenberg_frf_matches_the_dense_solve() {
        let fs = 2000.0;
        let mut models = vec![LinExt::nominal(chain3())];
        let mut m = LinExt::nominal(chain3());
        m.current_loop = Some(Loop {
            order: 1,
            bandwidth_hz: 700.0,
            zeta: 0.7,
        });
        m.delay_s = 0.37 / fs;
        models.push(m.clone());
        m.current_loop = Some(Loop {
            order: 2,
            bandwidth_hz: 900.0,
            zeta: 0.5,
        });
        m.ground_k = 3.0;
        m.motor_b = 0.01;
        models.push(m);
        let lines: Vec<f64> = (0..200)
            .map(|i| 0.3 * (999.0f64 / 0.3).powf(i as f64 / 199.0))
            .collect();
        for (i, m) in models.iter().enumerate() {
            let d = Discrete::new(m, fs, 1);
            for kind in [
                FrfKind::Position,
                FrfKind::Velocity,
                FrfKind::DifferencedVelocity,
            ] {
                for &f in &lines {
                    let (a, b) = (d.frf(f, kind), frf_dense(&d, f, kind));
                    assert!(
                        (a - b).norm() < 1e-7 * b.norm(),
                        "model {i} {kind:?} {f} Hz: {a} vs {b}"
                    );
                }
            }
        }
    }

    /// The fixed-size solve gives the any-size solve's result to the bit, for every state
    /// size it is used for (2-4 masses, no loop, a loop of order 1 and 2).
    #[test]
    fn fixed_size_solve_equals_the_any_size_solve_bit_for_bit() {
        let fs = 2000.0;
        let chains = [
            Chain::new(vec![3.6e-3, 5.1e-3], vec![2.9e4], vec![0.47]).unwrap(),
            chain3(),
            Chain::new(
                vec![3.6e-3, 5.1e-3, 17.2e-3, 9.0e-3],
                vec![2.9e4, 171.0, 40.0],
                vec![0.47, 0.018, 0.01],
            )
            .unwrap(),
        ];
        let mut sizes = Vec::new();
        for ch in chains {
            for order in [0u8, 1, 2] {
                let mut m = LinExt::nominal(ch.clone());
                m.delay_s = 0.3 / fs;
                if order > 0 {
                    m.current_loop = Some(Loop {
                        order,
                        bandwidth_hz: 800.0,
                        zeta: 0.6,
                    });
                }
                let d = Discrete::new(&m, fs, 1);
                sizes.push(d.qg1.len());
                let mut scratch = Vec::new();
                for i in 0..300 {
                    let f = 0.2 * (999.0f64 / 0.2).powf(i as f64 / 299.0);
                    let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f / fs);
                    let zi = 1.0 / z;
                    let fixed = d
                        .solve_sized(z, zi)
                        .unwrap_or_else(|| panic!("size {}", d.qg1.len()));
                    let rows = d.solve_rows(z, zi, &mut scratch);
                    assert_eq!(fixed, rows, "{} states, {f} Hz", d.qg1.len());
                }
            }
        }
        sizes.sort();
        assert_eq!(sizes, vec![4, 5, 6, 6, 7, 8, 8, 9, 10]);
    }

    #[test]
    fn diagnose_lti_reproduces_sampled_chain_and_whole_delays() {
        let fs = 2000.0;
        let sc = SampledChain::new(&chain3(), fs, 1).unwrap();
        let mut m = LinExt::nominal(chain3());
        let d = Discrete::new(&m, fs, 1);
        for f in [0.5, 3.0, 5.0, 100.0, 380.0, 590.0, 900.0] {
            let (a, b) = (d.frf(f, FrfKind::DifferencedVelocity), sc.frf(f));
            assert!((a - b).norm() < 1e-7 * b.norm(), "{f}: {a} {b}");
        }
        // a delay of exactly one sample through delay_s equals io_delay 1
        m.delay_s = 1.0 / fs;
        let d2 = Discrete::new(&m, fs, 0);
        for f in [3.0, 590.0] {
            let (a, b) = (d2.frf(f, FrfKind::DifferencedVelocity), sc.frf(f));
            assert!((a - b).norm() < 1e-7 * b.norm(), "{f}: {a} {b}");
        }
    }

    /// A band-limited input: the model is the continuous response at the line (reference:
    /// a mass on a spring and a damper to the ground in closed form, `1/(k - Jω² + jbω)`,
    /// times the backward difference `(1 - e^{-jωT})/T` and a delay `e^{-jωτ}`), unlike
    /// the held footing, which lags by about half a sample.
    #[test]
    fn a_band_limited_input_gives_the_continuous_response() {
        let (j, k, b, fs, tau) = (5.4e-6, 1.02, 2.3e-4, 610.35, 0.3e-3);
        let m = LinExt {
            ground_k: k,
            motor_b: b,
            ground_spring: true,
            delay_s: tau,
            ..LinExt::nominal(Chain::new(vec![j], vec![], vec![]).unwrap())
        };
        let d = Discrete::band_limited(&m, fs, 1);
        let held = Discrete::new(&m, fs, 1);
        for f in [0.1, 10.0, 69.5, 150.0, 199.9] {
            let w = 2.0 * std::f64::consts::PI * f;
            let x = 1.0 / Complex64::new(k - j * w * w, b * w);
            let zi = Complex64::from_polar(1.0, -w / fs);
            let want = x * (1.0 - zi) * fs * Complex64::from_polar(1.0, -w * (tau + 1.0 / fs));
            let got = d.frf(f, FrfKind::DifferencedVelocity);
            assert!(
                (got - want).norm() < 1e-9 * want.norm(),
                "{f}: {got} {want}"
            );
            assert!(
                (d.frf(f, FrfKind::Position)
                    - x * Complex64::from_polar(1.0, -w * (tau + 1.0 / fs)))
                .norm()
                    < 1e-9 * x.norm()
            );
            // the held input's response lags by about half a sample more
            let lag = (held.frf(f, FrfKind::DifferencedVelocity) / got).arg();
            assert!(
                (lag + 0.5 * w / fs).abs() < 0.2 * (0.5 * w / fs) + 1e-6,
                "{f}: {lag}"
            );
        }
    }
}
