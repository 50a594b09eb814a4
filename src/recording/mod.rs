//! The recording format: `REC.csv` (one row per sample at a uniform rate) and the optional
//! `REC.json` sidecar.

mod types;
pub use types::{MotionSignal, Recording, Sidecar};
