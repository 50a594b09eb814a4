//! What a fit of the chain gives: the chain, its uncertainties and the fit's figures.

use crate::model::Chain;
use serde::{Deserialize, Serialize};

/// One-sigma standard deviations of a chain's parameters, same shape and units as
/// [`Chain`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainStd {
    /// Standard deviations of `J1..Jn` [kg m^2].
    pub inertia_kgm2: Vec<f64>,
    /// Standard deviations of `c1..c(n-1)` [N m/rad].
    pub stiffness_nm_per_rad: Vec<f64>,
    /// Standard deviations of `d1..d(n-1)` [N m s/rad].
    pub damping_nms_per_rad: Vec<f64>,
}

/// Result of [`super::fit::fit_chain`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ChainFit {
    /// The best chain found.
    pub chain: Chain,
    /// Its standard deviations.
    pub std: ChainStd,
    /// Covariance of the log-parameters `ln(J.., c.., d..)`, row-major, `P x P`.
    pub cov_log: Vec<f64>,
    /// Weighted cost `chi2 = sum of squared residuals` [1] at the optimum.
    pub cost: f64,
    /// `chi2 / dof` with `dof = 2 lines - P` (about 1 when the model explains the data down
    /// to the noise).
    pub chi2_per_dof: f64,
    /// Number of fitted parameters `P = 3n - 2`.
    pub params: usize,
    /// Number of lines fitted.
    pub lines_used: usize,
    /// Starts tried.
    pub starts: usize,
    /// Starts that reached the best cost (within 1e-6 relative).
    pub starts_converged: usize,
    /// Residual evaluations of the best start.
    pub iterations: usize,
    /// Residual evaluations of all starts together.
    pub evaluations_total: usize,
    /// RMS of the magnitude error `20 log10 |H_model/H_meas|` over the lines [dB].
    pub residual_rms_db: f64,
    /// RMS of the phase error `arg(H_model/H_meas)` over the lines [deg].
    pub residual_rms_deg: f64,
}
