//! flexid-files: what flexid reads from and writes to disk, and its pictures.
//!
//! * [`recording`]: the `REC.csv` + `REC.json` pair on disk (read, written atomically);
//!   re-exports the core's recording types and parser so one path serves both.
//! * [`import`]: MAT v5 and DaISy files (and the presets for `../shared/data`) into
//!   recordings.
//! * [`plot`]: Bode and gap plots as SVG (plotters).
//! * [`report`]: the plain-text reports of an identification and of a diagnosis.
//! * [`plant`]: plant files read from disk.
//! * [`bounded_read`]: small text files (plant files, configurations) read with a bound.

pub mod bounded_read;
pub mod import;
pub mod plant;
pub mod plot;
pub mod recording;
pub mod report;
