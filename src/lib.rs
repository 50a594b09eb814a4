//! flexid: identification of compliant servo axes. This crate is the `flexid` command line
//! ([`cli`]); the work is done by the workspace's crates, re-exported here under the paths
//! the command line, the tests and the benchmarks use:
//!
//! * `flexid-core` (pure computation, no I/O): [`excitation`], [`frf`], [`model`],
//!   [`identify`], [`analysis`], [`diagnose`], [`plant`], [`sim`], and the recording's types;
//! * `flexid-files` (disk and pictures): [`recording`] (the core's types plus the file
//!   pair on disk), [`import`], [`plot`], [`report`];
//! * `flexid-rt` ([`rt`]): clock, pacer and the real-time cycle thread;
//! * `flexid-sweep` ([`sweep`]): the one sweep loop over a drive;
//! * `flexid-daemon` ([`daemon`]): the identification service.
//!
//! docs/architecture.md draws the crates and their direction of dependency.

pub mod cli;

pub use flexid_core::{analysis, diagnose, excitation, frf, identify, model, plant, sim};
pub use flexid_daemon as daemon;
/// Plant files read from disk (`flexid_files::plant`).
pub use flexid_files::plant as plant_file;
pub use flexid_files::{import, plot, recording, report};
pub use flexid_rt as rt;
pub use flexid_sweep as sweep;

pub use flexid_core::Complex64;
