//! Plant files (TOML): the chain and how it is measured, for `flexid simulate` and the demo.
//! The parsing lives in [`crate::plant`]; re-exported here for the command line's users.

pub use crate::plant::{Measurement, PlantFile, DEFAULT_PLANT};
