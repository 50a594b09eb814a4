//! Classic CAN 2.0 frames (no CAN FD): identifiers, data, remote and error frames.
//!
//! A [`CanFrame`] is a small `Copy` value (no heap) that is valid by construction: the
//! constructors reject identifiers outside 11/29 bits and payloads over 8 bytes.

use std::fmt;
use std::time::Instant;

/// Largest standard (11-bit) identifier.
pub const STANDARD_ID_MAX: u16 = 0x7FF;
/// Largest extended (29-bit) identifier.
pub const EXTENDED_ID_MAX: u32 = 0x1FFF_FFFF;
/// Largest payload of a classic CAN frame, in bytes.
pub const MAX_DATA_LEN: usize = 8;

/// Why a frame could not be built. The error type of the frame layer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum FrameError {
    /// The identifier does not fit in 11 bits (standard) or 29 bits (extended).
    #[error("CAN id {id:#x} does not fit a {} identifier", if *.extended { "29-bit extended" } else { "11-bit standard" })]
    InvalidId {
        /// The rejected identifier.
        id: u32,
        /// Whether an extended identifier was asked for.
        extended: bool,
    },
    /// More than 8 data bytes (or a remote frame's DLC above 8).
    #[error("CAN frame of {len} bytes: classic CAN carries at most 8")]
    TooLong {
        /// The rejected length, in bytes.
        len: usize,
    },
    /// An error frame's class word does not fit the 29 bits of `CAN_ERR_MASK`.
    #[error("error class {class:#x} exceeds 29 bits")]
    InvalidErrorClass {
        /// The rejected class word.
        class: u32,
    },
}

/// A CAN identifier: standard 11-bit or extended 29-bit, validated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum CanId {
    /// 11-bit identifier (CAN 2.0A), `0..=0x7FF`.
    Standard(u16),
    /// 29-bit identifier (CAN 2.0B), `0..=0x1FFF_FFFF`.
    Extended(u32),
}

impl CanId {
    /// An 11-bit identifier; errors above `0x7FF`.
    pub const fn standard(id: u16) -> Result<Self, FrameError> {
        if id <= STANDARD_ID_MAX {
            Ok(Self::Standard(id))
        } else {
            Err(FrameError::InvalidId {
                id: id as u32,
                extended: false,
            })
        }
    }

    /// A 29-bit identifier; errors above `0x1FFF_FFFF`.
    pub const fn extended(id: u32) -> Result<Self, FrameError> {
        if id <= EXTENDED_ID_MAX {
            Ok(Self::Extended(id))
        } else {
            Err(FrameError::InvalidId { id, extended: true })
        }
    }

    /// A standard or extended identifier, as a flag says (wire formats carry it so).
    pub const fn new(id: u32, extended: bool) -> Result<Self, FrameError> {
        if extended {
            Self::extended(id)
        } else if id <= STANDARD_ID_MAX as u32 {
            Ok(Self::Standard(id as u16))
        } else {
            Err(FrameError::InvalidId {
                id,
                extended: false,
            })
        }
    }

    /// The numeric identifier, without any format flag.
    pub const fn raw(self) -> u32 {
        match self {
            Self::Standard(id) => id as u32,
            Self::Extended(id) => id,
        }
    }

    /// Whether this is a 29-bit identifier.
    pub const fn is_extended(self) -> bool {
        matches!(self, Self::Extended(_))
    }
}

impl fmt::Display for CanId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Standard(id) => write!(f, "{id:03X}"),
            Self::Extended(id) => write!(f, "{id:08X}"),
        }
    }
}

/// What kind of frame a [`CanFrame`] is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameKind {
    /// A data frame carrying `len` bytes.
    Data,
    /// A remote transmission request; the DLC is the requested length, no data is carried.
    Remote,
    /// An error frame as reported by a controller (SocketCAN `CAN_ERR_FLAG`): the
    /// identifier holds the error class bits, the 8 data bytes their details
    /// (see [`crate::ErrorFrameInfo`]).
    Error,
}

/// One classic CAN frame. `Copy`, 16 bytes of payload and header, no heap.
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
pub struct CanFrame {
    id: CanId,
    kind: FrameKind,
    /// Data length code, 0..=8: the number of data bytes (requested bytes for RTR).
    dlc: u8,
    data: [u8; MAX_DATA_LEN],
}

impl CanFrame {
    /// A data frame with up to 8 bytes.
    pub fn new(id: CanId, data: &[u8]) -> Result<Self, FrameError> {
        if data.len() > MAX_DATA_LEN {
            return Err(FrameError::TooLong { len: data.len() });
        }
        let mut buf = [0; MAX_DATA_LEN];
        buf[..data.len()].copy_from_slice(data);
        Ok(Self {
            id,
            kind: FrameKind::Data,
            dlc: data.len() as u8,
            data: buf,
        })
    }

    /// A data frame with an 11-bit identifier (the CANopen case).
    pub fn standard(id: u16, data: &[u8]) -> Result<Self, FrameError> {
        Self::new(CanId::standard(id)?, data)
    }

    /// A data frame with a 29-bit identifier.
    pub fn extended(id: u32, data: &[u8]) -> Result<Self, FrameError> {
        Self::new(CanId::extended(id)?, data)
    }

    /// A remote transmission request asking for `dlc` (0..=8) bytes.
    pub fn remote(id: CanId, dlc: u8) -> Result<Self, FrameError> {
        if dlc as usize > MAX_DATA_LEN {
            return Err(FrameError::TooLong { len: dlc as usize });
        }
        Ok(Self {
            id,
            kind: FrameKind::Remote,
            dlc,
            data: [0; MAX_DATA_LEN],
        })
    }

    /// An error frame with SocketCAN's layout: `class` holds the `CAN_ERR_*` class bits
    /// (at most 29 bits), `data` the details (always 8 bytes, `CAN_ERR_DLC`).
    /// Virtual buses carry these so that tests can inject bus errors.
    pub fn error(class: u32, data: [u8; MAX_DATA_LEN]) -> Result<Self, FrameError> {
        if class > EXTENDED_ID_MAX {
            return Err(FrameError::InvalidErrorClass { class });
        }
        let id = if class <= STANDARD_ID_MAX as u32 {
            CanId::Standard(class as u16)
        } else {
            CanId::Extended(class)
        };
        Ok(Self {
            id,
            kind: FrameKind::Error,
            dlc: MAX_DATA_LEN as u8,
            data,
        })
    }

    /// The identifier (for error frames: the error class bits).
    pub const fn id(&self) -> CanId {
        self.id
    }

    /// Data, remote or error frame.
    pub const fn kind(&self) -> FrameKind {
        self.kind
    }

    /// Data length code, 0..=8 (for a remote frame: the requested length).
    pub const fn dlc(&self) -> u8 {
        self.dlc
    }

    /// The data bytes (empty for a remote frame).
    pub fn data(&self) -> &[u8] {
        match self.kind {
            FrameKind::Remote => &[],
            _ => &self.data[..self.dlc as usize],
        }
    }

    /// Whether this is a remote transmission request.
    pub const fn is_remote(&self) -> bool {
        matches!(self.kind, FrameKind::Remote)
    }

    /// Whether this is an error frame.
    pub const fn is_error(&self) -> bool {
        matches!(self.kind, FrameKind::Error)
    }

    /// Bits on the wire, worst case with bit stuffing and the interframe space
    /// (see [`crate::timing::frame_bits`]). Remote and error frames carry no data field.
    pub fn wire_bits(&self) -> u32 {
        let payload = match self.kind {
            FrameKind::Data => self.dlc,
            FrameKind::Remote | FrameKind::Error => 0,
        };
        crate::timing::frame_bits(payload, self.id.is_extended())
    }
}

impl fmt::Debug for CanFrame {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

impl fmt::Display for CanFrame {
    /// candump style: `123#0102`, `123#R2`, `ERR 040#...`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.kind {
            FrameKind::Remote => return write!(f, "{}#R{}", self.id, self.dlc),
            FrameKind::Error => write!(f, "ERR {}#", self.id)?,
            FrameKind::Data => write!(f, "{}#", self.id)?,
        }
        for b in self.data() {
            write!(f, "{b:02X}")?;
        }
        Ok(())
    }
}

/// A frame as received, with the host's monotonic receive time.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Received {
    /// The frame.
    pub frame: CanFrame,
    /// When the frame reached this handle (host monotonic clock): for sockets the
    /// kernel's receive stamp, not the time it was read; for the in-process bus: when it
    /// was sent, or under [`crate::timing::Paced`] when its transmission ends on the
    /// emulated wire.
    pub timestamp: Instant,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_are_validated() {
        assert!(CanId::standard(0x7FF).is_ok());
        assert_eq!(
            CanId::standard(0x800),
            Err(FrameError::InvalidId {
                id: 0x800,
                extended: false
            })
        );
        assert!(CanId::extended(0x1FFF_FFFF).is_ok());
        assert!(CanId::extended(0x2000_0000).is_err());
        assert!(CanId::new(0x800, false).is_err());
        assert_eq!(CanId::new(0x800, true), Ok(CanId::Extended(0x800)));
        assert!(CanId::Extended(5).is_extended() && !CanId::Standard(5).is_extended());
    }

    #[test]
    fn lengths_are_validated() {
        let f = CanFrame::standard(0x181, &[1, 2, 3]).unwrap();
        assert_eq!((f.dlc(), f.data()), (3, &[1u8, 2, 3][..]));
        assert_eq!(
            CanFrame::standard(0x181, &[0; 9]),
            Err(FrameError::TooLong { len: 9 })
        );
        assert!(CanFrame::standard(0x181, &[0; 8]).is_ok());
        assert!(CanFrame::standard(0x181, &[]).is_ok());
        assert!(CanFrame::extended(0x2000_0000, &[]).is_err());
    }

    #[test]
    fn remote_and_error_frames() {
        let r = CanFrame::remote(CanId::Standard(0x701), 1).unwrap();
        assert!(r.is_remote() && r.data().is_empty() && r.dlc() == 1);
        assert!(CanFrame::remote(CanId::Standard(0x701), 9).is_err());
        let e = CanFrame::error(0x40, [0; 8]).unwrap();
        assert!(e.is_error() && e.dlc() == 8 && e.id().raw() == 0x40);
        assert!(CanFrame::error(0x2000_0000, [0; 8]).is_err());
        assert_eq!(format!("{r}"), "701#R1");
        assert_eq!(
            format!("{}", CanFrame::standard(0x81, &[0xAB, 1]).unwrap()),
            "081#AB01"
        );
    }
}
