//! The exact inverse: the undamped chain whose free resonances and motor-locked
//! anti-resonances are exactly the given ones.
//!
//! The driving-point impedance of an undamped free chain is
//!
//! ```text
//! Z(s) = T/V1 = J s * prod(1 + s^2/w_R,i^2) / prod(1 + s^2/w_AR,i^2)
//! ```
//!
//! (resonances are zeros of Z, anti-resonances are its poles, `J` the total inertia fixes the
//! low-frequency asymptote `J s`). It is also the ladder
//! `Z = J1 s + 1/(s/c1 + 1/(J2 s + 1/(s/c2 + ...)))`, so expanding the rational function in a
//! continued fraction about `s = infinity` (Cauer's first form) yields `J1, c1, J2, c2, ..`
//! one after the other. A chain of springs and masses is thereby fixed by its two spectra
//! and its total inertia; the spectra must interlace (`AR1 < R1 < AR2 < R2 < ..`) for every
//! inertia and stiffness to come out positive.

use crate::model::Chain;

/// Errors of the exact inverse.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ExactError {
    #[error("{ar} anti-resonances and {r} resonances given; a chain has one of each per coupling")]
    Count { ar: usize, r: usize },
    #[error("total inertia {j_kgm2} kg m^2 must be positive and finite")]
    TotalInertia { j_kgm2: f64 },
    #[error("the frequencies do not interlace (need AR1 < R1 < AR2 < R2 < ...): {detail}")]
    NotInterlaced { detail: String },
    #[error("no physical chain has these spectra: {what} came out as {value}")]
    NotRealizable { what: String, value: f64 },
}

/// Polynomial in `x`, coefficients lowest power first.
type Poly = Vec<f64>;

fn product_of_factors(omega0: f64, freqs_hz: &[f64], gain: f64) -> Poly {
    // prod (1 + x * w0^2 / w_i^2), x = (s / w0)^2
    let mut p: Poly = vec![gain];
    for &f in freqs_hz {
        let w = 2.0 * std::f64::consts::PI * f;
        let a = (omega0 / w).powi(2);
        let mut q = vec![0.0; p.len() + 1];
        for (k, &c) in p.iter().enumerate() {
            q[k] += c;
            q[k + 1] += c * a;
        }
        p = q;
    }
    p
}

/// The chain (n = `ar_hz.len() + 1` bodies, motor first, dampings zero) whose undamped
/// anti-resonances are `ar_hz` and resonances `r_hz` [Hz] and whose total inertia is
/// `total_j` [kg m^2].
pub fn chain_from_spectra(total_j: f64, ar_hz: &[f64], r_hz: &[f64]) -> Result<Chain, ExactError> {
    if ar_hz.len() != r_hz.len() {
        return Err(ExactError::Count {
            ar: ar_hz.len(),
            r: r_hz.len(),
        });
    }
    if !(total_j.is_finite() && total_j > 0.0) {
        return Err(ExactError::TotalInertia { j_kgm2: total_j });
    }
    let mut ar = ar_hz.to_vec();
    let mut r = r_hz.to_vec();
    ar.sort_by(f64::total_cmp);
    r.sort_by(f64::total_cmp);
    for k in 0..ar.len() {
        let next_ar = ar.get(k + 1).copied().unwrap_or(f64::INFINITY);
        if !(ar[k] > 0.0 && ar[k] < r[k] && r[k] < next_ar && r[k].is_finite()) {
            return Err(ExactError::NotInterlaced {
                detail: format!("AR{} = {} Hz, R{} = {} Hz", k + 1, ar[k], k + 1, r[k]),
            });
        }
    }
    let n = ar.len() + 1;
    // scale x so that the coefficients stay near 1
    let omega0 = if ar.is_empty() {
        1.0
    } else {
        let logs: f64 = ar
            .iter()
            .chain(&r)
            .map(|f| (2.0 * std::f64::consts::PI * f).ln())
            .sum();
        (logs / (2 * ar.len()) as f64).exp()
    };
    let mut num = product_of_factors(omega0, &r, total_j); // Z/s = num/den
    let mut den = product_of_factors(omega0, &ar, 1.0);
    let mut inertia = Vec::with_capacity(n);
    let mut stiffness = Vec::with_capacity(n - 1);
    loop {
        let m = num.len() - 1;
        let j = num[m] / den[m];
        if !(j.is_finite() && j > 0.0) {
            return Err(ExactError::NotRealizable {
                what: format!("J{}", inertia.len() + 1),
                value: j,
            });
        }
        inertia.push(j);
        if m == 0 {
            break;
        }
        // remainder impedance s * num'/den with num' = num - j den (degree m-1)
        let rem: Poly = (0..m).map(|k| num[k] - j * den[k]).collect();
        // admittance den/(s rem) = s/c + ..., 1/c = lead(den) / (lead(rem) w0^2)
        let ratio = den[m] / rem[m - 1];
        let c = omega0 * omega0 / ratio;
        if !(c.is_finite() && c > 0.0) {
            return Err(ExactError::NotRealizable {
                what: format!("c{}", stiffness.len() + 1),
                value: c,
            });
        }
        stiffness.push(c);
        // den' = den - ratio * x * rem (degree m-1)
        let mut next_den: Poly = den[..m].to_vec();
        for k in 0..m {
            if k + 1 < m {
                next_den[k + 1] -= ratio * rem[k];
            }
        }
        // the x^m term cancels by construction; the x^(k+1) terms for k = m-1 went with it
        num = rem;
        den = next_den;
    }
    let chain = Chain {
        inertia_kgm2: inertia,
        stiffness_nm_per_rad: stiffness,
        damping_nms_per_rad: vec![0.0; n - 1],
    };
    Ok(polish(chain, total_j, &ar, &r))
}

/// Residual of a chain against the target spectra, in log units: `[ln(AR_i/AR*_i)..,
/// ln(R_i/R*_i).., ln(J/J*)]`.
fn spectral_residual(ch: &Chain, total_j: f64, ar: &[f64], r: &[f64]) -> Vec<f64> {
    let mut out: Vec<f64> = ch
        .antiresonances_hz()
        .iter()
        .zip(ar)
        .chain(ch.resonances_hz().iter().zip(r))
        .map(|(a, b)| (a / b).ln())
        .collect();
    out.push((ch.total_inertia() / total_j).ln());
    out
}

/// A few Gauss-Newton steps in log-parameters on the spectral residual: the polynomial
/// continued fraction loses digits when the spectra span decades; this restores them.
fn polish(chain: Chain, total_j: f64, ar: &[f64], r: &[f64]) -> Chain {
    let n = chain.masses();
    if n < 2 {
        return chain;
    }
    let p = 2 * n - 1;
    let to_theta = |c: &Chain| -> Vec<f64> {
        c.inertia_kgm2
            .iter()
            .chain(&c.stiffness_nm_per_rad)
            .map(|v| v.ln())
            .collect()
    };
    let of_theta = |t: &[f64]| Chain {
        inertia_kgm2: t[..n].iter().map(|v| v.exp()).collect(),
        stiffness_nm_per_rad: t[n..].iter().map(|v| v.exp()).collect(),
        damping_nms_per_rad: vec![0.0; n - 1],
    };
    let mut theta = to_theta(&chain);
    let mut res = spectral_residual(&chain, total_j, ar, r);
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _ in 0..8 {
        if norm(&res) < 1e-13 {
            break;
        }
        let h = 1e-6;
        let mut jac = nalgebra::DMatrix::<f64>::zeros(p, p);
        for k in 0..p {
            let mut tp = theta.clone();
            let mut tm = theta.clone();
            tp[k] += h;
            tm[k] -= h;
            let rp = spectral_residual(&of_theta(&tp), total_j, ar, r);
            let rm = spectral_residual(&of_theta(&tm), total_j, ar, r);
            for i in 0..p {
                jac[(i, k)] = (rp[i] - rm[i]) / (2.0 * h);
            }
        }
        let rhs = nalgebra::DVector::from_vec(res.iter().map(|v| -v).collect());
        let Some(step) = jac.lu().solve(&rhs) else {
            break;
        };
        let cand: Vec<f64> = theta.iter().zip(step.iter()).map(|(t, s)| t + s).collect();
        let cand_res = spectral_residual(&of_theta(&cand), total_j, ar, r);
        if norm(&cand_res) >= norm(&res) {
            break;
        }
        theta = cand;
        res = cand_res;
    }
    of_theta(&theta)
}

/// Give each coupling of an undamped chain the viscous damping of a two-body reducer with
/// damping ratio `zeta` [-]: `d_i = 2 zeta sqrt(c_i J_i J_(i+1) / (J_i + J_(i+1)))` —
/// a starting point for the refinement, not an identification.
pub fn with_coupling_damping(mut chain: Chain, zeta: f64) -> Chain {
    for i in 0..chain.stiffness_nm_per_rad.len() {
        let (ja, jb) = (chain.inertia_kgm2[i], chain.inertia_kgm2[i + 1]);
        let jr = ja * jb / (ja + jb);
        chain.damping_nms_per_rad[i] = 2.0 * zeta * (chain.stiffness_nm_per_rad[i] * jr).sqrt();
    }
    chain
}
