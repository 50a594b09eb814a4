//! Made-up manipulators for the module's tests.

use super::pose::{Motor, RigidPose};
use super::springs::{BearingAxis, Flexibilities, Spring, SpringKind};
use nalgebra::DMatrix;
use rand::{Rng, SeedableRng};

/// A made-up 2-axis arm with a bearing pair after joint 1: arm coordinates
/// `[q1, b1x, b1y, q2]`, a random symmetric positive definite mass matrix and a random
/// symmetric gravity stiffness of either sign; realistic sizes (arm side).
pub fn two_axis_pose(seed: u64) -> (RigidPose, Flexibilities) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let na = 4;
    let l = DMatrix::from_fn(na, na, |_, _| rng.random_range(-1.0..1.0));
    let arm_mass = &l * l.transpose() * 20.0 + DMatrix::identity(na, na) * 5.0;
    let g = DMatrix::from_fn(na, na, |_, _| rng.random_range(-2e3..2e3));
    let gravity_stiffness = (&g + g.transpose()) * 0.5;
    let motors = vec![
        Motor {
            rotor_inertia_kgm2: 4e-4,
            gear_ratio: 120.0,
        },
        Motor {
            rotor_inertia_kgm2: 2e-4,
            gear_ratio: 100.0,
        },
    ];
    let springs = vec![
        Spring {
            kind: SpringKind::Bearing {
                joint: 0,
                axis: BearingAxis::X,
            },
            arm_coord: 1,
        },
        Spring {
            kind: SpringKind::Bearing {
                joint: 0,
                axis: BearingAxis::Y,
            },
            arm_coord: 2,
        },
        Spring {
            kind: SpringKind::Gear { joint: 0 },
            arm_coord: 0,
        },
        Spring {
            kind: SpringKind::Gear { joint: 1 },
            arm_coord: 3,
        },
    ];
    let pose = RigidPose::new(arm_mass, gravity_stiffness, motors, springs).unwrap();
    let theta =
        Flexibilities::new(vec![8e5, 1.2e6, 3e5, 2e5], vec![150.0, 300.0, 90.0, 40.0]).unwrap();
    (pose, theta)
}
