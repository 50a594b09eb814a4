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
//! * [`daemon`]: `flexid daemon`, the identification service (HTTP API, results store, MQTT).
//! * [`plant`]: the physics plant of the simulated drive: the chain with unmodelled
//!   effects (friction, backlash, delay, current loop, ...), a fine-step simulator.
//! * [`rt`]: the real-time cycle thread (absolute-deadline pacing, `SCHED_FIFO`/`mlockall`
//!   when granted, timing statistics).
//! * [`sweep`]: one measurement on a drive in cyclic synchronous torque (any
//!   `flexid_canopen::CyclicDrive`): the run loop, its limits and how it ended.
//!
//! Conventions: SI units throughout (kg m^2, N m/rad, N m s/rad, rad, rad/s, Hz, s). The
//! plant is the motor mobility: motor torque -> motor angular velocity. Body 1 is the motor.

pub mod analysis;
pub mod cli;
pub mod daemon;
pub mod diagnose;
pub mod excitation;
pub mod frf;
pub mod identify;
pub mod import;
pub mod model;
pub mod plant;
pub mod plot;
pub mod recording;
pub mod rt;
pub mod sim;
pub mod sweep;

pub use num_complex::Complex64;
