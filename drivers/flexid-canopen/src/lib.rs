//! The CANopen master and CiA 402 drive control of flexid.
//!
//! Puts one CiA 402 servo drive into cyclic synchronous torque mode over CANopen,
//! streams torque set-points synchronised to SYNC and reads position, velocity and
//! torque back every cycle, in SI units.
//!
//! | module | what |
//! |---|---|
//! | [`cob`] | COB-IDs of the predefined connection set, frame classification |
//! | [`objects`] | object dictionary indices (CiA 301, CiA 402) |
//! | [`sdo`] | blocking SDO client over canopen-rs's sans-I/O `SdoClient`, abort texts |
//! | [`cia402`] | statusword/controlword, planner (master side), device transition (drive side), modes |
//! | [`profile`] | firmware profiles (TOML), selection by identity |
//! | [`scaling`] | SI conversions |
//! | [`pdo`] | default PDO mapping, its SDO configuration, cyclic codecs, bus load |
//! | [`master`] | [`Drive`]: bring-up, enable, cycle, disable (typestate) |
//! | [`drive`] | [`CyclicDrive`]: the fieldbus-independent drive interface, [`Feedback`] |
//!
//! CiA 301 protocol pieces come from canopen-rs 0.6.1 (sans-I/O): SDO client codec,
//! NMT/EMCY/PDO types. CiA 402, the master, the profiles and the bus-load check are
//! hand-written here (canopen-rs has no CiA 402).

#![warn(missing_docs)]

pub mod cia402;
pub mod cob;
pub mod drive;
pub mod master;
pub mod objects;
pub mod pdo;
pub mod profile;
pub mod scaling;
pub mod sdo;

pub use drive::{Counters, CyclicDrive, DriveErrorKind, Feedback, MultiAxisDrive};
pub use master::{
    bring_up, Configured, Drive, DriveGroup, Enabled, ErrorFramePolicy, MasterConfig, MasterError,
    PreOperational,
};
pub use profile::{EthercatIdentity, Identity, Profile, ProfileError, ProfileSet};
pub use scaling::Scaling;
pub use sdo::{Sdo, SdoError};
