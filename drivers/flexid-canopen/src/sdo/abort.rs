//! SDO abort codes (CiA 301 §7.2.4.3.17, Table 22) and their text.
//!
//! canopen-rs 0.6.1 names eleven codes (`SdoAbortCode`) but has no text and no table of
//! the rest: this is the full CiA 301 table, hand-written.

use canopen_rs::sdo::SdoPayload;

/// 0x05040000 SDO protocol timed out.
pub const PROTOCOL_TIMED_OUT: u32 = 0x0504_0000;
/// 0x08000000 General error.
pub const GENERAL_ERROR: u32 = 0x0800_0000;
/// 0x06020000 Object does not exist in the object dictionary.
pub const OBJECT_DOES_NOT_EXIST: u32 = 0x0602_0000;
/// 0x06090011 Sub-index does not exist.
pub const SUBINDEX_DOES_NOT_EXIST: u32 = 0x0609_0011;

/// The CiA 301 meaning of an SDO abort code ("unknown abort code" otherwise).
pub fn abort_text(code: u32) -> &'static str {
    match code {
        0x0503_0000 => "toggle bit not alternated",
        0x0504_0000 => "SDO protocol timed out",
        0x0504_0001 => "client/server command specifier not valid or unknown",
        0x0504_0002 => "invalid block size",
        0x0504_0003 => "invalid sequence number",
        0x0504_0004 => "CRC error",
        0x0504_0005 => "out of memory",
        0x0601_0000 => "unsupported access to an object",
        0x0601_0001 => "attempt to read a write only object",
        0x0601_0002 => "attempt to write a read only object",
        0x0602_0000 => "object does not exist in the object dictionary",
        0x0604_0041 => "object cannot be mapped to the PDO",
        0x0604_0042 => "the number and length of the objects to be mapped would exceed PDO length",
        0x0604_0043 => "general parameter incompatibility reason",
        0x0604_0047 => "general internal incompatibility in the device",
        0x0606_0000 => "access failed due to a hardware error",
        0x0607_0010 => "data type does not match, length of service parameter does not match",
        0x0607_0012 => "data type does not match, length of service parameter too high",
        0x0607_0013 => "data type does not match, length of service parameter too low",
        0x0609_0011 => "sub-index does not exist",
        0x0609_0030 => "invalid value for parameter (download only)",
        0x0609_0031 => "value of parameter written too high (download only)",
        0x0609_0032 => "value of parameter written too low (download only)",
        0x0609_0036 => "maximum value is less than minimum value",
        0x060A_0023 => "resource not available: SDO connection",
        0x0800_0000 => "general error",
        0x0800_0020 => "data cannot be transferred or stored to the application",
        0x0800_0021 => {
            "data cannot be transferred or stored to the application because of local control"
        }
        0x0800_0022 => {
            "data cannot be transferred or stored to the application because of the present device state"
        }
        0x0800_0023 => {
            "object dictionary dynamic generation fails or no object dictionary is present"
        }
        0x0800_0024 => "no data available",
        _ => "unknown abort code",
    }
}

/// An abort frame for `index:subindex` with any raw `code` (canopen-rs's `encode_abort`
/// takes only its eleven named codes).
pub fn encode(index: u16, subindex: u8, code: u32) -> SdoPayload {
    let i = index.to_le_bytes();
    let c = code.to_le_bytes();
    [0x80, i[0], i[1], subindex, c[0], c[1], c[2], c[3]]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texts_and_frame() {
        assert_eq!(
            abort_text(0x0602_0000),
            "object does not exist in the object dictionary"
        );
        assert_eq!(
            abort_text(0x0609_0030),
            "invalid value for parameter (download only)"
        );
        assert_eq!(abort_text(0x1234_5678), "unknown abort code");
        assert_eq!(
            encode(0x6060, 0, 0x0504_0000),
            [0x80, 0x60, 0x60, 0x00, 0x00, 0x00, 0x04, 0x05]
        );
    }
}
