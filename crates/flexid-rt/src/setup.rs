//! [`RtSetup`]: what a cycle thread asks for (`SCHED_FIFO`, `mlockall`, a CPU), and
//! [`RtGranted`]: what it got.
//!
//! Each item is attempted only when asked. A refusal is never an error: it is logged once
//! (`tracing` warning naming the missing right) and the thread runs without it. Applies to
//! the **calling thread** (scheduling, affinity) and the **whole process** (`mlockall`).

use serde::{Deserialize, Serialize};

/// Real-time settings to request for a cycle thread.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RtSetup {
    /// `SCHED_FIFO` with this priority (1..=99); `None`: normal scheduling.
    pub fifo_priority: Option<u8>,
    /// `mlockall(MCL_CURRENT | MCL_FUTURE)`: no page faults in the loop. Process-wide.
    pub lock_memory: bool,
    /// Pin the thread to this CPU (0-based); `None`: any CPU.
    pub cpu: Option<usize>,
}

impl RtSetup {
    /// Nothing asked: normal scheduling, no locking, any CPU.
    pub fn none() -> Self {
        Self::default()
    }

    /// `SCHED_FIFO` at `priority` (1..=99) and locked memory, any CPU.
    pub fn realtime(priority: u8) -> Self {
        RtSetup {
            fifo_priority: Some(priority),
            lock_memory: true,
            cpu: None,
        }
    }

    /// The same, pinned to `cpu`.
    pub fn on_cpu(mut self, cpu: usize) -> Self {
        self.cpu = Some(cpu);
        self
    }

    /// Applies the settings to the calling thread (and `mlockall` to the process);
    /// returns what was granted. Logs a warning for each refusal; never fails.
    pub fn apply(&self) -> RtGranted {
        let mut g = RtGranted::default();
        if let Some(p) = self.fifo_priority {
            match sys::set_fifo(p) {
                Ok(()) => g.fifo_priority = Some(p),
                Err(e) => g.refused.push(refusal(
                    format!("SCHED_FIFO priority {p}"),
                    "running with normal priority",
                    e,
                    "give the service CAP_SYS_NICE / LimitRTPRIO",
                )),
            }
        }
        if self.lock_memory {
            match sys::lock_memory() {
                Ok(()) => g.memory_locked = true,
                Err(e) => g.refused.push(refusal(
                    "mlockall(MCL_CURRENT|MCL_FUTURE)".into(),
                    "memory not locked, page faults possible in the loop",
                    e,
                    "give the service CAP_IPC_LOCK / LimitMEMLOCK=infinity",
                )),
            }
        }
        if let Some(c) = self.cpu {
            match sys::pin_cpu(c) {
                Ok(()) => g.cpu = Some(c),
                Err(e) => g.refused.push(refusal(
                    format!("CPU affinity to core {c}"),
                    "running on any CPU",
                    e,
                    "check the core exists and is in the service's cpuset (AllowedCPUs)",
                )),
            }
        }
        g
    }
}

/// What a cycle thread was granted (reported with its timing).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RtGranted {
    /// `SCHED_FIFO` priority in effect, if granted.
    pub fifo_priority: Option<u8>,
    /// `mlockall` succeeded.
    pub memory_locked: bool,
    /// The CPU the thread is pinned to, if granted.
    pub cpu: Option<usize>,
    /// One line per refused item (as logged).
    pub refused: Vec<String>,
}

/// Why a setting was refused: the OS error, or not supported on this system.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(not(target_os = "linux"), allow(dead_code))]
pub(crate) enum Refusal {
    /// The call failed with this errno.
    Errno(i32),
    /// The value is outside what the call accepts.
    Invalid,
    /// `mlockall` not attempted: `RLIMIT_MEMLOCK` is this many bytes and the process
    /// lacks `CAP_IPC_LOCK`, so with `MCL_FUTURE` later allocations past the limit would
    /// fail (and abort the process).
    MemlockLimit(u64),
    /// Not supported on this operating system.
    #[cfg_attr(target_os = "linux", allow(dead_code))]
    Unsupported,
}

fn refusal(what: String, consequence: &str, e: Refusal, hint: &str) -> String {
    let msg = match e {
        Refusal::Errno(n) => {
            let name = errno_name(n);
            let rights = n == EPERM || n == ENOMEM || n == EACCES;
            if rights {
                format!("{what} not granted ({name}): {consequence}; {hint}")
            } else {
                format!(
                    "{what} failed ({name}: {}): {consequence}",
                    std::io::Error::from_raw_os_error(n)
                )
            }
        }
        Refusal::Invalid => format!("{what} is out of range: {consequence}"),
        Refusal::MemlockLimit(b) => format!(
            "{what} not attempted (RLIMIT_MEMLOCK {} KiB without CAP_IPC_LOCK: later \
             allocations past it would fail): {consequence}; {hint}",
            b / 1024
        ),
        Refusal::Unsupported => {
            format!("{what} not supported on this operating system: {consequence}")
        }
    };
    tracing::warn!("{msg}");
    msg
}

const EPERM: i32 = 1;
const ENOMEM: i32 = 12;
const EACCES: i32 = 13;

fn errno_name(n: i32) -> String {
    match n {
        1 => "EPERM".into(),
        12 => "ENOMEM".into(),
        13 => "EACCES".into(),
        22 => "EINVAL".into(),
        3 => "ESRCH".into(),
        _ => format!("errno {n}"),
    }
}

#[cfg(target_os = "linux")]
mod sys {
    use super::Refusal;

    fn errno() -> i32 {
        std::io::Error::last_os_error().raw_os_error().unwrap_or(0)
    }

    pub fn set_fifo(priority: u8) -> Result<(), Refusal> {
        // SAFETY: plain queries of the scheduler's priority range.
        let (lo, hi) = unsafe {
            (
                libc::sched_get_priority_min(libc::SCHED_FIFO),
                libc::sched_get_priority_max(libc::SCHED_FIFO),
            )
        };
        let p = priority as i32;
        if p < lo || p > hi {
            return Err(Refusal::Invalid);
        }
        let param = libc::sched_param { sched_priority: p };
        // SAFETY: the calling thread's handle and a valid sched_param.
        let rc =
            unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
        if rc == 0 {
            Ok(())
        } else {
            Err(Refusal::Errno(rc))
        }
    }

    /// CAP_IPC_LOCK (bit 14) in the effective set, from /proc/self/status.
    fn has_cap_ipc_lock() -> bool {
        std::fs::read_to_string("/proc/self/status")
            .ok()
            .and_then(|s| {
                s.lines()
                    .find_map(|l| l.strip_prefix("CapEff:"))
                    .and_then(|v| u64::from_str_radix(v.trim(), 16).ok())
            })
            .is_some_and(|caps| caps & (1 << 14) != 0)
    }

    pub fn lock_memory() -> Result<(), Refusal> {
        let mut lim = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        // SAFETY: valid pointer to an rlimit.
        let rc = unsafe { libc::getrlimit(libc::RLIMIT_MEMLOCK, &mut lim) };
        if rc == 0 && lim.rlim_cur != libc::RLIM_INFINITY && !has_cap_ipc_lock() {
            #[allow(clippy::unnecessary_cast)] // rlim_t is not u64 on every libc
            return Err(Refusal::MemlockLimit(lim.rlim_cur as u64));
        }
        // SAFETY: no pointers involved.
        let rc = unsafe { libc::mlockall(libc::MCL_CURRENT | libc::MCL_FUTURE) };
        if rc == 0 {
            Ok(())
        } else {
            Err(Refusal::Errno(errno()))
        }
    }

    pub fn pin_cpu(cpu: usize) -> Result<(), Refusal> {
        if cpu >= libc::CPU_SETSIZE as usize {
            return Err(Refusal::Invalid);
        }
        // SAFETY: a zeroed cpu_set_t is the empty set; CPU_SET within CPU_SETSIZE; pid 0 is
        // the calling thread.
        let rc = unsafe {
            let mut set: libc::cpu_set_t = std::mem::zeroed();
            libc::CPU_SET(cpu, &mut set);
            libc::sched_setaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &set)
        };
        if rc == 0 {
            Ok(())
        } else {
            Err(Refusal::Errno(errno()))
        }
    }
}

#[cfg(not(target_os = "linux"))]
mod sys {
    use super::Refusal;

    pub fn set_fifo(_priority: u8) -> Result<(), Refusal> {
        Err(Refusal::Unsupported)
    }

    pub fn lock_memory() -> Result<(), Refusal> {
        Err(Refusal::Unsupported)
    }

    pub fn pin_cpu(_cpu: usize) -> Result<(), Refusal> {
        Err(Refusal::Unsupported)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nothing_asked_nothing_granted() {
        assert_eq!(RtSetup::none().apply(), RtGranted::default());
    }

    #[test]
    fn out_of_range_priority_and_cpu_are_refused_not_errors() {
        std::thread::spawn(|| {
            let g = RtSetup {
                fifo_priority: Some(0),
                lock_memory: false,
                cpu: Some(1 << 20),
            }
            .apply();
            assert_eq!(g.fifo_priority, None);
            assert_eq!(g.cpu, None);
            assert_eq!(g.refused.len(), 2, "{:?}", g.refused);
        })
        .join()
        .unwrap();
    }

    #[test]
    fn refusal_message_names_the_right() {
        let m = refusal(
            "SCHED_FIFO priority 80".into(),
            "running with normal priority",
            Refusal::Errno(EPERM),
            "give the service CAP_SYS_NICE / LimitRTPRIO",
        );
        assert_eq!(
            m,
            "SCHED_FIFO priority 80 not granted (EPERM): running with normal priority; \
             give the service CAP_SYS_NICE / LimitRTPRIO"
        );
    }
}
