//! The rigid part of the flexible manipulator linearised at one pose `q_r` (motor angles
//! at `q_r`, arm angles equal to them, bearing angles zero, everything at rest: the
//! paper's eq. (10)): the arm's mass matrix and gravity stiffness over its coordinates,
//! the motors, and the spring-damper pairs with the coordinates they join.
//!
//! The coordinates of the linear model are the arm's `n_a` (joint and bearing angles in
//! the kinematic chain's order) followed by the `N` motor angles, all on the arm side.

use super::springs::{Spring, SpringKind};
use super::ManipulatorError;
use nalgebra::DMatrix;
use serde::{Deserialize, Serialize};

/// A motor and its gear.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Motor {
    /// Rotor inertia on the motor side [kg m^2] (with the gear's input stage).
    pub rotor_inertia_kgm2: f64,
    /// Gear ratio `r` = motor angle / joint angle [-] (positive; the sign of a reversing
    /// gear is the joint axis's business).
    pub gear_ratio: f64,
}

impl Motor {
    /// The rotor inertia seen on the arm side, `J r^2` [kg m^2].
    pub fn arm_side_inertia_kgm2(&self) -> f64 {
        self.rotor_inertia_kgm2 * self.gear_ratio * self.gear_ratio
    }
}

/// The manipulator linearised at one pose, before its springs' values.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidPose {
    /// The arm's mass matrix `M_a(q_r)` over its coordinates [kg m^2] (`n_a x n_a`).
    pub arm_mass: DMatrix<f64>,
    /// The gravity stiffness `dg/dq` at `q_r` over the arm's coordinates [N m/rad].
    pub gravity_stiffness: DMatrix<f64>,
    /// The motors, joint by joint.
    pub motors: Vec<Motor>,
    /// The spring-damper pairs: one gear per joint, and the bearing pairs.
    pub springs: Vec<Spring>,
}

impl RigidPose {
    /// Validated: square matrices of one size, a gear pair for every motor and the
    /// springs' coordinates inside the arm's, no coordinate held by two pairs, positive
    /// inertias and gear ratios.
    pub fn new(
        arm_mass: DMatrix<f64>,
        gravity_stiffness: DMatrix<f64>,
        motors: Vec<Motor>,
        springs: Vec<Spring>,
    ) -> Result<Self, ManipulatorError> {
        use ManipulatorError as E;
        let na = arm_mass.nrows();
        for (what, m) in [
            ("arm_mass", &arm_mass),
            ("gravity_stiffness", &gravity_stiffness),
        ] {
            if m.nrows() != na || m.ncols() != na {
                return Err(E::Shape {
                    what,
                    rows: m.nrows(),
                    cols: m.ncols(),
                    expected: na,
                });
            }
        }
        for (index, m) in motors.iter().enumerate() {
            for (what, value) in [
                ("rotor_inertia_kgm2", m.rotor_inertia_kgm2),
                ("gear_ratio", m.gear_ratio),
            ] {
                if !(value.is_finite() && value > 0.0) {
                    return Err(E::NotPositive { what, index, value });
                }
            }
        }
        let mut held = vec![false; na];
        let mut geared = vec![false; motors.len()];
        for s in &springs {
            if s.arm_coord >= na || held[s.arm_coord] {
                return Err(E::Coordinate {
                    what: "springs",
                    index: s.arm_coord,
                    coords: na,
                });
            }
            held[s.arm_coord] = true;
            if let SpringKind::Gear { joint } = s.kind {
                if joint >= motors.len() || geared[joint] {
                    return Err(E::Coordinate {
                        what: "gear springs' joints",
                        index: joint,
                        coords: motors.len(),
                    });
                }
                geared[joint] = true;
            }
        }
        let gears = geared.iter().filter(|g| **g).count();
        if gears != motors.len() {
            return Err(E::Length {
                what: "gear springs",
                expected: motors.len(),
                got: gears,
            });
        }
        Ok(RigidPose {
            arm_mass,
            gravity_stiffness,
            motors,
            springs,
        })
    }

    /// Number of axes (motors) `N`.
    pub fn axes(&self) -> usize {
        self.motors.len()
    }

    /// Number of the arm's coordinates `n_a`.
    pub fn arm_coords(&self) -> usize {
        self.arm_mass.nrows()
    }

    /// Number of coordinates of the linear model, `n_a + N`.
    pub fn coords(&self) -> usize {
        self.arm_coords() + self.axes()
    }

    /// The coordinate of motor `i` in the linear model.
    pub fn motor_coord(&self, i: usize) -> usize {
        self.arm_coords() + i
    }

    /// The coordinates a pair joins: `(a, Some(m))` for a gear (its torque acts on the
    /// difference `q_a - q_m`), `(b, None)` for a bearing (to the ground of its link).
    pub fn spring_coords(&self, s: &Spring) -> (usize, Option<usize>) {
        match s.kind {
            SpringKind::Gear { joint } => (s.arm_coord, Some(self.motor_coord(joint))),
            SpringKind::Bearing { .. } => (s.arm_coord, None),
        }
    }
}
