//! Excitation signals in torque units [N m] and their description.
//!
//! * [`MultisineDesign`] -> [`Multisine`]: periodic multisines (Schroeder, random and odd
//!   random phases with detection lines), crest-factor reduction, peak and RMS limits.
//! * [`ChirpDesign`] -> [`Chirp`]: logarithmic swept sine with taper and amplitude shaping.
//! * [`OrthogonalMultisineDesign`] -> [`OrthogonalMultisine`]: orthogonal random-phase
//!   multisines over `N` axes (blocks of `N` experiments phased by the DFT matrix) for the
//!   `N x N` FRF matrix ([`crate::frf::MimoEstimator`]).
//! * [`SteppedSineDesign`] -> [`SteppedSine`]: exactly periodic dwell blocks per frequency.
//! * [`rms`], [`crest_factor`], [`peak_abs`]: signal statistics.
//!
//! Every generator returns [`ExcitationError`] on bad input instead of panicking, and its
//! output gives the [`ExcitationInfo`] to write beside the recording.

mod chirp;
mod description;
mod error;
mod lines;
mod multisine;
mod orthogonal;
mod phases;
mod stats;
mod stepped;
mod synth;
#[cfg(test)]
mod test_util;

pub use chirp::{Chirp, ChirpDesign};
pub use description::{ExcitationInfo, ExcitationKind, Realisation};
pub use error::ExcitationError;
pub use lines::{band_lines, MIN_PERIOD_SAMPLES};
pub use multisine::{AmplitudeShape, Multisine, MultisineDesign, PhaseDesign};
pub use orthogonal::{OrthogonalMultisine, OrthogonalMultisineDesign, ORTHOGONAL_DESIGN_NAME};
pub use stats::{crest_factor, peak_abs, rms, MAX_SIGNAL_SAMPLES};
pub use stepped::{SteppedBlock, SteppedSine, SteppedSineDesign};
