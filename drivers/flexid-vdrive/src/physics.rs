//! The physics behind the drive: the core's [`Physics`] trait and its implementations
//! (the exact linear chain, the nonlinear plant, a disturbance torque), shared with the
//! sweep's CAN-free simulated drive so that both step the same models.

pub use flexid_core::plant::physics::{
    LinearChain, Physics, PhysicsError, PlantSimPhysics, TorqueNoise,
};
pub use flexid_core::plant::AxisSample;
