//! The real-time cycle thread: a plain OS thread that sends a set-point and reads the
//! feedback once per period (1-4 kHz), and its timing.
//!
//! * [`Pacer`]: absolute deadlines on `CLOCK_MONOTONIC` (`clock_nanosleep` with
//!   `TIMER_ABSTIME`); on an overrun the missed deadlines are **skipped** (counted, never
//!   caught up: the cycle does not burst).
//! * [`RtSetup`] / [`RtGranted`]: optional `SCHED_FIFO`, `mlockall`, CPU affinity; a
//!   refusal is a logged warning, never an error.
//! * [`spawn_cycle_thread`]: applies the setup, paces a body `FnMut(&Tick) ->
//!   ControlFlow<()>`, joins to a [`CycleReport`].
//! * [`TimingStats`] / [`Histogram`]: lateness p50/p99/p99.9/max (relative error < 0.4 %),
//!   late wake-ups (> 10 % of the period), overruns; no allocation while recording.
//!
//! ```no_run
//! use std::ops::ControlFlow;
//! use std::time::Duration;
//! use flexid_rt::{spawn_cycle_thread, RtSetup};
//!
//! let h = spawn_cycle_thread("flexid-cycle", RtSetup::realtime(80), Duration::from_micros(500),
//!     move |tick| {
//!         // let fb = drive.cycle(torque[tick.index as usize], tick.next_deadline)?;
//!         if tick.index >= 3999 { ControlFlow::Break(()) } else { ControlFlow::Continue(()) }
//!     })?;
//! let report = h.join().expect("cycle thread panicked");
//! println!("p99 lateness {} ns, {} overruns", report.lateness.p99_ns, report.overruns);
//! # Ok::<(), flexid_rt::RtError>(())
//! ```
//!
//! Linux uses `libc`; other systems compile with a fallback (`Instant` and relative
//! sleeps, nothing real-time granted).

pub mod clock;
mod pacer;
mod setup;
mod stats;
mod thread;

use std::time::Duration;

pub use pacer::{skip_to, Pacer, Tick};
pub use setup::{RtGranted, RtSetup};
pub use stats::{Histogram, LatencySummary, TimingStats, RELATIVE_ERROR};
pub use thread::{run_cycle_loop, spawn_cycle_thread, CycleReport};

/// Errors of the cycle thread. Missing real-time rights are not errors (see [`RtSetup`]).
#[derive(Debug, thiserror::Error)]
pub enum RtError {
    /// The period is zero or longer than an hour.
    #[error("invalid cycle period {period:?}: must be > 0 and at most 1 h")]
    InvalidPeriod {
        /// The period given.
        period: Duration,
    },
    /// The OS refused to create the thread.
    #[error("cannot spawn the cycle thread: {0}")]
    Spawn(#[from] std::io::Error),
}
