//! Heartbeat producer (0x1017) and consumer (0x1016:1), with injected time.
//!
//! canopen-rs encodes the heartbeat frame (`Node::heartbeat`) but has no timers and no
//! heartbeat consumer on the device side: both are here.

use std::time::Duration;

/// Heartbeat producer timer: due every `period` after it is (re)started.
#[derive(Debug, Clone, Default)]
pub struct Producer {
    period: Duration,
    next: Option<Duration>,
}

impl Producer {
    /// (Re)starts the producer at `now` with a period of `ms` [ms] (0 = off).
    pub fn restart(&mut self, ms: u16, now: Duration) {
        self.period = Duration::from_millis(ms.into());
        self.next = (ms != 0).then(|| now + self.period);
    }

    /// Whether a heartbeat is due at `now` (at most one per call; a late call does not
    /// burst: the schedule skips to the next period after `now`).
    pub fn due(&mut self, now: Duration) -> bool {
        match self.next {
            Some(next) if now >= next => {
                let mut n = next + self.period;
                if n <= now {
                    n = now + self.period;
                }
                self.next = Some(n);
                true
            }
            _ => false,
        }
    }

    /// When the next heartbeat is due, if the producer runs.
    pub fn next_due(&self) -> Option<Duration> {
        self.next
    }
}

/// Heartbeat consumer of one node (0x1016:1 = `(node << 16) | time_ms`).
///
/// As CiA 301 specifies, monitoring starts with the first heartbeat received from that
/// node; from then on a gap longer than the consumer time is a heartbeat event.
#[derive(Debug, Clone, Default)]
pub struct Consumer {
    node: u8,
    time: Duration,
    last_seen: Option<Duration>,
}

impl Consumer {
    /// Configures from the 0x1016:1 value; resets monitoring.
    pub fn configure(&mut self, entry: u32) {
        self.node = ((entry >> 16) & 0x7F) as u8;
        self.time = Duration::from_millis(u64::from(entry & 0xFFFF));
        self.last_seen = None;
    }

    /// The monitored node id (0: off).
    pub fn node(&self) -> u8 {
        self.node
    }

    /// Whether the consumer is configured (node and time non-zero).
    pub fn enabled(&self) -> bool {
        self.node != 0 && !self.time.is_zero()
    }

    /// A heartbeat (or boot-up) from the monitored node arrived at `now`.
    pub fn seen(&mut self, now: Duration) {
        self.last_seen = Some(now);
    }

    /// Whether the monitored heartbeat is overdue at `now` (stays true until the next
    /// heartbeat).
    pub fn overdue(&self, now: Duration) -> bool {
        self.enabled()
            && self
                .last_seen
                .is_some_and(|t| now.saturating_sub(t) > self.time)
    }

    /// When the monitored heartbeat becomes overdue (for the runner's wake-up).
    pub fn deadline(&self) -> Option<Duration> {
        match (self.enabled(), self.last_seen) {
            (true, Some(t)) => Some(t + self.time + Duration::from_micros(1)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    #[test]
    fn producer_period() {
        let mut p = Producer::default();
        p.restart(100, ms(0));
        assert!(!p.due(ms(99)));
        assert!(p.due(ms(100)));
        assert!(!p.due(ms(150)));
        assert!(p.due(ms(200)));
        assert!(p.due(ms(1000)));
        assert!(!p.due(ms(1050)));
        p.restart(0, ms(0));
        assert!(!p.due(ms(10_000)));
    }

    #[test]
    fn consumer_arms_on_first_heartbeat() {
        let mut c = Consumer::default();
        c.configure((1 << 16) | 50);
        assert_eq!(c.node(), 1);
        assert!(!c.overdue(ms(1000)));
        c.seen(ms(1000));
        assert!(!c.overdue(ms(1050)));
        assert!(c.overdue(ms(1051)));
        c.seen(ms(1060));
        assert!(!c.overdue(ms(1100)));
    }
}
