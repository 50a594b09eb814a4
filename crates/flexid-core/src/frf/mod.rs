//! Frequency-response estimation.
//!
//! The shared result type is [`Frf`]: one complex value per frequency line with the
//! variance of that value (so that every Bode point carries an uncertainty) and, where the
//! estimator provides it, the coherence.
//!
//! * [`PeriodicEstimator`] / [`estimate_periodic`]: multisine excitation, per-line
//!   averaging over steady periods with the errors-in-variables variance, levels at
//!   non-excited lines ([`NonExcitedLevels`]) to detect nonlinear distortion; a velocity
//!   response is freed of the ramp of a constant acceleration (`ramp.rs`).
//! * [`estimate_realisations`]: several realisations of a multisine, one period each:
//!   the best linear approximation over them, its variance from their spread (noise and
//!   stochastic nonlinear distortion) and the noise alone from their lead-ins.
//! * [`estimate_stepped`]: stepped sine, one line per dwell block by the periodic
//!   estimator.
//! * [`estimate_lpm`]: one non-periodic record (a single sweep), the local polynomial
//!   method on the whole record's DFT, with the transient and a noise variance per line;
//!   [`LpmPlan`]: the same estimate planned for many responses to one input.
//! * [`MimoEstimator`]: the `N x N` FRF matrix of coupled axes from orthogonal multisine
//!   experiments (`G = Y U^+` per line), with the variance of every element and the
//!   symmetrised estimate ([`MimoFrf`]).
//! * [`WelchH1`] / [`welch_h1`]: arbitrary excitation, Welch-averaged H1 with coherence.
//! * [`differenced_velocity`], [`difference_quotient_response`], [`remove_linear_trend`]:
//!   turning drifting encoder position into something an FRF can be taken from.
//!
//! All estimators plan their FFT once and process streamed chunks without allocating.

mod error;
pub mod lpm;
mod lpm_plan;
mod mimo;
mod mimo_record;
mod periodic;
mod plan_cache;
pub mod quantisation;
pub mod quantisation_correlation;
pub mod quantisation_spectrum;
mod ramp;
mod realisations;
mod stepped;
mod support;
#[cfg(test)]
pub(crate) mod test_rng;
#[cfg(test)]
mod testutil;
mod types;
mod velocity;
mod welch;

pub use error::FrfError;
pub use lpm::{estimate_lpm, estimate_lpm_with_floor, lpm_dof};
pub use lpm_plan::{LpmPlan, LpmScratch};
pub use mimo::{MimoError, MimoEstimator, MimoFrf, MAX_INPUT_CONDITION};
pub use mimo_record::estimate_from_positions;
pub use periodic::{
    estimate_periodic, NonExcitedLevels, PeriodicEstimator, DEFAULT_INFER_THRESHOLD,
};
pub use realisations::{estimate_realisations, RealisationsEstimate};
pub use stepped::estimate_stepped;
pub use support::{supported_band, SupportedBand};
pub use types::{Frf, FrfKind};
pub use velocity::{
    difference_quotient_response, differenced_velocity, differenced_velocity_into,
    remove_linear_trend,
};
pub use welch::{welch_h1, WelchH1, Window};
