//! The model FRF matrix of the linearised flexible manipulator, from the motor torques
//! [N m, motor side] to the motor speeds [rad/s, motor side], and its derivatives with
//! respect to the logarithms of the spring-damper parameters.
//!
//! With the coordinates `q` of [`RigidPose`] (arm, then motors; arm side), the linearised
//! equations at rest are `M q'' + C q' + K q = P R u`:
//! * `M = diag(M_a(q_r), J_m r^2)`;
//! * `K = diag(dg/dq, 0) + sum_s k_s e_s e_s^T`, `C = sum_s c_s e_s e_s^T`, with `e_s` the
//!   difference of the coordinates pair `s` joins (gear: arm joint minus motor; bearing:
//!   the bearing coordinate alone);
//! * `P` selects the motor coordinates, `R = diag(r)`: motor torque `u_i` is `r_i u_i` on
//!   the arm side, and the motor speed is `r_i` times the arm-side one.
//!
//! With the dynamic stiffness `Z(s) = s^2 M + s C + K` (symmetric) and `X = Z^-1 P R`:
//! `G(s) = s (P R)^T X`, and since `dZ/d ln k_s = k_s e_s e_s^T`,
//! `dG/d ln k_s = -s k_s a_s^T a_s` and `dG/d ln c_s = -s^2 c_s a_s^T a_s` with the row
//! `a_s = e_s^T X` (`Z^-1` is symmetric, so `(P R)^T Z^-1 e_s = a_s^T`). One LU of `Z` and
//! `N` solves per line give the FRF and every derivative. `G` is symmetric (reciprocity:
//! the paper's eq. (13)).
//!
//! This is the continuous-time model. The measured FRF of a sampled drive (zero-order-hold
//! torque) differs from it by a half-sample delay and a magnitude change of a few hundredths
//! of a dB at a tenth of the sample rate (`../shared/design/multiaxis.md`, fact 3); the
//! identification's cost compares magnitudes only, so the delay does not enter.

use super::clu;
use super::pose::RigidPose;
use super::springs::Flexibilities;
use super::ManipulatorError;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// The model FRF matrices at a set of frequencies.
#[derive(Debug, Clone, PartialEq)]
pub struct ModelFrf {
    /// Frequencies [Hz].
    pub f_hz: Vec<f64>,
    /// `G(j 2 pi f)` per frequency, `N x N` [rad/s per N m, motor side]: row = speed of
    /// motor `n`, column = torque of motor `m`.
    pub g: Vec<DMatrix<Complex64>>,
}

/// The evaluation of one pose's model FRF, planned once: the base matrices and every
/// buffer of the per-line solve (nothing is allocated per line).
#[derive(Debug, Clone)]
pub struct FrfPlan {
    /// Coordinates `n_a + N`.
    n: usize,
    /// Axes `N`.
    axes: usize,
    /// `M` row-major [kg m^2].
    mass: Vec<f64>,
    /// `diag(dg/dq, 0)` row-major [N m/rad].
    gravity: Vec<f64>,
    /// Per pair: the coordinates it joins (`e_s = e_a - e_m`).
    pairs: Vec<(usize, Option<usize>)>,
    /// Motor coordinate and gear ratio per axis.
    motors: Vec<(usize, f64)>,
    /// `Z`, then its LU.
    z: Vec<Complex64>,
    piv: Vec<usize>,
    /// `X = Z^-1 P R` (`n x N`, row-major).
    x: Vec<Complex64>,
    /// `a_s` of one pair.
    a: Vec<Complex64>,
}

impl FrfPlan {
    /// The plan of `pose`.
    pub fn new(pose: &RigidPose) -> Self {
        let n = pose.coords();
        let na = pose.arm_coords();
        let axes = pose.axes();
        let mut mass = vec![0.0; n * n];
        let mut gravity = vec![0.0; n * n];
        for i in 0..na {
            for j in 0..na {
                mass[i * n + j] = pose.arm_mass[(i, j)];
                gravity[i * n + j] = pose.gravity_stiffness[(i, j)];
            }
        }
        let motors: Vec<(usize, f64)> = pose
            .motors
            .iter()
            .enumerate()
            .map(|(i, m)| (pose.motor_coord(i), m.gear_ratio))
            .collect();
        for (i, m) in pose.motors.iter().enumerate() {
            let c = pose.motor_coord(i);
            mass[c * n + c] = m.arm_side_inertia_kgm2();
        }
        FrfPlan {
            n,
            axes,
            mass,
            gravity,
            pairs: pose.springs.iter().map(|s| pose.spring_coords(s)).collect(),
            motors,
            z: vec![Complex64::new(0.0, 0.0); n * n],
            piv: vec![0; n],
            x: vec![Complex64::new(0.0, 0.0); n * axes],
            a: vec![Complex64::new(0.0, 0.0); axes],
        }
    }

    /// Number of axes `N`.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Number of spring-damper pairs.
    pub fn pairs(&self) -> usize {
        self.pairs.len()
    }

    /// `G(j 2 pi f_hz)` into `g` (`N x N` row-major).
    pub fn frf_into(
        &mut self,
        f_hz: f64,
        theta: &Flexibilities,
        g: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let s = self.solve(f_hz, theta)?;
        self.gather(s, g);
        Ok(())
    }

    /// `G(j 2 pi f_hz)` into `g` and its derivatives into `dg` (`2 S` blocks of `N x N`
    /// row-major: `d/d ln k_1 .. d/d ln k_S`, then `d/d ln c_1 .. d/d ln c_S`).
    pub fn frf_and_derivatives_into(
        &mut self,
        f_hz: f64,
        theta: &Flexibilities,
        g: &mut [Complex64],
        dg: &mut [Complex64],
    ) -> Result<(), ManipulatorError> {
        let s = self.solve(f_hz, theta)?;
        self.gather(s, g);
        let nn = self.axes * self.axes;
        let npairs = self.pairs.len();
        for p in 0..npairs {
            let (a, m) = self.pairs[p];
            for j in 0..self.axes {
                let xm = m.map_or(Complex64::new(0.0, 0.0), |m| self.x[m * self.axes + j]);
                self.a[j] = self.x[a * self.axes + j] - xm;
            }
            let fk = -s * theta.stiffness_nm_per_rad[p];
            let fc = -s * s * theta.damping_nms_per_rad[p];
            let (dk, rest) = dg[p * nn..].split_at_mut(nn);
            let dc = &mut rest[(npairs - 1) * nn..npairs * nn];
            for i in 0..self.axes {
                for j in 0..self.axes {
                    let aa = self.a[i] * self.a[j];
                    dk[i * self.axes + j] = fk * aa;
                    dc[i * self.axes + j] = fc * aa;
                }
            }
        }
        Ok(())
    }

    /// The FRF matrices at every frequency of `f_hz`.
    pub fn frf(
        &mut self,
        f_hz: &[f64],
        theta: &Flexibilities,
    ) -> Result<ModelFrf, ManipulatorError> {
        let mut buf = vec![Complex64::new(0.0, 0.0); self.axes * self.axes];
        let g = f_hz
            .iter()
            .map(|&f| {
                self.frf_into(f, theta, &mut buf)?;
                Ok(DMatrix::from_row_slice(self.axes, self.axes, &buf))
            })
            .collect::<Result<Vec<_>, ManipulatorError>>()?;
        Ok(ModelFrf {
            f_hz: f_hz.to_vec(),
            g,
        })
    }

    /// Builds `Z(s)` at `s = j 2 pi f_hz`, factorises it and solves `X = Z^-1 P R`;
    /// returns `s`.
    fn solve(&mut self, f_hz: f64, theta: &Flexibilities) -> Result<Complex64, ManipulatorError> {
        debug_assert_eq!(theta.pairs(), self.pairs.len());
        let n = self.n;
        let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f_hz);
        let s2 = s * s;
        for ((z, &m), &k) in self.z.iter_mut().zip(&self.mass).zip(&self.gravity) {
            *z = s2 * m + k;
        }
        for (p, &(a, m)) in self.pairs.iter().enumerate() {
            let w = theta.stiffness_nm_per_rad[p] + s * theta.damping_nms_per_rad[p];
            self.z[a * n + a] += w;
            if let Some(m) = m {
                self.z[m * n + m] += w;
                self.z[a * n + m] -= w;
                self.z[m * n + a] -= w;
            }
        }
        if !clu::factor(&mut self.z, n, &mut self.piv) {
            return Err(ManipulatorError::Singular { f_hz });
        }
        self.x.fill(Complex64::new(0.0, 0.0));
        for (j, &(c, r)) in self.motors.iter().enumerate() {
            self.x[c * self.axes + j] = Complex64::new(r, 0.0);
        }
        clu::solve(&self.z, n, &self.piv, &mut self.x, self.axes);
        Ok(s)
    }

    /// `G = s (P R)^T X` from the solved `X`.
    fn gather(&self, s: Complex64, g: &mut [Complex64]) {
        for (i, &(c, r)) in self.motors.iter().enumerate() {
            for j in 0..self.axes {
                g[i * self.axes + j] = s * r * self.x[c * self.axes + j];
            }
        }
    }
}

#[cfg(test)]
mod tests;
