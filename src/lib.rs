//! flexid: identification of compliant servo axes.
//!
//! The library is plain code over slices, free of I/O except in [`recording`] (files) and
//! [`plot`] (SVG output). The layers, bottom up:
//!
//! * [`excitation`]: torque excitation signals (multisines, swept and stepped sines) and
//!   their description, written beside every recording.
//! * [`frf`]: frequency-response estimation (periodic per-line averaging with variance,
//!   Welch H1 with coherence, streaming updates, velocity from encoder position).
//! * [`model`]: the compliant n-mass chain (analytic FRF, state space, exact ZOH-sampled
//!   FRF, discrete-time simulation).
//! * [`identify`]: total inertia, AR/R pair detection, the paper's step-by-step algorithm,
//!   the exact (Cauer) inverse and the Levenberg-Marquardt refinement.
//! * [`recording`]: the `REC.csv` + `REC.json` recording format.
//! * [`plot`]: Bode plots as SVG.
//! * [`import`]: MAT v5 and DaISy files into recordings.
//! * [`sim`]: simulated recordings of chains (exact ZOH sampling, noise, quantisation).
//! * [`plant`]: the physics plant of the simulated drive: the chain with unmodelled
//!   effects (friction, backlash, delay, current loop, ...), a fine-step simulator.
//!
//! Conventions: SI units throughout (kg m^2, N m/rad, N m s/rad, rad, rad/s, Hz, s). The
//! plant is the motor mobility: motor torque -> motor angular velocity. Body 1 is the motor.

pub mod analysis;
pub mod cli;
pub mod diagnose;
pub mod excitation;
pub mod frf;
pub mod identify;
pub mod import;
pub mod model;
pub mod plant;
pub mod plot;
pub mod recording;
pub mod sim;

pub use num_complex::Complex64;
