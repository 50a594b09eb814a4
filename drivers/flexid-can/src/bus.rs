//! The one interface every bus implements: blocking, for a real-time thread.

use std::time::{Duration, Instant};

use crate::error::BusError;
use crate::frame::{CanFrame, Received};

/// A handle on a CAN bus: one node's view (its own receive queue).
///
/// Blocking on purpose: the cycle thread is a plain (real-time) OS thread, not an async
/// task. Implementations: [`crate::InprocBus`] (unit tests), [`crate::UdpMulticastBus`]
/// (python-can compatible virtual bus) and `SocketCanBus` (Linux `can0`/`vcan0`); and
/// [`crate::timing::Paced`], which wraps any of them with bit-timing emulation.
///
/// Like a node on a real bus, a handle does not receive the frames it sent itself, but
/// does receive those of every other handle, including ones obtained through
/// [`CanBus::try_clone`] (as two SocketCAN sockets on one interface do).
///
/// Received error frames are not returned as frames: `recv_timeout` reports them as
/// [`BusError::ErrorFrame`] or [`BusError::BusOff`] (see [`BusError::is_report`]), and the
/// handle stays usable.
pub trait CanBus: Send {
    /// Queues one frame for transmission. Blocks at most as long as the OS (or the bit
    /// timing emulation) makes it.
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError>;

    /// Queues one frame that the bit-timing emulation ([`crate::timing::Paced`]) says is
    /// due at its receivers at `due` (the end of its transmission on the emulated wire).
    /// A bus that can carry the due time to the receivers stamps the frame with it (its
    /// [`Received::timestamp`], in-process bus); the default waits until `due`
    /// ([`crate::timing::wait_until`]), then sends.
    fn send_due(&mut self, frame: &CanFrame, due: Instant) -> Result<(), BusError> {
        crate::timing::wait_until(due);
        self.send(frame)
    }

    /// Waits up to `timeout` for the next frame from another node. `Ok(None)` when the
    /// time ran out. A zero timeout polls.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, BusError>;

    /// A second, independent handle on the same bus (its own socket and receive queue):
    /// e.g. the SDO client's, beside the cycle thread's. Frames sent through either
    /// handle are received by the other.
    fn try_clone(&self) -> Result<Self, BusError>
    where
        Self: Sized;

    /// The interface's name as used in errors (`can0`, `udp:239.74.163.2:43113`, ...).
    fn interface(&self) -> &str;

    /// Counters of this handle.
    fn stats(&self) -> BusStats {
        BusStats::default()
    }
}

/// Per-handle counters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BusStats {
    /// Frames sent.
    pub sent: u64,
    /// Frames received (data and remote frames handed to the caller).
    pub received: u64,
    /// Error frames received (reported as errors).
    pub error_frames: u64,
    /// Datagrams that were not valid messages, skipped (UDP only).
    pub malformed: u64,
    /// Valid messages this bus does not carry (CAN FD), skipped (UDP only).
    pub ignored: u64,
    /// Frames lost to a full receive queue.
    pub lost: u64,
}
