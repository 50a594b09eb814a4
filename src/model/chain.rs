use serde::{Deserialize, Serialize};

/// Errors of the model layer.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ModelError {
    #[error("a chain needs at least one body, got {masses}")]
    NoBodies { masses: usize },
    #[error("{what} has {got} entries, expected {expected}")]
    Length { what: &'static str, expected: usize, got: usize },
    #[error("{what}[{index}] = {value} must be positive and finite")]
    NotPositive { what: &'static str, index: usize, value: f64 },
}

/// An n-mass chain: inertias `J1` (motor) .. `Jn`, spring `c_i` and viscous damper `d_i`
/// between bodies `i` and `i+1`. Free at both ends (no spring to ground).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Chain {
    /// `J1..Jn` [kg m^2], motor first.
    pub inertia_kgm2: Vec<f64>,
    /// `c1..c(n-1)` [N m/rad].
    pub stiffness_nm_per_rad: Vec<f64>,
    /// `d1..d(n-1)` [N m s/rad], in parallel with the springs.
    pub damping_nms_per_rad: Vec<f64>,
}
