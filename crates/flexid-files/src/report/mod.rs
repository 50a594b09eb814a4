//! Plain-text reports, as `flexid identify` and `flexid diagnose` print them.

pub mod analysis;
pub mod diagnosis;
pub mod trajectory;

pub use analysis::render_report;
