//! FMMUs: each maps a range of the 32-bit logical address space onto ESC memory for reading
//! (inputs), writing (outputs) or both. Byte granularity: the start/end bit fields are
//! ignored (ethercrab maps whole bytes).

use super::registers::{FMMU0, FMMU_LEN};
use crate::le;

/// One FMMU as configured in registers `0x0600 + 16 n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Fmmu {
    pub logical_start: u32,
    /// Length, bytes.
    pub len: u16,
    pub physical_start: u16,
    pub read: bool,
    pub write: bool,
    pub enabled: bool,
}

impl Fmmu {
    /// FMMU `n` from ESC memory.
    pub fn read_from(memory: &[u8], n: u16) -> Option<Self> {
        let base = usize::from(FMMU0 + n * FMMU_LEN);
        let regs = memory.get(base..base + usize::from(FMMU_LEN))?;
        Some(Self {
            logical_start: le::u32_at(regs, 0)?,
            len: le::u16_at(regs, 4)?,
            physical_start: le::u16_at(regs, 8)?,
            read: regs[11] & 0x01 != 0,
            write: regs[11] & 0x02 != 0,
            enabled: regs[12] & 0x01 != 0,
        })
    }

    /// The overlap of this FMMU with the logical range `[start, start + len)` of a PDU:
    /// (offset in the PDU data, physical address, length), bytes.
    pub fn overlap(&self, start: u32, len: usize) -> Option<(usize, u16, usize)> {
        if !self.enabled || self.len == 0 {
            return None;
        }
        let pdu_start = u64::from(start);
        let pdu_end = pdu_start + len as u64;
        let fmmu_start = u64::from(self.logical_start);
        let fmmu_end = fmmu_start + u64::from(self.len);
        let from = pdu_start.max(fmmu_start);
        let to = pdu_end.min(fmmu_end);
        if from >= to {
            return None;
        }
        let physical = u64::from(self.physical_start) + (from - fmmu_start);
        let physical = u16::try_from(physical).ok()?;
        Some(((from - pdu_start) as usize, physical, (to - from) as usize))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_clips_to_both_ranges() {
        let f = Fmmu {
            logical_start: 100,
            len: 10,
            physical_start: 0x1100,
            read: false,
            write: true,
            enabled: true,
        };
        assert_eq!(f.overlap(90, 15), Some((10, 0x1100, 5)));
        assert_eq!(f.overlap(105, 20), Some((0, 0x1105, 5)));
        assert_eq!(f.overlap(110, 4), None);
        assert_eq!(
            Fmmu {
                enabled: false,
                ..f
            }
            .overlap(100, 4),
            None
        );
    }
}
