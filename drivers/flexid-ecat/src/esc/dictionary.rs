//! The CoE object dictionary of an emulated SubDevice: entries by (index, sub-index), their
//! access rights and PDO mappability, the rules of PDO mapping and assignment (CiA 301 /
//! ETG.1000.6: sub-index 0 must be 0 while entries change, and changes only in PRE-OP), and
//! the process-data layout the mapping gives.

use super::al::AlState;
use super::sii::Identity;
use crate::le;

/// SDO abort codes (ETG.1000.6 table 41).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
pub enum SdoAbort {
    /// Client/server command specifier not valid or unknown (segmented transfers).
    CommandSpecifier = 0x0504_0001,
    /// Out of memory: the value does not fit the mailbox (segmented upload not emulated).
    OutOfMemory = 0x0504_0005,
    /// Unsupported access to an object (complete access).
    UnsupportedAccess = 0x0601_0000,
    ReadOnly = 0x0601_0002,
    /// Sub-index cannot be written, sub-index 0 must be 0 for write access.
    SubIndex0MustBeZero = 0x0601_0003,
    NoObject = 0x0602_0000,
    /// Object cannot be mapped to the PDO.
    NotMappable = 0x0604_0041,
    /// The mapped objects exceed the PDO length.
    PdoTooLong = 0x0604_0042,
    /// Data type does not match, length of service parameter does not match.
    LengthMismatch = 0x0607_0010,
    NoSubIndex = 0x0609_0011,
    /// Value range of parameter exceeded.
    ValueRange = 0x0609_0030,
    /// Data cannot be transferred because of the present device state.
    DeviceState = 0x0800_0022,
}

impl SdoAbort {
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// Who may write an entry over SDO.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ObjectAccess {
    ReadOnly,
    ReadWrite,
}

/// Whether an entry can be mapped into a PDO, and which.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mappable {
    No,
    /// Into an RxPDO (MainDevice outputs).
    Rx,
    /// Into a TxPDO (MainDevice inputs).
    Tx,
}

/// One entry (sub-index) of the dictionary.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entry {
    pub index: u16,
    pub sub: u8,
    pub access: ObjectAccess,
    pub mappable: Mappable,
    /// The value, little-endian; its length is fixed at creation.
    pub data: Vec<u8>,
}

/// One mapped entry of a sync manager's process data.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MappedEntry {
    pub index: u16,
    pub sub: u8,
    /// Byte offset in the sync manager's buffer.
    pub offset: usize,
    /// Length, bytes.
    pub len: usize,
}

/// RxPDO mapping objects (outputs).
const RX_MAPPING: core::ops::RangeInclusive<u16> = 0x1600..=0x17FF;
/// TxPDO mapping objects (inputs).
const TX_MAPPING: core::ops::RangeInclusive<u16> = 0x1A00..=0x1BFF;
/// Sync manager 2 (outputs) PDO assignment.
pub const RX_ASSIGN: u16 = 0x1C12;
/// Sync manager 3 (inputs) PDO assignment.
pub const TX_ASSIGN: u16 = 0x1C13;
/// Longest PDO, bits.
const MAX_PDO_BITS: u32 = 8 * 128;

/// The dictionary: entries sorted by (index, sub-index).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ObjectDictionary {
    entries: Vec<Entry>,
}

impl ObjectDictionary {
    pub fn new() -> Self {
        Self::default()
    }

    /// Adds (or replaces) an entry.
    pub fn insert(
        &mut self,
        index: u16,
        sub: u8,
        access: ObjectAccess,
        mappable: Mappable,
        data: &[u8],
    ) {
        let entry = Entry {
            index,
            sub,
            access,
            mappable,
            data: data.to_vec(),
        };
        match self.position(index, sub) {
            Ok(at) => self.entries[at] = entry,
            Err(at) => self.entries.insert(at, entry),
        }
    }

    /// Adds a record or array: sub-index 0 (u8, the number of entries in use) and the
    /// 32-bit entries 1..=`capacity`, the first ones set from `values`.
    pub fn insert_u32_array(&mut self, index: u16, capacity: u8, values: &[u32]) {
        let access = ObjectAccess::ReadWrite;
        self.insert(index, 0, access, Mappable::No, &[values.len() as u8]);
        for sub in 1..=capacity {
            let value = values.get(usize::from(sub) - 1).copied().unwrap_or(0);
            self.insert(index, sub, access, Mappable::No, &value.to_le_bytes());
        }
    }

    fn position(&self, index: u16, sub: u8) -> Result<usize, usize> {
        self.entries
            .binary_search_by(|e| (e.index, e.sub).cmp(&(index, sub)))
    }

    /// The entry at (index, sub-index).
    pub fn entry(&self, index: u16, sub: u8) -> Result<&Entry, SdoAbort> {
        match self.position(index, sub) {
            Ok(at) => Ok(&self.entries[at]),
            Err(_) if self.has_object(index) => Err(SdoAbort::NoSubIndex),
            Err(_) => Err(SdoAbort::NoObject),
        }
    }

    /// Whether any sub-index of `index` exists.
    pub fn has_object(&self, index: u16) -> bool {
        self.entries.iter().any(|e| e.index == index)
    }

    /// The value at (index, sub-index), for the application (no access check).
    pub fn get(&self, index: u16, sub: u8) -> Option<&[u8]> {
        self.entry(index, sub).ok().map(|e| e.data.as_slice())
    }

    /// Sets a value from the application side (no access check); the length must match.
    pub fn set(&mut self, index: u16, sub: u8, data: &[u8]) -> Result<(), SdoAbort> {
        let at = self.position(index, sub).map_err(|_| SdoAbort::NoObject)?;
        let entry = &mut self.entries[at];
        if entry.data.len() != data.len() {
            return Err(SdoAbort::LengthMismatch);
        }
        entry.data.copy_from_slice(data);
        Ok(())
    }

    /// An SDO upload: the value the MainDevice reads.
    pub fn upload(&self, index: u16, sub: u8) -> Result<&[u8], SdoAbort> {
        self.entry(index, sub).map(|e| e.data.as_slice())
    }

    /// An SDO download in `state`: access, length and the PDO mapping rules checked.
    pub fn download(
        &mut self,
        index: u16,
        sub: u8,
        data: &[u8],
        state: AlState,
    ) -> Result<(), SdoAbort> {
        let entry = self.entry(index, sub)?;
        if entry.access == ObjectAccess::ReadOnly {
            return Err(SdoAbort::ReadOnly);
        }
        if entry.data.len() != data.len() {
            return Err(SdoAbort::LengthMismatch);
        }
        let pdo_object = RX_MAPPING.contains(&index)
            || TX_MAPPING.contains(&index)
            || index == RX_ASSIGN
            || index == TX_ASSIGN;
        if pdo_object {
            if state != AlState::PreOp {
                return Err(SdoAbort::DeviceState);
            }
            if sub == 0 {
                let count = data.first().copied().unwrap_or(0);
                self.check_pdo_object(index, count)?;
            } else if self.get(index, 0).and_then(|b| b.first().copied()) != Some(0) {
                return Err(SdoAbort::SubIndex0MustBeZero);
            }
        }
        self.set(index, sub, data)
    }

    /// Checks that entries 1..=`count` of a mapping or assignment object are valid.
    fn check_pdo_object(&self, index: u16, count: u8) -> Result<(), SdoAbort> {
        if count > 0 && self.entry(index, count).is_err() {
            return Err(SdoAbort::ValueRange);
        }
        let mut bits = 0u32;
        for sub in 1..=count {
            if index == RX_ASSIGN || index == TX_ASSIGN {
                let pdo = self
                    .get(index, sub)
                    .and_then(|b| le::u16_at(b, 0))
                    .unwrap_or(0);
                let range = if index == RX_ASSIGN {
                    RX_MAPPING
                } else {
                    TX_MAPPING
                };
                if !range.contains(&pdo) || !self.has_object(pdo) {
                    return Err(SdoAbort::ValueRange);
                }
                continue;
            }
            let value = self
                .get(index, sub)
                .and_then(|b| le::u32_at(b, 0))
                .ok_or(SdoAbort::LengthMismatch)?;
            let wanted = if RX_MAPPING.contains(&index) {
                Mappable::Rx
            } else {
                Mappable::Tx
            };
            let (mapped, mapped_sub, len_bits) =
                ((value >> 16) as u16, (value >> 8) as u8, value & 0xFF);
            let entry = self
                .entry(mapped, mapped_sub)
                .map_err(|_| SdoAbort::NotMappable)?;
            if entry.mappable != wanted || entry.data.len() * 8 != len_bits as usize {
                return Err(SdoAbort::NotMappable);
            }
            bits += len_bits;
        }
        if bits > MAX_PDO_BITS {
            return Err(SdoAbort::PdoTooLong);
        }
        Ok(())
    }

    /// The process data of a sync manager from its assignment object (0x1C12 outputs,
    /// 0x1C13 inputs): the mapped entries in order, byte aligned; `None` when the assignment
    /// or a mapping refers to something absent. Allocates: call on state changes only.
    pub fn layout(&self, assign: u16) -> Option<Vec<MappedEntry>> {
        let mut out = Vec::new();
        let mut offset = 0;
        let pdos = *self.get(assign, 0)?.first()?;
        for a in 1..=pdos {
            let pdo = le::u16_at(self.get(assign, a)?, 0)?;
            let entries = *self.get(pdo, 0)?.first()?;
            for e in 1..=entries {
                let value = le::u32_at(self.get(pdo, e)?, 0)?;
                let (index, sub, bits) = ((value >> 16) as u16, (value >> 8) as u8, value & 0xFF);
                if bits % 8 != 0 {
                    return None;
                }
                let len = bits as usize / 8;
                out.push(MappedEntry {
                    index,
                    sub,
                    offset,
                    len,
                });
                offset += len;
            }
        }
        Some(out)
    }

    /// A CiA 402 servo drive's dictionary: identity, device name, the PDO mapping of the
    /// cyclic synchronous torque mode (RxPDO 0x1600: control word, target torque, modes of
    /// operation; TxPDO 0x1A00: status word, position, velocity, torque, modes display) and
    /// the objects it maps.
    pub fn cia402_drive(identity: &Identity, name: &str) -> Self {
        use Mappable::{No, Rx, Tx};
        use ObjectAccess::{ReadOnly as Ro, ReadWrite as Rw};
        let mut od = Self::new();
        od.insert(0x1000, 0, Ro, No, &0x0002_0192u32.to_le_bytes());
        od.insert(0x1008, 0, Ro, No, name.as_bytes());
        od.insert(0x1018, 0, Ro, No, &[4]);
        for (sub, v) in [
            identity.vendor_id,
            identity.product_code,
            identity.revision,
            identity.serial,
        ]
        .into_iter()
        .enumerate()
        {
            od.insert(0x1018, sub as u8 + 1, Ro, No, &v.to_le_bytes());
        }
        let map = |index: u16, sub: u8, bits: u32| {
            (u32::from(index) << 16) | (u32::from(sub) << 8) | bits
        };
        od.insert_u32_array(
            0x1600,
            8,
            &[map(0x6040, 0, 16), map(0x6071, 0, 16), map(0x6060, 0, 8)],
        );
        od.insert_u32_array(
            0x1A00,
            8,
            &[
                map(0x6041, 0, 16),
                map(0x6064, 0, 32),
                map(0x606C, 0, 32),
                map(0x6077, 0, 16),
                map(0x6061, 0, 8),
            ],
        );
        // Sync manager communication types: mailbox out, mailbox in, outputs, inputs.
        od.insert(0x1C00, 0, Ro, No, &[4]);
        for (sub, v) in [1u8, 2, 3, 4].into_iter().enumerate() {
            od.insert(0x1C00, sub as u8 + 1, Ro, No, &[v]);
        }
        for (assign, pdo) in [(RX_ASSIGN, 0x1600u16), (TX_ASSIGN, 0x1A00)] {
            od.insert(assign, 0, Rw, No, &[1]);
            od.insert(assign, 1, Rw, No, &pdo.to_le_bytes());
            od.insert(assign, 2, Rw, No, &0u16.to_le_bytes());
        }
        od.insert(0x6040, 0, Rw, Rx, &0u16.to_le_bytes());
        od.insert(0x6041, 0, Ro, Tx, &0u16.to_le_bytes());
        od.insert(0x6060, 0, Rw, Rx, &[0]);
        od.insert(0x6061, 0, Ro, Tx, &[0]);
        od.insert(0x6064, 0, Ro, Tx, &0i32.to_le_bytes());
        od.insert(0x606C, 0, Ro, Tx, &0i32.to_le_bytes());
        od.insert(0x6071, 0, Rw, Rx, &0i16.to_le_bytes());
        od.insert(0x6077, 0, Ro, Tx, &0i16.to_le_bytes());
        // Supported drive modes: CSP, CSV, CST (bits 7, 8, 9).
        od.insert(0x6502, 0, Ro, No, &0x0000_0380u32.to_le_bytes());
        od
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn od() -> ObjectDictionary {
        let id = Identity {
            vendor_id: 1,
            product_code: 2,
            revision: 3,
            serial: 4,
        };
        ObjectDictionary::cia402_drive(&id, "AX")
    }

    #[test]
    fn default_mapping_gives_the_csp_torque_layout() {
        let od = od();
        let out = od.layout(RX_ASSIGN).expect("valid");
        let lens: Vec<_> = out.iter().map(|e| (e.index, e.offset, e.len)).collect();
        assert_eq!(lens, [(0x6040, 0, 2), (0x6071, 2, 2), (0x6060, 4, 1)]);
        let inputs = od.layout(TX_ASSIGN).expect("valid");
        assert_eq!(inputs.iter().map(|e| e.len).sum::<usize>(), 13);
    }

    #[test]
    fn mapping_changes_follow_the_sub_index_0_rule_and_the_state() {
        let mut od = od();
        let entry = (0x6071u32 << 16) | 16;
        assert_eq!(
            od.download(0x1600, 1, &entry.to_le_bytes(), AlState::SafeOp),
            Err(SdoAbort::DeviceState)
        );
        assert_eq!(
            od.download(0x1600, 1, &entry.to_le_bytes(), AlState::PreOp),
            Err(SdoAbort::SubIndex0MustBeZero)
        );
        assert_eq!(od.download(0x1600, 0, &[0], AlState::PreOp), Ok(()));
        assert_eq!(
            od.download(0x1600, 1, &entry.to_le_bytes(), AlState::PreOp),
            Ok(())
        );
        assert_eq!(od.download(0x1600, 0, &[1], AlState::PreOp), Ok(()));
        assert_eq!(od.layout(RX_ASSIGN).map(|l| l.len()), Some(1));
        // A TxPDO object in an RxPDO, and a wrong length, are refused.
        od.download(0x1600, 0, &[0], AlState::PreOp).expect("clear");
        let status = (0x6041u32 << 16) | 16;
        od.download(0x1600, 1, &status.to_le_bytes(), AlState::PreOp)
            .expect("entry");
        assert_eq!(
            od.download(0x1600, 0, &[1], AlState::PreOp),
            Err(SdoAbort::NotMappable)
        );
        let short = (0x6071u32 << 16) | 8;
        od.download(0x1600, 1, &short.to_le_bytes(), AlState::PreOp)
            .expect("entry");
        assert_eq!(
            od.download(0x1600, 0, &[1], AlState::PreOp),
            Err(SdoAbort::NotMappable)
        );
    }

    #[test]
    fn access_and_addressing_errors_have_their_abort_codes() {
        let mut od = od();
        assert_eq!(
            od.download(0x6041, 0, &[0, 0], AlState::PreOp),
            Err(SdoAbort::ReadOnly)
        );
        assert_eq!(
            od.download(0x6040, 0, &[0], AlState::PreOp),
            Err(SdoAbort::LengthMismatch)
        );
        assert_eq!(od.upload(0x1018, 9), Err(SdoAbort::NoSubIndex));
        assert_eq!(od.upload(0x2000, 0), Err(SdoAbort::NoObject));
        assert_eq!(od.upload(0x1018, 1), Ok(&1u32.to_le_bytes()[..]));
    }
}
