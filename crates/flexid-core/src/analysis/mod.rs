//! The whole analysis of one recording, each step kept for the report:
//! FRF estimation -> total inertia -> AR/R pairs -> the paper's step-by-step algorithm ->
//! the exact inverse -> Levenberg-Marquardt refinement with automatic model order.
//!
//! [`analyze`] is what `flexid identify`, `flexid bode`, the daemon and the tests call.

mod estimate;
mod json;
mod pipeline;
mod summary;
mod time_cap;

#[cfg(test)]
mod tests_ground_damper;
#[cfg(test)]
mod tests_sparse_lines;
#[cfg(test)]
mod tests_support;

pub use estimate::{
    estimate_frf, estimate_motion, estimate_torque_path, motion_frf_kind, periodic_excitation,
    reads_steady_state, single_sweep, EstimatedFrf, ResponseEstimate,
};
pub use json::to_json;
pub use pipeline::{
    analyze, analyze_estimate, measure_only, Analysis, AnalysisError, AnalysisOptions,
    GroundDamperOut,
};
pub use summary::{Coupling, ModelSummary};
pub use time_cap::TimeCap;
