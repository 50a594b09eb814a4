//! The master layer's error type.

use std::time::Duration;

use flexid_can::BusError;

use crate::cia402::State;
use crate::pdo::BusLoadError;
use crate::profile::ProfileError;
use crate::sdo::SdoError;

/// Errors of the master (bring-up, enable, cycle, disable); each names the node.
#[derive(Debug, thiserror::Error)]
pub enum MasterError {
    /// A bus operation of the master's own handle failed.
    #[error("node {node}: {during}: {source}")]
    Bus {
        /// The drive's node-id.
        node: u8,
        /// What the master was doing.
        during: &'static str,
        /// The bus error.
        #[source]
        source: BusError,
    },
    /// An SDO transfer failed (abort, timeout, ...).
    #[error(transparent)]
    Sdo(#[from] SdoError),
    /// No profile could be selected or loaded.
    #[error(transparent)]
    Profile(#[from] ProfileError),
    /// The cyclic traffic would overload the bus.
    #[error(transparent)]
    BusLoad(#[from] BusLoadError),
    /// No boot-up message (0x700 + id, data 0x00) after the NMT reset.
    #[error("node {node}: no boot-up message within {after:?} of the NMT reset")]
    BootUpMissing {
        /// The drive's node-id.
        node: u8,
        /// How long the master waited.
        after: Duration,
    },
    /// Something awaited did not come in time.
    #[error("node {node}: no {waiting_for} after {after:?}")]
    Timeout {
        /// The drive's node-id.
        node: u8,
        /// What was awaited.
        waiting_for: &'static str,
        /// How long the master waited.
        after: Duration,
    },
    /// The device type (0x1000) is not a CiA 402 drive.
    #[error("node {node}: device type {device_type:#010x} is not a CiA 402 drive (low 16 bits must be 402 = 0x192)")]
    NotCia402 {
        /// The drive's node-id.
        node: u8,
        /// 0x1000.
        device_type: u32,
    },
    /// The drive (by its profile or 0x6502) does not support a mode the master needs.
    #[error("node {node}: mode {mode} not supported (profile {profile})")]
    ModeUnsupported {
        /// The drive's node-id.
        node: u8,
        /// The mode (CST, ...).
        mode: &'static str,
        /// The profile used.
        profile: String,
    },
    /// 0x6061 does not show the mode written to 0x6060.
    #[error("node {node}: modes of operation display shows {shown}, {requested} was written")]
    ModeNotAccepted {
        /// The drive's node-id.
        node: u8,
        /// Written to 0x6060.
        requested: i8,
        /// Read from 0x6061.
        shown: i8,
    },
    /// The cycle period is shorter than the firmware allows.
    #[error("node {node}: cycle period {cycle:?} is below the {min:?} of profile {profile}")]
    CycleTooShort {
        /// The drive's node-id.
        node: u8,
        /// The period asked for.
        cycle: Duration,
        /// The profile's minimum.
        min: Duration,
        /// The profile.
        profile: String,
    },
    /// The default mapping needs more PDO entries than the firmware allows.
    #[error(
        "node {node}: mapping needs {entries} entries in one PDO, profile {profile} allows {max}"
    )]
    MappingTooLong {
        /// The drive's node-id.
        node: u8,
        /// Entries needed.
        entries: usize,
        /// Entries allowed.
        max: u8,
        /// The profile.
        profile: String,
    },
    /// An emergency message from the drive (CiA 301 EMCY), decoded.
    #[error("node {node}: EMCY {error_code:#06x} ({text}), error register {register:#04x}, data {data:02x?}")]
    Emergency {
        /// The drive's node-id.
        node: u8,
        /// Emergency error code (CiA 301 Table 21 / CiA 402).
        error_code: u16,
        /// Error register (0x1001).
        register: u8,
        /// Manufacturer-specific bytes.
        data: [u8; 5],
        /// The error code's class.
        text: &'static str,
    },
    /// The statusword shows Fault or Fault reaction active.
    #[error("node {node}: drive in fault, error code {error_code:#06x} ({text}), error register {register:#04x}")]
    Fault {
        /// The drive's node-id.
        node: u8,
        /// 0x603F (or the last EMCY's code; 0 if neither could be had).
        error_code: u16,
        /// 0x1001 (or the last EMCY's register).
        register: u8,
        /// The error code's class.
        text: &'static str,
    },
    /// Feedback missing for too many consecutive cycles.
    #[error("node {node}: no feedback (TPDO) in {consecutive} consecutive cycles")]
    TpdoLost {
        /// The drive's node-id.
        node: u8,
        /// Consecutive cycles without.
        consecutive: u32,
    },
    /// The drive's heartbeat reports a state other than Operational (or a boot-up).
    #[error(
        "node {node}: heartbeat reports NMT state {state:#04x} while operational was expected"
    )]
    NmtStateChanged {
        /// The drive's node-id.
        node: u8,
        /// The reported state byte (0x00 boot-up, 0x04 stopped, 0x7F pre-operational).
        state: u8,
    },
    /// The drive is NMT stopped (its heartbeat says 0x04): it answers no PDO and no SDO,
    /// so the master cannot walk it down; its abort connection option code (0x6007)
    /// decides what its power stage did when it stopped.
    #[error(
        "node {node} is NMT stopped: it answers no PDO and no SDO, so it cannot be disabled          by the master; its abort connection option (0x6007) decides its power stage"
    )]
    NmtStopped {
        /// The drive's node-id.
        node: u8,
    },
    /// The CiA 402 walk did not reach its target in time.
    #[error("node {node}: did not reach {target} within {after:?}, last state {last}")]
    StateMachine {
        /// The drive's node-id.
        node: u8,
        /// The target state.
        target: State,
        /// The last state seen (its statusword if outside the table).
        last: String,
        /// How long it tried.
        after: Duration,
    },
    /// The drive left Operation enabled without a fault (quick stop, disable by a
    /// local control or by its heartbeat consumer, ...).
    #[error("node {node}: drive left Operation enabled, now {state}")]
    Disabled {
        /// The drive's node-id.
        node: u8,
        /// The state it shows.
        state: State,
    },
    /// The drives of a group do not share one cycle period.
    #[error("node {node}: cycle period {period:?} differs from node {first}'s {first_period:?}: a group cycles with one SYNC")]
    GroupPeriod {
        /// The drive that differs.
        node: u8,
        /// Its period.
        period: std::time::Duration,
        /// The group's first drive.
        first: u8,
        /// Its period.
        first_period: std::time::Duration,
    },
    /// A group cycle got the wrong number of set-points or feedback slots.
    #[error("a group of {axes} drives got {torques} set-points and {feedback} feedback slots")]
    GroupSize {
        /// Drives in the group.
        axes: usize,
        /// Set-points given.
        torques: usize,
        /// Feedback slots given.
        feedback: usize,
    },
    /// A set-point that is not a finite number.
    #[error("node {node}: torque set-point {torque_nm} N m is not finite")]
    InvalidSetpoint {
        /// The drive's node-id.
        node: u8,
        /// The value given.
        torque_nm: f64,
    },
    /// More CAN error frames than the error-frame policy allows within its window.
    #[error("node {node}: {frames} CAN error frames within {window:?} (the policy allows {max}); last: {last}")]
    ErrorFrameBurst {
        /// The drive's node-id.
        node: u8,
        /// Error frames within the window.
        frames: u16,
        /// The policy's window.
        window: Duration,
        /// The policy's most frames.
        max: u16,
        /// The last error frame, decoded.
        last: String,
    },
    /// The master configuration is invalid.
    #[error("invalid master configuration: {0}")]
    Config(String),
}

/// The class of an emergency error code (CiA 301 Table 21, CiA 402 additions for the
/// common drive codes). Hand-written: canopen-rs has the class constants, no text.
pub fn emcy_text(code: u16) -> &'static str {
    match code {
        0x0000 => "error reset or no error",
        0x2310 => "continuous over current",
        0x3210 => "DC link over-voltage",
        0x3220 => "DC link under-voltage",
        0x4310 => "excess drive temperature",
        0x7121 => "motor blocked",
        0x7300..=0x73FF => "sensor (encoder) error",
        0x8100 => "communication (connection aborted)",
        0x8130 => "life guard or heartbeat error",
        0x8210 => "PDO not processed due to length error",
        0x8220 => "PDO length exceeded",
        0x8240 => "unexpected SYNC data length",
        0x8700 => "sync controller (SYNC lost)",
        0x8611 => "following error",
        _ => match code >> 8 {
            0x10 => "generic error",
            0x20..=0x2F => "current",
            0x30..=0x3F => "voltage",
            0x40..=0x4F => "temperature",
            0x50 => "device hardware",
            0x60..=0x6F => "device software",
            0x70 => "additional modules",
            0x80..=0x8F => "monitoring",
            0x90 => "external error",
            0xF0 => "additional functions",
            0xFF => "device specific",
            _ => "unknown error code",
        },
    }
}
