//! The bus layer's error type and the decoding of CAN error frames.

use std::fmt;
use std::io;
use std::sync::Arc;

use crate::frame::{CanFrame, FrameError};
use crate::pycan_wire::DecodeError;

/// Errors of the bus layer. Every variant names the interface it happened on
/// (`can0`, `udp:239.74.163.2:43113`, `inproc:test`).
///
/// `ErrorFrame`, `BusOff` and `Overrun` are reports, not broken handles: the caller may
/// keep calling [`crate::CanBus::recv_timeout`]. `Io` and `Open` mean the handle (or the
/// attempt to make one) failed.
#[derive(Debug, thiserror::Error)]
pub enum BusError {
    /// Opening or configuring the interface failed (missing interface, no `AF_CAN` in
    /// the kernel, multicast join refused, ...).
    #[error("cannot open {interface}: {what}: {source}")]
    Open {
        /// The interface or address that was asked for.
        interface: Arc<str>,
        /// The step that failed (e.g. "join multicast group").
        what: &'static str,
        /// The OS error.
        #[source]
        source: io::Error,
    },
    /// A send or receive on an open handle failed.
    #[error("{op} on {interface} failed: {source}")]
    Io {
        /// The interface or address.
        interface: Arc<str>,
        /// "send" or "receive".
        op: &'static str,
        /// The OS error.
        #[source]
        source: io::Error,
    },
    /// The controller went bus-off (too many transmit errors): it no longer takes part
    /// in bus traffic until restarted (e.g. `ip link set can0 type can restart-ms 100`).
    #[error("{interface} is bus-off ({info})")]
    BusOff {
        /// The interface.
        interface: Arc<str>,
        /// The decoded error frame that reported it.
        info: ErrorFrameInfo,
    },
    /// An error frame other than bus-off (error passive/warning, protocol violation, no
    /// ACK, lost arbitration, ...).
    #[error("error frame on {interface}: {info}")]
    ErrorFrame {
        /// The interface.
        interface: Arc<str>,
        /// The decoded error frame.
        info: ErrorFrameInfo,
    },
    /// Frames were dropped because this handle's receive queue was full.
    #[error("{interface}: receive queue overrun, {lost} frames lost")]
    Overrun {
        /// The interface.
        interface: Arc<str>,
        /// Frames lost since the last report.
        lost: u64,
    },
    /// A datagram that is not a python-can message. `recv_timeout` never returns this:
    /// it counts such datagrams in [`crate::BusStats::malformed`] and skips them;
    /// [`crate::udp_multicast::decode_datagram`] returns it.
    #[error("{interface}: malformed datagram of {len} bytes from {from}: {reason}")]
    Malformed {
        /// The interface (multicast group and port).
        interface: Arc<str>,
        /// The sender's address.
        from: String,
        /// Datagram length, in bytes.
        len: usize,
        /// What was wrong.
        reason: DecodeError,
    },
    /// The bus cannot carry this frame (e.g. sending an error frame on SocketCAN).
    #[error("{interface} cannot send {frame}: {why}")]
    Unsupported {
        /// The interface.
        interface: Arc<str>,
        /// The frame that was refused.
        frame: CanFrame,
        /// Why.
        why: &'static str,
    },
    /// A frame could not be built from what the bus delivered.
    #[error("{interface}: invalid frame: {source}")]
    Frame {
        /// The interface.
        interface: Arc<str>,
        /// The frame layer's error.
        #[source]
        source: FrameError,
    },
}

impl BusError {
    /// The report for a received error frame: [`BusError::BusOff`] when the bus-off
    /// class bit is set, [`BusError::ErrorFrame`] otherwise.
    pub fn from_error_frame(interface: &Arc<str>, frame: &CanFrame) -> Self {
        let info = ErrorFrameInfo::decode(frame);
        if info.class.contains(ErrorClass::BUS_OFF) {
            Self::BusOff {
                interface: interface.clone(),
                info,
            }
        } else {
            Self::ErrorFrame {
                interface: interface.clone(),
                info,
            }
        }
    }

    /// Whether the handle is still usable after this error (error frames, bus-off
    /// reports, overruns and malformed input are reports; I/O failures are not).
    pub fn is_report(&self) -> bool {
        matches!(
            self,
            Self::BusOff { .. }
                | Self::ErrorFrame { .. }
                | Self::Overrun { .. }
                | Self::Malformed { .. }
        )
    }
}

/// The class bits of an error frame's identifier (Linux `linux/can/error.h`, `CAN_ERR_*`).
#[derive(Clone, Copy, PartialEq, Eq, Hash, Default)]
pub struct ErrorClass(pub u32);

impl ErrorClass {
    /// TX timeout (by netdevice driver).
    pub const TX_TIMEOUT: Self = Self(0x001);
    /// Lost arbitration; `data[0]` holds the bit position.
    pub const LOST_ARBITRATION: Self = Self(0x002);
    /// Controller problems; `data[1]` holds the details (error passive/warning, overflow).
    pub const CONTROLLER: Self = Self(0x004);
    /// Protocol violation; `data[2]` type, `data[3]` location.
    pub const PROTOCOL: Self = Self(0x008);
    /// Transceiver status; `data[4]`.
    pub const TRANSCEIVER: Self = Self(0x010);
    /// No ACK received on transmission.
    pub const NO_ACK: Self = Self(0x020);
    /// Bus off.
    pub const BUS_OFF: Self = Self(0x040);
    /// Bus error (may flood!).
    pub const BUS_ERROR: Self = Self(0x080);
    /// Controller restarted.
    pub const RESTARTED: Self = Self(0x100);
    /// Error counters valid: `data[6]` TX, `data[7]` RX.
    pub const COUNTERS: Self = Self(0x200);

    const NAMES: [(Self, &'static str); 10] = [
        (Self::TX_TIMEOUT, "tx-timeout"),
        (Self::LOST_ARBITRATION, "lost-arbitration"),
        (Self::CONTROLLER, "controller"),
        (Self::PROTOCOL, "protocol-violation"),
        (Self::TRANSCEIVER, "transceiver"),
        (Self::NO_ACK, "no-ack"),
        (Self::BUS_OFF, "bus-off"),
        (Self::BUS_ERROR, "bus-error"),
        (Self::RESTARTED, "restarted"),
        (Self::COUNTERS, "counters"),
    ];

    /// Whether all bits of `other` are set.
    pub const fn contains(self, other: Self) -> bool {
        self.0 & other.0 == other.0
    }
}

impl fmt::Debug for ErrorClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl fmt::Display for ErrorClass {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut first = true;
        let mut rest = self.0;
        for (bit, name) in Self::NAMES {
            if self.contains(bit) {
                write!(f, "{}{name}", if first { "" } else { "|" })?;
                first = false;
                rest &= !bit.0;
            }
        }
        if rest != 0 || first {
            write!(f, "{}{rest:#x}", if first { "" } else { "|" })?;
        }
        Ok(())
    }
}

/// `data[1]` bits of a controller-class error frame (`CAN_ERR_CRTL_*`).
pub mod controller {
    /// RX buffer overflow.
    pub const RX_OVERFLOW: u8 = 0x01;
    /// TX buffer overflow.
    pub const TX_OVERFLOW: u8 = 0x02;
    /// Reached warning level for RX errors.
    pub const RX_WARNING: u8 = 0x04;
    /// Reached warning level for TX errors.
    pub const TX_WARNING: u8 = 0x08;
    /// Reached error passive status RX.
    pub const RX_PASSIVE: u8 = 0x10;
    /// Reached error passive status TX.
    pub const TX_PASSIVE: u8 = 0x20;
    /// Recovered to error active state.
    pub const ACTIVE: u8 = 0x40;
}

/// A decoded error frame (SocketCAN layout).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ErrorFrameInfo {
    /// Class bits from the identifier.
    pub class: ErrorClass,
    /// Bit position where arbitration was lost (`data[0]`, 0 = unspecified).
    pub lost_arbitration_bit: u8,
    /// Controller status bits (`data[1]`, see [`controller`]).
    pub controller: u8,
    /// Protocol violation type (`data[2]`, `CAN_ERR_PROT_*`).
    pub protocol_type: u8,
    /// Protocol violation location (`data[3]`, `CAN_ERR_PROT_LOC_*`).
    pub protocol_location: u8,
    /// Transmit and receive error counters (`data[6]`, `data[7]`), when the frame
    /// carries them.
    pub counters: Option<(u8, u8)>,
}

impl ErrorFrameInfo {
    /// Decodes an error frame; for other frames the class is taken from the id all the same.
    pub fn decode(frame: &CanFrame) -> Self {
        let mut d = [0u8; 8];
        let data = frame.data();
        d[..data.len()].copy_from_slice(data);
        let class = ErrorClass(frame.id().raw());
        Self {
            class,
            lost_arbitration_bit: d[0],
            controller: d[1],
            protocol_type: d[2],
            protocol_location: d[3],
            counters: class.contains(ErrorClass::COUNTERS).then_some((d[6], d[7])),
        }
    }
}

impl fmt::Display for ErrorFrameInfo {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.class)?;
        if self.class.contains(ErrorClass::CONTROLLER) {
            use controller::*;
            let state = if self.controller & (TX_PASSIVE | RX_PASSIVE) != 0 {
                "error-passive"
            } else if self.controller & (TX_WARNING | RX_WARNING) != 0 {
                "warning"
            } else if self.controller & ACTIVE != 0 {
                "error-active"
            } else {
                "other"
            };
            write!(f, ", controller {state} ({:#04x})", self.controller)?;
        }
        if self.class.contains(ErrorClass::PROTOCOL) {
            write!(
                f,
                ", protocol type {:#04x} at {:#04x}",
                self.protocol_type, self.protocol_location
            )?;
        }
        if let Some((tx, rx)) = self.counters {
            write!(f, ", tec {tx} rec {rx}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_frames_decode_to_reports() {
        let iface: Arc<str> = "inproc:t".into();
        let off = CanFrame::error(0x40, [0; 8]).unwrap();
        assert!(matches!(
            BusError::from_error_frame(&iface, &off),
            BusError::BusOff { .. }
        ));
        let passive = CanFrame::error(0x204, [0, 0x20, 0, 0, 0, 0, 130, 5]).unwrap();
        let e = BusError::from_error_frame(&iface, &passive);
        let BusError::ErrorFrame { info, .. } = &e else {
            panic!("{e}")
        };
        assert_eq!(info.counters, Some((130, 5)));
        assert!(e.is_report());
        let text = e.to_string();
        assert!(
            text.contains("controller|counters") && text.contains("error-passive"),
            "{text}"
        );
        assert_eq!(ErrorClass(0x1000).to_string(), "0x1000");
    }
}
