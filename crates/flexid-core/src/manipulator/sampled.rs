//! The linearised manipulator at one pose as a sampled plant: motor torques held over each
//! sample (zero-order hold), motor positions sampled at the same instants and the motor
//! speed formed as their backward difference, as a drive measures it. It simulates sample
//! by sample (the simulated multi-axis drive, the tests' measurements) and gives its own
//! exact FRF matrix, the one an estimate from its samples converges to
//! (`../shared/design/multiaxis.md`, fact 3: not the continuous model's).
//!
//! State `x = [q; v]` (the linear model's coordinates of [`super::RigidPose`] and their
//! speeds, arm side, deviations from the pose), `x' = A x + B u` with
//! `A = [[0, I], [-M^-1 K, -M^-1 C]]`, `B = [0; M^-1 P R]`, discretised exactly:
//! `x[k+1] = Ad x[k] + Bd u[k]`.

use super::clu;
use super::pose::RigidPose;
use super::springs::Flexibilities;
use super::ManipulatorError;
use nalgebra::DMatrix;
use num_complex::Complex64;

/// The sampled plant of one pose.
#[derive(Debug, Clone)]
pub struct SampledPose {
    /// States `2 n`.
    ns: usize,
    /// Axes `N`.
    axes: usize,
    /// `Ad` row-major.
    ad: Vec<f64>,
    /// `Bd` row-major (`2n x N`).
    bd: Vec<f64>,
    /// Per axis: the state index of its motor angle and the gear ratio.
    motors: Vec<(usize, f64)>,
    /// Sample interval [s].
    ts: f64,
    /// `Ad x` of the step being taken.
    next: Vec<f64>,
}

impl SampledPose {
    /// The sampled plant of `pose` with the springs `theta` at `fs_hz` [Hz].
    pub fn new(
        pose: &RigidPose,
        theta: &Flexibilities,
        fs_hz: f64,
    ) -> Result<Self, ManipulatorError> {
        if !(fs_hz.is_finite() && fs_hz > 0.0) {
            return Err(ManipulatorError::NotPositive {
                what: "fs_hz",
                index: 0,
                value: fs_hz,
            });
        }
        let (m, c, k) = second_order(pose, theta);
        let n = m.nrows();
        let axes = pose.axes();
        let minv = m
            .try_inverse()
            .ok_or(ManipulatorError::Singular { f_hz: 0.0 })?;
        let mut a = DMatrix::<f64>::zeros(2 * n, 2 * n);
        a.view_mut((0, n), (n, n)).fill_with_identity();
        a.view_mut((n, 0), (n, n)).copy_from(&(-&minv * k));
        a.view_mut((n, n), (n, n)).copy_from(&(-&minv * c));
        let mut b = DMatrix::<f64>::zeros(2 * n, axes);
        for (i, mo) in pose.motors.iter().enumerate() {
            let col = minv.column(pose.motor_coord(i)) * mo.gear_ratio;
            b.view_mut((n, i), (n, 1)).copy_from(&col);
        }
        let ts = 1.0 / fs_hz;
        let (ad, bd) = zoh(&a, &b, ts);
        let row_major = |x: &DMatrix<f64>| x.transpose().as_slice().to_vec();
        Ok(SampledPose {
            ns: 2 * n,
            axes,
            ad: row_major(&ad),
            bd: row_major(&bd),
            motors: pose
                .motors
                .iter()
                .enumerate()
                .map(|(i, mo)| (pose.motor_coord(i), mo.gear_ratio))
                .collect(),
            ts,
            next: vec![0.0; 2 * n],
        })
    }

    /// Number of states.
    pub fn states(&self) -> usize {
        self.ns
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Axis `axis`'s motor: the state index of its angle (its speed is `states() / 2`
    /// further) and its gear ratio (motor angle = ratio x that coordinate).
    pub fn motor(&self, axis: usize) -> (usize, f64) {
        self.motors[axis]
    }

    /// One sample: `x <- Ad x + Bd u` with the motor torques `u` [N m, motor side].
    pub fn step(&mut self, x: &mut [f64], u: &[f64]) {
        let (ns, axes) = (self.ns, self.axes);
        for i in 0..ns {
            let row = &self.ad[i * ns..(i + 1) * ns];
            let mut s: f64 = row.iter().zip(x.iter()).map(|(a, x)| a * x).sum();
            let brow = &self.bd[i * axes..(i + 1) * axes];
            s += brow.iter().zip(u).map(|(b, u)| b * u).sum::<f64>();
            self.next[i] = s;
        }
        x.copy_from_slice(&self.next);
    }

    /// The motor positions [rad, motor side] of state `x` into `p`.
    pub fn motor_positions(&self, x: &[f64], p: &mut [f64]) {
        for (p, &(c, r)) in p.iter_mut().zip(&self.motors) {
            *p = r * x[c];
        }
    }

    /// The exact FRF matrix at `f_hz` from the held motor torques to the backward-
    /// differenced motor speeds [rad/s per N m, motor side]:
    /// `(1 - z^-1) fs R P^T [I 0] (z I - Ad)^-1 Bd`, `z = e^(j 2 pi f / fs)`.
    pub fn frf(&self, f_hz: f64) -> Result<DMatrix<Complex64>, ManipulatorError> {
        let (ns, axes) = (self.ns, self.axes);
        let z = Complex64::from_polar(1.0, 2.0 * std::f64::consts::PI * f_hz * self.ts);
        let mut lhs: Vec<Complex64> = self.ad.iter().map(|&a| Complex64::new(-a, 0.0)).collect();
        for i in 0..ns {
            lhs[i * ns + i] += z;
        }
        let mut piv = vec![0; ns];
        if !clu::factor(&mut lhs, ns, &mut piv) {
            return Err(ManipulatorError::Singular { f_hz });
        }
        let mut x: Vec<Complex64> = self.bd.iter().map(|&b| Complex64::new(b, 0.0)).collect();
        clu::solve(&lhs, ns, &piv, &mut x, axes);
        let diff = (1.0 - z.inv()) / self.ts;
        Ok(DMatrix::from_fn(axes, axes, |i, j| {
            let (c, r) = self.motors[i];
            diff * r * x[c * axes + j]
        }))
    }
}

/// `M`, `C`, `K` of the linear model over its coordinates (arm, then motors; arm side):
/// the same matrices [`super::frf`] assembles per line.
pub fn second_order(
    pose: &RigidPose,
    theta: &Flexibilities,
) -> (DMatrix<f64>, DMatrix<f64>, DMatrix<f64>) {
    let na = pose.arm_coords();
    let n = pose.coords();
    let mut m = DMatrix::<f64>::zeros(n, n);
    let mut k = DMatrix::<f64>::zeros(n, n);
    let mut c = DMatrix::<f64>::zeros(n, n);
    m.view_mut((0, 0), (na, na)).copy_from(&pose.arm_mass);
    k.view_mut((0, 0), (na, na))
        .copy_from(&pose.gravity_stiffness);
    for (i, mo) in pose.motors.iter().enumerate() {
        let j = pose.motor_coord(i);
        m[(j, j)] = mo.arm_side_inertia_kgm2();
    }
    for (p, s) in pose.springs.iter().enumerate() {
        let (a, b) = pose.spring_coords(s);
        for (mat, v) in [
            (&mut k, theta.stiffness_nm_per_rad[p]),
            (&mut c, theta.damping_nms_per_rad[p]),
        ] {
            mat[(a, a)] += v;
            if let Some(b) = b {
                mat[(b, b)] += v;
                mat[(a, b)] -= v;
                mat[(b, a)] -= v;
            }
        }
    }
    (m, c, k)
}

/// `(e^(A t), int_0^t e^(A s) ds B)` through the exponential of the augmented matrix
/// `[[A, B], [0, 0]] t` (valid for a singular `A`).
fn zoh(a: &DMatrix<f64>, b: &DMatrix<f64>, t: f64) -> (DMatrix<f64>, DMatrix<f64>) {
    let (ns, ni) = (a.nrows(), b.ncols());
    let mut aug = DMatrix::<f64>::zeros(ns + ni, ns + ni);
    aug.view_mut((0, 0), (ns, ns)).copy_from(&(a * t));
    aug.view_mut((0, ns), (ns, ni)).copy_from(&(b * t));
    let e = aug.exp();
    (
        e.view((0, 0), (ns, ns)).into_owned(),
        e.view((0, ns), (ns, ni)).into_owned(),
    )
}

/// A decentralised PD position loop per axis on the motor side, the low-bandwidth loop a
/// robot is measured under (gravity makes most poses open-loop unstable:
/// `../shared/design/multiaxis.md`, fact 1). The multisine is added to its torque, and the
/// FRF is estimated from the total torque (the direct method).
#[derive(Debug, Clone, PartialEq)]
pub struct PositionLoop {
    /// Proportional gain per axis [N m/rad, motor side].
    pub kp: Vec<f64>,
    /// Derivative gain per axis on the backward-differenced speed [N m s/rad].
    pub kd: Vec<f64>,
}

impl PositionLoop {
    /// Gains for a bandwidth of `bandwidth_hz` on each axis's rigid inertia at the motor
    /// (`(M_a,jj + J_m r^2) / r^2`, damping ratio 0.7), plus what cancels the axis's own
    /// negative gravity stiffness.
    pub fn for_pose(pose: &RigidPose, bandwidth_hz: f64) -> Self {
        let w = 2.0 * std::f64::consts::PI * bandwidth_hz;
        let (mut kp, mut kd) = (Vec::new(), Vec::new());
        for (i, mo) in pose.motors.iter().enumerate() {
            let a = pose
                .springs
                .iter()
                .find_map(|s| match s.kind {
                    super::SpringKind::Gear { joint } if joint == i => Some(s.arm_coord),
                    _ => None,
                })
                .unwrap_or(0);
            let r2 = mo.gear_ratio * mo.gear_ratio;
            let j = (pose.arm_mass[(a, a)] + mo.arm_side_inertia_kgm2()) / r2;
            let gravity = (-pose.gravity_stiffness[(a, a)]).max(0.0) / r2;
            kp.push(j * w * w + gravity);
            kd.push(2.0 * 0.7 * j * w);
        }
        PositionLoop { kp, kd }
    }

    /// The loop's torques [N m] from the positions now `p` and one sample before `p_prev`
    /// [rad, motor side, deviations from the set-point] at `fs_hz`.
    pub fn torque(&self, p: &[f64], p_prev: &[f64], fs_hz: f64, out: &mut [f64]) {
        for i in 0..out.len() {
            out[i] = -self.kp[i] * p[i] - self.kd[i] * (p[i] - p_prev[i]) * fs_hz;
        }
    }
}

#[cfg(test)]
mod tests;
