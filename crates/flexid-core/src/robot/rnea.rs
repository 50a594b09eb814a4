//! Inverse dynamics by recursive Newton-Euler, in the base frame.
//!
//! Outward: each body's angular velocity and acceleration and its frame origin's linear
//! acceleration from its parent's (gravity entered as an upward acceleration of the base,
//! `-g0`), then the force and moment that accelerate the body (Newton and Euler at the
//! centre of mass). Inward: the wrench each joint transmits is its body's plus the next
//! joint's; the joint torque is the moment about the axis (revolute) or the force along it
//! (prismatic).

use nalgebra::{DVector, Vector3};

use super::kinematics::{bodies_at, BodyAt};
use super::{JointKind, RobotError, SerialRobot};

/// The motion of a body's frame, base axes.
#[derive(Debug, Clone, Copy)]
struct Motion {
    /// Angular velocity [rad/s].
    omega: Vector3<f64>,
    /// Angular acceleration [rad/s^2].
    omega_dot: Vector3<f64>,
    /// Linear acceleration of the frame's origin [m/s^2], gravity included as `-g0`.
    accel: Vector3<f64>,
    /// The frame's origin [m].
    origin: Vector3<f64>,
}

/// The force [N] and moment about the centre of mass [N m] that accelerate a body.
#[derive(Debug, Clone, Copy)]
struct Wrench {
    force: Vector3<f64>,
    moment_at_com: Vector3<f64>,
}

impl SerialRobot {
    /// The joint torques [N m] or forces [N] that produce joint accelerations `qdd`
    /// [rad/s^2 or m/s^2] at pose `q` [rad or m] and rates `qd` [rad/s or m/s]:
    /// `tau = M(q) qdd + C(q, qd) qd + g(q)` (Pinocchio's `rnea`).
    pub fn inverse_dynamics(
        &self,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
    ) -> Result<DVector<f64>, RobotError> {
        self.check_len("q", q)?;
        self.check_len("qd", qd)?;
        self.check_len("qdd", qdd)?;
        let bodies = bodies_at(self, q);
        let wrenches = self.outward(&bodies, qd, qdd);
        Ok(inward(&bodies, &wrenches))
    }

    /// The outward pass: each body's accelerating wrench.
    fn outward(&self, bodies: &[BodyAt], qd: &[f64], qdd: &[f64]) -> Vec<Wrench> {
        let base = Motion {
            omega: Vector3::zeros(),
            omega_dot: Vector3::zeros(),
            accel: -self.gravity_mps2,
            origin: Vector3::zeros(),
        };
        let mut out = Vec::with_capacity(bodies.len());
        out.extend(
            bodies
                .iter()
                .zip(qd.iter().zip(qdd))
                .scan(base, |parent, (body, (&v, &a))| {
                    *parent = child_motion(parent, body, v, a);
                    Some(accelerating_wrench(parent, body))
                }),
        );
        out
    }
}

/// The motion of `body`'s frame from its parent's and its joint's rate `v` and
/// acceleration `a`.
fn child_motion(parent: &Motion, body: &BodyAt, v: f64, a: f64) -> Motion {
    let (w, wd) = (parent.omega, parent.omega_dot);
    let d = body.origin - parent.origin;
    // the child's origin as a point of the parent body
    let carried = parent.accel + wd.cross(&d) + w.cross(&w.cross(&d));
    let z = body.axis;
    match body.kind {
        JointKind::Revolute => Motion {
            omega: w + z * v,
            omega_dot: wd + z * a + w.cross(&z) * v,
            accel: carried,
            origin: body.origin,
        },
        // sliding along z, fixed in the parent: Coriolis and relative acceleration
        JointKind::Prismatic => Motion {
            omega: w,
            omega_dot: wd,
            accel: carried + w.cross(&z) * (2.0 * v) + z * a,
            origin: body.origin,
        },
    }
}

/// Newton and Euler at the centre of mass: `F = m a_c`, `N = I wd + w x I w`.
fn accelerating_wrench(motion: &Motion, body: &BodyAt) -> Wrench {
    let (w, wd) = (motion.omega, motion.omega_dot);
    let r = body.com - motion.origin;
    let a_com = motion.accel + wd.cross(&r) + w.cross(&w.cross(&r));
    Wrench {
        force: a_com * body.mass,
        moment_at_com: body.inertia * wd + w.cross(&(body.inertia * w)),
    }
}

/// The inward pass: the wrench each joint transmits, projected on its axis.
fn inward(bodies: &[BodyAt], wrenches: &[Wrench]) -> DVector<f64> {
    let mut tau = DVector::zeros(bodies.len());
    // force [N] and moment [N m] transmitted by the next joint, about `at`
    let (mut force, mut moment, mut at) = (Vector3::zeros(), Vector3::zeros(), Vector3::zeros());
    for (i, (body, w)) in bodies.iter().zip(wrenches).enumerate().rev() {
        moment += (at - body.origin).cross(&force)
            + w.moment_at_com
            + (body.com - body.origin).cross(&w.force);
        force += w.force;
        at = body.origin;
        tau[i] = match body.kind {
            JointKind::Revolute => body.axis.dot(&moment),
            JointKind::Prismatic => body.axis.dot(&force),
        };
    }
    tau
}
