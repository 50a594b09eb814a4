//! Frequency-response estimation.
//!
//! The shared result type is [`Frf`]: one complex value per frequency line with the
//! variance of that value (so that every Bode point carries an uncertainty) and, where the
//! estimator provides it, the coherence.

mod types;
pub use types::{Frf, FrfKind};
