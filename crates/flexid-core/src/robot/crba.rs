//! The joint-space mass matrix M(q) by composite rigid bodies, in the base frame.
//!
//! The bodies from joint i outward, taken as one rigid composite (mass, centre of mass,
//! inertia about it), moved by a unit rate of joint i alone carry a momentum; its
//! projection on the motion of joint j <= i is `M_ji`: for a revolute joint j the angular
//! momentum about a point of j's axis along the axis, for a prismatic one the linear
//! momentum along the axis.

use nalgebra::{DMatrix, Vector3};

use super::kinematics::{bodies_at, BodyAt};
use super::{Inertial, JointKind, RobotError, SerialRobot};

impl SerialRobot {
    /// The mass matrix M(q) at pose `q` [rad or m]: symmetric positive (semi-)definite,
    /// entries in [kg m^2], [kg m] or [kg] after the joints' kinds; both triangles filled.
    pub fn mass_matrix(&self, q: &[f64]) -> Result<DMatrix<f64>, RobotError> {
        self.check_len("q", q)?;
        let bodies = bodies_at(self, q);
        let mut m = DMatrix::zeros(self.dof(), self.dof());
        let mut composite = Inertial::zero();
        for (i, body) in bodies.iter().enumerate().rev() {
            composite = composite.combined(&Inertial {
                mass_kg: body.mass,
                com_m: body.com,
                inertia_kgm2: body.inertia,
            });
            let (linear, angular_at_com) = unit_rate_momentum(&composite, body);
            for (j, joint) in bodies[..=i].iter().enumerate() {
                let mji = match joint.kind {
                    JointKind::Revolute => joint
                        .axis
                        .dot(&(angular_at_com + (composite.com_m - joint.origin).cross(&linear))),
                    JointKind::Prismatic => joint.axis.dot(&linear),
                };
                m[(j, i)] = mji;
                m[(i, j)] = mji;
            }
        }
        Ok(m)
    }
}

/// The momentum of the composite body (base frame) moved by a unit rate of `joint`'s
/// joint alone: (linear [kg m/s], angular about the composite's centre of mass
/// [kg m^2/s]) per [rad/s] or [m/s].
fn unit_rate_momentum(composite: &Inertial, joint: &BodyAt) -> (Vector3<f64>, Vector3<f64>) {
    match joint.kind {
        JointKind::Revolute => (
            joint.axis.cross(&(composite.com_m - joint.origin)) * composite.mass_kg,
            composite.inertia_kgm2 * joint.axis,
        ),
        JointKind::Prismatic => (joint.axis * composite.mass_kg, Vector3::zeros()),
    }
}
