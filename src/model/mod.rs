//! The compliant n-mass chain: body 1 (motor) .. body n joined by springs and dampers.

mod chain;
pub use chain::{Chain, ModelError};
