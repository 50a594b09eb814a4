//! Forward-mode derivatives of the ladder impedance at a pole: value, first and second
//! derivative in `s`, and first derivative in one log-parameter together with its mixed
//! derivative in `s` — what the implicit-function theorem needs to differentiate a pole
//! and its residue.

use crate::model::Chain;
use num_complex::Complex64;

/// Truncated bivariate Taylor coefficients `[1, e, e^2, t, t e]` in an `s`-perturbation `e`
/// (to second order) and a parameter perturbation `t` (to first order).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Jet(pub [Complex64; 5]);

impl Jet {
    pub(crate) fn constant(v: f64, dlog: bool) -> Jet {
        let z = Complex64::new(0.0, 0.0);
        let v = Complex64::new(v, 0.0);
        Jet([v, z, z, if dlog { v } else { z }, z])
    }

    pub(crate) fn variable(s: Complex64) -> Jet {
        let z = Complex64::new(0.0, 0.0);
        Jet([s, Complex64::new(1.0, 0.0), z, z, z])
    }

    fn add(self, o: Jet) -> Jet {
        let mut r = self.0;
        for (a, b) in r.iter_mut().zip(o.0) {
            *a += b;
        }
        Jet(r)
    }

    fn mul(self, o: Jet) -> Jet {
        let [a0, a1, a2, a3, a4] = self.0;
        let [b0, b1, b2, b3, b4] = o.0;
        Jet([
            a0 * b0,
            a0 * b1 + a1 * b0,
            a0 * b2 + a1 * b1 + a2 * b0,
            a0 * b3 + a3 * b0,
            a0 * b4 + a1 * b3 + a3 * b1 + a4 * b0,
        ])
    }

    fn inv(self) -> Jet {
        let [a0, a1, a2, a3, a4] = self.0;
        let b0 = 1.0 / a0;
        let b1 = -a1 * b0 * b0;
        let b2 = -(a1 * b1 + a2 * b0) * b0;
        let b3 = -a3 * b0 * b0;
        let b4 = -(a1 * b3 + a3 * b1 + a4 * b0) * b0;
        Jet([b0, b1, b2, b3, b4])
    }
}

/// Ladder impedance `Z(s)` of `chain` as a jet at `s`, differentiated with respect to the
/// log of parameter `param` (index in `[J1..Jn, c1..c(n-1), d1..d(n-1)]`), or to no
/// parameter when `param` is `None`.
pub(crate) fn impedance_jet(chain: &Chain, s: Complex64, param: Option<usize>) -> Jet {
    let n = chain.masses();
    let is = |k: usize| param == Some(k);
    let sj = Jet::variable(s);
    let inv_s = sj.inv();
    let jn = Jet::constant(chain.inertia_kgm2[n - 1], is(n - 1));
    let mut z = jn.mul(sj);
    for i in (0..n - 1).rev() {
        let c = Jet::constant(chain.stiffness_nm_per_rad[i], is(n + i));
        let d = Jet::constant(chain.damping_nms_per_rad[i], is(2 * n - 1 + i));
        let k = d.add(c.mul(inv_s));
        let q = k.mul(z).mul(k.add(z).inv());
        let ji = Jet::constant(chain.inertia_kgm2[i], is(i));
        z = ji.mul(sj).add(q);
    }
    z
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn jet_matches_the_ladder_and_finite_differences() {
        let ch = Chain::new(vec![2e-3, 3e-3, 7e-3], vec![800.0, 90.0], vec![0.05, 0.01]).unwrap();
        let s = Complex64::new(-4.0, 300.0);
        let jet = impedance_jet(&ch, s, Some(3));
        let (z, dz) = ch.impedance_and_derivative(s);
        assert!((jet.0[0] - z).norm() < 1e-12 * z.norm());
        assert!((jet.0[1] - dz).norm() < 1e-12 * dz.norm());
        let h = 1e-3;
        let d2 = (ch.impedance_and_derivative(s + h).1 - ch.impedance_and_derivative(s - h).1)
            / (2.0 * h);
        assert!((2.0 * jet.0[2] - d2).norm() < 1e-6 * d2.norm());
        // d/d ln c1
        let eps: f64 = 1e-6;
        let mut a = ch.clone();
        a.stiffness_nm_per_rad[0] *= eps.exp();
        let mut b = ch.clone();
        b.stiffness_nm_per_rad[0] *= (-eps).exp();
        let (za, dza) = a.impedance_and_derivative(s);
        let (zb, dzb) = b.impedance_and_derivative(s);
        let fd = (za - zb) / (2.0 * eps);
        let fds = (dza - dzb) / (2.0 * eps);
        assert!(
            (jet.0[3] - fd).norm() < 1e-6 * fd.norm(),
            "{} {}",
            jet.0[3],
            fd
        );
        assert!(
            (jet.0[4] - fds).norm() < 1e-6 * fds.norm(),
            "{} {}",
            jet.0[4],
            fds
        );
    }
}
