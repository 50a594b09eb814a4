//! Waiting for a due time without a sleep per short wait: the OS wake-up latency
//! (tens of microseconds, more on a loaded machine) is as long as a frame at 1 Mbit/s.

use std::time::{Duration, Instant};

/// Waits shorter than this are spun (the thread keeps its CPU); longer ones sleep until
/// this much before the due time, then spin.
pub const SPIN_BELOW: Duration = Duration::from_micros(200);

/// Returns at or after `due` (at once if it has passed): sleeps while more than
/// [`SPIN_BELOW`] is left, spins for the rest. No allocation, no lock.
#[inline]
pub fn wait_until(due: Instant) {
    loop {
        let now = Instant::now();
        if now >= due {
            return;
        }
        let left = due - now;
        if left > SPIN_BELOW {
            std::thread::sleep(left - SPIN_BELOW);
        } else {
            std::hint::spin_loop();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn never_returns_early() {
        for us in [0u64, 30, 150, 900, 3000] {
            let due = Instant::now() + Duration::from_micros(us);
            wait_until(due);
            assert!(Instant::now() >= due, "{us} us");
        }
        wait_until(Instant::now() - Duration::from_millis(1)); // passed: at once
    }
}
