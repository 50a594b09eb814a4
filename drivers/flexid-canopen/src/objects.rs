//! Object dictionary indices used by the master: CiA 301 communication objects and
//! CiA 402 drive objects (units on each).

/// CiA 301 communication profile objects.
pub mod comm {
    /// 0x1000 device type, u32 (low 16 bits: device profile number, 402 for drives).
    pub const DEVICE_TYPE: u16 = 0x1000;
    /// 0x1001 error register, u8 (bit field, CiA 301 §7.5.2.2).
    pub const ERROR_REGISTER: u16 = 0x1001;
    /// 0x1005 COB-ID SYNC message, u32.
    pub const SYNC_COB_ID: u16 = 0x1005;
    /// 0x1006 communication cycle period, u32, µs.
    pub const CYCLE_PERIOD: u16 = 0x1006;
    /// 0x1008 manufacturer device name, VISIBLE_STRING.
    pub const DEVICE_NAME: u16 = 0x1008;
    /// 0x1016 consumer heartbeat time, array of u32: `(node-id << 16) | time_ms`.
    pub const CONSUMER_HEARTBEAT: u16 = 0x1016;
    /// 0x1017 producer heartbeat time, u16, ms (0 = off).
    pub const PRODUCER_HEARTBEAT: u16 = 0x1017;
    /// 0x1018 identity object: sub 1 vendor-id, 2 product code, 3 revision, 4 serial (u32).
    pub const IDENTITY: u16 = 0x1018;
    /// 0x1400 + n-1: RPDO n communication parameter (sub 1 COB-ID u32, sub 2 transmission
    /// type u8).
    pub const RPDO_COMM: u16 = 0x1400;
    /// 0x1600 + n-1: RPDO n mapping parameter (sub 0 count u8, sub 1.. entries u32).
    pub const RPDO_MAPPING: u16 = 0x1600;
    /// 0x1800 + n-1: TPDO n communication parameter.
    pub const TPDO_COMM: u16 = 0x1800;
    /// 0x1A00 + n-1: TPDO n mapping parameter.
    pub const TPDO_MAPPING: u16 = 0x1A00;
}

/// CiA 402 drive profile objects.
pub mod cia402 {
    /// 0x603F error code, u16 (the EMCY error code of the last fault).
    pub const ERROR_CODE: u16 = 0x603F;
    /// 0x6040 controlword, u16.
    pub const CONTROLWORD: u16 = 0x6040;
    /// 0x6041 statusword, u16.
    pub const STATUSWORD: u16 = 0x6041;
    /// 0x6060 modes of operation, i8.
    pub const MODES_OF_OPERATION: u16 = 0x6060;
    /// 0x6061 modes of operation display, i8.
    pub const MODES_OF_OPERATION_DISPLAY: u16 = 0x6061;
    /// 0x6064 position actual value, i32, position units (increments by default).
    pub const POSITION_ACTUAL: u16 = 0x6064;
    /// 0x606C velocity actual value, i32, velocity units (increments/s by default).
    pub const VELOCITY_ACTUAL: u16 = 0x606C;
    /// 0x6071 target torque, i16, per-mille of rated torque.
    pub const TARGET_TORQUE: u16 = 0x6071;
    /// 0x6076 motor rated torque, u32, mN m.
    pub const RATED_TORQUE: u16 = 0x6076;
    /// 0x6077 torque actual value, i16, per-mille of rated torque.
    pub const TORQUE_ACTUAL: u16 = 0x6077;
    /// 0x608F position encoder resolution: sub 1 encoder increments, sub 2 motor
    /// revolutions (u32 each).
    pub const POSITION_ENCODER_RESOLUTION: u16 = 0x608F;
    /// 0x6502 supported drive modes, u32 bit field (bit 0 PP, ... bit 7 CSP, 8 CSV, 9 CST).
    pub const SUPPORTED_MODES: u16 = 0x6502;
}
