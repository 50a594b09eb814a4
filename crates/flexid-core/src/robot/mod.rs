//! Rigid-body dynamics of a serial robot arm: the mass matrix M(q), the gravity torque g(q),
//! its analytic derivative dg/dq (the gravity stiffness) and inverse dynamics, with a URDF
//! import. The flexible multi-axis model of issue 17 (joint, gear and bearing flexibilities
//! after the paper's section 2) is built on these: massless "bearing" joints are inserted
//! after a joint with [`SerialRobot::insert_joint`] and the arm's M and dg/dq are taken at
//! a pose.
//!
//! Why our own recursive Newton-Euler and composite-rigid-body code: no Rust crate does
//! rigid-body dynamics of a kinematic chain on nalgebra 0.34 (the one nalgebra of our
//! tree). `k` (openrr) does kinematics only (poses, Jacobians, inverse kinematics);
//! `rapier` is a contact/constraint simulation engine with no M(q) or dg/dq of a chain;
//! Pinocchio (the reference) is C++/Python. The algorithms are short and are checked
//! against Pinocchio (tests/robot_pinocchio.rs) and against independent computations in
//! this module's tests.
//!
//! * [`Inertial`], [`Link`], [`JointKind`], [`SerialRobot`]: the model (this file);
//!   [`Inertial`]'s algebra (re-expression, combination) in `inertial.rs`.
//! * `urdf.rs`: [`SerialRobot::from_urdf_str`], a serial chain from URDF text.
//! * `kinematics.rs`: the link frames in the base frame (forward kinematics), the stack of
//!   per-link states each dynamics call recurses over.
//! * `rnea.rs`: [`SerialRobot::inverse_dynamics`] (recursive Newton-Euler).
//! * `crba.rs`: [`SerialRobot::mass_matrix`] (composite rigid bodies).
//! * `gravity.rs`: [`SerialRobot::gravity_torque`] and [`SerialRobot::gravity_stiffness`].
//!
//! Conventions (Pinocchio's): q are the joint positions in chain order [rad or m]; the
//! dynamics read `tau = M(q) qdd + C(q, qd) qd + g(q)` with `tau` the joint torques [N m]
//! or forces [N] the actuators apply; g(q) is the torque that holds the arm still against
//! gravity (`computeGeneralizedGravity`), dg/dq its Jacobian
//! (`computeGeneralizedGravityDerivatives`). All vectors are in the base frame (the root
//! link's frame) unless named otherwise.
//!
//! Cost: each call allocates its output and one stack of per-link states (length
//! `dof()`; inverse dynamics a second one, the bodies' wrenches); nothing per link beyond
//! that. O(n) for g and inverse dynamics, O(n^2) for M and dg/dq.

mod crba;
mod gravity;
mod inertial;
mod kinematics;
mod rnea;
mod urdf;

use nalgebra::{Isometry3, Matrix3, Unit, Vector3};

#[cfg(test)]
mod tests;

/// Mass properties of one rigid body, in the frame of the link that carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    /// Mass [kg].
    pub mass_kg: f64,
    /// Centre of mass in the link frame [m].
    pub com_m: Vector3<f64>,
    /// Inertia tensor about the centre of mass, axes of the link frame [kg m^2].
    pub inertia_kgm2: Matrix3<f64>,
}

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the joint axis; q in [rad], tau in [N m].
    Revolute,
    /// Translation along the joint axis; q in [m], tau in [N].
    Prismatic,
}

/// One joint of the chain and the body it moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Name (the URDF child link's name on import).
    pub name: String,
    /// The joint's name (the URDF joint's on import; the bearing joints' own).
    pub joint: String,
    /// Pose of this joint's frame in the parent link's frame at q = 0 [m, rad]; the parent
    /// of the first link is the base.
    pub origin: Isometry3<f64>,
    /// Joint axis in the joint frame (unit, dimensionless).
    pub axis: Unit<Vector3<f64>>,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// The body moved by this joint, in the link frame: the joint frame moved by q (rotated
    /// about `axis` by q [rad], or shifted along it by q [m]).
    pub inertial: Inertial,
}

/// A serial (unbranched) chain of rigid bodies on a fixed base.
#[derive(Debug, Clone, PartialEq)]
pub struct SerialRobot {
    /// The base's mass properties in the base frame, if any; the base never moves, so they
    /// enter no dynamics (kept for the total mass and for completeness).
    pub base: Option<Inertial>,
    /// The joints and bodies from the base outwards; joint i is `links[i]`.
    pub links: Vec<Link>,
    /// Gravity's acceleration in the base frame [m/s^2] (-9.81 z by default).
    pub gravity_mps2: Vector3<f64>,
}

/// Why a robot model could not be built or evaluated.
#[derive(Debug, thiserror::Error)]
pub enum RobotError {
    /// A joint vector of the wrong length was given to a dynamics call.
    #[error("{what} has {got} entries, the robot has {dof} joints")]
    WrongLength {
        /// Which argument (`"q"`, `"qd"`, `"qdd"`).
        what: &'static str,
        /// Its length.
        got: usize,
        /// The robot's number of joints.
        dof: usize,
    },
    /// The URDF text is not valid URDF.
    #[error("URDF parse error: {0}")]
    Urdf(#[from] urdf_rs::UrdfError),
    /// The URDF is not a single serial chain.
    #[error("not a serial chain at link `{link}`: {why}")]
    NotSerial {
        /// The link where the chain branches, or that is disconnected or duplicated.
        link: String,
        /// What is wrong there.
        why: String,
    },
    /// A joint refers to a link that is not defined.
    #[error("joint `{joint}` names the undefined link `{link}`")]
    MissingLink {
        /// The joint.
        joint: String,
        /// The undefined link.
        link: String,
    },
    /// A joint type a serial arm model does not take (floating, planar, spherical).
    #[error("joint `{joint}` is {kind}: only revolute, continuous, prismatic and fixed joints are supported")]
    UnsupportedJoint {
        /// The joint.
        joint: String,
        /// Its URDF type.
        kind: String,
    },
    /// A joint axis that cannot be normalised.
    #[error("joint `{joint}` has a zero or non-finite axis {axis:?}")]
    BadAxis {
        /// The joint.
        joint: String,
        /// The axis as written.
        axis: [f64; 3],
    },
    /// Mass properties that are not physical (negative or non-finite mass, non-finite
    /// numbers).
    #[error("link `{link}` has invalid mass properties: {why}")]
    BadInertial {
        /// The link.
        link: String,
        /// What is wrong.
        why: String,
    },
}

impl Link {
    /// A massless revolute joint with the identity origin, about `axis` (unit in the joint
    /// frame): the bearing joints of the flexible model, for [`SerialRobot::insert_joint`].
    pub fn massless_revolute(name: impl Into<String>, axis: Unit<Vector3<f64>>) -> Self {
        let name = name.into();
        Link {
            joint: name.clone(),
            name,
            origin: Isometry3::identity(),
            axis,
            kind: JointKind::Revolute,
            inertial: Inertial::zero(),
        }
    }
}

impl SerialRobot {
    /// Number of joints (degrees of freedom).
    pub fn dof(&self) -> usize {
        self.links.len()
    }

    /// Total mass of the moving bodies [kg] (the base left out).
    pub fn moving_mass_kg(&self) -> f64 {
        self.links.iter().map(|l| l.inertial.mass_kg).sum()
    }

    /// Inserts `link` as the joint right after joint `after` (it becomes joint `after + 1`;
    /// the later joints shift by one), such that with the new joint at q = 0 the robot is
    /// the same robot:
    ///
    /// * the new joint's frame is `link.origin` in the (moved) frame of link `after`;
    /// * the body of link `after` moves outward onto the new link: its inertial, re-expressed
    ///   in the new link's frame (unchanged for the identity origin), becomes the new link's;
    ///   link `after` keeps `link.inertial` in its place (given in link `after`'s frame;
    ///   zero for a massless bearing joint, see [`Link::massless_revolute`]);
    /// * the next link's origin is re-expressed in the new link's frame (unchanged for the
    ///   identity origin).
    ///
    /// So for the paper's bearing flexibilities of joint i (joint i's rotation, then two
    /// small rotations about axes orthogonal to it, then body i): `insert_joint(i, bx)`
    /// then `insert_joint(i + 1, by)` with massless links; body i then rides after both.
    ///
    /// # Panics
    /// If `after >= self.dof()` (a programming error, not input: the index names an
    /// existing joint).
    pub fn insert_joint(&mut self, after: usize, mut link: Link) {
        assert!(
            after < self.dof(),
            "insert_joint: after = {after} but the robot has {} joints",
            self.dof()
        );
        let to_new = link.origin.inverse();
        let carried = self.links[after].inertial.transformed(&to_new);
        self.links[after].inertial = link.inertial;
        link.inertial = carried;
        if let Some(next) = self.links.get_mut(after + 1) {
            next.origin = to_new * next.origin;
        }
        self.links.insert(after + 1, link);
    }

    /// The frames of the links in the base frame at q [m, rad]: entry i is the pose of link
    /// i's frame (its joint frame moved by `q[i]`).
    pub fn forward_kinematics(&self, q: &[f64]) -> Result<Vec<Isometry3<f64>>, RobotError> {
        self.check_len("q", q)?;
        Ok(kinematics::link_poses(self, q).collect())
    }

    /// `Err(WrongLength)` unless `v` has one entry per joint.
    fn check_len(&self, what: &'static str, v: &[f64]) -> Result<(), RobotError> {
        if v.len() == self.dof() {
            Ok(())
        } else {
            Err(RobotError::WrongLength {
                what,
                got: v.len(),
                dof: self.dof(),
            })
        }
    }
}

/// Gravity's acceleration on Earth's surface, as Pinocchio's and URDF tools' default
/// [m/s^2].
pub const STANDARD_GRAVITY_MPS2: f64 = 9.81;
