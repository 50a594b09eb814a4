//! The CAN bus layer of flexid: one blocking interface, [`CanBus`], and its
//! implementations.
//!
//! - [`InprocBus`]: any number of handles on one in-process medium, for unit tests.
//! - [`UdpMulticastBus`]: a user-space virtual bus over UDP multicast, wire-compatible
//!   with python-can's `udp_multicast` interface (for machines without SocketCAN).
//! - `SocketCanBus` (Linux): `can0`, `vcan0`, ... through the `socketcan` crate.
//! - [`timing::Paced`]: bit-timing emulation over any of them, and the pure
//!   [`timing::frame_bits`] / [`timing::bus_load`] for admission checks.
//!
//! Frames are small `Copy` values ([`CanFrame`]); sending and receiving do not allocate
//! in the steady state.

pub mod bus;
pub mod error;
pub mod frame;
pub mod inproc;
pub mod loopback;
#[cfg(target_os = "linux")]
mod poll;
pub mod pycan_wire;
mod rx_stamp;
#[cfg(target_os = "linux")]
pub mod socketcan;
pub mod spec;
pub mod timing;
pub mod udp_multicast;

pub use bus::{BusStats, CanBus};
pub use error::{BusError, ErrorClass, ErrorFrameInfo};
pub use frame::{CanFrame, CanId, FrameError, FrameKind, Received};
pub use inproc::InprocBus;
pub use loopback::keep_multicast_on_loopback;
#[cfg(target_os = "linux")]
pub use socketcan::SocketCanBus;
pub use spec::BusSpec;
pub use udp_multicast::{UdpConfig, UdpMulticastBus};
