//! How far each coupling deflects under a tone excitation (a swept or stepped sine).
//!
//! An amplitude-dependent spring's start comes from its describing function, fed with the
//! coupling's deflection at each level ([`super::search::fit_spring`]). Under a multisine
//! the deflection is Gaussian-like and its RMS over the record is what the spring feels.
//! A sine plays one frequency at a time: passing the resonance the coupling deflects by its
//! quality factor times more than elsewhere, and that peak is where the spring's
//! nonlinearity shows in the FRF; the RMS over the whole record, dominated by the long low
//! part of a logarithmic sweep, is tens of times smaller (a world sweep: the describing
//! function's start 8x off the spring's true `x_ref`, out of the search's reach).
//!
//! The deflection of coupling `k` per unit torque on the motor is that of the chain's
//! receptance, `(K + jω C - ω² M)⁻¹ e₀`, a tridiagonal solve per line (the viscous friction
//! to the ground on the motor and a restoring stiffness on the last body included). The
//! tone's amplitude is `sqrt(2)` times the command's RMS (a constant-amplitude sine).

use super::lti::LinExt;
use crate::excitation::ExcitationKind;
use crate::recording::Recording;
use crate::Complex64;

/// The torque amplitude [N m] of a tone excitation (`sqrt(2)` RMS of the command), or
/// `None` when the recording's excitation is not one sine at a time.
pub fn tone_amplitude_nm(rec: &Recording) -> Option<f64> {
    let kind = rec.sidecar.excitation.as_ref()?.kind;
    if !matches!(kind, ExcitationKind::Chirp | ExcitationKind::SteppedSine) {
        return None;
    }
    let u = &rec.torque_cmd_nm;
    let rms = (u.iter().map(|v| v * v).sum::<f64>() / u.len().max(1) as f64).sqrt();
    (rms > 0.0).then_some(std::f64::consts::SQRT_2 * rms)
}

/// The deflections `x_k - x_{k+1}` [rad per N m] of every coupling at `f_hz` under a unit
/// torque on the motor (body 0), by the Thomas algorithm on the tridiagonal dynamic
/// stiffness. Empty for a single body.
pub fn deflections_per_nm(lin: &LinExt, f_hz: f64) -> Vec<Complex64> {
    let ch = &lin.chain;
    let n = ch.masses();
    if n < 2 {
        return Vec::new();
    }
    let w = 2.0 * std::f64::consts::PI * f_hz;
    let jw = Complex64::new(0.0, w);
    let spring = |k: usize| ch.stiffness_nm_per_rad[k] + jw * ch.damping_nms_per_rad[k];
    // diagonal, and the coupling terms (-spring) off it
    let mut diag: Vec<Complex64> = (0..n)
        .map(|i| {
            let mut d = Complex64::from(-w * w * ch.inertia_kgm2[i]);
            if i > 0 {
                d += spring(i - 1);
            }
            if i + 1 < n {
                d += spring(i);
            }
            d
        })
        .collect();
    diag[0] += jw * lin.motor_b;
    diag[n - 1] += lin.ground_k + jw * lin.ground_b;
    let mut rhs = vec![Complex64::from(0.0); n];
    rhs[0] = 1.0.into();
    // forward elimination: row i+1 -= (off / diag_i) row i, off = -spring(i)
    for i in 0..n - 1 {
        let off = -spring(i);
        let m = off / diag[i];
        diag[i + 1] -= m * off;
        let r = rhs[i];
        rhs[i + 1] -= m * r;
    }
    let mut x = vec![Complex64::from(0.0); n];
    x[n - 1] = rhs[n - 1] / diag[n - 1];
    for i in (0..n - 1).rev() {
        x[i] = (rhs[i] + spring(i) * x[i + 1]) / diag[i];
    }
    (0..n - 1).map(|k| x[k] - x[k + 1]).collect()
}

/// The largest deflection amplitude [rad] of each coupling over the lines `f_hz` under a
/// tone of amplitude `tone_nm`: the peak the coupling reaches as the sine passes its
/// resonance.
pub fn peak_deflections(lin: &LinExt, f_hz: &[f64], tone_nm: f64) -> Vec<f64> {
    let mut peak = vec![0.0; lin.chain.masses().saturating_sub(1)];
    for &f in f_hz {
        for (p, d) in peak.iter_mut().zip(deflections_per_nm(lin, f)) {
            *p = f64::max(*p, d.norm() * tone_nm);
        }
    }
    peak
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Chain;
    use nalgebra::{DMatrix, DVector};

    /// The tridiagonal solve against a dense complex solve of the same dynamic stiffness
    /// (an independent computation), on a 4-body chain with friction and a ground spring.
    #[test]
    fn the_deflections_are_those_of_the_dense_solve() {
        let chain = Chain::new(
            vec![1e-3, 4e-3, 2e-3, 5e-3],
            vec![300.0, 80.0, 40.0],
            vec![0.02, 0.01, 0.005],
        )
        .unwrap();
        let mut lin = LinExt::nominal(chain.clone());
        lin.motor_b = 0.03;
        lin.ground_k = 7.0;
        for f in [0.5, 12.0, 37.0, 140.0, 900.0] {
            let w = 2.0 * std::f64::consts::PI * f;
            let jw = Complex64::new(0.0, w);
            let n = 4;
            let mut a = DMatrix::<Complex64>::zeros(n, n);
            for i in 0..n {
                a[(i, i)] += -w * w * chain.inertia_kgm2[i];
            }
            for k in 0..n - 1 {
                let s = chain.stiffness_nm_per_rad[k] + jw * chain.damping_nms_per_rad[k];
                a[(k, k)] += s;
                a[(k + 1, k + 1)] += s;
                a[(k, k + 1)] -= s;
                a[(k + 1, k)] -= s;
            }
            a[(0, 0)] += jw * 0.03;
            a[(n - 1, n - 1)] += Complex64::from(7.0);
            let mut b = DVector::<Complex64>::zeros(n);
            b[0] = 1.0.into();
            let x = a.lu().solve(&b).unwrap();
            let d = deflections_per_nm(&lin, f);
            for k in 0..n - 1 {
                let want = x[k] - x[k + 1];
                assert!(
                    (d[k] - want).norm() <= 1e-12 * want.norm(),
                    "{f} Hz coupling {k}: {} vs {want}",
                    d[k]
                );
            }
        }
    }

    /// A two-body chain's coupling deflects most at its resonance, by about the quality
    /// factor times its quasi-static deflection `J2 / (J1 + J2) / c` per N m.
    #[test]
    fn the_peak_is_at_the_resonance() {
        let (j1, j2, c, d) = (1e-3, 4e-3, 200.0, 0.01);
        let lin = LinExt::nominal(Chain::new(vec![j1, j2], vec![c], vec![d]).unwrap());
        let fr = (c * (1.0 / j1 + 1.0 / j2)).sqrt() / (2.0 * std::f64::consts::PI);
        let lines: Vec<f64> = (1..4000).map(|i| i as f64 * 0.05).collect();
        let peak = peak_deflections(&lin, &lines, 2.0)[0];
        let wr = 2.0 * std::f64::consts::PI * fr;
        // the resonance of the relative motion: m_eff = J1 J2 / (J1 + J2), Q = m_eff wr / d
        let m_eff = j1 * j2 / (j1 + j2);
        let q = m_eff * wr / d;
        let quasi_static = j2 / (j1 + j2) / c;
        let want = 2.0 * q * quasi_static;
        assert!((peak / want - 1.0).abs() < 0.02, "{peak} vs {want}");
    }
}
