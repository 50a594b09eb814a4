//! A flexible manipulator built from its rigid links ([`SerialRobot`], from a URDF) and
//! its flexibility file ([`FlexFile`]): the bearing joints inserted after their joints as
//! massless revolute joints (the paper: "introducing `q_b` directly after the joint angles
//! `q_a` in the kinematic chain"), the gear and bearing pairs, the motors, the nominal
//! parameters; and, at any pose, the [`RigidPose`] the FRF and the identification use.

use super::flex_file::{FlexFile, PoseRole, PoseSpec};
use super::pose::{Motor, RigidPose};
use super::springs::{BearingAxis, Flexibilities, Spring, SpringKind};
use super::ManipulatorError;
use crate::robot::{Link, SerialRobot};
use nalgebra::{Unit, Vector3};

/// A flexible manipulator ready to be linearised.
#[derive(Debug, Clone, PartialEq)]
pub struct FlexibleRobot {
    /// A human-readable name.
    pub name: String,
    /// The arm with the bearing joints inserted: its coordinates are the linear model's
    /// arm coordinates.
    pub arm: SerialRobot,
    /// Per axis: the coordinate of its joint in `arm`.
    pub joint_coord: Vec<usize>,
    /// The motors, axis by axis.
    pub motors: Vec<Motor>,
    /// The spring-damper pairs in the paper's order (eq. (5)): the bearing pairs joint by
    /// joint, then the gears.
    pub springs: Vec<Spring>,
    /// The file's values, arm side, in the order of `springs`.
    pub nominal: Flexibilities,
    /// Whether the gravity stiffness acts on the bearing coordinates.
    pub gravity_on_bearings: bool,
    /// The poses of the file.
    pub poses: Vec<PoseSpec>,
}

impl FlexibleRobot {
    /// `rigid`'s joints must be the file's axes, in order and by name.
    pub fn new(rigid: SerialRobot, file: &FlexFile) -> Result<Self, ManipulatorError> {
        let bad = |what: &str, detail: String| ManipulatorError::Robot {
            what: what.to_string(),
            detail,
        };
        if rigid.dof() != file.axes.len() {
            return Err(bad(
                "axes",
                format!(
                    "the URDF has {} joints, the flexibility file {} axes",
                    rigid.dof(),
                    file.axes.len()
                ),
            ));
        }
        for (i, (link, axis)) in rigid.links.iter().zip(&file.axes).enumerate() {
            if link.joint != axis.joint {
                return Err(bad(
                    "axes",
                    format!(
                        "axis {} drives `{}`, but the URDF's joint {} is `{}`",
                        i + 1,
                        axis.joint,
                        i + 1,
                        link.joint
                    ),
                ));
            }
        }
        let mut arm = rigid;
        let mut joint_coord = Vec::with_capacity(file.axes.len());
        let mut bearings = Vec::new();
        let mut bearing_values = Vec::new();
        let mut coord = 0;
        for (i, a) in file.axes.iter().enumerate() {
            joint_coord.push(coord);
            let joint_axis = arm.links[coord].axis;
            for (k, b) in a.bearings.iter().enumerate() {
                let letter = BearingAxis::from(b.axis);
                let dir = unit(letter);
                if joint_axis.dot(&dir).abs() > 1e-9 {
                    return Err(bad(
                        "bearings",
                        format!(
                            "axis {} ({}): bearing axis {} is not orthogonal to the joint's axis {:?}",
                            i + 1,
                            a.joint,
                            letter.letter(),
                            joint_axis.as_ref()
                        ),
                    ));
                }
                let name = format!("{}_bearing_{}", a.joint, letter.letter());
                arm.insert_joint(coord + k, Link::massless_revolute(name, dir));
                bearings.push(Spring {
                    kind: SpringKind::Bearing {
                        joint: i,
                        axis: letter,
                    },
                    arm_coord: coord + k + 1,
                });
                let s = file.to_arm_side(i);
                bearing_values.push((b.stiffness * s, b.damping * s));
            }
            coord += 1 + a.bearings.len();
        }
        let gears = joint_coord.iter().enumerate().map(|(i, &c)| Spring {
            kind: SpringKind::Gear { joint: i },
            arm_coord: c,
        });
        let gear_values = file.axes.iter().enumerate().map(|(i, a)| {
            let s = file.to_arm_side(i);
            (a.gear.stiffness * s, a.gear.damping * s)
        });
        let springs: Vec<Spring> = bearings.into_iter().chain(gears).collect();
        let (k, c): (Vec<f64>, Vec<f64>) = bearing_values.into_iter().chain(gear_values).unzip();
        Ok(FlexibleRobot {
            name: file.name.clone().unwrap_or_else(|| "robot".into()),
            arm,
            joint_coord,
            motors: file
                .axes
                .iter()
                .map(|a| Motor {
                    rotor_inertia_kgm2: a.motor_inertia_kgm2,
                    gear_ratio: a.gear_ratio,
                })
                .collect(),
            springs,
            nominal: Flexibilities::new(k, c)?,
            gravity_on_bearings: file.conventions.gravity_on_bearings,
            poses: file.poses.clone(),
        })
    }

    /// Number of axes.
    pub fn axes(&self) -> usize {
        self.motors.len()
    }

    /// The parameters' names, stiffnesses then dampings (`k_b1x` .. `c_g6`).
    pub fn parameter_names(&self) -> Vec<String> {
        let k = self.springs.iter().map(|s| s.name('k'));
        k.chain(self.springs.iter().map(|s| s.name('c'))).collect()
    }

    /// The model linearised at the joint angles `q_rad` [rad] (bearing angles zero, at
    /// rest: the paper's eq. (10)).
    pub fn pose(&self, q_rad: &[f64]) -> Result<RigidPose, ManipulatorError> {
        if q_rad.len() != self.axes() {
            return Err(ManipulatorError::Length {
                what: "joint angles",
                expected: self.axes(),
                got: q_rad.len(),
            });
        }
        let mut q = vec![0.0; self.arm.dof()];
        for (&c, &qi) in self.joint_coord.iter().zip(q_rad) {
            q[c] = qi;
        }
        let robot = |e: crate::robot::RobotError| ManipulatorError::Robot {
            what: "dynamics".into(),
            detail: e.to_string(),
        };
        let m = self.arm.mass_matrix(&q).map_err(robot)?;
        let mut k = self.arm.gravity_stiffness(&q).map_err(robot)?;
        if !self.gravity_on_bearings {
            for s in &self.springs {
                if let SpringKind::Bearing { .. } = s.kind {
                    k.row_mut(s.arm_coord).fill(0.0);
                    k.column_mut(s.arm_coord).fill(0.0);
                }
            }
        }
        RigidPose::new(m, k, self.motors.clone(), self.springs.clone())
    }

    /// The file's poses of `role`, each with its joint angles [rad].
    pub fn poses_of(&self, role: PoseRole) -> Vec<(String, Vec<f64>)> {
        self.poses
            .iter()
            .filter(|p| p.role == role)
            .map(|p| {
                (
                    p.name.clone(),
                    p.q_deg.iter().map(|d| d.to_radians()).collect(),
                )
            })
            .collect()
    }
}

/// The unit vector of a bearing axis letter.
fn unit(a: BearingAxis) -> Unit<Vector3<f64>> {
    match a {
        BearingAxis::X => Vector3::x_axis(),
        BearingAxis::Y => Vector3::y_axis(),
        BearingAxis::Z => Vector3::z_axis(),
    }
}

#[cfg(test)]
mod tests;
