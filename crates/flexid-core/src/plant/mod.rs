//! The physics plant of the simulated servo drive: the compliant chain plus the effects the
//! identification does not model (current loop, friction with stiction, backlash, hardening
//! spring, fractional time delay, gravity, an extra mode, torque noise, encoder
//! quantisation), integrated on a fine fixed grid.
//!
//! * [`PlantSpec`] / [`Effects`]: what to simulate (serde, TOML `[chain]` + `[effects]`).
//! * [`PlantSim`]: the stateful simulator, one [`PlantSim::step`] per drive cycle,
//!   allocation-free, [`AxisSample`] per cycle.
//! * [`PlantFile`]: the plant files of `flexid simulate` / `flexid demo`
//!   (`[measurement]` and optional `[effects]`).
//!
//! Units are SI (kg m^2, N m, rad, rad/s, s, Hz). Body 1 is the motor.

mod dynamics;
mod error;
mod file;
pub mod physics;
mod sim;
mod spec;

pub use error::{PlantError, PlantFileError};
pub use file::{simulate_file_positions, Measurement, PlantFile, DEFAULT_PLANT, DEFAULT_SUBSTEPS};
pub use sim::{run, simulate_positions, AxisSample, PlantSim};
pub use spec::{
    Backlash, CurrentLoop, Effects, ExtraMode, Friction, Gravity, Hardening, PlantSpec, TimeDelay,
};

#[cfg(test)]
mod tests;
