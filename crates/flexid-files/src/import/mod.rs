//! Import of external measurement files (MAT v5, DaISy ASCII) into [`crate::recording::Recording`].
//!
//! * [`MatFile`]: a defensive MAT v5 reader (numeric arrays of any storage type as `f64`,
//!   complex parts, chars, nested 1x1 structs, zlib-compressed elements; cells, sparse
//!   matrices and MATLAB objects are kept as [`MatValue::Other`]).
//! * [`MatSpec`] + [`mat_to_recording`]: which variables are input (stored in the torque
//!   column, whatever its unit: the sidecar's `source` says) and output (one motion column),
//!   the sample rate, the period and the excited lines.
//! * [`daisy_to_recording`] / [`text_to_recording`]: whitespace-separated column files.
//! * [`preset`] / [`load_preset`]: the data sets of the shared data folder
//!   ([`shared_data_dir`], overridable by `FLEXID_SHARED_DATA`).
//!
//! Conventions: `time_s[k] = k / fs`; line `k` of a period of `P` samples is at `k fs / P` Hz.

mod daisy;
mod error;
mod lines;
mod mat5;
mod presets;
pub mod realisations;
mod spec;
#[cfg(test)]
mod tests;

pub use daisy::{daisy_to_recording, read_columns, text_to_recording};
pub use error::ImportError;
pub use lines::{excited_lines, mean_period};
pub use mat5::{dims_text, MatFile, MatValue};
pub use presets::{
    import_file, load_preset, preset, shared_data_dir, PRESET_NAMES, SHARED_DATA_ENV,
};
pub use spec::{mat_to_recording, signal, MatSpec, SAMPLE_PERIOD_NAMES, SAMPLE_RATE_NAMES};
