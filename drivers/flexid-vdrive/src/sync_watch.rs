//! SYNC-loss supervision, with injected time.
//!
//! In a cyclic synchronous mode a drive that stops receiving SYNC has lost its master:
//! the last set-point must not be held. The watch is armed by the first SYNC after the
//! drive entered Operation enabled (an old SYNC does not count) and trips when no SYNC
//! has come for `cycles` communication cycle periods (0x1006). The drive core
//! ([`crate::drive`]) turns a trip into a fault: torque off at once, EMCY 0x8700.

use std::time::Duration;

/// Shortest supervision window in lock-step [ms]: there the SYNCs come at the master's
/// pace, not at 0x1006 (a lock-step master waits only for the feedback), and the plant
/// stands still between SYNCs, so the held torque acts on nothing until the next SYNC.
/// The floor keeps a master preempted for a few milliseconds on a loaded host from
/// tripping the drive, while a dead master still loses the torque within 50 ms (instead
/// of the heartbeat consumer's 300 ms).
pub const LOCKSTEP_FLOOR: Duration = Duration::from_millis(50);

/// SYNC-loss supervision of one drive.
#[derive(Debug, Clone, Default)]
pub struct SyncWatch {
    /// Cycles without SYNC that trip the watch (0: off).
    cycles: u16,
    /// The last SYNC while armed.
    last: Option<Duration>,
}

impl SyncWatch {
    /// A disarmed watch tripping after `cycles` periods without SYNC (0: never).
    pub fn new(cycles: u16) -> Self {
        Self { cycles, last: None }
    }

    /// Cycles without SYNC that trip the watch (0: off).
    pub fn cycles(&self) -> u16 {
        self.cycles
    }

    /// A SYNC arrived at `now`: (re-)arms the watch.
    pub fn seen(&mut self, now: Duration) {
        self.last = Some(now);
    }

    /// Stops supervising until the next SYNC (the drive left, or just entered, Operation
    /// enabled).
    pub fn disarm(&mut self) {
        self.last = None;
    }

    /// Whether a SYNC has armed the watch.
    pub fn armed(&self) -> bool {
        self.last.is_some()
    }

    /// The window after the last SYNC for a communication cycle `period` (`None`: no
    /// supervision, cycles 0 or period 0).
    pub fn window(&self, period: Duration, floor: Duration) -> Option<Duration> {
        (self.cycles != 0 && !period.is_zero())
            .then(|| (period * u32::from(self.cycles)).max(floor))
    }

    /// When the watch trips if no SYNC comes (for the runner's wake-up).
    pub fn deadline(&self, window: Option<Duration>) -> Option<Duration> {
        Some(self.last? + window?)
    }

    /// Whether no SYNC has come for the whole window at `now`.
    pub fn overdue(&self, now: Duration, window: Option<Duration>) -> bool {
        self.deadline(window).is_some_and(|d| now >= d)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn us(v: u64) -> Duration {
        Duration::from_micros(v)
    }

    #[test]
    fn trips_after_the_window_once_armed() {
        let mut w = SyncWatch::new(3);
        let win = w.window(us(500), Duration::ZERO);
        assert_eq!(win, Some(us(1500)));
        assert!(!w.overdue(us(1_000_000), win), "not armed");
        w.seen(us(1000));
        assert!(!w.overdue(us(2499), win));
        assert!(w.overdue(us(2500), win));
        w.disarm();
        assert!(!w.overdue(us(9000), win));
        assert_eq!(SyncWatch::new(0).window(us(500), Duration::ZERO), None);
        assert_eq!(w.window(Duration::ZERO, Duration::ZERO), None);
        assert_eq!(w.window(us(500), LOCKSTEP_FLOOR), Some(LOCKSTEP_FLOOR));
    }
}
