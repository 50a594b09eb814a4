//! Forward kinematics: each link's frame, joint axis and body in the base frame at a pose.
//! The dynamics calls collect these into one stack (a `Vec` of length `dof()`) and
//! recurse over it.

use nalgebra::{Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use super::{JointKind, Link, SerialRobot};

/// One link at a pose, everything in the base frame.
#[derive(Debug, Clone, Copy)]
pub(super) struct BodyAt {
    /// How its joint moves.
    pub kind: JointKind,
    /// The link frame's origin [m]: on the joint axis for a revolute joint.
    pub origin: Vector3<f64>,
    /// The joint axis (unit).
    pub axis: Vector3<f64>,
    /// Mass [kg].
    pub mass: f64,
    /// Centre of mass [m].
    pub com: Vector3<f64>,
    /// Inertia about the centre of mass, base axes [kg m^2].
    pub inertia: Matrix3<f64>,
}

/// The joint's motion by `q`: the link frame in the joint frame [rad or m].
fn joint_motion(link: &Link, q: f64) -> Isometry3<f64> {
    match link.kind {
        JointKind::Revolute => Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(&link.axis, q),
        ),
        JointKind::Prismatic => Isometry3::from_parts(
            Translation3::from(link.axis.into_inner() * q),
            UnitQuaternion::identity(),
        ),
    }
}

/// The link frames in the base frame, base outwards: `T_i = T_(i-1) origin_i motion_i(q_i)`.
/// `q` must have one entry per joint (checked by the callers).
pub(super) fn link_poses<'a>(
    robot: &'a SerialRobot,
    q: &'a [f64],
) -> impl Iterator<Item = Isometry3<f64>> + 'a {
    robot
        .links
        .iter()
        .zip(q)
        .scan(Isometry3::identity(), |parent, (link, &qi)| {
            *parent = *parent * link.origin * joint_motion(link, qi);
            Some(*parent)
        })
}

/// Every link at pose `q` in the base frame (the dynamics calls' stack).
pub(super) fn bodies_at(robot: &SerialRobot, q: &[f64]) -> Vec<BodyAt> {
    let mut out = Vec::with_capacity(robot.dof());
    out.extend(
        robot
            .links
            .iter()
            .zip(link_poses(robot, q))
            .map(|(link, pose)| {
                let r = pose.rotation.to_rotation_matrix();
                let r = r.matrix();
                BodyAt {
                    kind: link.kind,
                    origin: pose.translation.vector,
                    axis: r * link.axis.into_inner(),
                    mass: link.inertial.mass_kg,
                    com: pose.transform_point(&link.inertial.com_m.into()).coords,
                    inertia: r * link.inertial.inertia_kgm2 * r.transpose(),
                }
            }),
    );
    out
}
