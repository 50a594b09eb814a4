//! The in-process link: ethercrab's `PduTx`/`PduRx` frame interface straight into a
//! [`Segment`], without sockets or privileges (the always-run test tier).
//!
//! [`SegmentLink`] is a future like ethercrab's own `tx_rx_task`: spawn it next to the
//! `MainDevice`. Each poll takes every sendable frame, copies it into one preallocated
//! buffer, sets the segment clock, processes the frame in place and hands it back to
//! `PduRx` (no allocation per frame unless recording).

use crate::frame::FrameError;
use crate::segment::Segment;
use ethercrab::{PduRx, PduTx, ReceiveAction};
use std::future::Future;
use std::pin::Pin;
use std::sync::{Arc, Mutex};
use std::task::{Context, Poll};
use std::time::Instant;
use thiserror::Error;

/// A segment shared between the link and the test (or the simulation that drives the
/// application behind the SubDevices).
pub type SharedSegment = Arc<Mutex<Segment>>;

/// Longest frame the link carries: a standard Ethernet frame without FCS, bytes.
pub const MAX_FRAME: usize = 1514;

/// Why the link stopped.
#[derive(Debug, Error)]
pub enum LinkError {
    #[error("frame {frame} ({len} bytes) is longer than the link's {max} bytes")]
    TooLong { frame: u64, len: usize, max: usize },
    #[error("the segment rejected frame {frame}: {source}")]
    Frame {
        frame: u64,
        #[source]
        source: FrameError,
    },
    #[error("ethercrab failed on frame {frame} while {stage}: {source}")]
    Ethercrab {
        frame: u64,
        stage: &'static str,
        #[source]
        source: ethercrab::error::Error,
    },
    #[error("ethercrab ignored returned frame {frame} (source MAC not marked forwarded?)")]
    Ignored { frame: u64 },
    #[error("the segment's lock is poisoned")]
    Poisoned,
}

/// One frame as sent by the MainDevice and as the segment returned it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Exchange {
    pub sent: Vec<u8>,
    pub returned: Vec<u8>,
}

/// Recorded exchanges, shared with the test.
pub type Recording = Arc<Mutex<Vec<Exchange>>>;

/// The link future; see the module documentation.
pub struct SegmentLink<'sto> {
    tx: PduTx<'sto>,
    rx: PduRx<'sto>,
    segment: SharedSegment,
    buffer: Box<[u8]>,
    clock: Box<dyn FnMut() -> u64 + Send>,
    recording: Option<Recording>,
    frames: u64,
}

impl<'sto> SegmentLink<'sto> {
    /// A link whose segment clock is the wall clock since the link was made (ns).
    pub fn new(tx: PduTx<'sto>, rx: PduRx<'sto>, segment: SharedSegment) -> Self {
        let start = Instant::now();
        Self {
            tx,
            rx,
            segment,
            buffer: vec![0u8; MAX_FRAME].into_boxed_slice(),
            clock: Box::new(move || start.elapsed().as_nanos() as u64),
            recording: None,
            frames: 0,
        }
    }

    /// Replaces the segment clock (ns), e.g. by a deterministic one for byte-exact replays.
    pub fn with_clock(mut self, clock: impl FnMut() -> u64 + Send + 'static) -> Self {
        self.clock = Box::new(clock);
        self
    }

    /// Records every exchange (allocates two buffers per frame).
    pub fn recording(mut self, recording: Recording) -> Self {
        self.recording = Some(recording);
        self
    }

    /// Sends, processes and returns one frame; `Ok(false)` when nothing was sendable.
    fn exchange_one(&mut self) -> Result<bool, LinkError> {
        let Some(frame) = self.tx.next_sendable_frame() else {
            return Ok(false);
        };
        let number = self.frames;
        self.frames += 1;
        let mut len = 0;
        let buffer = &mut self.buffer;
        let mut too_long = None;
        let sent = frame.send_blocking(|bytes| match buffer.get_mut(..bytes.len()) {
            Some(dst) => {
                dst.copy_from_slice(bytes);
                len = bytes.len();
                Ok(bytes.len())
            }
            None => {
                too_long = Some(bytes.len());
                Err(ethercrab::error::Error::SendFrame)
            }
        });
        if let Some(len) = too_long {
            return Err(LinkError::TooLong {
                frame: number,
                len,
                max: MAX_FRAME,
            });
        }
        sent.map_err(|source| LinkError::Ethercrab {
            frame: number,
            stage: "sending",
            source,
        })?;
        let sent_copy = self.recording.as_ref().map(|_| self.buffer[..len].to_vec());
        {
            let mut segment = self.segment.lock().map_err(|_| LinkError::Poisoned)?;
            segment.set_time_ns((self.clock)());
            segment
                .process(&mut self.buffer[..len])
                .map_err(|source| LinkError::Frame {
                    frame: number,
                    source,
                })?;
        }
        if let (Some(recording), Some(sent)) = (&self.recording, sent_copy) {
            let returned = self.buffer[..len].to_vec();
            recording
                .lock()
                .map_err(|_| LinkError::Poisoned)?
                .push(Exchange { sent, returned });
        }
        match self.rx.receive_frame(&self.buffer[..len]) {
            Ok(ReceiveAction::Processed) => Ok(true),
            Ok(ReceiveAction::Ignored) => Err(LinkError::Ignored { frame: number }),
            Err(source) => Err(LinkError::Ethercrab {
                frame: number,
                stage: "receiving",
                source,
            }),
        }
    }
}

impl Future for SegmentLink<'_> {
    type Output = Result<(), LinkError>;

    fn poll(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Self::Output> {
        let this = self.get_mut();
        this.tx.replace_waker(cx.waker());
        loop {
            if this.tx.should_exit() {
                return Poll::Ready(Ok(()));
            }
            match this.exchange_one() {
                Ok(true) => continue,
                Ok(false) => return Poll::Pending,
                Err(e) => return Poll::Ready(Err(e)),
            }
        }
    }
}
