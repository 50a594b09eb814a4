//! The error-frame policy of the cycle: what a CAN error frame (or another bus report)
//! does to a running exchange. Sans-I/O: reports and their arrival time in, a verdict
//! out; no allocation.
//!
//! A single error frame is what a healthy CAN bus shows now and then (a disturbed bit, a
//! node plugged in): the bus retransmits and the cycle goes on. What ends the exchange:
//!
//! * bus-off: this controller no longer takes part in the bus;
//! * error passive (controller class, TX or RX passive): the error counters say the bus
//!   has been failing for a while (at least 16 errors without the successes to recover);
//! * a burst: more than [`ErrorFramePolicy::max_frames`] error frames within
//!   [`ErrorFramePolicy::window`].
//!
//! Receive-queue overruns and malformed datagrams are reports too; they lose frames, which
//! the exchange counts as missed feedback, so they are tolerated here.

use std::time::{Duration, Instant};

use flexid_can::error::controller;
use flexid_can::BusError;

/// Most error frames a burst threshold can count (the watch's fixed ring).
pub const MAX_BURST_FRAMES: u16 = 64;

/// When CAN error frames stop the cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorFramePolicy {
    /// More error frames than this within `window` stop the cycle (1..=64).
    pub max_frames: u16,
    /// The window of the burst count.
    pub window: Duration,
}

impl Default for ErrorFramePolicy {
    /// More than 10 error frames within 1 s.
    fn default() -> Self {
        Self {
            max_frames: 10,
            window: Duration::from_secs(1),
        }
    }
}

impl ErrorFramePolicy {
    /// Checks ranges; the message names the field.
    pub fn validate(&self) -> Result<(), String> {
        if !(1..=MAX_BURST_FRAMES).contains(&self.max_frames) {
            return Err(format!(
                "error_frames.max_frames {} outside 1..={MAX_BURST_FRAMES}",
                self.max_frames
            ));
        }
        if self.window.is_zero() {
            return Err("error_frames.window must be positive".into());
        }
        Ok(())
    }
}

/// What a bus report means to the cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Counted; the exchange goes on.
    Tolerate,
    /// The bus is unusable (bus-off, error passive, not a report at all).
    Abort,
    /// More than `max_frames` error frames within the window: `frames` of them.
    Burst {
        /// Error frames within the window, this one included.
        frames: u16,
    },
}

/// The error frames of the recent window.
#[derive(Debug, Clone)]
pub struct ErrorFrameWatch {
    policy: ErrorFramePolicy,
    /// Arrival times of the last error frames (a ring of `max_frames + 1`).
    ring: [Option<Instant>; MAX_BURST_FRAMES as usize + 1],
    next: usize,
    /// Error frames seen since the watch was made.
    pub frames: u64,
}

impl ErrorFrameWatch {
    /// A watch with nothing seen.
    pub fn new(policy: ErrorFramePolicy) -> Self {
        Self {
            policy,
            ring: [None; MAX_BURST_FRAMES as usize + 1],
            next: 0,
            frames: 0,
        }
    }

    /// A bus error received at `at`: whether the exchange may go on.
    pub fn on_error(&mut self, e: &BusError, at: Instant) -> Verdict {
        match e {
            BusError::ErrorFrame { info, .. } => {
                if info.controller & (controller::TX_PASSIVE | controller::RX_PASSIVE) != 0
                    && info.class.contains(flexid_can::ErrorClass::CONTROLLER)
                {
                    return Verdict::Abort;
                }
                self.frames += 1;
                let n = usize::from(self.policy.max_frames.min(MAX_BURST_FRAMES)) + 1;
                self.ring[self.next % n] = Some(at);
                self.next = (self.next + 1) % n;
                let recent = self.ring[..n]
                    .iter()
                    .flatten()
                    .filter(|t| at.saturating_duration_since(**t) < self.policy.window)
                    .count() as u16;
                if recent > self.policy.max_frames {
                    Verdict::Burst { frames: recent }
                } else {
                    Verdict::Tolerate
                }
            }
            BusError::Overrun { .. } | BusError::Malformed { .. } => Verdict::Tolerate,
            _ => Verdict::Abort, // bus-off, I/O failures
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use flexid_can::CanFrame;
    use std::sync::Arc;

    fn report(class: u32, data: [u8; 8]) -> BusError {
        let iface: Arc<str> = "inproc:t".into();
        BusError::from_error_frame(&iface, &CanFrame::error(class, data).unwrap())
    }

    #[test]
    fn single_frames_pass_bursts_and_passive_do_not() {
        let t0 = Instant::now();
        let ms = |v: u64| t0 + Duration::from_millis(v);
        let mut w = ErrorFrameWatch::new(ErrorFramePolicy {
            max_frames: 2,
            window: Duration::from_millis(10),
        });
        let proto = report(0x008, [0; 8]);
        assert_eq!(w.on_error(&proto, ms(0)), Verdict::Tolerate);
        assert_eq!(w.on_error(&proto, ms(5)), Verdict::Tolerate);
        assert_eq!(
            w.on_error(&proto, ms(11)),
            Verdict::Tolerate,
            "0 ms left the window"
        );
        assert_eq!(w.on_error(&proto, ms(12)), Verdict::Burst { frames: 3 });
        assert_eq!(w.frames, 4);
        let passive = report(0x004, [0, controller::RX_PASSIVE, 0, 0, 0, 0, 0, 0]);
        assert_eq!(w.on_error(&passive, ms(100)), Verdict::Abort);
        let warning = report(0x004, [0, controller::TX_WARNING, 0, 0, 0, 0, 0, 0]);
        assert_eq!(w.on_error(&warning, ms(200)), Verdict::Tolerate);
        assert_eq!(w.on_error(&report(0x040, [0; 8]), ms(300)), Verdict::Abort);
    }
}
