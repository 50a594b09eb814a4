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
//! The segment clock is a [`SegmentClock`] (the monotonic clock) shared with the SYNC0
//! clock thread ([`crate::sync0_clock::run_sync0_clock`]).

use crate::inprocess::SharedSegment;
use crate::sync0_clock::SegmentClock;
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
    /// A frame of `len` bytes arrived from the wire.
    Frame { len: usize },
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

    /// Waits at most `wait` for a frame and receives it into `buffer`.
    pub fn receive(&self, buffer: &mut [u8], wait: Duration) -> Result<Received, SocketError> {
        let mut pfd = libc::pollfd {
            fd: self.fd.as_raw_fd(),
            events: libc::POLLIN,
            revents: 0,
        };
        let ms = wait.as_millis().min(i32::MAX as u128) as i32;
        // SAFETY: one valid pollfd.
        let n = unsafe { libc::poll(&mut pfd, 1, ms) };
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
        let mut from_len = std::mem::size_of::<libc::sockaddr_ll>() as libc::socklen_t;
        // SAFETY: buffer and address are valid for the lengths given.
        let len = unsafe {
            libc::recvfrom(
                self.fd.as_raw_fd(),
                buffer.as_mut_ptr().cast(),
                buffer.len(),
                libc::MSG_TRUNC | libc::MSG_DONTWAIT,
                (&mut from as *mut libc::sockaddr_ll).cast(),
                &mut from_len,
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
        Ok(Received::Frame { len })
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

    /// Answers frames until `stop` is set (looked at every [`POLL_INTERVAL`] at least).
    pub fn serve(&mut self, stop: &AtomicBool) -> Result<LinkStats, SocketError> {
        while !stop.load(Ordering::Relaxed) {
            self.serve_one(POLL_INTERVAL)?;
        }
        Ok(self.stats)
    }

    /// Waits at most `wait` for one frame and answers it.
    pub fn serve_one(&mut self, wait: Duration) -> Result<(), SocketError> {
        let len = match self.socket.receive(&mut self.buffer, wait)? {
            Received::Frame { len } => len,
            Received::Skipped => {
                self.stats.skipped += 1;
                return Ok(());
            }
            Received::Nothing => return Ok(()),
        };
        self.stats.received += 1;
        let processed = {
            let mut segment = self.segment.lock().map_err(|_| SocketError::Poisoned)?;
            segment.set_time_ns(self.clock.now_ns());
            segment.process(&mut self.buffer[..len])
        };
        if processed.is_err() {
            self.stats.rejected += 1;
            return Ok(());
        }
        self.socket.send(&self.buffer[..len])?;
        self.stats.returned += 1;
        Ok(())
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
