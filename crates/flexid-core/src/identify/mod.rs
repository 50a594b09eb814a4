//! Identification of the compliant chain from a measured FRF, each step visible:
//!
//! 1. [`inertia`]: total inertia from the low-frequency gain (paper step 1).
//! 2. [`detect`]: anti-resonance / resonance pairs on the measured FRF.
//! 3. [`paper`]: the paper's step-by-step algorithm (mismatch ratios, amplitude increments).
//! 4. [`exact`]: the exact inverse (the chain whose spectra are exactly the measured ones).
//! 5. [`fit`]: Levenberg-Marquardt refinement of all J, c, d on the weighted log-complex FRF
//!    error, with multi-start, standard deviations and automatic model order.
//!
//! [`ground_damper`] takes a significant damper from the motor to the ground out of the
//! measurement first, so that the chain identified is free, as the model is.
//!
//! Failures are reported as [`error::IdentifyError`].

/// Significance of a parameter that must differ from zero, or of a gap that must exceed
/// the noise [standard deviations]: the one-sided probability that noise alone reaches it
/// is 0.13 %. The project's one significance level.
pub const SIGNIFICANT_SIGMA: f64 = 3.0;

mod budget;
mod chain_fit;
pub mod detect;
pub mod error;
pub mod exact;
pub mod fit;
pub mod ground_damper;
pub mod inertia;
mod jet;
mod lines;
mod local_fit;
pub mod paper;
mod problem;

#[cfg(test)]
mod tests_fit;
#[cfg(test)]
mod tests_lm;
#[cfg(test)]
mod tests_paper;
