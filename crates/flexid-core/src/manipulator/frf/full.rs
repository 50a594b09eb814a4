//! The full dynamic stiffness `Z(s) = s^2 M + s C + K` over all `n_a + N` coordinates
//! (arm and motors), factorised by one `n x n` LU per line: the direct form of
//! [`super::FrfPlan`]'s solve. The plan takes it where eliminating the motors loses
//! precision ([`super::reduced`]), and the tests take it as the reference of the reduced
//! form.

use super::super::clu;
use super::super::pose::RigidPose;
use super::super::springs::Flexibilities;
use num_complex::Complex64;

/// The full system of one pose: the base matrices and the LU's buffers.
#[derive(Debug, Clone)]
pub(super) struct FullSystem {
    /// Coordinates `n_a + N`.
    n: usize,
    /// `M` row-major [kg m^2].
    mass: Vec<f64>,
    /// `diag(dg/dq, 0)` row-major [N m/rad].
    gravity: Vec<f64>,
    /// `Z`, then its LU.
    z: Vec<Complex64>,
    piv: Vec<usize>,
}

impl FullSystem {
    pub(super) fn new(pose: &RigidPose) -> Self {
        let n = pose.coords();
        let na = pose.arm_coords();
        let mut mass = vec![0.0; n * n];
        let mut gravity = vec![0.0; n * n];
        for i in 0..na {
            for j in 0..na {
                mass[i * n + j] = pose.arm_mass[(i, j)];
                gravity[i * n + j] = pose.gravity_stiffness[(i, j)];
            }
        }
        for (i, m) in pose.motors.iter().enumerate() {
            let c = pose.motor_coord(i);
            mass[c * n + c] = m.arm_side_inertia_kgm2();
        }
        FullSystem {
            n,
            mass,
            gravity,
            z: vec![Complex64::new(0.0, 0.0); n * n],
            piv: vec![0; n],
        }
    }

    /// `X = Z(s)^-1 P R` into `x` (`n x N` row-major); `false` when `Z` is singular.
    pub(super) fn solve(
        &mut self,
        s: Complex64,
        theta: &Flexibilities,
        pairs: &[(usize, Option<usize>)],
        motors: &[(usize, f64)],
        x: &mut [Complex64],
    ) -> bool {
        let n = self.n;
        let axes = motors.len();
        let s2 = s * s;
        for ((z, &m), &k) in self.z.iter_mut().zip(&self.mass).zip(&self.gravity) {
            *z = s2 * m + k;
        }
        for (p, &(a, m)) in pairs.iter().enumerate() {
            let w = theta.stiffness_nm_per_rad[p] + s * theta.damping_nms_per_rad[p];
            self.z[a * n + a] += w;
            if let Some(m) = m {
                self.z[m * n + m] += w;
                self.z[a * n + m] -= w;
                self.z[m * n + a] -= w;
            }
        }
        if !clu::factor(&mut self.z, n, &mut self.piv) {
            return false;
        }
        x.fill(Complex64::new(0.0, 0.0));
        for (j, &(c, r)) in motors.iter().enumerate() {
            x[c * axes + j] = Complex64::new(r, 0.0);
        }
        clu::solve(&self.z, n, &self.piv, x, axes);
        true
    }
}
