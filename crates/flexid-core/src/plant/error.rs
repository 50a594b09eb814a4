//! Errors of the plant layer.

use crate::model::ModelError;

/// Why a [`super::PlantSpec`] or a [`super::PlantSim`] could not be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum PlantError {
    /// The chain itself is invalid (lengths, signs).
    #[error("[chain] {0}")]
    Chain(#[from] ModelError),
    /// A parameter is out of its range (non-finite, negative, zero where positive is needed).
    #[error("{what} = {value} {requirement}")]
    Parameter {
        /// The parameter, as `section.key`.
        what: &'static str,
        /// The offending value.
        value: f64,
        /// What it must be, e.g. "must be positive and finite".
        requirement: &'static str,
    },
    /// An effect names a coupling the (extended) chain does not have.
    #[error("[effects.{effect}] coupling = {index}, but the chain has {couplings} coupling(s) (0-based: 0 joins the motor and body 2)")]
    Coupling {
        /// The effect's section name.
        effect: &'static str,
        /// The 0-based coupling index given.
        index: usize,
        /// How many couplings the chain (with the extra mode) has.
        couplings: usize,
    },
    /// The cycle rate [Hz] is not positive and finite.
    #[error("cycle rate {cycle_hz} Hz must be positive and finite")]
    CycleRate {
        /// The rate given [Hz].
        cycle_hz: f64,
    },
    /// Zero sub-steps per cycle.
    #[error("substeps must be at least 1")]
    Substeps,
    /// The fixed integration step is too long for the fastest dynamics (RK4 would diverge).
    #[error("integration step {step_s:e} s is too long for the fastest eigenvalue |lambda| = {lambda_max:.4e} 1/s (|lambda| h = {lh:.2} > {limit}); raise substeps or the cycle rate")]
    Unstable {
        /// The longest sub-step [s].
        step_s: f64,
        /// The largest eigenvalue magnitude of the linearised plant [1/s].
        lambda_max: f64,
        /// `lambda_max * step_s` [-].
        lh: f64,
        /// The limit used for `lambda_max * step_s` [-].
        limit: f64,
    },
    /// A plant text could not be parsed (TOML syntax or schema).
    #[error("{0}")]
    Parse(String),
}

/// Why a plant file's text was refused; every variant names the file (`origin`).
#[derive(Debug, thiserror::Error)]
pub enum PlantFileError {
    /// Not TOML, or not the plant file's shape (unknown keys, wrong types).
    #[error("{origin}: {source}")]
    Syntax {
        /// The file's name (or "embedded default plant").
        origin: String,
        /// What the TOML reader said.
        source: toml::de::Error,
    },
    /// The `[chain]` section is invalid.
    #[error("{origin}: [chain] {source}")]
    Chain {
        /// The file's name.
        origin: String,
        /// What is wrong with the chain.
        source: ModelError,
    },
    /// An effect or the measurement section is out of range.
    #[error("{origin}: {source}")]
    Plant {
        /// The file's name.
        origin: String,
        /// What is wrong.
        source: PlantError,
    },
    /// `[measurement] substeps = 0`.
    #[error("{origin}: [measurement] substeps must be at least 1")]
    Substeps {
        /// The file's name.
        origin: String,
    },
    /// A `[measurement]` number out of its range (issue 16: `sample_rate_hz = 0` was
    /// accepted and refused later without naming the file or the key).
    #[error("{origin}: [measurement] {key} = {value} {requirement}")]
    Measurement {
        /// The file's name.
        origin: String,
        /// The key.
        key: &'static str,
        /// The value given.
        value: f64,
        /// What it must be.
        requirement: &'static str,
    },
}
