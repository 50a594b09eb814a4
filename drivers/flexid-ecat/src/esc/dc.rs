//! Distributed clocks: the local clock of a SubDevice, the receive-time latches of register
//! 0x0900, system time (local time + offset), the system time difference written by the
//! drift compensation (FRMW of the reference's time), and SYNC0.
//!
//! The emulated clocks do not drift, and the drift control loop is ideal: a write of the
//! reference's time reports the error in the difference register and corrects the offset by
//! it at once (a real ESC slews its clock over many writes).

use super::registers::{
    DC_RECEIVE_TIME_PU, DC_SYNC0_CYCLE, DC_SYNC_ACTIVE, DC_SYNC_START_TIME, DC_SYSTEM_TIME,
    DC_SYSTEM_TIME_DELAY, DC_SYSTEM_TIME_DIFFERENCE, DC_SYSTEM_TIME_OFFSET, DC_TIME_PORT0,
};
use crate::le;

/// When a frame passed this SubDevice, in its local time (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PortTimes {
    /// Arrival at port 0 (from the MainDevice), ns.
    pub port0: u64,
    /// Return through port 1 (from the SubDevices behind), ns; `None` when port 1 is open.
    pub port1: Option<u64>,
}

/// Latches the receive times on a write to 0x0900: ports 0..3 (low 32 bits) and the
/// processing unit's receive time (64 bits).
pub fn latch(memory: &mut [u8], times: PortTimes) {
    let base = usize::from(DC_TIME_PORT0);
    let _ = le::put_u32(memory, base, times.port0 as u32);
    let _ = le::put_u32(memory, base + 4, times.port1.unwrap_or(0) as u32);
    let _ = le::put_u32(memory, base + 8, 0);
    let _ = le::put_u32(memory, base + 12, 0);
    let _ = le::put_u64(memory, usize::from(DC_RECEIVE_TIME_PU), times.port0);
}

/// System time at local time `local` (ns): local time plus the offset register.
pub fn system_time(memory: &[u8], local: u64) -> u64 {
    let offset = le::u64_at(memory, usize::from(DC_SYSTEM_TIME_OFFSET)).unwrap_or(0);
    local.wrapping_add(offset)
}

/// Refreshes the system time register for a frame arriving at local time `local`.
pub fn refresh(memory: &mut [u8], local: u64) {
    let now = system_time(memory, local);
    let _ = le::put_u64(memory, usize::from(DC_SYSTEM_TIME), now);
}

/// A write of the reference's system time to 0x0910 (drift compensation): stores the
/// difference between it (plus the transmission delay) and the own system time, sign and
/// magnitude, corrects the offset by it, and restores the register to the (corrected) own
/// system time.
pub fn compare_system_time(memory: &mut [u8], local: u64) {
    let written = le::u64_at(memory, usize::from(DC_SYSTEM_TIME)).unwrap_or(0);
    let delay = le::u32_at(memory, usize::from(DC_SYSTEM_TIME_DELAY)).unwrap_or(0);
    let own = system_time(memory, local);
    let reference = written.wrapping_add(u64::from(delay));
    let (sign, magnitude) = if reference >= own {
        (0, reference - own)
    } else {
        (1u32 << 31, own - reference)
    };
    let difference = sign | (magnitude.min(0x7FFF_FFFF) as u32);
    let _ = le::put_u32(memory, usize::from(DC_SYSTEM_TIME_DIFFERENCE), difference);
    let offset_at = usize::from(DC_SYSTEM_TIME_OFFSET);
    let offset = le::u64_at(memory, offset_at).unwrap_or(0);
    let _ = le::put_u64(
        memory,
        offset_at,
        offset.wrapping_add(reference.wrapping_sub(own)),
    );
    refresh(memory, local);
}

/// SYNC0 as configured: first pulse and cycle, system time (ns).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Sync0 {
    /// System time of the first pulse, ns.
    pub start: u64,
    /// Cycle time, ns (> 0).
    pub cycle: u64,
}

impl Sync0 {
    /// SYNC0 when cyclic operation and SYNC0 are both activated (0x0981 bits 0 and 1) with a
    /// non-zero cycle.
    pub fn configured(memory: &[u8]) -> Option<Self> {
        let active = *memory.get(usize::from(DC_SYNC_ACTIVE))?;
        let cycle = u64::from(le::u32_at(memory, usize::from(DC_SYNC0_CYCLE))?);
        let start = le::u64_at(memory, usize::from(DC_SYNC_START_TIME))?;
        (active & 0x03 == 0x03 && cycle > 0).then_some(Self { start, cycle })
    }

    /// Pulses generated up to system time `now` (inclusive), ns.
    pub fn pulses_until(&self, now: u64) -> u64 {
        if now < self.start {
            0
        } else {
            (now - self.start) / self.cycle + 1
        }
    }

    /// System time of the first pulse after `now`, ns.
    pub fn next_after(&self, now: u64) -> u64 {
        self.start + self.pulses_until(now) * self.cycle
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_time_is_local_plus_offset_and_differences_are_sign_magnitude() {
        let mut mem = vec![0u8; 0x1000];
        let _ = le::put_u64(
            &mut mem,
            usize::from(DC_SYSTEM_TIME_OFFSET),
            1_000u64.wrapping_neg(),
        );
        assert_eq!(system_time(&mem, 5_000), 4_000);
        let _ = le::put_u64(&mut mem, usize::from(DC_SYSTEM_TIME), 3_900);
        let _ = le::put_u32(&mut mem, usize::from(DC_SYSTEM_TIME_DELAY), 50);
        compare_system_time(&mut mem, 5_000);
        assert_eq!(le::u32_at(&mem, 0x092C), Some((1 << 31) | 50));
        // Corrected at once: the own system time is now the reference's plus the delay.
        assert_eq!(le::u64_at(&mem, 0x0910), Some(3_950));
        assert_eq!(system_time(&mem, 6_000), 4_950);
    }

    #[test]
    fn sync0_counts_pulses_from_its_start() {
        let s = Sync0 {
            start: 1_000_000,
            cycle: 250_000,
        };
        assert_eq!(s.pulses_until(999_999), 0);
        assert_eq!(s.pulses_until(1_000_000), 1);
        assert_eq!(s.pulses_until(2_000_000), 5);
        assert_eq!(s.next_after(2_000_000), 2_250_000);
    }
}
