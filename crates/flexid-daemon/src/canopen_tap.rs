//! [`Tap`]: a [`CyclicDrive`] around the enabled drive that the CANopen backend hands to
//! [`flexid_sweep::run_sweep`]. Every cycle it
//!
//! * measures the wake-up lateness after the previous cycle's deadline (real-time pacing)
//!   into a [`TimingStats`] allocated before the sweep;
//! * enforces the axis's position window (relative to the position at the first cycle):
//!   beyond it, it raises the sweep's stop flag, so the loop ends, ramps the torque to zero
//!   and keeps the rows, and remembers where the axis was for the reason.
//!
//! Nothing here allocates per cycle.

use flexid_canopen::{Counters, CyclicDrive, Feedback};
use flexid_rt::TimingStats;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// The drive seen by the sweep loop.
pub struct Tap<'a, D> {
    inner: &'a mut D,
    stop: &'a AtomicBool,
    window_rad: f64,
    realtime: bool,
    origin_rad: Option<f64>,
    prev_deadline: Option<Instant>,
    /// Wake-up lateness (real-time pacing only).
    pub stats: TimingStats,
    /// The position [rad, from the start] at which the window was left, if it was.
    pub window_trip_rad: Option<f64>,
}

impl<'a, D: CyclicDrive> Tap<'a, D> {
    /// Wraps `inner`; `stop` is the flag the sweep loop polls.
    pub fn new(inner: &'a mut D, stop: &'a AtomicBool, window_rad: f64, realtime: bool) -> Self {
        let period_ns = inner.cycle_period().as_nanos().max(1) as u64;
        Tap {
            inner,
            stop,
            window_rad,
            realtime,
            origin_rad: None,
            prev_deadline: None,
            stats: TimingStats::new(period_ns),
            window_trip_rad: None,
        }
    }
}

impl<D: CyclicDrive> CyclicDrive for Tap<'_, D> {
    type Error = D::Error;

    fn cycle(&mut self, torque_nm: f64, deadline: Instant) -> Result<Feedback, Self::Error> {
        if self.realtime {
            if let Some(prev) = self.prev_deadline {
                let late = Instant::now().saturating_duration_since(prev);
                self.stats
                    .record_wakeup(late.as_nanos().min(u64::MAX as u128) as u64, 0);
            }
            self.prev_deadline = Some(deadline);
        }
        let fb = self.inner.cycle(torque_nm, deadline)?;
        let origin = *self.origin_rad.get_or_insert(fb.position_rad);
        let moved = fb.position_rad - origin;
        if self.window_trip_rad.is_none() && !(moved.abs() <= self.window_rad) {
            self.window_trip_rad = Some(moved);
            self.stop.store(true, Ordering::Release);
        }
        Ok(fb)
    }

    fn cycle_period(&self) -> Duration {
        self.inner.cycle_period()
    }

    fn rated_torque_nm(&self) -> f64 {
        self.inner.rated_torque_nm()
    }

    fn counters(&self) -> Counters {
        self.inner.counters()
    }

    /// The wrapped drive's classification.
    fn error_kind(error: &Self::Error) -> Option<flexid_canopen::DriveErrorKind> {
        D::error_kind(error)
    }
}
