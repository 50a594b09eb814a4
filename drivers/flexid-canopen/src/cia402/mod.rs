//! CiA 402 (IEC 61800-7-201) drive profile: the power state machine seen from both sides,
//! and the modes of operation. Hand-written: canopen-rs has no CiA 402.
//!
//! - [`state`]: the statusword and its eight states (the mask/value table of the standard);
//! - [`controlword`]: the controlword commands;
//! - [`planner`]: the master's half, [`next_controlword`] from the state seen to a target;
//! - [`device`]: the drive's half, [`device_transition`], for a simulated drive to reuse;
//! - [`modes`]: modes of operation (0x6060/0x6061) and supported modes (0x6502).

pub mod controlword;
pub mod device;
pub mod modes;
pub mod planner;
pub mod state;

pub use controlword::Controlword;
pub use device::device_transition;
pub use modes::{ModeOfOperation, SupportedModes};
pub use planner::{next_controlword, Target};
pub use state::{State, Statusword};
