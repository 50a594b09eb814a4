//! Gravity torque g(q) and its analytic Jacobian dg/dq, the gravity stiffness.
//!
//! The potential energy is `V(q) = -g0 . h(q)` with `g0` gravity's acceleration and
//! `h = sum_j m_j c_j` the bodies' first moment of mass. Moving joint i moves the bodies
//! outward of it, so `u_i = dh/dq_i` is `z_i x (h_i - M_i o_i)` for a revolute joint (axis
//! `z_i` through `o_i`; `M_i`, `h_i` the mass and first moment of the bodies from i
//! outward) and `M_i z_i` for a prismatic one. Then
//!
//! * `g_i = dV/dq_i = -g0 . u_i` (Pinocchio's sign: the torque that holds the arm);
//! * `d g_i / d q_k = -g0 . (z_a x u_b)` with `a = min(i, k)`, `b = max(i, k)` when joint
//!   a is revolute (`u_b` is built of vectors outward of joint a, which turn with it about
//!   `z_a`), and 0 when joint a is prismatic (a shift turns no vector). Symmetric: it is
//!   the Hessian of V.

use nalgebra::{DMatrix, DVector, Vector3};

use super::kinematics::{bodies_at, BodyAt};
use super::{JointKind, RobotError, SerialRobot};

impl SerialRobot {
    /// The gravity torque g(q) [N m or N per joint] at pose `q` [rad or m]: the joint
    /// torques that hold the arm still, the sign of Pinocchio's
    /// `computeGeneralizedGravity` (`tau = M qdd + C qd + g`).
    pub fn gravity_torque(&self, q: &[f64]) -> Result<DVector<f64>, RobotError> {
        self.check_len("q", q)?;
        let bodies = bodies_at(self, q);
        let mut g = DVector::zeros(self.dof());
        for (i, u) in moment_rates(&bodies) {
            g[i] = -self.gravity_mps2.dot(&u);
        }
        Ok(g)
    }

    /// The gravity stiffness dg/dq at pose `q` [N m/rad, N/m, N m/m or N/rad]: entry
    /// (i, k) is d g_i / d q_k, analytic (Pinocchio's
    /// `computeGeneralizedGravityDerivatives`); symmetric.
    pub fn gravity_stiffness(&self, q: &[f64]) -> Result<DMatrix<f64>, RobotError> {
        self.check_len("q", q)?;
        let bodies = bodies_at(self, q);
        let mut k = DMatrix::zeros(self.dof(), self.dof());
        for (b, u) in moment_rates(&bodies) {
            for (a, joint) in bodies[..=b].iter().enumerate() {
                if joint.kind == JointKind::Revolute {
                    let kab = -self.gravity_mps2.dot(&joint.axis.cross(&u));
                    k[(a, b)] = kab;
                    k[(b, a)] = kab;
                }
            }
        }
        Ok(k)
    }
}

/// `(i, u_i)` from the last joint to the first: the rate of the first moment of mass of
/// the bodies outward of joint i per unit of q_i [kg m/rad or kg]; `u_i` moves with the
/// bodies outward of every earlier joint.
fn moment_rates(bodies: &[BodyAt]) -> impl Iterator<Item = (usize, Vector3<f64>)> + '_ {
    bodies.iter().enumerate().rev().scan(
        (0.0, Vector3::zeros()),
        |(mass, moment): &mut (f64, Vector3<f64>), (i, body)| {
            *mass += body.mass;
            *moment += body.com * body.mass;
            let u = match body.kind {
                JointKind::Revolute => body.axis.cross(&(*moment - body.origin * *mass)),
                JointKind::Prismatic => body.axis * *mass,
            };
            Some((i, u))
        },
    )
}
