//! The emulated segment on a network interface (Linux): the OS adapter of the veth tier.
//!
//! [`RawSocket`] is an `AF_PACKET` raw socket bound to one interface for EtherType 0x88A4
//! (opening it needs `CAP_NET_RAW`). [`SocketLink::serve`] receives every EtherCAT frame
//! that arrives on the interface, passes it through the [`crate::Segment`] in place (the
//! SYNC0 pulses due before it first, then every SubDevice; the segment sets the locally
//! administered bit of the source MAC as a real ESC does, so ethercrab takes the frame as
//! returned) and sends it back out of the same interface. Frames this socket sent itself
//! (`PACKET_OUTGOING`) and frames the segment rejects are not answered (counted). One
//! buffer, allocated when the link is made: no allocation per frame.
//!
//! Time order. A real ESC is hardware: a frame passes it when it arrives on the wire and a
//! SYNC0 pulse comes at its time, whatever the host does. An emulator is a process that a
//! loaded host stops for milliseconds now and then (2 ms seen on a 2-core CI runner): a
//! frame that arrived in time waits in the socket while the pulse after it is due, and a
//! clock thread that fires that pulse first makes the servo miss a cycle the wire did not
//! miss (3 % of a 4 kHz sweep's cycles there). So each frame carries the kernel's receive
//! time (`SO_TIMESTAMPNS`) as its segment time, and [`SocketLink::serve_with_sync0`] runs
//! frames and pulses on one thread in that order: after a wake-up, every queued frame
//! first (each after the pulses due before its arrival), then the pulses due by now. A
//! frame the master sent late stays late, as on a wire. Only its answer leaves late, which
//! the MainDevice sees as a late exchange (its data was latched in time).
//!
//! The segment clock is a [`SegmentClock`] (the monotonic clock); the in-process tier runs
//! the pulses on a clock thread of its own ([`crate::sync0_clock::run_sync0_clock`]).

use crate::inprocess::SharedSegment;
use crate::sync0_clock::{SegmentClock, Sync0ClockStats};
use std::ffi::CString;
use std::io;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;
use thiserror::Error;

/// EtherType of EtherCAT frames.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Receive buffer, bytes: a standard frame (1514) with room to see a longer one as such.
pub const BUFFER_LEN: usize = 2048;
/// How long one wait for a frame lasts before the stop flag is looked at again.
pub const POLL_INTERVAL: Duration = Duration::from_millis(20);

/// Why the socket adapter failed.
#[derive(Debug, Error)]
pub enum SocketError {
    #[error("interface name {interface:?}: not a Linux interface name (1-15 bytes, no NUL)")]
    BadName { interface: String },
    #[error(
        "interface {interface}: opening a raw socket needs CAP_NET_RAW (run as root, or \
         `setcap cap_net_raw+ep` on the binary): {source}"
    )]
    Permission {
        interface: String,
        #[source]
        source: io::Error,
    },
    #[error("interface {interface}: no such interface in this network namespace")]
    NoInterface { interface: String },
    #[error("interface {interface}: {stage}: {source}")]
    Io {
        interface: String,
        stage: &'static str,
        #[source]
        source: io::Error,
    },
    #[error("the segment's lock is poisoned")]
    Poisoned,
}

/// An `AF_PACKET` raw socket bound to one interface for EtherCAT frames.
#[derive(Debug)]
pub struct RawSocket {
    fd: OwnedFd,
    ifindex: i32,
    interface: String,
}

/// One frame taken from the socket.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Received {
    /// A frame of `len` bytes arrived from the wire `age_ns` ago (the kernel's receive
    /// time stamp against the clock now; 0 when the kernel gave none).
    Frame { len: usize, age_ns: u64 },
    /// A frame this host sent (seen by packet sockets too), or one longer than the buffer.
    Skipped,
    /// Nothing within the wait.
    Nothing,
}

impl RawSocket {
    /// Opens a raw socket for EtherType 0x88A4 bound to `interface`.
    pub fn open(interface: &str) -> Result<Self, SocketError> {
        let bad_name = || SocketError::BadName {
            interface: interface.to_string(),
        };
        if interface.is_empty() || interface.len() >= libc::IF_NAMESIZE {
            return Err(bad_name());
        }
        let name = CString::new(interface).map_err(|_| bad_name())?;
        let protocol = ETHERTYPE_ETHERCAT.to_be();
        // SAFETY: plain socket(2) call; the result is checked and owned below.
        let raw = unsafe { libc::socket(libc::AF_PACKET, libc::SOCK_RAW, i32::from(protocol)) };
        if raw < 0 {
            let source = io::Error::last_os_error();
            return Err(match source.raw_os_error() {
                Some(libc::EPERM) | Some(libc::EACCES) => SocketError::Permission {
                    interface: interface.to_string(),
                    source,
                },
                _ => SocketError::Io {
                    interface: interface.to_string(),
                    stage: "opening an AF_PACKET socket",
                    source,
                },
            });
        }
        // SAFETY: `raw` is a fresh descriptor nothing else owns.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        // SAFETY: a NUL-terminated name.
        let ifindex = unsafe { libc::if_nametoindex(name.as_ptr()) } as i32;
        if ifindex == 0 {
            return Err(SocketError::NoInterface {
                interface: interface.to_string(),
            });
        }
        let socket = Self {
            fd,
            ifindex,
            interface: interface.to_string(),
        };
        let address = socket.address();
        // SAFETY: a valid sockaddr_ll of the size given.
        let rc = unsafe {
            libc::bind(
                socket.fd.as_raw_fd(),
                (&address as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if rc < 0 {
            return Err(socket.io("binding to the interface", io::Error::last_os_error()));
        }
        // The kernel's receive time of each frame (CLOCK_REALTIME, in a control message);
        // a kernel that refuses leaves frames unstamped (their time: when they are read).
        let on: libc::c_int = 1;
        // SAFETY: a valid int option of the size given.
        unsafe {
            libc::setsockopt(
                socket.fd.as_raw_fd(),
                libc::SOL_SOCKET,
                libc::SO_TIMESTAMPNS,
                (&on as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            );
        }
        Ok(socket)
    }

    /// The interface's name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    fn io(&self, stage: &'static str, source: io::Error) -> SocketError {
        SocketError::Io {
            interface: self.interface.clone(),
            stage,
            source,
        }
    }

    fn address(&self) -> libc::sockaddr_ll {
        // SAFETY: sockaddr_ll is plain data; all zeros is a valid value.
        let mut a: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        a.sll_family = libc::AF_PACKET as u16;
        a.sll_protocol = ETHERTYPE_ETHERCAT.to_be();
        a.sll_ifindex = self.ifindex;
        a.sll_halen = 6;
        a
    }

    /// Waits at most `wait` (to the nanosecond; zero: only what is queued) for a frame and
    /// receives it into `buffer`.
    pub fn receive(&self, buffer: &mut [u8], wait: Duration) -> Result<Received, SocketError> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let timeout = libc::timespec {
            tv_sec: wait.as_secs().min(i32::MAX as u64) as libc::time_t,
            tv_nsec: wait.subsec_nanos() as libc::c_long,
        };
        // SAFETY: one valid pollfd, a valid timespec, no signal mask.
        let n = unsafe { libc::ppoll(&mut pfd, 1, &timeout, std::ptr::null()) };
        if n < 0 {
            let e = io::Error::last_os_error();
            if e.kind() == io::ErrorKind::Interrupted {
                return Ok(Received::Nothing);
            }
            return Err(self.io("waiting for a frame", e));
        }
        if n == 0 {
            return Ok(Received::Nothing);
        }
        // SAFETY: sockaddr_ll is plain data.
        let mut from: libc::sockaddr_ll = unsafe { std::mem::zeroed() };
        let mut iov = libc::iovec {
            iov_base: buffer.as_mut_ptr().cast(),
            iov_len: buffer.len(),
        };
        // Room for one SCM_TIMESTAMPNS control message (a timespec), u64-aligned.
        let mut control = [0u64; 8];
        // SAFETY: msghdr is plain data; all zeros is a valid value.
        let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
        msg.msg_name = (&mut from as *mut libc::sockaddr_ll).cast();
        msg.msg_namelen = std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
        msg.msg_iov = &mut iov;
        msg.msg_iovlen = 1;
        msg.msg_control = control.as_mut_ptr().cast();
        msg.msg_controllen = std::mem::size_of_val(&control) as _;
        // SAFETY: every buffer the header points to is valid for the length given.
        let len = unsafe {
            libc::recvmsg(
                self.fd.as_raw_fd(),
                &mut msg,
                libc::MSG_TRUNC | libc::MSG_DONTWAIT,
            )
        };
        if len < 0 {
            let e = io::Error::last_os_error();
            if matches!(
                e.kind(),
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted
            ) {
                return Ok(Received::Nothing);
            }
            return Err(self.io("receiving a frame", e));
        }
        let len = len as usize;
        if from.sll_pkttype == libc::PACKET_OUTGOING || len > buffer.len() {
            return Ok(Received::Skipped);
        }
        let age_ns = receive_stamp(&msg).map_or(0, |stamp| realtime_ns().saturating_sub(stamp));
        Ok(Received::Frame { len, age_ns })
    }

    /// Sends `frame` (a whole Ethernet frame) out of the interface.
    pub fn send(&self, frame: &[u8]) -> Result<(), SocketError> {
        let address = self.address();
        // SAFETY: frame and address are valid for the lengths given.
        let sent = unsafe {
            libc::sendto(
                self.fd.as_raw_fd(),
                frame.as_ptr().cast(),
                frame.len(),
                0,
                (&address as *const libc::sockaddr_ll).cast(),
                std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t,
            )
        };
        if sent < 0 {
            return Err(self.io("sending a frame", io::Error::last_os_error()));
        }
        Ok(())
    }
}

/// The kernel's receive time of the message (`SCM_TIMESTAMPNS`, CLOCK_REALTIME), ns.
fn receive_stamp(msg: &libc::msghdr) -> Option<u64> {
    // SAFETY: the CMSG macros walk the control buffer recvmsg filled, within its length.
    unsafe {
        let mut cmsg = libc::CMSG_FIRSTHDR(msg);
        while !cmsg.is_null() {
            if (*cmsg).cmsg_level == libc::SOL_SOCKET && (*cmsg).cmsg_type == libc::SCM_TIMESTAMPNS
            {
                let ts: libc::timespec = std::ptr::read_unaligned(libc::CMSG_DATA(cmsg).cast());
                return Some(ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64);
            }
            cmsg = libc::CMSG_NXTHDR(msg, cmsg);
        }
    }
    None
}

/// CLOCK_REALTIME now, ns (the clock of the kernel's receive time stamps).
fn realtime_ns() -> u64 {
    // SAFETY: timespec is plain data.
    let mut ts: libc::timespec = unsafe { std::mem::zeroed() };
    // SAFETY: a valid timespec to fill.
    unsafe { libc::clock_gettime(libc::CLOCK_REALTIME, &mut ts) };
    ts.tv_sec as u64 * 1_000_000_000 + ts.tv_nsec as u64
}

/// What the link did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LinkStats {
    /// EtherCAT frames received from the wire.
    pub received: u64,
    /// Frames processed and sent back.
    pub returned: u64,
    /// Frames the segment rejected (not a valid EtherCAT frame): not answered.
    pub rejected: u64,
    /// Frames skipped: sent by this host, or longer than the buffer.
    pub skipped: u64,
}

/// The segment served on an interface; see the module documentation.
#[derive(Debug)]
pub struct SocketLink {
    socket: RawSocket,
    segment: SharedSegment,
    clock: SegmentClock,
    buffer: Box<[u8]>,
    stats: LinkStats,
}

impl SocketLink {
    /// Opens `interface` for `segment`, whose time is `clock`.
    pub fn open(
        interface: &str,
        segment: SharedSegment,
        clock: SegmentClock,
    ) -> Result<Self, SocketError> {
        Ok(Self {
            socket: RawSocket::open(interface)?,
            segment,
            clock,
            buffer: vec![0u8; BUFFER_LEN].into_boxed_slice(),
            stats: LinkStats::default(),
        })
    }

    /// The interface's name.
    pub fn interface(&self) -> &str {
        self.socket.interface()
    }

    pub fn stats(&self) -> LinkStats {
        self.stats
    }

    /// Frames and SYNC0 pulses on this thread, in time order, until `stop` is set (see the
    /// module documentation): waits for a frame until the next pulse is due, answers every
    /// frame queued (each at its arrival time), then runs the pulses due by now. Returns
    /// what the link did and the pulses' wake-ups.
    pub fn serve_with_sync0(
        &mut self,
        stop: &AtomicBool,
    ) -> Result<(LinkStats, Sync0ClockStats), SocketError> {
        let mut clock_stats = Sync0ClockStats::default();
        let mut due = self.next_pulse_ns()?;
        while !stop.load(Ordering::Relaxed) {
            let wait = due.map_or(POLL_INTERVAL, |at| {
                Duration::from_nanos(at.saturating_sub(self.clock.now_ns())).min(POLL_INTERVAL)
            });
            // Every frame that arrived before `now` is answered before the pulses up to it.
            let mut answered = self.serve_one(wait)?;
            let now = self.clock.now_ns();
            while answered {
                answered = self.serve_one(Duration::ZERO)?;
            }
            let mut segment = self.segment.lock().map_err(|_| SocketError::Poisoned)?;
            clock_stats.count(due, now, segment.run_sync0_until(now));
            due = segment.next_sync0_ns();
        }
        Ok((self.stats, clock_stats))
    }

    fn next_pulse_ns(&self) -> Result<Option<u64>, SocketError> {
        let segment = self.segment.lock().map_err(|_| SocketError::Poisoned)?;
        Ok(segment.next_sync0_ns())
    }

    /// Waits at most `wait` for one frame and answers it, the segment's time set to the
    /// frame's arrival (the SYNC0 pulses due before it run first). Returns whether a frame
    /// (answered or not) was taken.
    pub fn serve_one(&mut self, wait: Duration) -> Result<bool, SocketError> {
        let (len, age_ns) = match self.socket.receive(&mut self.buffer, wait)? {
            Received::Frame { len, age_ns } => (len, age_ns),
            Received::Skipped => {
                self.stats.skipped += 1;
                return Ok(true);
            }
            Received::Nothing => return Ok(false),
        };
        self.stats.received += 1;
        let processed = {
            let mut segment = self.segment.lock().map_err(|_| SocketError::Poisoned)?;
            segment.set_time_ns(self.clock.now_ns().saturating_sub(age_ns));
            segment.process(&mut self.buffer[..len])
        };
        if processed.is_err() {
            self.stats.rejected += 1;
            return Ok(true);
        }
        self.socket.send(&self.buffer[..len])?;
        self.stats.returned += 1;
        Ok(true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_cannot_be_interfaces_are_refused_before_any_socket() {
        for name in ["", "a-name-far-too-long-for-linux", "nul\0name"] {
            let e = RawSocket::open(name).expect_err(name);
            assert!(matches!(e, SocketError::BadName { .. }), "{name:?}: {e}");
        }
    }

    #[test]
    fn a_missing_interface_or_missing_rights_are_named() {
        match RawSocket::open("flexid-none0") {
            Err(SocketError::NoInterface { interface }) => assert_eq!(interface, "flexid-none0"),
            Err(SocketError::Permission { interface, .. }) => {
                assert_eq!(interface, "flexid-none0");
                let e = RawSocket::open("flexid-none0").expect_err("no rights");
                assert!(e.to_string().contains("CAP_NET_RAW"), "{e}");
            }
            other => panic!("{other:?}"),
        }
    }
}
