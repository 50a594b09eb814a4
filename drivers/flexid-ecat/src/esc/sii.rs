//! The SII EEPROM: an image builder (identity, mailbox, strings, general, FMMU and sync
//! manager categories; ETG.1000.6 table 17, ETG.2010) and the EEPROM interface registers
//! 0x0500..0x050F through which a MainDevice reads it.

use super::registers::{SII_ADDRESS, SII_CONFIG, SII_CONTROL, SII_DATA};
use crate::le;
use thiserror::Error;

/// The SII cannot be built from this description.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SiiError {
    #[error("SII string {index} ({len} bytes) is longer than 255 bytes")]
    StringTooLong { index: usize, len: usize },
    #[error("SII has {count} strings, at most 255 fit")]
    TooManyStrings { count: usize },
    #[error("SII image of {bytes} bytes exceeds the EEPROM of {capacity} bytes")]
    TooLarge { bytes: usize, capacity: usize },
}

/// Identity of a SubDevice (SII words 0x08..0x0F, CoE object 0x1018).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Identity {
    pub vendor_id: u32,
    pub product_code: u32,
    pub revision: u32,
    pub serial: u32,
}

/// A mailbox sync manager: where the mailbox is in process RAM and how long it is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MailboxArea {
    /// Start address in ESC memory.
    pub start: u16,
    /// Length, bytes.
    pub len: u16,
}

/// What the SII image holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SiiDescription {
    pub identity: Identity,
    /// Order code, reported by ethercrab as the SubDevice's name.
    pub name: String,
    /// Long name (description).
    pub description: String,
    /// Configured station alias (word 0x04).
    pub alias: u16,
    /// Mailbox the MainDevice writes to (SM0).
    pub receive_mailbox: MailboxArea,
    /// Mailbox the MainDevice reads from (SM1).
    pub send_mailbox: MailboxArea,
    /// Start of the outputs (SM2) in ESC memory.
    pub outputs_start: u16,
    /// Start of the inputs (SM3) in ESC memory.
    pub inputs_start: u16,
}

/// Mailbox protocols word (0x1C): CoE.
const PROTOCOL_COE: u16 = 0x0004;
/// Category types.
const CAT_STRINGS: u16 = 10;
const CAT_GENERAL: u16 = 30;
const CAT_FMMU: u16 = 40;
const CAT_SYNC_MANAGER: u16 = 41;
const CAT_END: u16 = 0xFFFF;
/// CoE details of the general category: SDO, PDO assign and PDO configuration (no SDO info,
/// no complete access: not emulated).
const COE_DETAILS: u8 = 0x01 | 0x04 | 0x08;
/// EEPROM capacity, bytes (word 0x3E holds capacity / 128 - 1).
pub const EEPROM_BYTES: usize = 2048;

/// CRC-8 (polynomial 0x07, initial 0xFF) over the first 7 words: the SII checksum (word 7).
pub fn checksum(bytes: &[u8]) -> u8 {
    let mut crc: u8 = 0xFF;
    for &b in bytes {
        crc ^= b;
        for _ in 0..8 {
            crc = if crc & 0x80 != 0 {
                (crc << 1) ^ 0x07
            } else {
                crc << 1
            };
        }
    }
    crc
}

impl SiiDescription {
    /// The EEPROM image (bytes, little-endian words), padded with 0xFF to [`EEPROM_BYTES`].
    pub fn build(&self) -> Result<Vec<u8>, SiiError> {
        let mut img = vec![0u8; 0x80];
        // Words 0..6: PDI control and configuration, sync impulse, alias.
        let _ = le::put_u16(&mut img, 0x04 * 2, self.alias);
        img[0x07 * 2] = checksum(&img[..14]);
        let id = &self.identity;
        for (word, value) in [
            (0x08, id.vendor_id),
            (0x0A, id.product_code),
            (0x0C, id.revision),
            (0x0E, id.serial),
        ] {
            let _ = le::put_u32(&mut img, word * 2, value);
        }
        for (word, value) in [
            (0x18, self.receive_mailbox.start),
            (0x19, self.receive_mailbox.len),
            (0x1A, self.send_mailbox.start),
            (0x1B, self.send_mailbox.len),
            (0x1C, PROTOCOL_COE),
            (0x3E, (EEPROM_BYTES / 128 - 1) as u16),
            (0x3F, 1),
        ] {
            let _ = le::put_u16(&mut img, word * 2, value);
        }

        // Strings: 1 the name (order code), 2 the description.
        let strings = [self.name.as_bytes(), self.description.as_bytes()];
        if strings.len() > 255 {
            return Err(SiiError::TooManyStrings {
                count: strings.len(),
            });
        }
        let mut cat = vec![strings.len() as u8];
        for (index, s) in strings.iter().enumerate() {
            let len = u8::try_from(s.len()).map_err(|_| SiiError::StringTooLong {
                index: index + 1,
                len: s.len(),
            })?;
            cat.push(len);
            cat.extend_from_slice(s);
        }
        push_category(&mut img, CAT_STRINGS, &cat);

        // General: group, image, order (1), name (2), reserved, CoE details, FoE, EoE,
        // SoE channels, DS402 channels, SysmanClass, flags, ebus current, ports.
        let mut general = [0u8; 32];
        general[2] = 1;
        general[3] = 2;
        general[5] = COE_DETAILS;
        push_category(&mut img, CAT_GENERAL, &general);

        // FMMUs: 0 outputs, 1 inputs, 2 SM status.
        push_category(&mut img, CAT_FMMU, &[0x01, 0x02, 0x03, 0xFF]);

        // Sync managers: start, length, control, status, enable, type.
        let mut sms = Vec::with_capacity(32);
        for (start, len, control, usage) in [
            (
                self.receive_mailbox.start,
                self.receive_mailbox.len,
                0x26,
                1,
            ),
            (self.send_mailbox.start, self.send_mailbox.len, 0x22, 2),
            (self.outputs_start, 0, 0x64, 3),
            (self.inputs_start, 0, 0x20, 4),
        ] {
            sms.extend_from_slice(&start.to_le_bytes());
            sms.extend_from_slice(&len.to_le_bytes());
            sms.extend_from_slice(&[control, 0x00, 0x01, usage]);
        }
        push_category(&mut img, CAT_SYNC_MANAGER, &sms);
        img.extend_from_slice(&CAT_END.to_le_bytes());
        img.extend_from_slice(&0u16.to_le_bytes());

        if img.len() > EEPROM_BYTES {
            return Err(SiiError::TooLarge {
                bytes: img.len(),
                capacity: EEPROM_BYTES,
            });
        }
        img.resize(EEPROM_BYTES, 0xFF);
        Ok(img)
    }
}

/// Appends a category header (type, length in words) and its data, padded to whole words.
fn push_category(img: &mut Vec<u8>, category: u16, data: &[u8]) {
    let words = data.len().div_ceil(2);
    img.extend_from_slice(&category.to_le_bytes());
    img.extend_from_slice(&(words as u16).to_le_bytes());
    img.extend_from_slice(data);
    if data.len() % 2 == 1 {
        img.push(0);
    }
}

/// EEPROM control/status bits (0x0502).
mod bits {
    /// Write access enabled (written with the write command).
    pub const WRITE_ENABLE: u16 = 1 << 0;
    /// Read size: 8 bytes per read command.
    pub const READ_8_BYTES: u16 = 1 << 6;
    /// Two address bytes (EEPROM larger than 16 Kbit).
    pub const ADDRESS_16BIT: u16 = 1 << 7;
    pub const READ: u16 = 1 << 8;
    pub const WRITE: u16 = 1 << 9;
    pub const RELOAD: u16 = 1 << 10;
    pub const COMMAND_ERROR: u16 = 1 << 13;
}

/// The EEPROM interface of an ESC: the image and the command handling of 0x0502. Commands
/// complete at once, so the busy bit never shows.
#[derive(Debug, Clone)]
pub struct SiiInterface {
    image: Vec<u8>,
}

impl SiiInterface {
    pub fn new(image: Vec<u8>) -> Self {
        Self { image }
    }

    /// The EEPROM contents.
    pub fn image(&self) -> &[u8] {
        &self.image
    }

    /// The status register value when idle.
    fn idle_status() -> u16 {
        bits::READ_8_BYTES
            | if EEPROM_BYTES > 2048 {
                bits::ADDRESS_16BIT
            } else {
                0
            }
    }

    /// Initial register contents.
    pub fn reset(&self, memory: &mut [u8]) {
        let _ = le::put_u16(memory, usize::from(SII_CONTROL), Self::idle_status());
    }

    /// After the MainDevice wrote `[start, end)`: runs the command when the control word was
    /// written and the EtherCAT side owns the EEPROM (0x0500 bit 0 clear).
    pub fn after_write(&mut self, memory: &mut [u8], start: u16, end: u16) {
        let control = usize::from(SII_CONTROL);
        if !(start <= SII_CONTROL + 1 && end > SII_CONTROL) {
            return;
        }
        let owner_pdi = memory
            .get(usize::from(SII_CONFIG))
            .is_some_and(|b| b & 1 != 0);
        let written = le::u16_at(memory, control).unwrap_or(0);
        let mut status = Self::idle_status();
        let commands = written & (bits::READ | bits::WRITE | bits::RELOAD);
        let word = le::u32_at(memory, usize::from(SII_ADDRESS)).unwrap_or(0) as usize;
        let data = usize::from(SII_DATA);
        if owner_pdi {
            status |= bits::COMMAND_ERROR;
        } else if commands == bits::READ {
            for i in 0..8 {
                let byte = self.image.get(word * 2 + i).copied().unwrap_or(0xFF);
                if let Some(slot) = memory.get_mut(data + i) {
                    *slot = byte;
                }
            }
        } else if commands == bits::WRITE && written & bits::WRITE_ENABLE != 0 {
            let value = [
                memory.get(data).copied().unwrap_or(0xFF),
                memory.get(data + 1).copied().unwrap_or(0xFF),
            ];
            match self.image.get_mut(word * 2..word * 2 + 2) {
                Some(slot) => slot.copy_from_slice(&value),
                None => status |= bits::COMMAND_ERROR,
            }
        } else if commands != bits::RELOAD && commands != 0 {
            status |= bits::COMMAND_ERROR;
        }
        let _ = le::put_u16(memory, control, status);
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn description() -> SiiDescription {
        SiiDescription {
            identity: Identity {
                vendor_id: 0x0000_0A1D,
                product_code: 0x0402_0001,
                revision: 3,
                serial: 77,
            },
            name: "FLEXID-AX".into(),
            description: "flexid emulated servo axis".into(),
            alias: 0,
            receive_mailbox: MailboxArea {
                start: 0x1000,
                len: 128,
            },
            send_mailbox: MailboxArea {
                start: 0x1080,
                len: 128,
            },
            outputs_start: 0x1100,
            inputs_start: 0x1400,
        }
    }

    #[test]
    fn image_holds_identity_mailboxes_and_categories() {
        let img = description().build().expect("fits");
        assert_eq!(img.len(), EEPROM_BYTES);
        assert_eq!(le::u32_at(&img, 0x10), Some(0x0A1D));
        assert_eq!(le::u32_at(&img, 0x14), Some(0x0402_0001));
        assert_eq!(le::u16_at(&img, 0x30), Some(0x1000));
        assert_eq!(le::u16_at(&img, 0x38), Some(PROTOCOL_COE));
        assert_eq!(img[14], checksum(&img[..14]));
        // The first category is the strings, then the general category.
        assert_eq!(le::u16_at(&img, 0x80), Some(CAT_STRINGS));
        let words = usize::from(le::u16_at(&img, 0x82).unwrap_or(0));
        assert_eq!(img[0x84], 2);
        assert_eq!(&img[0x86..0x86 + 9], b"FLEXID-AX");
        assert_eq!(le::u16_at(&img, 0x84 + 2 * words), Some(CAT_GENERAL));
    }

    #[test]
    fn checksum_is_the_ethercat_crc8() {
        // Poly 0x07, init 0xFF, unreflected, no final xor (ethercrab's SII algorithm; its
        // `check` field says 0x80 but the crc crate does not use it): CRC("123456789") = 0xFB.
        // The integration test checks the checksum ethercrab itself writes.
        assert_eq!(checksum(b"123456789"), 0xFB);
        assert_eq!(checksum(&[]), 0xFF);
    }

    #[test]
    fn read_command_fills_the_data_register_and_pdi_ownership_refuses() {
        let mut sii = SiiInterface::new(description().build().expect("fits"));
        let mut mem = vec![0u8; 0x1000];
        sii.reset(&mut mem);
        let _ = le::put_u32(&mut mem, 0x0504, 0x08);
        let _ = le::put_u16(&mut mem, 0x0502, bits::READ);
        sii.after_write(&mut mem, 0x0502, 0x0508);
        assert_eq!(le::u32_at(&mem, 0x0508), Some(0x0A1D));
        assert_eq!(le::u32_at(&mem, 0x050C), Some(0x0402_0001));
        assert_eq!(le::u16_at(&mem, 0x0502), Some(bits::READ_8_BYTES));
        mem[0x0500] = 1;
        let _ = le::put_u16(&mut mem, 0x0502, bits::READ);
        sii.after_write(&mut mem, 0x0502, 0x0504);
        assert_ne!(
            le::u16_at(&mem, 0x0502).unwrap_or(0) & bits::COMMAND_ERROR,
            0
        );
    }
}
