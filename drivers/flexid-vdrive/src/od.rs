//! The drive's object dictionary (CiA 301 communication objects + the CiA 402 objects the
//! virtual drive implements), built on `canopen_rs::ObjectDictionary`.
//!
//! canopen-rs has no CiA 402 profile: the 0x6000 objects below are plain entries the
//! drive core ([`crate::drive`]) reads and publishes every cycle.

use canopen_rs::{Address, ByteString, Entry, ObjectDictionary, Value};

/// Entries the dictionary can hold (`heapless::LinearMap` capacity).
pub const OD_CAPACITY: usize = 112;
/// The drive's object dictionary type.
pub type Od = ObjectDictionary<OD_CAPACITY>;

/// 0x1000 device type: CiA 402 (0x0192), servo drive (0x0002 in the upper word).
pub const DEVICE_TYPE: u32 = 0x0002_0192;
/// 0x1018:1 vendor id. PLACEHOLDER: 0x0F1D is not a CiA-assigned vendor id.
pub const VENDOR_ID: u32 = 0x0000_0F1D;
/// 0x1018:2 product code.
pub const PRODUCT_CODE: u32 = 0x0000_0402;
/// 0x1018:3 revision number (major 1, minor 0).
pub const REVISION: u32 = 0x0001_0000;
/// 0x1008 manufacturer device name.
pub const DEVICE_NAME: &str = "flexid-vdrive";
/// 0x6502 supported drive modes: PT (bit 3), CSP (bit 7), CSV (bit 8), CST (bit 9).
pub const SUPPORTED_MODES: u32 = (1 << 3) | (1 << 7) | (1 << 8) | (1 << 9);

/// Object indices used by the drive.
pub mod idx {
    pub const DEVICE_TYPE: u16 = 0x1000;
    pub const ERROR_REGISTER: u16 = 0x1001;
    pub const ERROR_FIELD: u16 = 0x1003;
    pub const SYNC_COB_ID: u16 = 0x1005;
    pub const CYCLE_PERIOD: u16 = 0x1006;
    pub const DEVICE_NAME: u16 = 0x1008;
    pub const HB_CONSUMER: u16 = 0x1016;
    pub const HB_PRODUCER: u16 = 0x1017;
    pub const IDENTITY: u16 = 0x1018;
    pub const ERROR_BEHAVIOUR: u16 = 0x1029;
    pub const RPDO_COMM: u16 = 0x1400;
    pub const RPDO_MAP: u16 = 0x1600;
    pub const TPDO_COMM: u16 = 0x1800;
    pub const TPDO_MAP: u16 = 0x1A00;
    pub const ABORT_CONNECTION: u16 = 0x6007;
    pub const ERROR_CODE: u16 = 0x603F;
    pub const CONTROLWORD: u16 = 0x6040;
    pub const STATUSWORD: u16 = 0x6041;
    pub const MODES: u16 = 0x6060;
    pub const MODES_DISPLAY: u16 = 0x6061;
    pub const POSITION_ACTUAL: u16 = 0x6064;
    pub const VELOCITY_ACTUAL: u16 = 0x606C;
    pub const TARGET_TORQUE: u16 = 0x6071;
    pub const MAX_TORQUE: u16 = 0x6072;
    pub const RATED_TORQUE: u16 = 0x6076;
    pub const TORQUE_ACTUAL: u16 = 0x6077;
    pub const TARGET_POSITION: u16 = 0x607A;
    pub const TARGET_VELOCITY: u16 = 0x60FF;
    pub const SUPPORTED_MODES: u16 = 0x6502;
}

/// 0x6007 abort connection option codes (CiA 402): what the drive does when the
/// connection to its master is aborted (NMT Operational left, reset communication) while
/// the power stage is on.
pub mod abort_connection {
    /// No action.
    pub const NO_ACTION: i16 = 0;
    /// Fault signal: Fault, EMCY 0x8100.
    pub const FAULT: i16 = 1;
    /// Disable voltage command (the default).
    pub const DISABLE_VOLTAGE: i16 = 2;
    /// Quick stop command.
    pub const QUICK_STOP: i16 = 3;
}

/// 0x1029:1 error behaviour on a communication error (CiA 301).
pub mod error_behaviour {
    /// Change to NMT pre-operational if operational.
    pub const PRE_OPERATIONAL: u8 = 0;
    /// No change of the NMT state (the default: the TPDOs keep flowing, so the master
    /// reads the Fault statusword; the torque is off through the fault either way).
    pub const NO_CHANGE: u8 = 1;
    /// Change to NMT stopped.
    pub const STOPPED: u8 = 2;
}

/// Bit 30 of a TPDO COB-ID (CiA 301): no RTR allowed. Always set: the drive does not
/// serve PDOs by remote request, as most CiA 402 drives today (CiA AN 802 advises against
/// remote frames, CAN FD has none, and a synchronous TPDO already comes every SYNC).
pub const TPDO_NO_RTR: u32 = 0x4000_0000;

/// Receive PDOs the drive has (RPDO1).
pub const RPDOS: u16 = 1;
/// Transmit PDOs the drive has (TPDO1, TPDO2).
pub const TPDOS: u16 = 2;
/// Entries of the pre-defined error field 0x1003.
pub const ERROR_HISTORY: usize = 8;
/// Mapping entries per PDO (canopen-rs's `MAX_PDO_MAPPING`).
pub const MAX_MAPPED: u8 = 8;

/// Objects an RPDO may map (written by the master every cycle).
pub const RPDO_MAPPABLE: [u16; 6] = [
    idx::CONTROLWORD,
    idx::MODES,
    idx::TARGET_TORQUE,
    idx::MAX_TORQUE,
    idx::TARGET_POSITION,
    idx::TARGET_VELOCITY,
];
/// Objects a TPDO may map.
pub const TPDO_MAPPABLE: [u16; 13] = [
    idx::ERROR_REGISTER,
    idx::ERROR_CODE,
    idx::STATUSWORD,
    idx::MODES_DISPLAY,
    idx::POSITION_ACTUAL,
    idx::VELOCITY_ACTUAL,
    idx::TORQUE_ACTUAL,
    idx::CONTROLWORD,
    idx::MODES,
    idx::TARGET_TORQUE,
    idx::MAX_TORQUE,
    idx::TARGET_POSITION,
    idx::TARGET_VELOCITY,
];

/// Errors building the dictionary.
#[derive(Debug, thiserror::Error)]
pub enum OdError {
    /// An entry could not be inserted (capacity) or set.
    #[error("object {index:#06x}:{sub}: {source}")]
    Entry {
        index: u16,
        sub: u8,
        #[source]
        source: canopen_rs::Error,
    },
}

/// Values the dictionary starts with (after power-on / reset node).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OdDefaults {
    /// Node id (1..=127).
    pub node_id: u8,
    /// 0x1006 communication cycle period [µs].
    pub cycle_us: u32,
    /// 0x1017 producer heartbeat time [ms].
    pub heartbeat_ms: u16,
    /// 0x1016:1 consumer heartbeat entry `(node << 16) | time_ms`.
    pub heartbeat_consumer: u32,
    /// 0x6076 rated torque [mN m].
    pub rated_torque_mnm: u32,
    /// 0x6072 max torque [per-mille of rated].
    pub max_torque_permille: u16,
    /// 0x6060 initial mode of operation.
    pub mode: i8,
}

/// Builds the dictionary with its defaults: identity, heartbeat, default PDO mappings
/// (RPDO1 = controlword + target torque; TPDO1 = statusword + position + torque actual;
/// TPDO2 = velocity actual; all transmission type 1).
pub fn build(d: &OdDefaults) -> Result<Od, OdError> {
    let mut od = Od::new();
    let id = u32::from(d.node_id);
    let mut put = |index: u16, sub: u8, e: Entry| {
        od.insert(Address::new(index, sub), e)
            .map_err(|source| OdError::Entry { index, sub, source })
    };
    use Value::*;
    put(
        idx::DEVICE_TYPE,
        0,
        Entry::constant(Unsigned32(DEVICE_TYPE)),
    )?;
    put(idx::ERROR_REGISTER, 0, Entry::ro(Unsigned8(0)))?;
    // sub 0 is writable: 0 clears the history (any other value is refused)
    put(idx::ERROR_FIELD, 0, Entry::rw(Unsigned8(0)))?;
    for sub in 1..=ERROR_HISTORY as u8 {
        put(idx::ERROR_FIELD, sub, Entry::ro(Unsigned32(0)))?;
    }
    put(idx::SYNC_COB_ID, 0, Entry::rw(Unsigned32(0x80)))?;
    put(idx::CYCLE_PERIOD, 0, Entry::rw(Unsigned32(d.cycle_us)))?;
    let name = ByteString::from_bytes(DEVICE_NAME.as_bytes()).map_err(|source| OdError::Entry {
        index: idx::DEVICE_NAME,
        sub: 0,
        source,
    })?;
    put(idx::DEVICE_NAME, 0, Entry::constant(VisibleString(name)))?;
    put(idx::HB_CONSUMER, 0, Entry::constant(Unsigned8(1)))?;
    put(
        idx::HB_CONSUMER,
        1,
        Entry::rw(Unsigned32(d.heartbeat_consumer)),
    )?;
    put(idx::HB_PRODUCER, 0, Entry::rw(Unsigned16(d.heartbeat_ms)))?;
    put(idx::IDENTITY, 0, Entry::constant(Unsigned8(4)))?;
    put(idx::IDENTITY, 1, Entry::constant(Unsigned32(VENDOR_ID)))?;
    put(idx::IDENTITY, 2, Entry::constant(Unsigned32(PRODUCT_CODE)))?;
    put(idx::IDENTITY, 3, Entry::constant(Unsigned32(REVISION)))?;
    put(idx::IDENTITY, 4, Entry::constant(Unsigned32(id)))?;
    put(idx::ERROR_BEHAVIOUR, 0, Entry::constant(Unsigned8(1)))?;
    put(
        idx::ERROR_BEHAVIOUR,
        1,
        Entry::rw(Unsigned8(error_behaviour::NO_CHANGE)),
    )?;

    let pdo = |base: u16,
               cob: u32,
               map: &[u32],
               put: &mut dyn FnMut(u16, u8, Entry) -> Result<(), OdError>| {
        put(base, 0, Entry::constant(Unsigned8(2)))?;
        put(base, 1, Entry::rw(Unsigned32(cob)))?;
        put(base, 2, Entry::rw(Unsigned8(1)))?;
        let m = base + 0x200;
        put(m, 0, Entry::rw(Unsigned8(map.len() as u8)))?;
        for sub in 1..=MAX_MAPPED {
            let v = map.get(sub as usize - 1).copied().unwrap_or(0);
            put(m, sub, Entry::rw(Unsigned32(v)))?;
        }
        Ok(())
    };
    pdo(
        idx::RPDO_COMM,
        0x200 + id,
        &[0x6040_0010, 0x6071_0010],
        &mut put,
    )?;
    pdo(
        idx::TPDO_COMM,
        TPDO_NO_RTR | (0x180 + id),
        &[0x6041_0010, 0x6064_0020, 0x6077_0010],
        &mut put,
    )?;
    pdo(
        idx::TPDO_COMM + 1,
        TPDO_NO_RTR | (0x280 + id),
        &[0x606C_0020],
        &mut put,
    )?;

    put(
        idx::ABORT_CONNECTION,
        0,
        Entry::rw(Integer16(abort_connection::DISABLE_VOLTAGE)),
    )?;
    put(idx::ERROR_CODE, 0, Entry::ro(Unsigned16(0)))?;
    put(idx::CONTROLWORD, 0, Entry::rw(Unsigned16(0)))?;
    put(idx::STATUSWORD, 0, Entry::ro(Unsigned16(0)))?;
    put(idx::MODES, 0, Entry::rw(Integer8(d.mode)))?;
    put(idx::MODES_DISPLAY, 0, Entry::ro(Integer8(d.mode)))?;
    put(idx::POSITION_ACTUAL, 0, Entry::ro(Integer32(0)))?;
    put(idx::VELOCITY_ACTUAL, 0, Entry::ro(Integer32(0)))?;
    put(idx::TARGET_TORQUE, 0, Entry::rw(Integer16(0)))?;
    put(
        idx::MAX_TORQUE,
        0,
        Entry::rw(Unsigned16(d.max_torque_permille)),
    )?;
    put(
        idx::RATED_TORQUE,
        0,
        Entry::rw(Unsigned32(d.rated_torque_mnm)),
    )?;
    put(idx::TORQUE_ACTUAL, 0, Entry::ro(Integer16(0)))?;
    put(idx::TARGET_POSITION, 0, Entry::rw(Integer32(0)))?;
    put(idx::TARGET_VELOCITY, 0, Entry::rw(Integer32(0)))?;
    put(
        idx::SUPPORTED_MODES,
        0,
        Entry::constant(Unsigned32(SUPPORTED_MODES)),
    )?;
    Ok(od)
}

/// Reads an object as a u32 (any unsigned/signed integer type widened), `None` if absent.
pub fn get_u32(od: &Od, index: u16, sub: u8) -> Option<u32> {
    Some(match od.entry(Address::new(index, sub))?.value {
        Value::Unsigned8(v) => v.into(),
        Value::Unsigned16(v) => v.into(),
        Value::Unsigned32(v) => v,
        Value::Integer8(v) => v as u32,
        Value::Integer16(v) => v as u32,
        Value::Integer32(v) => v as u32,
        _ => return None,
    })
}

/// Reads an integer object as i64, `None` if absent or not an integer.
pub fn get_i64(od: &Od, index: u16) -> Option<i64> {
    Some(match od.entry(Address::new(index, 0))?.value {
        Value::Unsigned8(v) => v.into(),
        Value::Unsigned16(v) => v.into(),
        Value::Unsigned32(v) => v.into(),
        Value::Integer8(v) => v.into(),
        Value::Integer16(v) => v.into(),
        Value::Integer32(v) => v.into(),
        _ => return None,
    })
}

/// Sets a sub-index 0 object from the device side (ignores access rights); a type
/// mismatch or absent object is ignored (the dictionary is built by [`build`]).
pub fn set(od: &mut Od, index: u16, value: Value) {
    let _ = od.set(Address::new(index, 0), value);
}
