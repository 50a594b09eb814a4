//! When a received frame reached the host: the kernel's receive time stamp of a socket's
//! last datagram or frame (`SIOCGSTAMPNS`), as an [`Instant`].
//!
//! A stamp taken in user space after the read returns says when the frame was *read*; a
//! frame that arrived while the reader was busy elsewhere (sending the next SYNC, say)
//! would look newer than it is. The CANopen master orders feedback against the SYNC it
//! sent by these stamps (`flexid_canopen::master::exchange`).

use std::os::fd::RawFd;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// `SIOCGSTAMPNS` (linux/sockios.h; the 64-bit `time_t` value on 64-bit targets).
#[cfg(target_os = "linux")]
const SIOCGSTAMPNS: libc::c_ulong = 0x8907;

/// Turns the kernel's receive stamping on for `fd` (the first stamp request does);
/// call once when the socket is opened, so that the first frame is stamped too.
pub(crate) fn enable(fd: RawFd) {
    let _ = kernel_stamp(fd);
}

/// The arrival of the last datagram or frame read from `fd`, on the monotonic clock.
/// The first call on a socket turns the kernel's stamping on (from then on every packet
/// is stamped); where no stamp is available it is the time of the call.
pub(crate) fn last_arrival(fd: RawFd) -> Instant {
    let now = Instant::now();
    match kernel_stamp(fd) {
        Some(at) => {
            let age = SystemTime::now()
                .duration_since(at)
                .unwrap_or(Duration::ZERO);
            now.checked_sub(age).unwrap_or(now)
        }
        None => now,
    }
}

#[cfg(target_os = "linux")]
fn kernel_stamp(fd: RawFd) -> Option<SystemTime> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: SIOCGSTAMPNS writes one timespec into `ts`; fd is an open socket.
    let r = unsafe { libc::ioctl(fd, SIOCGSTAMPNS as _, &mut ts as *mut libc::timespec) };
    if r != 0 || ts.tv_sec <= 0 {
        return None; // ENOENT on the first call: stamping has just been turned on
    }
    UNIX_EPOCH.checked_add(Duration::new(ts.tv_sec as u64, ts.tv_nsec as u32))
}

#[cfg(not(target_os = "linux"))]
fn kernel_stamp(_fd: RawFd) -> Option<SystemTime> {
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::net::UdpSocket;
    use std::os::fd::AsRawFd;

    /// A datagram that waited 20 ms in the queue is stamped 20 ms before it was read
    /// (the reference: the user-space read time, which is 20 ms later).
    #[test]
    fn a_queued_datagram_is_stamped_with_its_arrival_not_its_read() {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let tx = UdpSocket::bind("127.0.0.1:0").unwrap();
        let mut buf = [0u8; 8];
        enable(rx.as_raw_fd());
        tx.send_to(b"x", rx.local_addr().unwrap()).unwrap();
        let sent = Instant::now();
        std::thread::sleep(Duration::from_millis(20));
        rx.recv_from(&mut buf).unwrap();
        let read = Instant::now();
        let at = last_arrival(rx.as_raw_fd());
        assert!(read.duration_since(sent) >= Duration::from_millis(20));
        let early = read.saturating_duration_since(at);
        assert!(
            early >= Duration::from_millis(15),
            "stamped only {early:?} before the read"
        );
        assert!(at.saturating_duration_since(sent) < Duration::from_millis(5));
    }
}
