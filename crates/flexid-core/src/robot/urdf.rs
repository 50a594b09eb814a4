//! URDF import of a serial chain (text in, no file I/O): the `urdf-rs` parser, then the
//! chain from the root link outward, fixed joints merged into the body before them.

use std::collections::HashMap;

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3};

use super::{Inertial, JointKind, Link, RobotError, SerialRobot, STANDARD_GRAVITY_MPS2};

impl SerialRobot {
    /// The serial robot described by URDF text `urdf` (parsed by `urdf_rs::read_from_string`).
    ///
    /// * The links must form one unbranched chain from one root link (the base): a link
    ///   with two child joints, a link that is the child of two joints, a second root or a
    ///   link not connected to the root is refused with [`RobotError::NotSerial`] naming it.
    /// * Revolute and continuous joints become [`JointKind::Revolute`], prismatic joints
    ///   [`JointKind::Prismatic`]; joint limits are not used. Floating, planar and
    ///   spherical joints are refused.
    /// * A fixed joint's child body is merged into the body before it (mass added, inertia
    ///   combined about the common centre of mass); a movable joint after it gets the fixed
    ///   joint's origin composed into its own. Fixed joints before the first movable joint
    ///   merge into the base.
    /// * Each joint's `<origin xyz rpy>` (rpy: fixed-axis roll about x, then pitch about y,
    ///   then yaw about z, `R = Rz(y) Ry(p) Rx(r)`), `<axis xyz>` (normalised; default
    ///   x) and each link's `<inertial>` (`<origin>`: the centre of mass and the axes of the
    ///   inertia tensor) are honoured; a link without `<inertial>` is massless.
    /// * Gravity is -9.81 m/s^2 along the base's z (URDF has no gravity element).
    pub fn from_urdf_str(urdf: &str) -> Result<Self, RobotError> {
        let robot = urdf_rs::read_from_string(urdf)?;
        let chain = ordered_chain(&robot)?;
        assemble(&robot, &chain)
    }
}

/// The links of the chain from the root outward, each but the root with the index of the
/// joint that leads to it: `(root link, [(joint, child link)])`.
fn ordered_chain(robot: &urdf_rs::Robot) -> Result<(usize, Vec<(usize, usize)>), RobotError> {
    let mut index: HashMap<&str, usize> = HashMap::new();
    for (i, link) in robot.links.iter().enumerate() {
        if index.insert(link.name.as_str(), i).is_some() {
            return Err(not_serial(&link.name, "the link is defined twice"));
        }
    }
    let find = |joint: &urdf_rs::Joint, name: &str| {
        index
            .get(name)
            .copied()
            .ok_or_else(|| RobotError::MissingLink {
                joint: joint.name.clone(),
                link: name.to_string(),
            })
    };
    let mut child_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
    let mut parent_joint: Vec<Option<usize>> = vec![None; robot.links.len()];
    for (j, joint) in robot.joints.iter().enumerate() {
        let (parent, child) = (
            find(joint, &joint.parent.link)?,
            find(joint, &joint.child.link)?,
        );
        if let Some(other) = child_joint[parent].replace(j) {
            return Err(not_serial(
                &joint.parent.link,
                &format!(
                    "the chain branches: joints `{}` and `{}` both start there",
                    robot.joints[other].name, joint.name
                ),
            ));
        }
        if let Some(other) = parent_joint[child].replace(j) {
            return Err(not_serial(
                &joint.child.link,
                &format!(
                    "the link is the child of two joints, `{}` and `{}`",
                    robot.joints[other].name, joint.name
                ),
            ));
        }
    }
    let mut roots = (0..robot.links.len()).filter(|&l| parent_joint[l].is_none());
    let root = roots
        .next()
        .ok_or_else(|| not_serial(&robot.name, "no root link (the joints form a loop)"))?;
    if let Some(second) = roots.next() {
        return Err(not_serial(
            &robot.links[second].name,
            &format!(
                "a second root link (no parent joint) besides `{}`",
                robot.links[root].name
            ),
        ));
    }
    let mut chain = Vec::with_capacity(robot.joints.len());
    let mut at = root;
    while let Some(j) = child_joint[at] {
        at = find(&robot.joints[j], &robot.joints[j].child.link)?;
        chain.push((j, at));
    }
    if chain.len() + 1 < robot.links.len() {
        let mut on_chain = vec![false; robot.links.len()];
        on_chain[root] = true;
        chain.iter().for_each(|&(_, l)| on_chain[l] = true);
        if let Some(off) = (0..robot.links.len()).find(|&l| !on_chain[l]) {
            return Err(not_serial(
                &robot.links[off].name,
                "the link is not connected to the root (a loop of joints)",
            ));
        }
    }
    Ok((root, chain))
}

/// The robot from the ordered chain: movable joints become links, fixed joints merge.
fn assemble(
    robot: &urdf_rs::Robot,
    (root, chain): &(usize, Vec<(usize, usize)>),
) -> Result<SerialRobot, RobotError> {
    let mut base = link_inertial(&robot.links[*root])?;
    let mut links: Vec<Link> = Vec::new();
    // pose of the current URDF link's frame in the frame of the body it merges into
    let mut merged_at = Isometry3::identity();
    for &(j, child) in chain {
        let joint = &robot.joints[j];
        let body = link_inertial(&robot.links[child])?;
        let origin = merged_at * pose(&joint.origin);
        let kind = match joint.joint_type {
            urdf_rs::JointType::Fixed => None,
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                Some(JointKind::Revolute)
            }
            urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
            ref other => {
                return Err(RobotError::UnsupportedJoint {
                    joint: joint.name.clone(),
                    kind: format!("{other:?}").to_lowercase(),
                })
            }
        };
        let Some(kind) = kind else {
            let into = links.last_mut().map_or(&mut base, |l| &mut l.inertial);
            *into = into.combined(&body.transformed(&origin));
            merged_at = origin;
            continue;
        };
        let axis = Vector3::from(joint.axis.xyz.0);
        let axis = Unit::try_new(axis, 1e-12)
            .filter(|a| a.iter().all(|x| x.is_finite()))
            .ok_or(RobotError::BadAxis {
                joint: joint.name.clone(),
                axis: joint.axis.xyz.0,
            })?;
        links.push(Link {
            name: robot.links[child].name.clone(),
            joint: joint.name.clone(),
            origin,
            axis,
            kind,
            inertial: body,
        });
        merged_at = Isometry3::identity();
    }
    Ok(SerialRobot {
        base: (base.mass_kg > 0.0).then_some(base),
        links,
        gravity_mps2: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY_MPS2),
    })
}

/// A URDF `<origin xyz rpy>` as an isometry: translation, then `Rz(yaw) Ry(pitch) Rx(roll)`.
fn pose(p: &urdf_rs::Pose) -> Isometry3<f64> {
    let [x, y, z] = p.xyz.0;
    let [roll, pitch, yaw] = p.rpy.0;
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_euler_angles(roll, pitch, yaw),
    )
}

/// A URDF link's `<inertial>` in the link frame: the tensor rotated from the inertial
/// frame to the link's axes. Refuses a negative or non-finite mass and non-finite numbers.
fn link_inertial(link: &urdf_rs::Link) -> Result<Inertial, RobotError> {
    let i = &link.inertial.inertia;
    let in_own_axes = Inertial {
        mass_kg: link.inertial.mass.value,
        com_m: Vector3::zeros(),
        inertia_kgm2: Matrix3::new(
            i.ixx, i.ixy, i.ixz, //
            i.ixy, i.iyy, i.iyz, //
            i.ixz, i.iyz, i.izz,
        ),
    };
    let mass = in_own_axes.mass_kg;
    let finite = in_own_axes.inertia_kgm2.iter().all(|x| x.is_finite())
        && link
            .inertial
            .origin
            .xyz
            .iter()
            .chain(link.inertial.origin.rpy.iter())
            .all(|x| x.is_finite());
    if !mass.is_finite() || mass < 0.0 || !finite {
        return Err(RobotError::BadInertial {
            link: link.name.clone(),
            why: format!("mass {mass} kg, or a non-finite inertia or origin"),
        });
    }
    Ok(in_own_axes.transformed(&pose(&link.inertial.origin)))
}

fn not_serial(link: &str, why: &str) -> RobotError {
    RobotError::NotSerial {
        link: link.to_string(),
        why: why.to_string(),
    }
}
