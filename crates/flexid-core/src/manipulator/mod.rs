//! The flexible manipulator of issue 17 (after `../shared/papers/001_2e9448849e905e58.txt`):
//! rigid links joined by a gear spring-damper in every joint and, after chosen joints,
//! a pair of orthogonal bearing spring-dampers; motors with rotor inertia and gear ratio.
//! Linearised at a pose with everything at rest, it gives the model FRF matrix from the
//! motor torques to the motor speeds, which the identification fits to the measured one.
//!
//! The pieces, bottom up:
//! * [`springs`]: the spring-damper pairs (gear, bearing), their names and the parameter
//!   vector `theta` of the paper's eq. (5).
//! * [`pose`]: the rigid part of the model linearised at one pose (the arm's mass matrix
//!   and gravity stiffness over its coordinates, the motors).
//! * [`flex_file`], [`flexible`]: the flexibility file beside a robot's URDF and the
//!   flexible robot built from both (bearing joints inserted), linearised at any pose.
//! * [`clu`]: a small complex LU in place (the full model's solve per line, no
//!   allocation); [`augmented`]: the same elimination on `[A | B]` with real and imaginary
//!   parts apart (the motor-eliminated model's solve per line, vectorised).
//! * [`cost`]: the paper's identification cost (eqs. (12), (15)): per-element bands,
//!   weights (the paper's, or the measured variance's), the `p`-norm, the symmetric
//!   reduction.
//! * [`identify`]: the multi-start local fit of `theta` over several poses.
//! * [`frf`]: the model FRF matrix `G(jw, theta)` and its derivatives with respect to the
//!   logarithms of the parameters.
//!
//! Conventions (the robot file states them too, `robots/README.md`): every stiffness,
//! damping, inertia and angle of the mechanics is on the **arm side** of the gear; the
//! motor torque `u` [N m] and the motor speed `v` [rad/s] are on the **motor side**
//! (`q_motor = r q_arm_side`, torque `r u` on the arm side). The gravity stiffness is
//! `dg/dq` of the arm's generalised gravity torque (`tau = M qdd + C qd + g(q)`), which
//! enters the linearised stiffness matrix with its sign (negative where gravity pulls the
//! arm away from the pose: open-loop unstable). Bearing coordinates carry gravity too (they
//! are joints of the arm's kinematic chain, held at zero at the pose).

pub mod augmented;
pub mod clu;
pub mod cost;
pub mod flex_file;
pub mod flexible;
pub mod frf;
pub mod identify;
pub mod measure;
pub mod pose;
pub mod reference;
pub mod sampled;
pub mod springs;
#[cfg(test)]
mod tests_support;

pub use cost::{Cost, CostSpec, PoseMeasurement, Weighting};
pub use flex_file::{FlexFile, PoseRole};
pub use flexible::FlexibleRobot;
pub use frf::{FrfPlan, ModelFrf};
pub use identify::{identify, FrfForm, Identification, IdentifyOptions, StartOutcome};
pub use pose::{Motor, RigidPose};
pub use sampled::{PositionLoop, SampledPose};
pub use springs::{Flexibilities, Spring, SpringKind};

/// Errors of the manipulator model.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ManipulatorError {
    #[error("{what} has {got} entries, expected {expected}")]
    Length {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    #[error("{what} is {rows} x {cols}, expected {expected} x {expected}")]
    Shape {
        what: &'static str,
        rows: usize,
        cols: usize,
        expected: usize,
    },
    #[error("{what}[{index}] = {value} must be positive and finite")]
    NotPositive {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error("{what}[{index}] = {value} must be non-negative and finite")]
    Negative {
        what: &'static str,
        index: usize,
        value: f64,
    },
    #[error(
        "coordinate {index} of {what} is outside the arm's {coords} coordinates (or used twice)"
    )]
    Coordinate {
        what: &'static str,
        index: usize,
        coords: usize,
    },
    #[error("the robot's {what}: {detail}")]
    Robot { what: String, detail: String },
    #[error("the simulated measurement: {detail}")]
    Measurement { detail: String },
    #[error("none of the {starts} starts converged (the first: {first_failure})")]
    NoStartConverged {
        starts: usize,
        first_failure: String,
    },
    #[error("the dynamic stiffness at {f_hz} Hz is singular (a mode without damping exactly on the line)")]
    Singular { f_hz: f64 },
}
