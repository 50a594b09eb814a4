//! CAN bit timing: worst-case frame lengths, bus load, and [`Paced`], a wrapper that
//! makes a virtual bus take as long as a real one.
//!
//! - [`frame_bits`], [`bus_load`]: pure admission arithmetic (this file).
//! - [`WireClock`] / [`BusClock`] (`wire.rs`): when the emulated medium is free; each
//!   frame gets a start and a due (end-of-transmission) time.
//! - [`Paced`] (`paced.rs`): a [`CanBus`](crate::CanBus) wrapper that stamps frames with
//!   their due time instead of sleeping per frame, and delivers them no earlier.
//! - [`wait_until`] (`wait.rs`): the receiver's wait for a due time (short waits spun,
//!   long ones slept).
//!
//! # Frame length
//!
//! A classic CAN data frame with `n` data bytes consists of
//!
//! | field | standard (11-bit id) | extended (29-bit id) |
//! |---|---|---|
//! | SOF | 1 | 1 |
//! | arbitration | 11 id + RTR = 12 | 11 id + SRR + IDE + 18 id + RTR = 32 |
//! | control | IDE + r0 + 4 DLC = 6 | r1 + r0 + 4 DLC = 6 |
//! | data | 8n | 8n |
//! | CRC | 15 | 15 |
//! | CRC delimiter, ACK slot, ACK delimiter, EOF | 1 + 1 + 1 + 7 = 10 | 10 |
//! | **total, unstuffed** | **44 + 8n** | **64 + 8n** |
//!
//! Bit stuffing applies from SOF to the end of the CRC: `g + 8n` bits with `g = 34`
//! (standard) or `g = 54` (extended). After five equal bits the transmitter inserts a
//! complementary one, which itself can start the next run of five: the worst case is one
//! stuff bit after the first 5 bits and then one after every 4, at most
//! `⌊(g + 8n − 1) / 4⌋` stuff bits (Davis, Burns, Bril, Lukkien, "Controller Area Network
//! (CAN) schedulability analysis: refuted, revisited and revised", Real-Time Systems
//! 35(3), 2007, eq. 1). Adding the 3-bit interframe space that must follow before the
//! next frame can start gives
//!
//! ```text
//! bits(n) = g + 8n + 13 + ⌊(g + 8n − 1) / 4⌋
//! ```
//!
//! i.e. 135 bits for 8 bytes standard (55 for 0 bytes), 160 for 8 bytes extended (80 for
//! 0 bytes): the figures of that paper. Remote frames have no data field (`n = 0`,
//! whatever their DLC).

use std::time::Duration;

mod paced;
mod wait;
mod wire;

pub use paced::Paced;
pub use wait::{wait_until, SPIN_BELOW};
pub use wire::{BusClock, Slot, WireClock};

/// Interframe space, in bits (counted in [`frame_bits`]).
pub const IFS_BITS: u32 = 3;

/// Worst-case bits a frame with `data_len` data bytes (clamped to 8) occupies on the bus,
/// bit stuffing and interframe space included (see the module docs).
pub const fn frame_bits(data_len: u8, extended: bool) -> u32 {
    let n = if data_len > 8 { 8 } else { data_len } as u32;
    let g = if extended { 54 } else { 34 };
    g + 8 * n + 10 + IFS_BITS + (g + 8 * n - 1) / 4
}

/// Time on the bus of `bits` at `bitrate` (bits/s).
pub fn bits_duration(bits: u32, bitrate: u32) -> Duration {
    Duration::from_nanos(bits_ns(bits, bitrate))
}

/// Time on the bus of `bits` at `bitrate` (bits/s), in ns (truncated).
pub const fn bits_ns(bits: u32, bitrate: u32) -> u64 {
    let rate = if bitrate == 0 { 1 } else { bitrate };
    bits as u64 * 1_000_000_000 / rate as u64
}

/// The shape of a frame for load calculations.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameShape {
    /// Data bytes (0..=8; 0 for remote frames).
    pub data_len: u8,
    /// 29-bit identifier.
    pub extended: bool,
}

impl FrameShape {
    /// A standard-id frame of `data_len` bytes (CANopen PDOs, SYNC, SDOs).
    pub const fn standard(data_len: u8) -> Self {
        Self {
            data_len,
            extended: false,
        }
    }
}

/// Worst-case bus load, as a fraction of the bus's capacity (1.0 = saturated), of sending
/// `frames_per_cycle` every cycle at `cycle_rate_hz` (cycles/s) on a bus of `bitrate`
/// (bits/s). A cycle set is admissible only well below 1 (CANopen practice: ≤ 0.7,
/// leaving room for SDOs, EMCYs and error frames).
pub fn bus_load(frames_per_cycle: &[FrameShape], cycle_rate_hz: f64, bitrate: u32) -> f64 {
    let bits: u64 = frames_per_cycle
        .iter()
        .map(|f| frame_bits(f.data_len, f.extended) as u64)
        .sum();
    bits as f64 * cycle_rate_hz / bitrate as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_bits_match_published_worst_cases() {
        // Davis et al. 2007 (and Tindell's earlier analysis): 135 bits for 8 bytes
        // standard, 160 for 8 bytes extended, interframe space included.
        assert_eq!(frame_bits(8, false), 135);
        assert_eq!(frame_bits(0, false), 55);
        assert_eq!(frame_bits(8, true), 160);
        assert_eq!(frame_bits(0, true), 80);
        // closed form for standard frames: 55 + 10n (Davis: "C = (55 + 10 s) τ")
        for n in 0..=8u8 {
            assert_eq!(frame_bits(n, false), 55 + 10 * n as u32, "n={n}");
        }
        // unstuffed length + IFS is the lower bound
        for n in 0..=8u8 {
            assert!(frame_bits(n, false) >= 44 + 8 * n as u32 + IFS_BITS);
            assert!(frame_bits(n, true) >= 64 + 8 * n as u32 + IFS_BITS);
        }
        assert_eq!(frame_bits(200, false), 135);
    }

    #[test]
    fn bus_load_of_a_canopen_cycle() {
        // SYNC (0 bytes) + 2 RPDOs + 2 TPDOs of 8 bytes at 1 kHz on 1 Mbit/s:
        // (55 + 4 * 135) bits * 1000 / 1e6 = 0.595
        let frames = [
            FrameShape::standard(0),
            FrameShape::standard(8),
            FrameShape::standard(8),
            FrameShape::standard(8),
            FrameShape::standard(8),
        ];
        let load = bus_load(&frames, 1000.0, 1_000_000);
        assert!((load - 0.595).abs() < 1e-12, "{load}");
        assert_eq!(bits_duration(135, 500_000), Duration::from_micros(270));
    }
}
