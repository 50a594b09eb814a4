//! [`Paced`]: bit-timing emulation over any [`CanBus`] without a sleep per frame.

use std::time::{Duration, Instant};

use super::wait::wait_until;
use super::wire::BusClock;
use super::{bits_ns, frame_bits};
use crate::bus::{BusStats, CanBus};
use crate::error::BusError;
use crate::frame::{CanFrame, Received};

/// Bit-timing emulation over a virtual bus: every frame occupies the emulated wire for
/// its [`CanFrame::wire_bits`] at the bitrate, from when the wire is free ([`BusClock`]),
/// and reaches the other nodes when its last bit has gone (its *due* time), as on a real
/// bus.
///
/// - **Send** never sleeps per frame: it reserves the frame's slot on the clock and hands
///   the frame, stamped with its due time, to the inner bus ([`CanBus::send_due`]) while
///   holding the clock, so the medium sees frames in wire order. Back-pressure only when
///   the transmit queue is full: when the wire is booked more than the queue's worth
///   ahead ([`Paced::with_tx_queue`], default [`Paced::DEFAULT_TX_QUEUE`] 8-byte
///   frames), the sender waits until it has drained to that bound.
/// - **Receive** delivers a frame no earlier than its due time (the frame's
///   [`Received::timestamp`]): short waits are spun, long ones slept ([`wait_until`]).
///   A frame due after the caller's timeout is kept for the next call.
///
/// The in-process bus ([`crate::InprocBus`]) carries the due time to the receivers: give
/// every handle the same [`BusClock`] (or clone handles with [`CanBus::try_clone`]) and
/// wrap every receiving handle in `Paced` too (a bare handle would get frames early, with
/// a timestamp in the future). Senders are served in the order they call `send`, not by
/// identifier (no arbitration). Buses between processes (UDP, SocketCAN) cannot carry
/// the due time: their `send_due` waits for it before sending, so each process paces
/// only its own frames (per-sender pacing, as before: several senders together can exceed
/// the bitrate unnoticed; an admission check with [`super::bus_load`] covers that).
#[derive(Debug)]
pub struct Paced<B> {
    inner: B,
    bitrate: u32,
    clock: BusClock,
    tx_queue_ns: u64,
    /// A frame received but not yet due when the last call's timeout ran out.
    pending: Option<Received>,
}

impl<B: CanBus> Paced<B> {
    /// Transmit queue depth, in 8-byte standard frames, before `send` waits.
    pub const DEFAULT_TX_QUEUE: u32 = 32;

    /// Paces `inner` at `bitrate` (bits/s) on a clock of its own.
    pub fn new(inner: B, bitrate: u32) -> Self {
        Self::with_clock(inner, bitrate, BusClock::new())
    }

    /// Paces `inner` at `bitrate` (bits/s) on a shared clock.
    pub fn with_clock(inner: B, bitrate: u32, clock: BusClock) -> Self {
        let bitrate = bitrate.max(1);
        Self {
            inner,
            bitrate,
            clock,
            tx_queue_ns: bits_ns(Self::DEFAULT_TX_QUEUE * frame_bits(8, false), bitrate),
            pending: None,
        }
    }

    /// The same with a transmit queue of `frames` 8-byte frames' wire time: `send` waits
    /// while the wire is booked further ahead than that (at least one frame).
    pub fn with_tx_queue(mut self, frames: u32) -> Self {
        self.tx_queue_ns = bits_ns(frames.max(1) * frame_bits(8, false), self.bitrate);
        self
    }

    /// The bus clock (to share with further handles).
    pub fn clock(&self) -> &BusClock {
        &self.clock
    }

    /// The emulated bitrate, in bits/s.
    pub fn bitrate(&self) -> u32 {
        self.bitrate
    }

    /// The wrapped bus.
    pub fn inner(&self) -> &B {
        &self.inner
    }

    /// Time `frame` occupies the bus (worst-case stuffing, interframe space included).
    pub fn frame_time(&self, frame: &CanFrame) -> Duration {
        Duration::from_nanos(bits_ns(frame.wire_bits(), self.bitrate))
    }
}

impl<B: CanBus> CanBus for Paced<B> {
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        let d = bits_ns(frame.wire_bits(), self.bitrate);
        let mut wire = self.clock.lock();
        let now = self.clock.now_ns();
        let slot = wire.reserve(now, d);
        let sent = self.inner.send_due(frame, self.clock.instant(slot.due_ns));
        drop(wire);
        // transmit queue full: wait until the wire is booked at most a queue ahead
        if slot.due_ns - now > self.tx_queue_ns {
            wait_until(self.clock.instant(slot.due_ns - self.tx_queue_ns));
        }
        sent
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, BusError> {
        let deadline = Instant::now().checked_add(timeout);
        let r = match self.pending.take() {
            Some(r) => r,
            None => match self.inner.recv_timeout(timeout)? {
                Some(r) => r,
                None => return Ok(None),
            },
        };
        match deadline {
            Some(d) if r.timestamp > d => {
                // due after this call's timeout: keep it (later frames are due later still)
                self.pending = Some(r);
                wait_until(d);
                Ok(None)
            }
            _ => {
                wait_until(r.timestamp);
                Ok(Some(r))
            }
        }
    }

    fn try_clone(&self) -> Result<Self, BusError> {
        Ok(Self {
            inner: self.inner.try_clone()?,
            bitrate: self.bitrate,
            clock: self.clock.clone(),
            tx_queue_ns: self.tx_queue_ns,
            pending: None,
        })
    }

    fn interface(&self) -> &str {
        self.inner.interface()
    }

    fn stats(&self) -> BusStats {
        self.inner.stats()
    }
}
