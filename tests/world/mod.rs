//! An independent world for the diagnosis's benchmark (issue 15): axes that flexid's own
//! simulator never produced, measured the ways users measure, with effects inside the
//! diagnosis's library, pairs of them, and causes outside it. Shared by
//! `benches/diagnose_world.rs` and `tests/diagnose_world.rs`.
//!
//! * [`plant`]: what an axis is made of (plain data, written whole into `truth.json`);
//! * [`simulator`]: the fine-step RK4 simulation (no code shared with `flexid::plant`,
//!   `flexid::sim` or the diagnosis's `nlsim`); [`substeps`]: its sub-step count;
//! * [`analytic`]: the small-signal FRF from `(K - w^2 M + j w C)^-1` and the filters;
//! * [`plants`]: random nominal chains; [`excitation`]: the excitation kinds;
//! * [`effects`]: the library's effects; [`causes`]: causes outside it;
//! * [`visibility`]: how clearly a change shows against the line noise, sizing, and
//!   where a cause acts;
//! * [`cases`]: groups, seeds and the truth file; [`generate`]: a case from its seed;
//!   [`scoring`]: the groups' rules and tables.
#![allow(dead_code)]

pub mod analytic;
pub mod cases;
pub mod causes;
pub mod effects;
pub mod excitation;
pub mod generate;
pub mod plant;
pub mod plants;
pub mod scoring;
pub mod simulator;
pub mod substeps;
pub mod visibility;
