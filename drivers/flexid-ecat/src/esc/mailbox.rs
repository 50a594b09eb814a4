//! The mailbox and its CoE SDO server (ETG.1000.6 5.6): expedited and normal upload and
//! download, and abort. A request arrives whole in the receive mailbox (SM0); the response is
//! written into the send mailbox (SM1).
//!
//! Not emulated yet: segmented transfers (answered with abort 0x05040001), complete access
//! (abort 0x06010000), SDO information, emergencies, EoE/FoE/SoE (mailbox error replies).

use super::al::AlState;
use super::dictionary::{ObjectDictionary, SdoAbort};
use crate::le;
use thiserror::Error;

/// Mailbox header length (length, address, channel/priority, type/counter), bytes.
pub const MAILBOX_HEADER_LEN: usize = 6;
/// Mailbox type of CoE.
const TYPE_COE: u8 = 0x03;
/// Mailbox type of an error reply.
const TYPE_ERROR: u8 = 0x00;
/// CoE services.
const SERVICE_SDO_REQUEST: u16 = 0x2;
const SERVICE_SDO_RESPONSE: u16 = 0x3;
/// SDO command specifiers (bits 5..7 of the SDO command byte).
const CCS_DOWNLOAD_SEGMENT: u8 = 0;
const CCS_DOWNLOAD: u8 = 1;
const CCS_UPLOAD: u8 = 2;
const CCS_UPLOAD_SEGMENT: u8 = 3;
const CCS_ABORT: u8 = 4;
/// Bytes of mailbox header, CoE header, SDO command, index and sub-index.
const SDO_HEADER_END: usize = 12;

/// A mailbox request the SubDevice cannot serve; answered with a mailbox error reply.
#[derive(Debug, Error, Clone, Copy, PartialEq, Eq)]
pub enum MailboxError {
    #[error("mailbox request of {len} bytes is shorter than its headers")]
    TooShort { len: usize },
    #[error("mailbox header announces {announced} bytes, the mailbox holds {capacity}")]
    InvalidSize { announced: usize, capacity: usize },
    #[error("mailbox type {mailbox_type:#x} is not supported (CoE only)")]
    UnsupportedProtocol { mailbox_type: u8 },
    #[error("CoE service {service:#x} is not supported (SDO requests only)")]
    UnsupportedService { service: u16 },
}

impl MailboxError {
    /// The detail code of the mailbox error reply (ETG.1000.4 table 30).
    pub fn detail_code(&self) -> u16 {
        match self {
            Self::TooShort { .. } => 0x0006,
            Self::InvalidSize { .. } => 0x0008,
            Self::UnsupportedProtocol { .. } => 0x0002,
            Self::UnsupportedService { .. } => 0x0004,
        }
    }
}

/// What the SubDevice did with a request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Outcome {
    /// An upload answered with `len` bytes of data.
    Uploaded { index: u16, sub: u8, len: usize },
    /// A download written.
    Downloaded { index: u16, sub: u8, len: usize },
    /// The request was refused with an SDO abort.
    Aborted {
        index: u16,
        sub: u8,
        abort: SdoAbort,
    },
    /// The MainDevice aborted a transfer: no response.
    AbortReceived,
    /// A mailbox error reply.
    Error(MailboxError),
}

impl Outcome {
    /// Whether a response was written into the send mailbox.
    pub fn responds(&self) -> bool {
        !matches!(self, Self::AbortReceived)
    }
}

/// Serves one request from `request` (the receive mailbox) into `response` (the send
/// mailbox), whose length is the send mailbox size.
pub fn serve(
    request: &[u8],
    response: &mut [u8],
    od: &mut ObjectDictionary,
    state: AlState,
) -> Outcome {
    let counter = request.get(5).map_or(0, |b| (b >> 4) & 0x07);
    match serve_coe(request, response, od, state, counter) {
        Ok(outcome) => outcome,
        Err(error) => {
            response.fill(0);
            write_mailbox_header(response, 4, TYPE_ERROR, counter);
            let _ = le::put_u16(response, 6, 0x0001);
            let _ = le::put_u16(response, 8, error.detail_code());
            Outcome::Error(error)
        }
    }
}

fn serve_coe(
    request: &[u8],
    response: &mut [u8],
    od: &mut ObjectDictionary,
    state: AlState,
    counter: u8,
) -> Result<Outcome, MailboxError> {
    let len = le::u16_at(request, 0).ok_or(MailboxError::TooShort { len: request.len() })?;
    let announced = usize::from(len) + MAILBOX_HEADER_LEN;
    if announced > request.len() {
        return Err(MailboxError::InvalidSize {
            announced,
            capacity: request.len(),
        });
    }
    let mailbox_type = request.get(5).map_or(0, |b| b & 0x0F);
    if mailbox_type != TYPE_COE {
        return Err(MailboxError::UnsupportedProtocol { mailbox_type });
    }
    if announced < SDO_HEADER_END {
        return Err(MailboxError::TooShort { len: announced });
    }
    let service = le::u16_at(request, 6).unwrap_or(0) >> 12;
    if service != SERVICE_SDO_REQUEST {
        return Err(MailboxError::UnsupportedService { service });
    }
    let command = request[8];
    let index = le::u16_at(request, 9).unwrap_or(0);
    let sub = request[11];
    let complete_access = command & 0x10 != 0;
    let body = &request[SDO_HEADER_END..announced];

    response.fill(0);
    let result = match command >> 5 {
        _ if complete_access => Err(SdoAbort::UnsupportedAccess),
        CCS_UPLOAD => upload(response, od, index, sub, counter),
        CCS_DOWNLOAD => download(command, body, response, od, state, index, sub, counter),
        CCS_ABORT => return Ok(Outcome::AbortReceived),
        CCS_UPLOAD_SEGMENT | CCS_DOWNLOAD_SEGMENT => Err(SdoAbort::CommandSpecifier),
        _ => Err(SdoAbort::CommandSpecifier),
    };
    Ok(match result {
        Ok(outcome) => outcome,
        Err(abort) => {
            write_sdo_header(response, 10, 0x80, index, sub, counter);
            let _ = le::put_u32(response, SDO_HEADER_END, abort.code());
            Outcome::Aborted { index, sub, abort }
        }
    })
}

fn upload(
    response: &mut [u8],
    od: &ObjectDictionary,
    index: u16,
    sub: u8,
    counter: u8,
) -> Result<Outcome, SdoAbort> {
    let value = od.upload(index, sub)?;
    let len = value.len();
    if (1..=4).contains(&len) {
        // Expedited: size indicated, expedited, 4 - len unused bytes.
        let command = 0x40 | 0x02 | 0x01 | (((4 - len) as u8) << 2);
        let dst = response
            .get_mut(SDO_HEADER_END..SDO_HEADER_END + len)
            .ok_or(SdoAbort::OutOfMemory)?;
        dst.copy_from_slice(value);
        write_sdo_header(response, 10, command, index, sub, counter);
    } else {
        // Normal: size indicated, complete size, then the data.
        let end = SDO_HEADER_END + 4 + len;
        if end > response.len() {
            return Err(SdoAbort::OutOfMemory);
        }
        write_sdo_header(response, (10 + len) as u16, 0x41, index, sub, counter);
        let _ = le::put_u32(response, SDO_HEADER_END, len as u32);
        response[SDO_HEADER_END + 4..end].copy_from_slice(value);
    }
    Ok(Outcome::Uploaded { index, sub, len })
}

#[allow(clippy::too_many_arguments)]
fn download(
    command: u8,
    body: &[u8],
    response: &mut [u8],
    od: &mut ObjectDictionary,
    state: AlState,
    index: u16,
    sub: u8,
    counter: u8,
) -> Result<Outcome, SdoAbort> {
    let data = if command & 0x02 != 0 {
        // Expedited: up to 4 bytes in the request, the size in bits 2..3 when indicated.
        let len = if command & 0x01 != 0 {
            4 - usize::from((command >> 2) & 0x03)
        } else {
            4
        };
        body.get(..len).ok_or(SdoAbort::LengthMismatch)?
    } else {
        // Normal: the complete size, then the data.
        let size = le::u32_at(body, 0).ok_or(SdoAbort::LengthMismatch)? as usize;
        body.get(4..4 + size).ok_or(SdoAbort::LengthMismatch)?
    };
    od.download(index, sub, data, state)?;
    write_sdo_header(response, 10, 0x60, index, sub, counter);
    Ok(Outcome::Downloaded {
        index,
        sub,
        len: data.len(),
    })
}

fn write_mailbox_header(response: &mut [u8], len: u16, mailbox_type: u8, counter: u8) {
    let _ = le::put_u16(response, 0, len);
    if let Some(b) = response.get_mut(5) {
        *b = mailbox_type | (counter << 4);
    }
}

/// Mailbox and CoE headers of an SDO response, then the SDO command, index and sub-index.
fn write_sdo_header(response: &mut [u8], len: u16, command: u8, index: u16, sub: u8, counter: u8) {
    write_mailbox_header(response, len, TYPE_COE, counter);
    let _ = le::put_u16(response, 6, SERVICE_SDO_RESPONSE << 12);
    if let Some(b) = response.get_mut(8) {
        *b = command;
    }
    let _ = le::put_u16(response, 9, index);
    if let Some(b) = response.get_mut(11) {
        *b = sub;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::esc::sii::Identity;

    fn od() -> ObjectDictionary {
        let id = Identity {
            vendor_id: 0xAB,
            product_code: 2,
            revision: 3,
            serial: 4,
        };
        ObjectDictionary::cia402_drive(&id, "flexid emulated axis")
    }

    /// An SDO request as ethercrab builds it: mailbox length 10, CoE, counter 1.
    fn request(command: u8, index: u16, sub: u8, data: [u8; 4]) -> [u8; 128] {
        let mut r = [0u8; 128];
        r[0] = 10;
        r[5] = 0x13;
        r[7] = 0x20;
        r[8] = command;
        r[9..11].copy_from_slice(&index.to_le_bytes());
        r[11] = sub;
        r[12..16].copy_from_slice(&data);
        r
    }

    #[test]
    fn expedited_upload_and_download() {
        let mut od = od();
        let mut resp = [0u8; 128];
        let out = serve(
            &request(0x40, 0x1018, 1, [0; 4]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert_eq!(
            out,
            Outcome::Uploaded {
                index: 0x1018,
                sub: 1,
                len: 4
            }
        );
        assert_eq!(resp[8], 0x43);
        assert_eq!(le::u32_at(&resp, 12), Some(0xAB));
        assert_eq!(resp[7] >> 4, 0x3);

        let out = serve(
            &request(0x2F, 0x6060, 0, [10, 0, 0, 0]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert_eq!(
            out,
            Outcome::Downloaded {
                index: 0x6060,
                sub: 0,
                len: 1
            }
        );
        assert_eq!(resp[8], 0x60);
        assert_eq!(od.get(0x6060, 0), Some(&[10u8][..]));
    }

    #[test]
    fn normal_upload_carries_the_complete_size() {
        let mut od = od();
        let mut resp = [0u8; 128];
        let out = serve(
            &request(0x40, 0x1008, 0, [0; 4]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert_eq!(
            out,
            Outcome::Uploaded {
                index: 0x1008,
                sub: 0,
                len: 20
            }
        );
        assert_eq!(resp[8], 0x41);
        assert_eq!(le::u16_at(&resp, 0), Some(30));
        assert_eq!(le::u32_at(&resp, 12), Some(20));
        assert_eq!(&resp[16..36], b"flexid emulated axis");
    }

    #[test]
    fn refusals_are_aborts_and_foreign_protocols_mailbox_errors() {
        let mut od = od();
        let mut resp = [0u8; 128];
        let out = serve(
            &request(0x40, 0x2000, 0, [0; 4]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert_eq!(
            out,
            Outcome::Aborted {
                index: 0x2000,
                sub: 0,
                abort: SdoAbort::NoObject
            }
        );
        assert_eq!(resp[8], 0x80);
        assert_eq!(le::u32_at(&resp, 12), Some(0x0602_0000));
        let out = serve(
            &request(0x2B, 0x6041, 0, [1, 0, 0, 0]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert_eq!(le::u32_at(&resp, 12), Some(0x0601_0002));
        assert!(matches!(
            out,
            Outcome::Aborted {
                abort: SdoAbort::ReadOnly,
                ..
            }
        ));
        let out = serve(
            &request(0x60, 0x6040, 0, [0; 4]),
            &mut resp,
            &mut od,
            AlState::PreOp,
        );
        assert!(matches!(
            out,
            Outcome::Aborted {
                abort: SdoAbort::CommandSpecifier,
                ..
            }
        ));

        let mut foe = request(0x40, 0x1000, 0, [0; 4]);
        foe[5] = 0x14;
        let out = serve(&foe, &mut resp, &mut od, AlState::PreOp);
        assert_eq!(
            out,
            Outcome::Error(MailboxError::UnsupportedProtocol { mailbox_type: 4 })
        );
        assert_eq!(resp[5] & 0x0F, 0);
        assert_eq!(le::u16_at(&resp, 8), Some(0x0002));
    }
}
