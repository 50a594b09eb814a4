//! Sync managers: each guards an area of process RAM as a mailbox (one buffer, handshake on
//! the last byte) or as a process-data buffer. The 3-buffer exchange of process data is
//! emulated as one buffer: the MainDevice always sees the latest data.

use super::registers::{SM0, SM_LEN};
use crate::le;

/// Sync manager operation mode (control bits 0..1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmMode {
    /// Buffered (process data).
    Buffered,
    /// Mailbox (one buffer, full/empty handshake).
    Mailbox,
}

/// Who writes the area (control bits 2..3).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SmDirection {
    /// The MainDevice reads (inputs, send mailbox).
    MainDeviceReads,
    /// The MainDevice writes (outputs, receive mailbox).
    MainDeviceWrites,
}

/// One sync manager as configured in registers `0x0800 + 8 n`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SyncManager {
    pub start: u16,
    /// Length, bytes.
    pub len: u16,
    pub mode: SmMode,
    pub direction: SmDirection,
    pub enabled: bool,
}

impl SyncManager {
    /// Sync manager `n` from ESC memory.
    pub fn read_from(memory: &[u8], n: u16) -> Option<Self> {
        let base = usize::from(SM0 + n * SM_LEN);
        let control = *memory.get(base + 4)?;
        Some(Self {
            start: le::u16_at(memory, base)?,
            len: le::u16_at(memory, base + 2)?,
            mode: if control & 0x03 == 0x02 {
                SmMode::Mailbox
            } else {
                SmMode::Buffered
            },
            direction: if control & 0x0C == 0x04 {
                SmDirection::MainDeviceWrites
            } else {
                SmDirection::MainDeviceReads
            },
            enabled: memory.get(base + 6).is_some_and(|b| b & 0x01 != 0),
        })
    }

    /// Whether the area overlaps `[start, end)`.
    pub fn overlaps(&self, start: u32, end: u32) -> bool {
        let own_start = u32::from(self.start);
        let own_end = own_start + u32::from(self.len);
        self.enabled && self.len > 0 && start < own_end && end > own_start
    }

    /// Whether `[start, end)` covers the last byte of the area (the mailbox handshake byte).
    pub fn covers_last_byte(&self, start: u32, end: u32) -> bool {
        let last = u32::from(self.start) + u32::from(self.len) - 1;
        self.enabled && self.len > 0 && start <= last && end > last
    }

    /// Address of the status byte of sync manager `n`.
    pub fn status_address(n: u16) -> usize {
        usize::from(SM0 + n * SM_LEN + 5)
    }
}

/// Status byte bit: mailbox full.
pub const STATUS_MAILBOX_FULL: u8 = 1 << 3;
