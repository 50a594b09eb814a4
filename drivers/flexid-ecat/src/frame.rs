//! EtherCAT frames: the Ethernet header (EtherType 0x88A4), the EtherCAT header and the chain
//! of datagrams (PDUs) it carries, parsed in place without allocation.
//!
//! A PDU is 10 header bytes (command, index, 32-bit address, 11-bit length with the
//! "circulated" and "more follows" flags, IRQ), the data, and a 16-bit working counter.

use crate::le;
use thiserror::Error;

/// The EtherType of EtherCAT frames.
pub const ETHERTYPE_ETHERCAT: u16 = 0x88A4;
/// Length of the Ethernet header (destination, source, EtherType), bytes.
pub const ETHERNET_HEADER_LEN: usize = 14;
/// Length of the EtherCAT frame header, bytes.
pub const ECAT_HEADER_LEN: usize = 2;
/// Length of a PDU header (before its data), bytes.
pub const PDU_HEADER_LEN: usize = 10;
/// Length of the working counter that closes every PDU, bytes.
pub const PDU_WKC_LEN: usize = 2;
/// The frame type of the EtherCAT header that carries PDUs.
const FRAME_TYPE_PDU: u8 = 1;
/// The 11 bits of a length field.
const LEN_MASK: u16 = 0x07FF;
/// "More PDUs follow" bit of the PDU length field.
const MORE_FOLLOWS: u16 = 0x8000;
/// The locally administered bit of the first MAC address octet, set by a SubDevice in the
/// source address of every frame it forwards.
pub const LOCALLY_ADMINISTERED: u8 = 0x02;

/// A frame the segment cannot process.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum FrameError {
    #[error("frame of {len} bytes is shorter than the Ethernet and EtherCAT headers")]
    TooShort { len: usize },
    #[error("EtherType {ethertype:#06x} is not EtherCAT (0x88a4)")]
    NotEtherCat { ethertype: u16 },
    #[error("EtherCAT frame type {frame_type} is not a PDU frame (1)")]
    UnsupportedType { frame_type: u8 },
    #[error("EtherCAT header announces {announced} bytes of PDUs, the frame holds {available}")]
    LengthMismatch { announced: usize, available: usize },
    #[error(
        "PDU {pdu} at byte {offset} runs past the end of the EtherCAT payload ({payload} bytes)"
    )]
    PduTruncated {
        pdu: usize,
        offset: usize,
        payload: usize,
    },
    #[error("PDU {pdu} has the unknown command code {code:#04x}")]
    UnknownCommand { pdu: usize, code: u8 },
}

/// How a command addresses SubDevices.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Addressing {
    /// No SubDevice is addressed.
    None,
    /// Auto-increment (position) addressing: the SubDevice that sees position 0 is addressed;
    /// every SubDevice increments the position.
    Position,
    /// Configured station address (register 0x0010).
    Configured,
    /// Every SubDevice; every SubDevice increments the position field.
    Broadcast,
    /// The 32-bit logical address space, mapped by each SubDevice's FMMUs.
    Logical,
}

/// What a command does with the addressed memory.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    None,
    Read,
    Write,
    ReadWrite,
    /// The addressed SubDevice reads, all others write what it read (ARMW, FRMW).
    ReadMultipleWrite,
}

/// The EtherCAT commands (ETG.1000.4), by their code.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum Command {
    Nop = 0x00,
    Aprd = 0x01,
    Apwr = 0x02,
    Aprw = 0x03,
    Fprd = 0x04,
    Fpwr = 0x05,
    Fprw = 0x06,
    Brd = 0x07,
    Bwr = 0x08,
    Brw = 0x09,
    Lrd = 0x0A,
    Lwr = 0x0B,
    Lrw = 0x0C,
    Armw = 0x0D,
    Frmw = 0x0E,
}

impl Command {
    /// The command of a code, `None` for codes EtherCAT does not define.
    pub fn from_code(code: u8) -> Option<Self> {
        Some(match code {
            0x00 => Self::Nop,
            0x01 => Self::Aprd,
            0x02 => Self::Apwr,
            0x03 => Self::Aprw,
            0x04 => Self::Fprd,
            0x05 => Self::Fpwr,
            0x06 => Self::Fprw,
            0x07 => Self::Brd,
            0x08 => Self::Bwr,
            0x09 => Self::Brw,
            0x0A => Self::Lrd,
            0x0B => Self::Lwr,
            0x0C => Self::Lrw,
            0x0D => Self::Armw,
            0x0E => Self::Frmw,
            _ => return None,
        })
    }

    /// How the command addresses SubDevices.
    pub fn addressing(self) -> Addressing {
        match self {
            Self::Nop => Addressing::None,
            Self::Aprd | Self::Apwr | Self::Aprw | Self::Armw => Addressing::Position,
            Self::Fprd | Self::Fpwr | Self::Fprw | Self::Frmw => Addressing::Configured,
            Self::Brd | Self::Bwr | Self::Brw => Addressing::Broadcast,
            Self::Lrd | Self::Lwr | Self::Lrw => Addressing::Logical,
        }
    }

    /// What the command does with the memory it addresses.
    pub fn access(self) -> Access {
        match self {
            Self::Nop => Access::None,
            Self::Aprd | Self::Fprd | Self::Brd | Self::Lrd => Access::Read,
            Self::Apwr | Self::Fpwr | Self::Bwr | Self::Lwr => Access::Write,
            Self::Aprw | Self::Fprw | Self::Brw | Self::Lrw => Access::ReadWrite,
            Self::Armw | Self::Frmw => Access::ReadMultipleWrite,
        }
    }
}

/// One PDU of a frame, borrowed mutably: the fields a SubDevice changes are the address (the
/// position of auto-increment and broadcast commands), the data and the working counter;
/// [`Pdu::store`] writes them back.
#[derive(Debug)]
pub struct Pdu<'a> {
    pub command: Command,
    /// The PDU index the MainDevice uses to match replies.
    pub index: u8,
    /// The 32-bit address field: position or station address in the low 16 bits and the
    /// register (offset) in the high 16 bits, or the logical address.
    pub address: u32,
    pub data: &'a mut [u8],
    pub working_counter: u16,
}

impl Pdu<'_> {
    /// The position or configured station address (ADP).
    pub fn station(&self) -> u16 {
        (self.address & 0xFFFF) as u16
    }

    /// The register offset (ADO).
    pub fn offset(&self) -> u16 {
        (self.address >> 16) as u16
    }

    /// Replaces the position/station field (ADP), keeping the offset.
    pub fn set_station(&mut self, station: u16) {
        self.address = (self.address & 0xFFFF_0000) | u32::from(station);
    }
}

/// A validated EtherCAT frame: where its PDUs are.
#[derive(Debug, Clone, Copy)]
pub struct FrameLayout {
    /// Number of PDUs in the frame.
    pub pdus: usize,
    /// End of the EtherCAT payload in the frame, bytes.
    end: usize,
}

impl FrameLayout {
    /// Checks the Ethernet and EtherCAT headers and walks the PDU chain once.
    pub fn parse(frame: &[u8]) -> Result<Self, FrameError> {
        let start = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
        if frame.len() < start {
            return Err(FrameError::TooShort { len: frame.len() });
        }
        let ethertype = u16::from_be_bytes([frame[12], frame[13]]);
        if ethertype != ETHERTYPE_ETHERCAT {
            return Err(FrameError::NotEtherCat { ethertype });
        }
        let header = le::u16_at(frame, ETHERNET_HEADER_LEN).unwrap_or(0);
        let frame_type = (header >> 12) as u8;
        if frame_type != FRAME_TYPE_PDU {
            return Err(FrameError::UnsupportedType { frame_type });
        }
        let announced = usize::from(header & LEN_MASK);
        let available = frame.len() - start;
        if announced > available {
            return Err(FrameError::LengthMismatch {
                announced,
                available,
            });
        }
        let end = start + announced;
        let mut offset = start;
        let mut pdus = 0;
        loop {
            let (code, len, more) = pdu_header(frame, offset, end, pdus)?;
            if Command::from_code(code).is_none() {
                return Err(FrameError::UnknownCommand { pdu: pdus, code });
            }
            offset += PDU_HEADER_LEN + len + PDU_WKC_LEN;
            pdus += 1;
            if !more || offset >= end {
                break;
            }
        }
        Ok(Self { pdus, end })
    }

    /// Calls `each` with every PDU in order, writing its changed fields back into the frame.
    /// The frame must be the one this layout was parsed from.
    pub fn for_each_pdu(&self, frame: &mut [u8], mut each: impl FnMut(&mut Pdu<'_>)) {
        let mut offset = ETHERNET_HEADER_LEN + ECAT_HEADER_LEN;
        for n in 0..self.pdus {
            let Ok((code, len, _)) = pdu_header(frame, offset, self.end, n) else {
                return;
            };
            let Some(command) = Command::from_code(code) else {
                return;
            };
            let (head, rest) = frame[offset..].split_at_mut(PDU_HEADER_LEN);
            let (data, tail) = rest.split_at_mut(len);
            let mut pdu = Pdu {
                command,
                index: head[1],
                address: le::u32_at(head, 2).unwrap_or(0),
                working_counter: le::u16_at(tail, 0).unwrap_or(0),
                data,
            };
            each(&mut pdu);
            let _ = le::put_u32(head, 2, pdu.address);
            let _ = le::put_u16(tail, 0, pdu.working_counter);
            offset += PDU_HEADER_LEN + len + PDU_WKC_LEN;
        }
    }
}

/// (command code, data length, more follows) of the PDU at `offset`, checked to end before
/// `end`.
fn pdu_header(
    frame: &[u8],
    offset: usize,
    end: usize,
    pdu: usize,
) -> Result<(u8, usize, bool), FrameError> {
    let truncated = FrameError::PduTruncated {
        pdu,
        offset,
        payload: end.saturating_sub(ETHERNET_HEADER_LEN + ECAT_HEADER_LEN),
    };
    let header = frame
        .get(offset..offset + PDU_HEADER_LEN)
        .filter(|_| offset + PDU_HEADER_LEN <= end)
        .ok_or_else(|| truncated.clone())?;
    let flags = le::u16_at(header, 6).ok_or_else(|| truncated.clone())?;
    let len = usize::from(flags & LEN_MASK);
    if offset + PDU_HEADER_LEN + len + PDU_WKC_LEN > end {
        return Err(truncated);
    }
    Ok((header[0], len, flags & MORE_FOLLOWS != 0))
}

/// Sets the locally administered bit in the source MAC address, as every real SubDevice does
/// to the frames it forwards (ethercrab drops replies whose source is still its own address).
pub fn mark_forwarded(frame: &mut [u8]) {
    if let Some(first) = frame.get_mut(6) {
        *first |= LOCALLY_ADMINISTERED;
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A frame from MAC 10:10:10:10:10:10 with the given (command, address, data) PDUs.
    pub(crate) fn build(pdus: &[(Command, u32, &[u8])]) -> Vec<u8> {
        let mut f = vec![0xFF; 6];
        f.extend_from_slice(&[0x10; 6]);
        f.extend_from_slice(&ETHERTYPE_ETHERCAT.to_be_bytes());
        f.extend_from_slice(&[0, 0]);
        for (i, (command, address, data)) in pdus.iter().enumerate() {
            f.push(*command as u8);
            f.push(i as u8);
            f.extend_from_slice(&address.to_le_bytes());
            let more = if i + 1 < pdus.len() { MORE_FOLLOWS } else { 0 };
            f.extend_from_slice(&(data.len() as u16 | more).to_le_bytes());
            f.extend_from_slice(&[0, 0]);
            f.extend_from_slice(data);
            f.extend_from_slice(&[0, 0]);
        }
        let len = (f.len() - 16) as u16 | 0x1000;
        f[14..16].copy_from_slice(&len.to_le_bytes());
        f
    }

    /// The data and working counter of PDU `n` of a frame.
    pub(crate) fn pdu(frame: &mut [u8], n: usize) -> (Vec<u8>, u16) {
        let layout = FrameLayout::parse(frame).expect("valid frame");
        let mut out = None;
        let mut i = 0;
        layout.for_each_pdu(frame, |p| {
            if i == n {
                out = Some((p.data.to_vec(), p.working_counter));
            }
            i += 1;
        });
        out.expect("pdu index in range")
    }

    #[test]
    fn parses_a_chain_of_pdus_and_rejects_damaged_frames() {
        let frame = build(&[
            (Command::Brd, 0, &[0, 0]),
            (Command::Fprd, 0x0130_1000, &[0; 2]),
        ]);
        assert_eq!(FrameLayout::parse(&frame).map(|l| l.pdus), Ok(2));

        let mut wrong_type = frame.clone();
        wrong_type[12] = 0x08;
        assert_eq!(
            FrameLayout::parse(&wrong_type).map(|l| l.pdus),
            Err(FrameError::NotEtherCat { ethertype: 0x08A4 })
        );
        let short = &frame[..frame.len() - 1];
        assert!(matches!(
            FrameLayout::parse(short),
            Err(FrameError::LengthMismatch { .. })
        ));
        let mut unknown = frame.clone();
        unknown[16] = 0x0F;
        assert_eq!(
            FrameLayout::parse(&unknown).map(|l| l.pdus),
            Err(FrameError::UnknownCommand { pdu: 0, code: 0x0F })
        );
        let mut long_pdu = frame.clone();
        long_pdu[22] = 0x40;
        assert!(matches!(
            FrameLayout::parse(&long_pdu),
            Err(FrameError::PduTruncated { pdu: 0, .. })
        ));
    }
}
