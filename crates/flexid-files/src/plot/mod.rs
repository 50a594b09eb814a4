//! Bode plots as SVG, for commissioning technicians.
//!
//! [`BodePlot`] draws a measured [`flexid_core::frf::Frf`] with its uncertainty band, optional
//! model curves and resonance / anti-resonance markers in stacked magnitude, phase and
//! (when available) coherence panels over a logarithmic frequency axis; [`bode_matrix_svg`]
//! the N x N magnitude matrix of a multi-axis measurement with its model.

mod axes;
mod bode;
mod error;
mod gap;
mod matrix;
mod series;
mod trajectory;
mod units;

pub use bode::BodePlot;
pub use error::PlotError;
pub use gap::gap_svg;
pub use matrix::{bode_matrix_svg, BodeMatrix};
pub use series::{BAND_FLOOR_RELATIVE, PHASE_BAND_MAX_DEG};
pub use trajectory::trajectory_svg;
pub use units::{frf_unit, magnitude_label};

#[cfg(test)]
mod tests;
