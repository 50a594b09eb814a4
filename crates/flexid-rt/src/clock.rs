//! The monotonic clock in nanoseconds, absolute sleeps on it, and the calling thread's CPU
//! time.
//!
//! Linux: `clock_gettime(CLOCK_MONOTONIC)` (vDSO, no kernel entry) and
//! `clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)`; CPU time from
//! `CLOCK_THREAD_CPUTIME_ID`. Other systems: [`std::time::Instant`] from a process-wide
//! origin and [`std::thread::sleep`] (relative, so a late wake-up is not corrected until
//! the next deadline); no thread CPU time.

use std::time::{Duration, Instant};

/// A point on the monotonic clock, ns. On Linux it is `CLOCK_MONOTONIC` itself (the clock
/// of [`Instant`]), elsewhere ns since a process-wide origin.
pub type MonoNs = u64;

/// Now on the monotonic clock, ns.
#[cfg(target_os = "linux")]
#[inline]
pub fn now_ns() -> MonoNs {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid pointer to a timespec; CLOCK_MONOTONIC always exists on Linux.
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// Sleeps until the monotonic clock reads at least `deadline` (ns), restarting after
/// signals. Returns at once if the deadline has passed.
#[cfg(target_os = "linux")]
#[inline]
pub fn sleep_until_ns(deadline: MonoNs) {
    let ts = libc::timespec {
        tv_sec: (deadline / 1_000_000_000) as libc::time_t,
        tv_nsec: (deadline % 1_000_000_000) as libc::c_long,
    };
    loop {
        // SAFETY: valid timespec; the remainder pointer may be null with TIMER_ABSTIME.
        let rc = unsafe {
            libc::clock_nanosleep(
                libc::CLOCK_MONOTONIC,
                libc::TIMER_ABSTIME,
                &ts,
                std::ptr::null_mut(),
            )
        };
        // clock_nanosleep returns the error number (not -1/errno); only EINTR repeats.
        if rc != libc::EINTR {
            return;
        }
    }
}

/// CPU time consumed by the calling thread so far, ns (`None` where not available).
#[cfg(target_os = "linux")]
pub fn thread_cpu_ns() -> Option<u64> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: valid pointer to a timespec.
    let rc = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    (rc == 0).then(|| ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64)
}

#[cfg(not(target_os = "linux"))]
fn origin() -> Instant {
    static ORIGIN: std::sync::OnceLock<Instant> = std::sync::OnceLock::new();
    *ORIGIN.get_or_init(Instant::now)
}

/// Now on the monotonic clock, ns (since a process-wide origin on this system).
#[cfg(not(target_os = "linux"))]
#[inline]
pub fn now_ns() -> MonoNs {
    origin().elapsed().as_nanos() as u64
}

/// Sleeps until the monotonic clock reads at least `deadline` (ns) (relative sleep on
/// this system).
#[cfg(not(target_os = "linux"))]
pub fn sleep_until_ns(deadline: MonoNs) {
    loop {
        let now = now_ns();
        if now >= deadline {
            return;
        }
        std::thread::sleep(Duration::from_nanos(deadline - now));
    }
}

/// CPU time of the calling thread: not available on this system.
#[cfg(not(target_os = "linux"))]
pub fn thread_cpu_ns() -> Option<u64> {
    None
}

/// Maps [`MonoNs`] to [`Instant`] (e.g. for `CyclicDrive::cycle`'s deadline) by
/// arithmetic only: a pair of readings of both clocks taken once. On Linux both are
/// `CLOCK_MONOTONIC`, so the mapping is off by at most the gap between the two readings
/// (the smallest of a few tries, typically < 100 ns).
#[derive(Debug, Clone, Copy)]
pub struct InstantMap {
    base_ns: MonoNs,
    base: Instant,
}

impl InstantMap {
    /// Calibrates the map (a few clock readings; call before the cycle loop).
    pub fn calibrate() -> Self {
        let mut best = (u64::MAX, 0, Instant::now());
        for _ in 0..5 {
            let a = now_ns();
            let i = Instant::now();
            let b = now_ns();
            if b - a < best.0 {
                best = (b - a, a + (b - a) / 2, i);
            }
        }
        InstantMap {
            base_ns: best.1,
            base: best.2,
        }
    }

    /// The [`Instant`] of a monotonic time (no system call).
    #[inline]
    pub fn instant(&self, t: MonoNs) -> Instant {
        if t >= self.base_ns {
            self.base + Duration::from_nanos(t - self.base_ns)
        } else {
            self.base - Duration::from_nanos(self.base_ns - t)
        }
    }
}
