//! The segment's wall clock and the thread that runs SYNC0 pulses at their time.
//!
//! A segment served on a real interface ([`crate::socket_link`]) or linked in process with
//! a wall clock needs its SYNC0 pulses to come when they are due, also while no frame
//! arrives (a late or missing frame must show as a missed cycle of a servo on the SYNC0
//! clock, not as a slowed plant). [`run_sync0_clock`] sleeps to the next pulse of any
//! SubDevice and hands the pulses due to the applications
//! ([`crate::Segment::run_sync0_until`]); frames run the pulses due before them
//! themselves, so pulses and frames stay in time order whichever thread comes first.

use crate::inprocess::SharedSegment;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Longest sleep of the clock thread (while SYNC0 is off, and to look at the stop flag).
pub const IDLE_SLEEP: Duration = Duration::from_millis(1);

/// The segment clock on the wall: ns since an origin (the OS's monotonic clock, the one
/// the MainDevice's `Instant` and ethercrab's `ethercat_now` read).
#[derive(Debug, Clone, Copy)]
pub struct SegmentClock {
    origin: Instant,
}

impl SegmentClock {
    /// A clock whose 0 is now.
    pub fn start() -> Self {
        Self {
            origin: Instant::now(),
        }
    }

    /// Segment time now, ns.
    pub fn now_ns(&self) -> u64 {
        self.origin.elapsed().as_nanos() as u64
    }

    /// The instant of segment time `ns`.
    pub fn instant(&self, ns: u64) -> Instant {
        self.origin + Duration::from_nanos(ns)
    }
}

impl Default for SegmentClock {
    fn default() -> Self {
        Self::start()
    }
}

/// What the clock thread did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Sync0ClockStats {
    /// Pulses it handed over (those run by frames are not counted here).
    pub pulses: u64,
    /// Wake-ups for a pulse.
    pub wakeups: u64,
    /// Largest lateness of a wake-up after its pulse, ns.
    pub max_late_ns: u64,
    /// Sum of the wake-ups' lateness, ns (over `wakeups`: the mean).
    pub total_late_ns: u64,
}

impl Sync0ClockStats {
    /// Counts a wake-up at segment time `now_ns` that ran `pulses` pulses, the first due at
    /// `due_ns`.
    pub fn count(&mut self, due_ns: Option<u64>, now_ns: u64, pulses: u64) {
        if let (Some(at), true) = (due_ns, pulses > 0) {
            let late = now_ns.saturating_sub(at);
            self.wakeups += 1;
            self.max_late_ns = self.max_late_ns.max(late);
            self.total_late_ns += late;
        }
        self.pulses += pulses;
    }
}

/// Runs the SYNC0 pulses of `segment` at their segment time on `clock` until `stop` is
/// set. Returns what it did, or `None` if the segment's lock was poisoned.
pub fn run_sync0_clock(
    segment: &SharedSegment,
    clock: SegmentClock,
    stop: &AtomicBool,
) -> Option<Sync0ClockStats> {
    let mut stats = Sync0ClockStats::default();
    let mut due: Option<u64> = None;
    while !stop.load(Ordering::Relaxed) {
        let now = clock.now_ns();
        let next = {
            let mut seg = segment.lock().ok()?;
            stats.count(due, now, seg.run_sync0_until(now));
            seg.next_sync0_ns()
        };
        due = next;
        let sleep = next.map_or(IDLE_SLEEP, |at| {
            Duration::from_nanos(at.saturating_sub(clock.now_ns())).min(IDLE_SLEEP)
        });
        std::thread::sleep(sleep);
    }
    Some(stats)
}
