//! The arm's dynamic stiffness with the motors eliminated: [`super::FrfPlan`]'s solve per
//! line as an `n_a x n_a` LU instead of the full `(n_a + N) x (n_a + N)` one (12 instead of
//! 18 coordinates for the paper's robot: about a third of the LU's arithmetic).
//!
//! Motor `i` (arm-side inertia `m_i`) couples to nothing but its gear, the pair
//! `w_i = k_i + s c_i` to arm coordinate `a_i`. Its row of `Z X = P R` reads
//! `d_i X_m,i - w_i X_a,i = r_i e_i^T` with `d_i = s^2 m_i + w_i`, so
//! `X_m,i = (r_i e_i^T + w_i X_a,i) / d_i`, and the arm's rows become
//! `S X_a = B`: `S` is `Z_aa` with the gear's `w_i` at `(a_i, a_i)` replaced by the motor
//! and gear in series, `w_i s^2 m_i / d_i` (the Schur complement `Z_aa - sum w_i^2 / d_i`),
//! and `B` has `w_i r_i / d_i` at `(a_i, i)`. `X` (arm rows `X_a`, motor rows `X_m`) is
//! then the full form's, and so are `G` and its derivatives.
//!
//! Precision: `X_m,i` is a difference divided by `d_i`; where `|d_i|` is small against
//! `|w_i|` (the motor's resonance on its gear with the arm held, `-w^2 m_i + k_i = 0`, and
//! little damping: `|d_i| >= w c_i` there) the difference cancels and `|w_i| / |d_i|` of
//! the relative precision is lost. Below [`MIN_D_OVER_W`] the plan takes the full form.

use super::super::augmented::Augmented;
use super::super::pose::RigidPose;
use super::super::springs::{Flexibilities, SpringKind};
use num_complex::Complex64;

/// `|d_i| / |w_i|` below which the motors are not eliminated: the reduced form then keeps
/// at least 1e-16 / 1e-6 = 1e-10 of relative precision in `X_m` (its cancellation's
/// amplification is `|w_i| / |d_i|`).
pub const MIN_D_OVER_W: f64 = 1e-6;

/// One axis's motor and gear.
#[derive(Debug, Clone, Copy)]
pub(super) struct Gear {
    /// The gear pair's index in the parameters.
    pub(super) pair: usize,
    /// Its arm coordinate `a_i`.
    pub(super) arm: usize,
    /// The motor's arm-side inertia `m_i` [kg m^2].
    pub(super) inertia: f64,
    /// Gear ratio `r_i` [-].
    pub(super) ratio: f64,
}

/// A bearing pair: its index in the parameters, its arm coordinate.
pub(super) type Bearing = (usize, usize);

/// The motors' gears (per axis) and the bearing pairs of `pose`,
/// where its motors can be eliminated: `None` when an axis has no gear pair or the motors
/// are not the last coordinates (then only the full form applies).
pub(super) fn gears_and_bearings(pose: &RigidPose) -> Option<(Vec<Gear>, Vec<Bearing>)> {
    let na = pose.arm_coords();
    let axes = pose.axes();
    let mut gears: Vec<Option<Gear>> = vec![None; axes];
    let mut bearings = Vec::new();
    for (p, s) in pose.springs.iter().enumerate() {
        match s.kind {
            SpringKind::Gear { joint } => {
                let m = pose.motors[joint];
                gears[joint] = Some(Gear {
                    pair: p,
                    arm: s.arm_coord,
                    inertia: m.arm_side_inertia_kgm2(),
                    ratio: m.gear_ratio,
                });
            }
            SpringKind::Bearing { .. } => bearings.push((p, s.arm_coord)),
        }
    }
    let gears = gears.into_iter().collect::<Option<Vec<_>>>()?;
    if (0..axes).any(|i| pose.motor_coord(i) != na + i) {
        return None;
    }
    Some((gears, bearings))
}

/// The reduced system of one pose: the arm's base matrices and the LU's buffers.
#[derive(Debug, Clone)]
pub(super) struct ReducedSystem {
    /// Arm coordinates `n_a`.
    na: usize,
    /// `M_a` row-major [kg m^2].
    mass: Vec<f64>,
    /// `dg/dq` row-major [N m/rad].
    gravity: Vec<f64>,
    /// Bearing pairs: index, arm coordinate.
    bearings: Vec<(usize, usize)>,
    /// Per axis.
    gears: Vec<Gear>,
    /// `[S | B]`, then `X_a`.
    aug: Augmented,
    /// Per axis: `w_i`, `1 / d_i`.
    wd: Vec<(Complex64, Complex64)>,
}

impl ReducedSystem {
    /// The system of `pose`; `None` when an axis has no gear pair (then only the full form
    /// applies).
    pub(super) fn new(pose: &RigidPose) -> Option<Self> {
        let na = pose.arm_coords();
        let axes = pose.axes();
        let (gears, bearings) = gears_and_bearings(pose)?;
        Some(ReducedSystem {
            na,
            mass: pose.arm_mass.transpose().as_slice().to_vec(),
            gravity: pose.gravity_stiffness.transpose().as_slice().to_vec(),
            bearings,
            gears,
            aug: Augmented::new(na, axes),
            wd: vec![(Complex64::new(0.0, 0.0), Complex64::new(0.0, 0.0)); axes],
        })
    }

    /// `X = Z(s)^-1 P R` into `x` (`(n_a + N) x N` row-major: arm rows, then motor rows);
    /// `false` when a motor is not eliminated to full precision ([`MIN_D_OVER_W`]) or `S`
    /// is singular: the full form decides then.
    pub(super) fn solve(
        &mut self,
        s: Complex64,
        theta: &Flexibilities,
        x: &mut [Complex64],
    ) -> bool {
        let na = self.na;
        let axes = self.gears.len();
        // s = j w: s^2 = -w^2 is real
        let s2 = s * s;
        let (mass, gravity) = (&self.mass, &self.gravity);
        self.aug
            .set_matrix(|i, j| gravity[i * na + j] + s2.re * mass[i * na + j]);
        for &(p, b) in &self.bearings {
            self.aug.add_a(
                b,
                b,
                theta.stiffness_nm_per_rad[p] + s * theta.damping_nms_per_rad[p],
            );
        }
        for (i, (g, wd)) in self.gears.iter().zip(&mut self.wd).enumerate() {
            let w = theta.stiffness_nm_per_rad[g.pair] + s * theta.damping_nms_per_rad[g.pair];
            let sm = s2 * g.inertia;
            let d = sm + w;
            // also false for a NaN
            if !(d.norm_sqr() >= MIN_D_OVER_W * MIN_D_OVER_W * w.norm_sqr())
                || d == Complex64::new(0.0, 0.0)
            {
                return false;
            }
            let inv = d.inv();
            self.aug.add_a(g.arm, g.arm, w * sm * inv);
            self.aug.set_b(g.arm, i, w * g.ratio * inv);
            *wd = (w, inv);
        }
        if !self.aug.solve() {
            return false;
        }
        let (xa, xm) = x.split_at_mut(na * axes);
        for (c, row) in xa.chunks_exact_mut(axes).enumerate() {
            for (j, x) in row.iter_mut().enumerate() {
                *x = self.aug.x(c, j);
            }
        }
        for (i, (g, &(w, inv))) in self.gears.iter().zip(&self.wd).enumerate() {
            let row = &mut xm[i * axes..(i + 1) * axes];
            for (xm, xa) in row.iter_mut().zip(&xa[g.arm * axes..(g.arm + 1) * axes]) {
                *xm = w * *xa * inv;
            }
            row[i] += g.ratio * inv;
        }
        true
    }
}
