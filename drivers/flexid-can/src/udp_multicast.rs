//! A user-space virtual CAN bus over UDP multicast, wire-compatible with python-can's
//! `udp_multicast` interface (python-can 4.6.1): same groups, port and message encoding
//! ([`crate::pycan_wire`]), so flexid and `can.Bus(interface="udp_multicast", ...)`
//! processes see each other's frames.
//!
//! # Sockets, as python-can sets them up
//!
//! python-can uses one socket per bus: `SO_REUSEADDR` + `SO_REUSEPORT`, bound to
//! `[::]`/`0.0.0.0`:43113, joined to the group on the default interface
//! (`INADDR_ANY` / ifindex 0), multicast TTL / hop limit 1, multicast loop left on (the
//! Linux default), and sends to `group:port` from that same socket.
//!
//! A python-can bus therefore receives its own frames (loop on, same socket). flexid does
//! not, so that its handles behave like CAN nodes: each handle has a receive socket set
//! up exactly as python-can's, and a separate send socket with an ephemeral port; that
//! port (with the source IP the kernel picks for the group) identifies the handle's own
//! datagrams, which the receive side drops. Frames of other flexid handles (other send sockets) and
//! of python-can processes (source port 43113) are received. [`UdpConfig::receive_own`]
//! turns the filter off.
//!
//! # Multicast on one machine
//!
//! The datagrams go out on the interface the routing table picks for the group (or
//! [`UdpConfig::interface_v4`]). On a machine whose default route is a real network,
//! that is the network: to keep the bus on the machine (tests, sandboxes), route the
//! group to loopback, once, as root:
//!
//! ```text
//! ip link set lo multicast on
//! ip route add 239.0.0.0/8 dev lo
//! ```
//!
//! IPv6 multicast on `lo` did not deliver in our sandbox (Linux, loopback only), so the
//! default here is python-can's IPv4 group ([`DEFAULT_GROUP_V4`]); python-can's own
//! default channel is the IPv6 group ([`DEFAULT_GROUP_V6`]), which works on a real LAN.
//! A python peer must be opened with the same `channel` string as [`UdpConfig::group`].

use std::io;
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};
use std::os::fd::AsRawFd;
use std::sync::Arc;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use socket2::{Domain, Protocol, SockAddr, Socket, Type};

use crate::bus::{BusStats, CanBus};
use crate::error::BusError;
use crate::frame::{CanFrame, Received};
use crate::pycan_wire::{self, Decoded, MAX_ENCODED_LEN};

/// python-can's `UdpMulticastBus.DEFAULT_GROUP_IPv6` (site-local scope).
pub const DEFAULT_GROUP_V6: Ipv6Addr = Ipv6Addr::new(
    0xff15, 0x7079, 0x7468, 0x6f6e, 0x6465, 0x6d6f, 0x6d63, 0x6173,
);
/// python-can's `UdpMulticastBus.DEFAULT_GROUP_IPv4` (administratively scoped).
pub const DEFAULT_GROUP_V4: Ipv4Addr = Ipv4Addr::new(239, 74, 163, 2);
/// python-can's default port.
pub const DEFAULT_PORT: u16 = 43113;
/// python-can's receive buffer (`max_buffer`); larger datagrams are truncated, hence malformed.
pub const MAX_DATAGRAM: usize = 4096;

/// Where and how to join the virtual bus.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UdpConfig {
    /// Multicast group (`224.0.0.0/4` or `ff00::/8`): python-can's `channel`.
    pub group: IpAddr,
    /// UDP port (python-can: `port`).
    pub port: u16,
    /// IPv4 TTL / IPv6 hop limit of sent datagrams (python-can: `hop_limit`, 1 = this link).
    pub hop_limit: u32,
    /// IPv4 address of the interface to send on and join on; `None`: the routing
    /// table's choice, as python-can does.
    pub interface_v4: Option<Ipv4Addr>,
    /// IPv6 interface index to send on and join on; 0: the routing table's choice.
    pub interface_v6: u32,
    /// Also receive this handle's own frames (python-can's behaviour; off: CAN-like).
    pub receive_own: bool,
}

impl Default for UdpConfig {
    /// python-can's IPv4 group and port, hop limit 1, routing's interface, own frames filtered.
    fn default() -> Self {
        Self {
            group: IpAddr::V4(DEFAULT_GROUP_V4),
            port: DEFAULT_PORT,
            hop_limit: 1,
            interface_v4: None,
            interface_v6: 0,
            receive_own: false,
        }
    }
}

impl UdpConfig {
    /// The default configuration on another group.
    pub fn group(group: IpAddr) -> Self {
        Self {
            group,
            ..Self::default()
        }
    }

    /// The default configuration on another group and port.
    pub fn group_port(group: IpAddr, port: u16) -> Self {
        Self {
            group,
            port,
            ..Self::default()
        }
    }
}

/// One node on a UDP multicast virtual CAN bus.
#[derive(Debug)]
pub struct UdpMulticastBus {
    config: UdpConfig,
    name: Arc<str>,
    rx: UdpSocket,
    tx: UdpSocket,
    /// `group:port`.
    dest: SocketAddr,
    /// Where this handle's datagrams come from.
    own: OwnAddr,
    stats: BusStats,
    buf: Box<[u8; MAX_DATAGRAM]>,
}

/// The source of a handle's own datagrams: its send socket's port and the source IP the
/// kernel picks for the group (`None` if that could not be learnt: port alone decides).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct OwnAddr {
    ip: Option<IpAddr>,
    port: u16,
}

impl OwnAddr {
    fn matches(&self, from: SocketAddr) -> bool {
        from.port() == self.port && self.ip.is_none_or(|ip| ip == from.ip())
    }
}

impl UdpMulticastBus {
    /// Joins the bus described by `config`.
    pub fn open(config: UdpConfig) -> Result<Self, BusError> {
        let name: Arc<str> = format!("udp:{}", SocketAddr::new(config.group, config.port)).into();
        let err = |what: &'static str| {
            let name = name.clone();
            move |source: io::Error| BusError::Open {
                interface: name,
                what,
                source,
            }
        };
        if !config.group.is_multicast() {
            return Err(err("check group")(io::Error::new(
                io::ErrorKind::InvalidInput,
                format!("{} is not a multicast address", config.group),
            )));
        }
        let dest = SocketAddr::new(config.group, config.port);
        let domain = Domain::for_address(dest);

        // Receive socket: as python-can's.
        let rx = Socket::new(domain, Type::DGRAM, Some(Protocol::UDP)).map_err(err("socket"))?;
        rx.set_reuse_address(true).map_err(err("SO_REUSEADDR"))?;
        rx.set_reuse_port(true).map_err(err("SO_REUSEPORT"))?;
        let any: SocketAddr = match config.group {
            IpAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, config.port).into(),
            IpAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, config.port).into(),
        };
        rx.bind(&any.into()).map_err(err("bind"))?;
        rx.set_nonblocking(true).map_err(err("O_NONBLOCK"))?;
        crate::rx_stamp::enable(rx.as_raw_fd());
        match config.group {
            IpAddr::V4(g) => {
                rx.join_multicast_v4(&g, &config.interface_v4.unwrap_or(Ipv4Addr::UNSPECIFIED))
            }
            IpAddr::V6(g) => rx.join_multicast_v6(&g, config.interface_v6),
        }
        .map_err(err("join multicast group"))?;

        // Send socket: its own ephemeral port identifies this handle's datagrams. (Not
        // connected: on Linux a connected UDP socket's multicast to a group routed via
        // `lo` is not looped back to the group's members.)
        let tx = Self::send_socket(&config, domain).map_err(err("configure send socket"))?;
        let unspecified: SocketAddr = match config.group {
            IpAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, 0).into(),
            IpAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, 0).into(),
        };
        tx.bind(&unspecified.into())
            .map_err(err("bind send socket"))?;
        let port = tx
            .local_addr()
            .map_err(err("getsockname"))?
            .as_socket()
            .map_or(0, |a| a.port());
        // The source IP the kernel will pick: ask a connected twin (no datagram is sent).
        let source = Self::send_socket(&config, domain)
            .and_then(|probe| {
                probe.connect(&SockAddr::from(dest))?;
                probe.local_addr()
            })
            .ok()
            .and_then(|a| a.as_socket())
            .map(|a| a.ip());
        let own = OwnAddr { ip: source, port };

        Ok(Self {
            config,
            name,
            rx: rx.into(),
            tx: tx.into(),
            dest,
            own,
            stats: BusStats::default(),
            buf: Box::new([0; MAX_DATAGRAM]),
        })
    }

    /// Joins python-can's IPv4 default bus (`239.74.163.2:43113`).
    pub fn open_default() -> Result<Self, BusError> {
        Self::open(UdpConfig::default())
    }

    /// The configuration this handle was opened with.
    pub fn config(&self) -> &UdpConfig {
        &self.config
    }

    /// The address this handle's datagrams come from (its send socket; IP unspecified
    /// when it could not be learnt).
    pub fn local_addr(&self) -> SocketAddr {
        let ip = self.own.ip.unwrap_or(match self.config.group {
            IpAddr::V4(_) => Ipv4Addr::UNSPECIFIED.into(),
            IpAddr::V6(_) => Ipv6Addr::UNSPECIFIED.into(),
        });
        SocketAddr::new(ip, self.own.port)
    }

    /// A UDP socket with the multicast send options of `config`.
    fn send_socket(config: &UdpConfig, domain: Domain) -> io::Result<Socket> {
        let tx = Socket::new(domain, Type::DGRAM, Some(Protocol::UDP))?;
        match config.group {
            IpAddr::V4(_) => {
                tx.set_multicast_ttl_v4(config.hop_limit)?;
                tx.set_multicast_loop_v4(true)?;
                if let Some(ifa) = config.interface_v4 {
                    tx.set_multicast_if_v4(&ifa)?;
                }
            }
            IpAddr::V6(_) => {
                tx.set_multicast_hops_v6(config.hop_limit)?;
                tx.set_multicast_loop_v6(true)?;
                if config.interface_v6 != 0 {
                    tx.set_multicast_if_v6(config.interface_v6)?;
                }
            }
        }
        Ok(tx)
    }
}

/// Decodes one datagram as [`UdpMulticastBus`] does: `Ok(None)` for valid messages that
/// this bus does not carry (CAN FD), [`BusError::Malformed`] for the rest.
pub fn decode_datagram(
    interface: &Arc<str>,
    datagram: &[u8],
    from: SocketAddr,
) -> Result<Option<CanFrame>, BusError> {
    match pycan_wire::decode(datagram) {
        Ok(Decoded::Frame { frame, .. }) => Ok(Some(frame)),
        Ok(Decoded::CanFd) => Ok(None),
        Err(reason) => Err(BusError::Malformed {
            interface: interface.clone(),
            from: from.to_string(),
            len: datagram.len(),
            reason,
        }),
    }
}

fn rx_error(interface: &Arc<str>, source: io::Error) -> BusError {
    BusError::Io {
        interface: interface.clone(),
        op: "receive",
        source,
    }
}

fn unix_seconds() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl CanBus for UdpMulticastBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        let mut buf = [0u8; MAX_ENCODED_LEN];
        let datagram = pycan_wire::encode(frame, unix_seconds(), &mut buf);
        match self.tx.send_to(datagram, self.dest) {
            Ok(n) if n == datagram.len() => {
                self.stats.sent += 1;
                Ok(())
            }
            Ok(n) => Err(BusError::Io {
                interface: self.name.clone(),
                op: "send",
                source: io::Error::new(
                    io::ErrorKind::WriteZero,
                    format!("sent {n} of {} bytes", datagram.len()),
                ),
            }),
            Err(source) => Err(BusError::Io {
                interface: self.name.clone(),
                op: "send",
                source,
            }),
        }
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, BusError> {
        // The socket is non-blocking; waits are ppoll(2), kept to the microsecond.
        // (SO_RCVTIMEO, which this used, rounds up to scheduler ticks: a 100 us wait took
        // 8 ms at HZ=250, two whole cycles at 250 Hz, each time a TPDO was missing.)
        let deadline = Instant::now().checked_add(timeout);
        loop {
            let (len, from) = match self.rx.recv_from(&mut self.buf[..]) {
                Ok(x) => x,
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {
                    let left = match deadline {
                        Some(d) => d.saturating_duration_since(Instant::now()),
                        None => Duration::from_secs(24 * 3600),
                    };
                    if left.is_zero() {
                        return Ok(None);
                    }
                    crate::poll::wait_readable(self.rx.as_raw_fd(), left)
                        .map_err(|e| rx_error(&self.name, e))?;
                    continue; // readable, woken early or interrupted: read again
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(rx_error(&self.name, e)),
            };
            if !self.config.receive_own && self.own.matches(from) {
                continue;
            }
            let timestamp = crate::rx_stamp::last_arrival(self.rx.as_raw_fd());
            match decode_datagram(&self.name, &self.buf[..len], from) {
                Ok(Some(frame)) if frame.is_error() => {
                    self.stats.error_frames += 1;
                    return Err(BusError::from_error_frame(&self.name, &frame));
                }
                Ok(Some(frame)) => {
                    self.stats.received += 1;
                    return Ok(Some(Received { frame, timestamp }));
                }
                Ok(None) => self.stats.ignored += 1,
                Err(e) => {
                    self.stats.malformed += 1;
                    tracing::debug!("{e}");
                }
            }
        }
    }

    fn try_clone(&self) -> Result<Self, BusError> {
        Self::open(self.config.clone())
    }

    fn interface(&self) -> &str {
        &self.name
    }

    fn stats(&self) -> BusStats {
        self.stats
    }
}
