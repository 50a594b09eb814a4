//! The compliant n-mass chain: body 1 (motor) .. body n joined by springs and dampers.
//!
//! * [`Chain`]: parameters, the analytic motor mobility, undamped resonance and
//!   anti-resonance spectra.
//! * [`StateSpace`]: continuous state space and its exact ZOH discretisation (matrix
//!   exponential), used for simulation.
//! * [`SampledChain`]: the exact FRF of the sampled measurement (ZOH torque, backward
//!   differenced position), the footing on which models and measurements are compared.

mod chain;
pub(crate) mod eigen;
mod sampled;
mod state_space;
pub mod truth;
pub use chain::{Chain, ModelError};
pub use sampled::SampledChain;
pub use state_space::{DiscreteStateSpace, StateSpace};
pub use truth::ParamError;

#[cfg(test)]
mod tests;
