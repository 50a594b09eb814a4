//! The CiA 301 slave: canopen-rs's `Node` (object dictionary, SDO server, NMT, PDO
//! packing/unpacking, EMCY, boot-up/heartbeat frames) plus what it lacks, written here:
//!
//! * SDO checks canopen-rs does not make: sub-index missing (0x06090011), length too
//!   low (0x06070013, canopen-rs answers "too high" for any mismatch), value range
//!   (0x06090030) of 0x6060 / 0x1006 / 0x1005 / PDO parameters, and the CiA 301 PDO
//!   re-mapping procedure (mapping only while the PDO is invalid and its count is 0, in
//!   pre-operational; mappable objects and lengths checked);
//! * SYNC-triggered TPDOs honouring transmission type `n` (every n-th SYNC: canopen-rs
//!   sends every synchronous TPDO on every SYNC);
//! * NMT reset handling (canopen-rs goes to Initialising and stays: we rebuild and boot).
//!
//! canopen-rs holds at most 4 RPDOs + 4 TPDOs of 8 entries; the drive uses RPDO1, TPDO1,
//! TPDO2.

use canopen_rs::node::Node;
use canopen_rs::{Address, NmtState, NodeId, TxFrame, Value};
use flexid_can::CanFrame;

use crate::od::{self, idx, Od, OdDefaults, OdError, OD_CAPACITY};

/// SDO abort codes (CiA 301 table 22) the slave itself produces.
pub mod abort {
    /// Unsupported access to an object.
    pub const UNSUPPORTED_ACCESS: u32 = 0x0601_0000;
    /// Object does not exist in the object dictionary.
    pub const NO_OBJECT: u32 = 0x0602_0000;
    /// Object cannot be mapped to the PDO.
    pub const NOT_MAPPABLE: u32 = 0x0604_0041;
    /// The number and length of the objects to be mapped would exceed the PDO length.
    pub const MAP_LENGTH: u32 = 0x0604_0042;
    /// Data type does not match, length of service parameter too low.
    pub const LENGTH_LOW: u32 = 0x0607_0013;
    /// Sub-index does not exist.
    pub const NO_SUBINDEX: u32 = 0x0609_0011;
    /// Invalid value for parameter (download only).
    pub const VALUE_RANGE: u32 = 0x0609_0030;
    /// Data cannot be transferred because of the present device state.
    pub const DEVICE_STATE: u32 = 0x0800_0022;
}

/// Shortest cycle period the master may set in 0x1006 [µs].
pub const MIN_CYCLE_US: u32 = 50;
/// Longest cycle period the master may set in 0x1006 [µs].
pub const MAX_CYCLE_US: u32 = 1_000_000;

/// What a received frame meant to the slave (for the drive core).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SlaveEvent {
    /// Nothing the drive must react to.
    None,
    /// An NMT command addressed to us (start, stop, pre-op); the state is already applied.
    Nmt(u8),
    /// NMT reset node (`communication_only = false`) or reset communication.
    Reset { communication_only: bool },
    /// An SDO download completed to this object.
    Written(Address),
    /// RPDO1 was received while operational (its objects are written).
    Rpdo,
    /// RPDO1 of the wrong length while operational (CiA 301): shorter than its mapping,
    /// not processed (EMCY 0x8210); longer, processed from its mapped bytes (EMCY
    /// 0x8220).
    RpdoLength {
        /// The EMCY code to report.
        code: u16,
        /// Whether the objects were written (then it is also an [`SlaveEvent::Rpdo`]).
        processed: bool,
    },
}

/// EMCY: PDO not processed due to length error (CiA 301).
pub const EMCY_PDO_LENGTH: u16 = 0x8210;
/// EMCY: PDO length exceeded (CiA 301).
pub const EMCY_PDO_LENGTH_EXCEEDED: u16 = 0x8220;
/// EMCY: unexpected SYNC data length (CiA 301).
pub const EMCY_SYNC_LENGTH: u16 = 0x8240;

/// The CiA 301 slave of the drive.
#[derive(Debug)]
pub struct Slave {
    node: Node<OD_CAPACITY>,
    defaults: OdDefaults,
    sync_count: [u8; od::TPDOS as usize],
    cycle_adjustable: bool,
    /// The pre-defined error field 0x1003, most recent first: kept here because
    /// canopen-rs clears it with the error register, and a fault reset must not.
    history: [u32; od::ERROR_HISTORY],
    history_len: usize,
}

/// Errors of the slave layer.
#[derive(Debug, thiserror::Error)]
pub enum SlaveError {
    /// The node id is not 1..=127.
    #[error("node id {0} is not in 1..=127")]
    NodeId(u8),
    /// The object dictionary could not be built.
    #[error("object dictionary: {0}")]
    Od(#[from] OdError),
}

impl Slave {
    /// A slave in NMT Initialising; [`Slave::boot`] sends it to pre-operational.
    pub fn new(defaults: OdDefaults) -> Result<Self, SlaveError> {
        let id = NodeId::new(defaults.node_id).map_err(|_| SlaveError::NodeId(defaults.node_id))?;
        if defaults.node_id == 0 || defaults.node_id > 127 {
            return Err(SlaveError::NodeId(defaults.node_id));
        }
        let mut node = Node::new(id, od::build(&defaults)?);
        node.configure_pdos_from_od();
        Ok(Self {
            node,
            defaults,
            sync_count: [0; od::TPDOS as usize],
            cycle_adjustable: false,
            history: [0; od::ERROR_HISTORY],
            history_len: 0,
        })
    }

    /// Whether the master may write 0x1006 with another cycle period (50 µs ..= 1 s); else
    /// only 0 or the current value are accepted.
    pub fn set_cycle_adjustable(&mut self, yes: bool) {
        self.cycle_adjustable = yes;
    }

    /// Node id.
    pub fn node_id(&self) -> u8 {
        self.defaults.node_id
    }

    /// Enter pre-operational; the boot-up frame (0x700 + id, `[0x00]`).
    pub fn boot(&mut self) -> Option<CanFrame> {
        can(self.node.boot())
    }

    /// Rebuilds the dictionary for a reset. Reset communication keeps the application
    /// objects (0x2000..=0x9FFF) and the EMCY history is cleared; reset node restores
    /// everything to its defaults. The slave is left in Initialising: call [`Slave::boot`].
    pub fn reset(&mut self, communication_only: bool) -> Result<(), SlaveError> {
        let mut fresh = Slave::new(self.defaults)?;
        fresh.cycle_adjustable = self.cycle_adjustable;
        if communication_only {
            for index in [
                idx::ABORT_CONNECTION,
                idx::CONTROLWORD,
                idx::MODES,
                idx::MODES_DISPLAY,
                idx::TARGET_TORQUE,
                idx::MAX_TORQUE,
                idx::RATED_TORQUE,
                idx::TARGET_POSITION,
                idx::TARGET_VELOCITY,
                idx::ERROR_CODE,
                idx::STATUSWORD,
            ] {
                if let Some(e) = self.node.od().entry(Address::new(index, 0)) {
                    od::set(fresh.node.od_mut(), index, e.value);
                }
            }
        }
        *self = fresh;
        Ok(())
    }

    /// NMT state.
    pub fn nmt(&self) -> NmtState {
        self.node.state()
    }

    /// The object dictionary.
    pub fn od(&self) -> &Od {
        self.node.od()
    }

    /// The object dictionary, device side.
    pub fn od_mut(&mut self) -> &mut Od {
        self.node.od_mut()
    }

    /// The heartbeat frame for the current NMT state.
    pub fn heartbeat(&self) -> Option<CanFrame> {
        can(self.node.heartbeat())
    }

    /// Node-guarding response (RTR on 0x700 + id).
    pub fn node_guard(&mut self) -> Option<CanFrame> {
        can(self.node.node_guard_response())
    }

    /// Raises an EMCY (error register and 0x1003 updated); the frame to send.
    pub fn emergency(
        &mut self,
        code: u16,
        register: canopen_rs::ErrorRegister,
    ) -> Option<CanFrame> {
        let frame = can(self.node.raise_emergency(code, register, [0; 5]));
        self.history.copy_within(0..od::ERROR_HISTORY - 1, 1);
        self.history[0] = u32::from(code);
        self.history_len = (self.history_len + 1).min(od::ERROR_HISTORY);
        self.mirror_history();
        frame
    }

    /// A fault reset: clears the error register (0x1001) and keeps the error history
    /// (0x1003, CiA 301: only writing 0 to its sub-index 0 clears it); the EMCY "error
    /// reset" frame to send.
    pub fn error_reset(&mut self) -> Option<CanFrame> {
        let frame = can(self.node.clear_errors());
        self.mirror_history();
        frame
    }

    /// The pre-defined error field (0x1003 sub 1..), most recent first.
    pub fn error_history(&self) -> &[u32] {
        &self.history[..self.history_len]
    }

    /// Writes the history into 0x1003 (sub 0: the count; unused entries 0).
    fn mirror_history(&mut self) {
        let od = self.node.od_mut();
        let _ = od.set(
            Address::new(idx::ERROR_FIELD, 0),
            Value::Unsigned8(self.history_len as u8),
        );
        for (i, &e) in self.history.iter().enumerate() {
            let v = if i < self.history_len { e } else { 0 };
            let _ = od.set(
                Address::new(idx::ERROR_FIELD, i as u8 + 1),
                Value::Unsigned32(v),
            );
        }
    }

    /// Changes the NMT state from inside the device (0x1029 error behaviour): `command`
    /// is an NMT command specifier (0x02 stop, 0x80 pre-operational).
    pub fn enter_nmt(&mut self, command: u8) {
        let id = self.defaults.node_id;
        let _ = self.node.on_frame(0, &[command, id]);
    }

    /// The SYNC COB-ID (0x1005 bits 0..10).
    pub fn sync_cob_id(&self) -> u16 {
        (od::get_u32(self.od(), idx::SYNC_COB_ID, 0).unwrap_or(0x80) & 0x7FF) as u16
    }

    /// The COB-ID of RPDO1 when it is valid.
    pub fn rpdo_cob_id(&self) -> Option<u16> {
        let c = od::get_u32(self.od(), idx::RPDO_COMM, 1)?;
        (c & 0x8000_0000 == 0).then_some((c & 0x7FF) as u16)
    }

    /// Handles one standard data frame. Returns the response (SDO) and what happened.
    /// Never panics, whatever the bytes.
    pub fn on_frame(&mut self, cob: u16, data: &[u8]) -> (Option<CanFrame>, SlaveEvent) {
        let id = self.defaults.node_id;
        if cob == 0 {
            if data.len() != 2 || (data[1] != 0 && data[1] != id) {
                return (None, SlaveEvent::None);
            }
            let before = self.node.state();
            self.node.on_frame(cob, data);
            return match data[0] {
                0x81 | 0x82 if self.node.state() == NmtState::Initialising => (
                    None,
                    SlaveEvent::Reset {
                        communication_only: data[0] == 0x82,
                    },
                ),
                0x01 | 0x02 | 0x80 if before != NmtState::Initialising => {
                    (None, SlaveEvent::Nmt(data[0]))
                }
                _ => (None, SlaveEvent::None),
            };
        }
        if cob == 0x600 + u16::from(id) {
            if data.len() != 8 {
                return (None, SlaveEvent::None); // CiA 301: SDO frames have DLC 8
            }
            if !matches!(
                self.node.state(),
                NmtState::PreOperational | NmtState::Operational
            ) {
                return (None, SlaveEvent::None);
            }
            if let Some(code) = self.sdo_precheck(data) {
                let mut p = [0u8; 8];
                p[0] = 0x80;
                p[1..4].copy_from_slice(&data[1..4]);
                p[4..8].copy_from_slice(&code.to_le_bytes());
                return (
                    CanFrame::standard(0x580 + u16::from(id), &p).ok(),
                    SlaveEvent::None,
                );
            }
            let resp = self.node.on_frame(cob, data).and_then(can);
            let ev = match self.node.take_written_object() {
                Some(a) if a == Address::new(idx::ERROR_FIELD, 0) => {
                    // 0 written to 0x1003:0 (the only value accepted): history cleared
                    self.history_len = 0;
                    self.mirror_history();
                    SlaveEvent::Written(a)
                }
                Some(a) => {
                    let tpdo_comm = idx::TPDO_COMM..idx::TPDO_COMM + od::TPDOS;
                    if tpdo_comm.contains(&a.index) && a.subindex == 1 {
                        // RTR is not served: bit 30 reads 1 whatever was written
                        if let Some(v) = od::get_u32(self.od(), a.index, 1) {
                            let _ = self
                                .node
                                .od_mut()
                                .set(a, Value::Unsigned32(v | od::TPDO_NO_RTR));
                        }
                    }
                    if (0x1400..=0x1BFF).contains(&a.index) {
                        self.node.configure_pdos_from_od();
                        self.sync_count = [0; od::TPDOS as usize];
                    }
                    SlaveEvent::Written(a)
                }
                None => SlaveEvent::None,
            };
            return (resp, ev);
        }
        let operational = self.node.state() == NmtState::Operational;
        if operational && Some(cob) == self.rpdo_cob_id() {
            let mapped = self.rpdo_length();
            if data.len() < mapped {
                let ev = SlaveEvent::RpdoLength {
                    code: EMCY_PDO_LENGTH,
                    processed: false,
                };
                return (None, ev);
            }
            let _ = self.node.on_frame(cob, &data[..mapped]);
            let ev = if data.len() > mapped {
                SlaveEvent::RpdoLength {
                    code: EMCY_PDO_LENGTH_EXCEEDED,
                    processed: true,
                }
            } else {
                SlaveEvent::Rpdo
            };
            return (None, ev);
        }
        let resp = self.node.on_frame(cob, data).and_then(can);
        (resp, SlaveEvent::None)
    }

    /// The bytes RPDO1's mapping (0x1600) takes.
    fn rpdo_length(&self) -> usize {
        let od = self.od();
        let count = od::get_u32(od, idx::RPDO_MAP, 0).unwrap_or(0) as u8;
        let bits: u32 = (1..=count)
            .map(|s| od::get_u32(od, idx::RPDO_MAP, s).unwrap_or(0) & 0xFF)
            .sum();
        (bits as usize).div_ceil(8)
    }

    /// The TPDOs due at this SYNC (operational only), packed from the dictionary as it is
    /// now; `emit` is called for each.
    pub fn sync_tpdos(&mut self, mut emit: impl FnMut(CanFrame)) {
        let frames = self.node.sync_tpdos();
        for f in frames.iter() {
            for n in 0..od::TPDOS {
                let comm = idx::TPDO_COMM + n;
                let Some(c) = od::get_u32(self.od(), comm, 1) else {
                    continue;
                };
                if c & 0x8000_0000 != 0 || (c & 0x7FF) as u16 != f.cob_id {
                    continue;
                }
                let t = od::get_u32(self.od(), comm, 2).unwrap_or(1) as u8;
                let slot = &mut self.sync_count[n as usize];
                *slot = slot.saturating_add(1);
                if t == 0 || *slot >= t {
                    *slot = 0;
                    if let Some(c) = can(*f) {
                        emit(c);
                    }
                }
                break;
            }
        }
    }

    /// CiA 301 checks canopen-rs's SDO server does not make; `Some(abort code)` to refuse.
    fn sdo_precheck(&self, req: &[u8]) -> Option<u32> {
        let ccs = req[0] >> 5;
        if ccs != 1 && ccs != 2 {
            return None; // segments, aborts, block transfer: canopen-rs
        }
        let index = u16::from_le_bytes([req[1], req[2]]);
        let sub = req[3];
        let od = self.od();
        let Some(entry) = od.entry(Address::new(index, sub)) else {
            return Some(if od.entry(Address::new(index, 0)).is_some() {
                abort::NO_SUBINDEX
            } else {
                abort::NO_OBJECT
            });
        };
        if ccs == 2 || !entry.access.is_writable() {
            return None; // uploads and read-only objects: canopen-rs answers
        }
        let fixed = entry.value.data_type().fixed_size();
        let expedited = req[0] & 0x02 != 0;
        let sized = req[0] & 0x01 != 0;
        let len = match (expedited, sized) {
            (true, true) => 4 - usize::from((req[0] >> 2) & 0x03),
            (true, false) => fixed.unwrap_or(4),
            (false, true) => u32::from_le_bytes([req[4], req[5], req[6], req[7]]) as usize,
            (false, false) => return None,
        };
        if let Some(f) = fixed {
            if len < f {
                return Some(abort::LENGTH_LOW);
            }
            if len > f {
                return None; // canopen-rs: 0x06070012
            }
        }
        if !expedited || len > 4 {
            return None; // only small values are range-checked
        }
        let mut raw = [0u8; 4];
        raw[..len].copy_from_slice(&req[4..4 + len]);
        let v = u32::from_le_bytes(raw);
        self.check_value(index, sub, v, len)
    }

    /// Value checks of writable objects; `v` holds the little-endian value bytes.
    fn check_value(&self, index: u16, sub: u8, v: u32, len: usize) -> Option<u32> {
        let od = self.od();
        let state = self.node.state();
        match index {
            idx::MODES => {
                (!crate::cia402::mode::supported(v as u8 as i8)).then_some(abort::VALUE_RANGE)
            }
            idx::CYCLE_PERIOD => {
                let current = od::get_u32(od, idx::CYCLE_PERIOD, 0).unwrap_or(0);
                let ok = v == 0
                    || v == current
                    || (self.cycle_adjustable && (MIN_CYCLE_US..=MAX_CYCLE_US).contains(&v));
                (!ok).then_some(abort::VALUE_RANGE)
            }
            idx::SYNC_COB_ID => (v & !0x8000_07FF != 0).then_some(abort::VALUE_RANGE),
            idx::ERROR_FIELD if sub == 0 => (v != 0).then_some(abort::VALUE_RANGE),
            idx::ABORT_CONNECTION => {
                (!(0..=3).contains(&(v as u16 as i16))).then_some(abort::VALUE_RANGE)
            }
            idx::ERROR_BEHAVIOUR if sub == 1 => (v > 2).then_some(abort::VALUE_RANGE),
            i if (idx::RPDO_COMM..idx::RPDO_COMM + od::RPDOS).contains(&i)
                || (idx::TPDO_COMM..idx::TPDO_COMM + od::TPDOS).contains(&i) =>
            {
                let tpdo = i >= idx::TPDO_COMM;
                match sub {
                    1 => {
                        let cur = od::get_u32(od, i, 1).unwrap_or(0x8000_0000);
                        let cob = v & 0x7FF;
                        let new_valid = v & 0x8000_0000 == 0;
                        // 29-bit ids are not supported, the CAN-ID must not change
                        // while the PDO is valid, and 0x000..0x07F (NMT, SYNC) is reserved.
                        let bad = v & 0x2000_0000 != 0
                            || (v & 0x1FFF_F800) != 0
                            || (new_valid && cur & 0x8000_0000 == 0 && (cur & 0x7FF) != cob)
                            || (new_valid && cob < 0x80);
                        bad.then_some(abort::VALUE_RANGE)
                    }
                    2 => {
                        let ok = if tpdo { v <= 240 } else { v <= 240 || v >= 254 };
                        (!ok).then_some(abort::VALUE_RANGE)
                    }
                    _ => None,
                }
            }
            i if (idx::RPDO_MAP..idx::RPDO_MAP + od::RPDOS).contains(&i)
                || (idx::TPDO_MAP..idx::TPDO_MAP + od::TPDOS).contains(&i) =>
            {
                let tpdo = i >= idx::TPDO_MAP;
                let comm = i - 0x200;
                if state == NmtState::Operational {
                    return Some(abort::DEVICE_STATE);
                }
                let valid = od::get_u32(od, comm, 1).is_some_and(|c| c & 0x8000_0000 == 0);
                if valid {
                    return Some(abort::UNSUPPORTED_ACCESS); // destroy the PDO first
                }
                if sub == 0 {
                    let count = v as u8;
                    if len != 1 || count > od::MAX_MAPPED {
                        return Some(abort::MAP_LENGTH);
                    }
                    let mut bits = 0u32;
                    for s in 1..=count {
                        let e = od::get_u32(od, i, s).unwrap_or(0);
                        if let Some(code) = mappable(od, e, tpdo) {
                            return Some(code);
                        }
                        bits += e & 0xFF;
                    }
                    (bits > 64).then_some(abort::MAP_LENGTH)
                } else {
                    if od::get_u32(od, i, 0).unwrap_or(0) != 0 {
                        return Some(abort::UNSUPPORTED_ACCESS); // count must be 0 first
                    }
                    if v == 0 {
                        None
                    } else {
                        mappable(od, v, tpdo)
                    }
                }
            }
            _ => None,
        }
    }
}

/// Whether mapping entry `e` (`0xIIIISSLL`) names a mappable object of that length.
fn mappable(od: &Od, e: u32, tpdo: bool) -> Option<u32> {
    let index = (e >> 16) as u16;
    let sub = (e >> 8) as u8;
    let bits = e as u8;
    let list: &[u16] = if tpdo {
        &od::TPDO_MAPPABLE
    } else {
        &od::RPDO_MAPPABLE
    };
    let Some(entry) = od.entry(Address::new(index, sub)) else {
        return Some(abort::NO_OBJECT);
    };
    if !list.contains(&index) || sub != 0 {
        return Some(abort::NOT_MAPPABLE);
    }
    let size = entry.value.data_type().fixed_size().unwrap_or(0);
    (usize::from(bits) != size * 8 || matches!(entry.value, Value::VisibleString(_)))
        .then_some(abort::NOT_MAPPABLE)
}

/// A canopen-rs transmit frame as a bus frame (`None` only for an impossible id).
pub(crate) fn can(t: TxFrame) -> Option<CanFrame> {
    CanFrame::standard(t.cob_id, t.data()).ok()
}
