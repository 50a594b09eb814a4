//! Waiting for a socket to become readable with `ppoll(2)`: the timeout is an hrtimer,
//! kept to the microsecond. (`SO_RCVTIMEO` rounds a wait up to whole scheduler ticks,
//! 4 ms at HZ = 250: a wait for this cycle's feedback that runs out would end several
//! cycles late.)

use std::io;
use std::os::fd::RawFd;
use std::time::Duration;

/// Waits until `fd` is readable or `timeout` has passed: `true` when readable. A signal
/// ends the wait early (`false`, as a timeout).
pub(crate) fn wait_readable(fd: RawFd, timeout: Duration) -> io::Result<bool> {
    let mut pfd = libc::pollfd {
        fd,
        events: libc::POLLIN,
        revents: 0,
    };
    let ts = libc::timespec {
        tv_sec: timeout.as_secs().min(i32::MAX as u64) as libc::time_t,
        tv_nsec: timeout.subsec_nanos() as libc::c_long,
    };
    // SAFETY: one valid pollfd, a valid timespec, no signal mask.
    let ready = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
    if ready < 0 {
        let e = io::Error::last_os_error();
        if e.kind() == io::ErrorKind::Interrupted {
            return Ok(false);
        }
        return Err(e);
    }
    Ok(ready > 0)
}
