//! flexid-core: the pure computation of flexid, identification of compliant servo axes.
//!
//! Plain code over slices and the recording's types: no file, socket or terminal I/O, no
//! async runtime, no plotting. The same input and seed give the same output. The layers,
//! bottom up:
//!
//! * [`excitation`]: torque excitation signals (multisines, swept and stepped sines) and
//!   their description, written beside every recording.
//! * [`frf`]: frequency-response estimation (periodic per-line averaging with variance,
//!   Welch H1 with coherence, streaming updates, velocity from encoder position).
//! * [`model`]: the compliant n-mass chain (analytic FRF, state space, exact ZOH-sampled
//!   FRF, discrete-time simulation).
//! * [`identify`]: total inertia, AR/R pair detection, the paper's step-by-step algorithm,
//!   the exact (Cauer) inverse and the Levenberg-Marquardt refinement.
//! * [`lsq`]: the one Levenberg-Marquardt solver, shared by identification and diagnosis.
//! * [`recording`]: the recording's types, its CSV/JSON parser over any reader and its
//!   formatter over any writer (`flexid-files` opens and replaces the files).
//! * [`analysis`]: the measured FRF of a recording and the identified chain, with the
//!   report's numbers.
//! * [`diagnose`]: the sim-to-real gap: where model and measurement part and which
//!   unmodelled effect explains it.
//! * [`sim`]: simulated recordings of chains (exact ZOH sampling, noise, quantisation).
//! * [`manipulator`]: the flexible manipulator of the multi-axis identification (gear and
//!   bearing spring-dampers on rigid links), linearised at a pose, and its FRF matrix.
//! * [`plant`]: the physics plant of the simulated drive: the chain with unmodelled
//!   effects (friction, backlash, delay, current loop, ...), a fine-step simulator, and
//!   the plant file's types and parser.
//! * [`robot`]: rigid-body dynamics of a serial robot arm (URDF import, M(q), g(q), the
//!   analytic gravity stiffness dg/dq, inverse dynamics), for the multi-axis model.
//!
//! Conventions: SI units throughout (kg m^2, N m/rad, N m s/rad, rad, rad/s, Hz, s). The
//! plant is the motor mobility: motor torque -> motor angular velocity. Body 1 is the motor.

pub mod analysis;
pub mod diagnose;
pub mod excitation;
pub mod frf;
pub mod identify;
pub mod lsq;
pub mod manipulator;
pub mod model;
pub mod plant;
pub mod recording;
pub mod robot;
pub mod sim;

pub use num_complex::Complex64;
