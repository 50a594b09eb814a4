//! [`Pacer`]: absolute periodic deadlines on the monotonic clock.
//!
//! # Overrun policy: skip
//!
//! Deadline `k` is `origin + k * period` (a fixed grid: no drift, whatever the wake-up
//! jitter). When the thread wakes after the *next* deadline has already passed (the body
//! or the scheduler held it for more than a period), the deadlines that passed unserved
//! are **skipped**, not caught up: the tick returned is the latest deadline not after the
//! wake-up, its lateness is below one period, and the missed deadlines are counted
//! ([`Tick::missed`], [`Pacer::missed_deadlines`]). The cycle therefore never bursts (a
//! drive would see back-to-back set-points and SYNCs otherwise); the caller sees the gap
//! in [`Tick::index`] and can e.g. hold the excitation's phase on the grid.

use std::time::{Duration, Instant};

use super::clock::{self, InstantMap, MonoNs};
use super::RtError;

/// One wake-up of the [`Pacer`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Tick {
    /// Grid index of this deadline: `deadline = first deadline + index * period`. It
    /// jumps by `1 + missed` after an overrun.
    pub index: u64,
    /// Deadlines skipped just before this one (0 normally).
    pub missed: u64,
    /// This cycle's deadline (when it should have started).
    pub deadline: Instant,
    /// The next deadline: the end of this cycle (e.g. the deadline to pass to
    /// `CyclicDrive::cycle` for this cycle's feedback).
    pub next_deadline: Instant,
    /// When the thread woke up (read once after the sleep).
    pub woke_at: Instant,
    /// `woke_at - deadline`, ns, in `[0, period)` (skip policy).
    pub lateness_ns: u64,
    /// `deadline` on the monotonic clock, ns.
    pub deadline_ns: MonoNs,
}

/// Paces a loop at a fixed period on absolute deadlines. No allocation; the only system
/// calls in [`wait_next`](Pacer::wait_next) are the clock's (`clock_nanosleep`, and
/// `clock_gettime` in the vDSO).
#[derive(Debug, Clone)]
pub struct Pacer {
    period_ns: u64,
    first_ns: MonoNs,
    /// Grid index of the next deadline to wait for.
    next_index: u64,
    map: InstantMap,
    ticks: u64,
    overruns: u64,
    missed: u64,
}

/// Where the tick lands after waking at `woke` for grid deadline `index` (skip policy):
/// `(index of the tick, deadlines skipped)`. Pure; `woke >= deadline(index)` expected
/// (an early wake is treated as on time).
#[inline]
pub fn skip_to(first_ns: MonoNs, period_ns: u64, index: u64, woke: MonoNs) -> (u64, u64) {
    let deadline = first_ns + index * period_ns;
    let missed = woke.saturating_sub(deadline) / period_ns;
    (index + missed, missed)
}

impl Pacer {
    /// A pacer whose first deadline is one period from now.
    ///
    /// Errors: [`RtError::InvalidPeriod`] for a zero period or one above an hour.
    pub fn new(period: Duration) -> Result<Self, RtError> {
        let period_ns = check_period(period)?;
        Ok(Self::with_first_deadline_ns(
            period_ns,
            clock::now_ns() + period_ns,
        ))
    }

    /// A pacer with the given period (ns, > 0) and first deadline (monotonic ns).
    pub fn with_first_deadline_ns(period_ns: u64, first_ns: MonoNs) -> Self {
        assert!(period_ns > 0, "period must be > 0");
        Pacer {
            period_ns,
            first_ns,
            next_index: 0,
            map: InstantMap::calibrate(),
            ticks: 0,
            overruns: 0,
            missed: 0,
        }
    }

    /// Sleeps until the next deadline and returns its tick (skip policy on overrun, see the
    /// module documentation).
    #[inline]
    pub fn wait_next(&mut self) -> Tick {
        let index = self.next_index;
        clock::sleep_until_ns(self.first_ns + index * self.period_ns);
        let woke = clock::now_ns();
        let (index, missed) = skip_to(self.first_ns, self.period_ns, index, woke);
        if missed > 0 {
            self.overruns += 1;
            self.missed += missed;
        }
        self.ticks += 1;
        self.next_index = index + 1;
        let deadline_ns = self.first_ns + index * self.period_ns;
        Tick {
            index,
            missed,
            deadline: self.map.instant(deadline_ns),
            next_deadline: self.map.instant(deadline_ns + self.period_ns),
            woke_at: self.map.instant(woke),
            lateness_ns: woke.saturating_sub(deadline_ns),
            deadline_ns,
        }
    }

    /// The period, ns.
    pub fn period_ns(&self) -> u64 {
        self.period_ns
    }

    /// Ticks returned so far.
    pub fn ticks(&self) -> u64 {
        self.ticks
    }

    /// Wake-ups that found at least one further deadline passed (overrun events).
    pub fn overruns(&self) -> u64 {
        self.overruns
    }

    /// Deadlines skipped in total.
    pub fn missed_deadlines(&self) -> u64 {
        self.missed
    }

    /// The [`Instant`] of a monotonic time, ns (arithmetic only).
    pub fn instant_of(&self, t: MonoNs) -> Instant {
        self.map.instant(t)
    }
}

/// The period in ns, checked: > 0 and at most an hour.
pub(crate) fn check_period(period: Duration) -> Result<u64, RtError> {
    let ns = period.as_nanos();
    if ns == 0 || ns > 3_600_000_000_000 {
        return Err(RtError::InvalidPeriod { period });
    }
    Ok(ns as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn skip_policy_pure() {
        // on time, slightly late, just before the next deadline: no skip
        assert_eq!(skip_to(1000, 100, 5, 1500), (5, 0));
        assert_eq!(skip_to(1000, 100, 5, 1530), (5, 0));
        assert_eq!(skip_to(1000, 100, 5, 1599), (5, 0));
        // exactly at the next deadline: that one is served, one skipped
        assert_eq!(skip_to(1000, 100, 5, 1600), (6, 1));
        // 3.5 periods late: three skipped, the tick is the latest passed deadline
        assert_eq!(skip_to(1000, 100, 5, 1850), (8, 3));
        // early wake (never from clock_nanosleep): on time
        assert_eq!(skip_to(1000, 100, 5, 1400), (5, 0));
    }

    #[test]
    fn zero_period_is_an_error() {
        assert!(matches!(
            Pacer::new(Duration::ZERO),
            Err(RtError::InvalidPeriod { .. })
        ));
    }

    /// A slow body (3.5 periods once) makes the next wake-up skip the passed deadlines:
    /// no burst (every lateness below one period, ticks at least a period apart after it).
    #[test]
    fn slow_body_skips_missed_deadlines() {
        let period = Duration::from_millis(4);
        let mut p = Pacer::new(period).unwrap();
        let mut ticks = Vec::new();
        for k in 0..12 {
            let t = p.wait_next();
            ticks.push(t);
            if k == 3 {
                std::thread::sleep(Duration::from_millis(14));
            }
        }
        let pns = p.period_ns();
        for w in ticks.windows(2) {
            assert!(w[1].index > w[0].index);
            assert_eq!(w[1].index - w[0].index, 1 + w[1].missed);
            assert_eq!(w[1].deadline_ns - w[0].deadline_ns, (1 + w[1].missed) * pns);
        }
        for t in &ticks {
            assert!(t.lateness_ns < pns, "lateness {} >= period", t.lateness_ns);
            assert!(t.woke_at >= t.deadline);
            assert_eq!(t.next_deadline - t.deadline, period);
        }
        // the body's 14 ms = 3.5 periods from deadline 3: deadline 4 is 2.5 periods past
        // when the pacer is called, so deadlines 4 and 5 are skipped and tick 6 served
        assert!(ticks[4].missed >= 2, "missed {}", ticks[4].missed);
        assert!(ticks[4].index >= 6);
        assert!(p.overruns() >= 1);
        let total: u64 = ticks.iter().map(|t| t.missed).sum();
        assert_eq!(total, p.missed_deadlines());
        assert_eq!(p.ticks(), 12);
    }
}
