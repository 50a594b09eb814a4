//! When the emulated medium is free: [`WireClock`] (pure arithmetic on nanoseconds) and
//! [`BusClock`] (one shared by every handle of a bus, on the monotonic clock).
//!
//! A frame queued at `now` starts when the bus is free (`max(now, free)`) and ends
//! (is *due* at its receivers) its bit time later; the bus is then free at the due time.
//! Frames therefore serialise in the order they are queued, with no gap while there is a
//! backlog: a burst of frames `f1, f2, ...` queued on an idle bus at `t0` is due at
//! `t0 + T1`, `t0 + T1 + T2`, ... (no arbitration by identifier).

use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

/// One frame's time on the wire, ns on the clock it was reserved on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    /// When its first bit (SOF) goes out.
    pub start_ns: u64,
    /// When its last bit (interframe space included) has gone: when receivers get it.
    pub due_ns: u64,
}

/// The state of one emulated medium: when it is next free, and how much wire time it has
/// carried. Pure: the caller passes the time.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct WireClock {
    free_ns: u64,
    busy_ns: u64,
    frames: u64,
}

impl WireClock {
    /// A bus free since time 0 that has carried nothing.
    pub const fn new() -> Self {
        Self {
            free_ns: 0,
            busy_ns: 0,
            frames: 0,
        }
    }

    /// Reserves `duration_ns` of wire for a frame queued at `now_ns`: it starts at the
    /// later of now and the end of the previous frame.
    #[inline]
    pub fn reserve(&mut self, now_ns: u64, duration_ns: u64) -> Slot {
        let start_ns = self.free_ns.max(now_ns);
        let due_ns = start_ns + duration_ns;
        self.free_ns = due_ns;
        self.busy_ns += duration_ns;
        self.frames += 1;
        Slot { start_ns, due_ns }
    }

    /// When the bus is next free (the due time of the last frame reserved).
    pub fn free_ns(&self) -> u64 {
        self.free_ns
    }

    /// Wire time reserved in total, ns.
    pub fn busy_ns(&self) -> u64 {
        self.busy_ns
    }

    /// Frames reserved in total.
    pub fn frames(&self) -> u64 {
        self.frames
    }
}

/// A [`WireClock`] on the monotonic clock, shared by all [`super::Paced`] handles given
/// it (and by their [`crate::CanBus::try_clone`]s). Cloning shares it.
#[derive(Debug, Clone)]
pub struct BusClock {
    origin: Instant,
    wire: Arc<Mutex<WireClock>>,
}

impl Default for BusClock {
    fn default() -> Self {
        Self::new()
    }
}

impl BusClock {
    /// A bus that is free now.
    pub fn new() -> Self {
        Self {
            origin: Instant::now(),
            wire: Arc::new(Mutex::new(WireClock::new())),
        }
    }

    /// Nanoseconds since this clock's origin.
    #[inline]
    pub fn now_ns(&self) -> u64 {
        self.ns_of(Instant::now())
    }

    /// An instant as ns since this clock's origin (0 before it).
    #[inline]
    pub fn ns_of(&self, t: Instant) -> u64 {
        t.saturating_duration_since(self.origin).as_nanos() as u64
    }

    /// The instant of `ns` since this clock's origin.
    #[inline]
    pub fn instant(&self, ns: u64) -> Instant {
        self.origin + Duration::from_nanos(ns)
    }

    /// The wire, locked: reserve a slot and hand the frame to the medium while holding it,
    /// so that the medium sees frames in wire order.
    pub fn lock(&self) -> MutexGuard<'_, WireClock> {
        self.wire.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Reserves `d` of wire for a frame queued now; returns its due time.
    pub fn reserve(&self, d: Duration) -> Instant {
        let mut w = self.lock();
        let slot = w.reserve(self.now_ns(), d.as_nanos() as u64);
        self.instant(slot.due_ns)
    }

    /// Wire time reserved so far (all handles).
    pub fn busy(&self) -> Duration {
        Duration::from_nanos(self.lock().busy_ns())
    }

    /// A copy of the wire's state.
    pub fn snapshot(&self) -> WireClock {
        *self.lock()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::timing::{bits_ns, bus_load, frame_bits, FrameShape};

    /// The default CANopen cycle of one axis at 1 Mbit/s, queued as a burst on an idle
    /// bus at t = 10 us: RPDO1 (4 B, 95 bits), SYNC (0 B, 55 bits), then the drive's
    /// TPDO1 (8 B, 135 bits) and TPDO2 (4 B, 95 bits), both queued at 12 us (the bus is
    /// still busy). Due times by hand, 1 bit = 1 us.
    #[test]
    fn due_times_of_a_burst_by_hand() {
        let mut w = WireClock::new();
        let us = 1_000;
        let bit = |n: u8| bits_ns(frame_bits(n, false), 1_000_000);
        assert_eq!(bit(4), 95 * us);
        let a = w.reserve(10 * us, bit(4));
        let b = w.reserve(10 * us, bit(0));
        let c = w.reserve(12 * us, bit(8));
        let d = w.reserve(12 * us, bit(4));
        assert_eq!((a.start_ns, a.due_ns), (10 * us, 105 * us));
        assert_eq!((b.start_ns, b.due_ns), (105 * us, 160 * us));
        assert_eq!((c.start_ns, c.due_ns), (160 * us, 295 * us));
        assert_eq!((d.start_ns, d.due_ns), (295 * us, 390 * us));
        // an idle gap: the next frame starts when queued, not when the bus became free
        let e = w.reserve(1000 * us, bit(1));
        assert_eq!((e.start_ns, e.due_ns), (1000 * us, 1065 * us));
        assert_eq!(w.busy_ns(), (95 + 55 + 135 + 95 + 65) * us);
        assert_eq!(w.frames(), 5);
        assert_eq!(w.free_ns(), 1065 * us);
    }

    /// Bus load measured from the reserved wire time of a periodic cycle equals
    /// [`bus_load`]'s formula, below saturation; above it the bus is busy all the time
    /// and the backlog (free time - now) grows by the excess each cycle.
    #[test]
    fn bus_load_from_the_wire_matches_the_formula() {
        let shapes = [0u8, 4, 8, 4].map(FrameShape::standard);
        let bitrate = 1_000_000;
        for rate_hz in [500u64, 1000, 2000, 2500, 3000] {
            let period_ns = 1_000_000_000 / rate_hz;
            let mut w = WireClock::new();
            let cycles = 200;
            for k in 0..cycles {
                for s in &shapes {
                    w.reserve(
                        k * period_ns,
                        bits_ns(frame_bits(s.data_len, false), bitrate),
                    );
                }
            }
            let formula = bus_load(&shapes, 1e9 / period_ns as f64, bitrate);
            let span = cycles * period_ns;
            if formula <= 1.0 {
                let measured = w.busy_ns() as f64 / span as f64;
                assert!(
                    (measured - formula).abs() < 1e-9,
                    "{rate_hz}: {measured} vs {formula}"
                );
                assert!(w.free_ns() <= span, "backlog at {rate_hz} Hz");
            } else {
                // saturated: contiguous from 0, backlog = (load - 1) * span
                assert_eq!(w.free_ns(), w.busy_ns());
                let backlog = w.free_ns() as f64 - span as f64;
                let want = (formula - 1.0) * span as f64;
                assert!(
                    (backlog - want).abs() < 1e-6 * span as f64,
                    "{backlog} vs {want}"
                );
            }
        }
    }
}
