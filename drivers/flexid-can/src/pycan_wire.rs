//! python-can's `udp_multicast` message encoding (python-can 4.6.1,
//! `can/interfaces/udp_multicast/utils.py`): one msgpack map per datagram,
//!
//! ```text
//! {"timestamp": float, "arbitration_id": int, "is_extended_id": bool,
//!  "is_remote_frame": bool, "is_error_frame": bool, "channel": any, "dlc": int,
//!  "data": bin, "is_fd": bool, "bitrate_switch": bool, "error_state_indicator": bool}
//! ```
//!
//! packed with `use_bin_type=True` (so `data` is a msgpack `bin`). Hand-written, both
//! ways without allocation: [`encode`] writes into a caller's buffer, [`decode`] reads a
//! borrowed datagram. The decoder is strict about the fields it uses and lenient about
//! the rest: unknown keys and any `channel` value are skipped; whatever else is wrong
//! gives a [`DecodeError`], never a panic.
//!
//! python-can's receiver checks (`Message(check=True)`) that `dlc == len(data)` for data
//! frames and that remote frames carry no data; [`encode`] always satisfies that, and
//! [`decode`] demands the same of what it receives.

use crate::frame::{CanFrame, CanId, MAX_DATA_LEN};

/// Largest datagram [`encode`] produces, in bytes (an extended frame with 8 data bytes is 164).
pub const MAX_ENCODED_LEN: usize = 256;

/// Why a datagram is not a python-can message.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DecodeError {
    /// The datagram ended inside a value.
    #[error("truncated at byte {at}")]
    Truncated {
        /// Offset where more bytes were needed.
        at: usize,
    },
    /// The top-level value is not a map.
    #[error("not a msgpack map (first byte {first:#04x})")]
    NotAMap {
        /// The first byte.
        first: u8,
    },
    /// A byte that is not a valid msgpack marker (0xc1) or a key that is not a string.
    #[error("unexpected byte {byte:#04x} at {at}")]
    Unexpected {
        /// The byte.
        byte: u8,
        /// Its offset.
        at: usize,
    },
    /// A known field with a value of the wrong type or range.
    #[error("field {field} has a wrong type or value")]
    BadField {
        /// The field's key.
        field: &'static str,
    },
    /// `arbitration_id` is missing.
    #[error("no arbitration_id")]
    NoId,
    /// The fields do not make a valid classic CAN frame.
    #[error("invalid frame: {0}")]
    Frame(#[from] crate::frame::FrameError),
    /// `dlc` and the length of `data` disagree on a data frame, or a remote frame carries data.
    #[error("dlc {dlc} does not match {len} data bytes")]
    DlcMismatch {
        /// The `dlc` field.
        dlc: u64,
        /// Length of `data`.
        len: usize,
    },
    /// Nesting deeper than the decoder follows (in skipped values).
    #[error("nesting too deep")]
    TooDeep,
    /// Bytes after the map.
    #[error("{extra} bytes after the message")]
    Trailing {
        /// How many.
        extra: usize,
    },
}

/// What a valid datagram holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Decoded {
    /// A classic CAN frame, with the sender's timestamp (seconds, as python-can writes
    /// `Message.timestamp`, usually UNIX time; 0 when absent).
    Frame {
        /// The frame.
        frame: CanFrame,
        /// The sender's timestamp, in seconds.
        timestamp: f64,
    },
    /// A valid CAN FD message: not carried by this (classic CAN) bus.
    CanFd,
}

/// Encodes `frame` as python-can does; returns the datagram (a prefix of `buf`).
/// `timestamp` is in seconds (python-can writes UNIX time); the receiving python-can
/// replaces it by its own receive time. `channel` is sent as nil (python-can's default).
pub fn encode<'b>(
    frame: &CanFrame,
    timestamp: f64,
    buf: &'b mut [u8; MAX_ENCODED_LEN],
) -> &'b [u8] {
    let mut w = Writer { buf, at: 0 };
    w.byte(0x80 | 11); // fixmap, 11 entries
    w.key("timestamp");
    w.byte(0xcb);
    w.bytes(&timestamp.to_be_bytes());
    w.key("arbitration_id");
    w.uint(frame.id().raw() as u64);
    w.key("is_extended_id");
    w.bool(frame.id().is_extended());
    w.key("is_remote_frame");
    w.bool(frame.is_remote());
    w.key("is_error_frame");
    w.bool(frame.is_error());
    w.key("channel");
    w.byte(0xc0);
    w.key("dlc");
    w.uint(frame.dlc() as u64);
    w.key("data");
    w.byte(0xc4); // bin 8
    w.byte(frame.data().len() as u8);
    w.bytes(frame.data());
    w.key("is_fd");
    w.bool(false);
    w.key("bitrate_switch");
    w.bool(false);
    w.key("error_state_indicator");
    w.bool(false);
    let n = w.at;
    &buf[..n]
}

struct Writer<'a> {
    buf: &'a mut [u8; MAX_ENCODED_LEN],
    at: usize,
}

impl Writer<'_> {
    fn byte(&mut self, b: u8) {
        self.buf[self.at] = b;
        self.at += 1;
    }
    fn bytes(&mut self, b: &[u8]) {
        self.buf[self.at..self.at + b.len()].copy_from_slice(b);
        self.at += b.len();
    }
    /// Keys are all shorter than 32 bytes: fixstr.
    fn key(&mut self, k: &str) {
        self.byte(0xa0 | k.len() as u8);
        self.bytes(k.as_bytes());
    }
    fn bool(&mut self, v: bool) {
        self.byte(if v { 0xc3 } else { 0xc2 });
    }
    /// Smallest encoding, as msgpack-python writes it.
    fn uint(&mut self, v: u64) {
        if v < 0x80 {
            self.byte(v as u8);
        } else if v <= u8::MAX as u64 {
            self.byte(0xcc);
            self.byte(v as u8);
        } else if v <= u16::MAX as u64 {
            self.byte(0xcd);
            self.bytes(&(v as u16).to_be_bytes());
        } else if v <= u32::MAX as u64 {
            self.byte(0xce);
            self.bytes(&(v as u32).to_be_bytes());
        } else {
            self.byte(0xcf);
            self.bytes(&v.to_be_bytes());
        }
    }
}

/// Deepest nesting followed when skipping unknown values.
const MAX_DEPTH: u32 = 16;

/// Decodes one datagram. Unknown keys are ignored; missing fields take python-can's
/// `Message` defaults (`is_extended_id` true, flags false, `dlc` = `len(data)`), except
/// `arbitration_id`, which is required.
pub fn decode(buf: &[u8]) -> Result<Decoded, DecodeError> {
    let mut r = Reader { buf, at: 0 };
    let first = r.peek()?;
    let entries = match first {
        0x80..=0x8f => {
            r.at += 1;
            (first & 0x0f) as u32
        }
        0xde => {
            r.at += 1;
            u16::from_be_bytes(r.array()?) as u32
        }
        0xdf => {
            r.at += 1;
            u32::from_be_bytes(r.array()?)
        }
        _ => return Err(DecodeError::NotAMap { first }),
    };

    let mut timestamp = 0.0;
    let mut id: Option<u64> = None;
    let mut extended = true;
    let mut remote = false;
    let mut error = false;
    let mut fd = false;
    let mut dlc: Option<u64> = None;
    let mut data: &[u8] = &[];
    for _ in 0..entries {
        let key = r.str()?;
        match key {
            b"timestamp" => timestamp = r.float("timestamp")?,
            b"arbitration_id" => id = Some(r.uint("arbitration_id")?),
            b"is_extended_id" => extended = r.bool("is_extended_id")?,
            b"is_remote_frame" => remote = r.bool("is_remote_frame")?,
            b"is_error_frame" => error = r.bool("is_error_frame")?,
            b"is_fd" => fd = r.bool("is_fd")?,
            b"dlc" => dlc = r.opt_uint("dlc")?,
            b"data" => data = r.bin("data")?,
            _ => r.skip(0)?,
        }
    }
    if r.at != buf.len() {
        return Err(DecodeError::Trailing {
            extra: buf.len() - r.at,
        });
    }
    if fd {
        return Ok(Decoded::CanFd);
    }
    let id = id.ok_or(DecodeError::NoId)?;
    let id = u32::try_from(id).map_err(|_| DecodeError::BadField {
        field: "arbitration_id",
    })?;
    let dlc = dlc.unwrap_or(data.len() as u64);
    let frame = if error {
        let mut d = [0u8; MAX_DATA_LEN];
        if data.len() > MAX_DATA_LEN {
            return Err(crate::frame::FrameError::TooLong { len: data.len() }.into());
        }
        d[..data.len()].copy_from_slice(data);
        CanFrame::error(id, d)?
    } else if remote {
        if !data.is_empty() || dlc > MAX_DATA_LEN as u64 {
            return Err(DecodeError::DlcMismatch {
                dlc,
                len: data.len(),
            });
        }
        CanFrame::remote(CanId::new(id, extended)?, dlc as u8)?
    } else {
        if dlc != data.len() as u64 {
            return Err(DecodeError::DlcMismatch {
                dlc,
                len: data.len(),
            });
        }
        CanFrame::new(CanId::new(id, extended)?, data)?
    };
    Ok(Decoded::Frame { frame, timestamp })
}

struct Reader<'a> {
    buf: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn peek(&self) -> Result<u8, DecodeError> {
        self.buf
            .get(self.at)
            .copied()
            .ok_or(DecodeError::Truncated { at: self.at })
    }
    fn next(&mut self) -> Result<u8, DecodeError> {
        let b = self.peek()?;
        self.at += 1;
        Ok(b)
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], DecodeError> {
        let end = self
            .at
            .checked_add(n)
            .filter(|&e| e <= self.buf.len())
            .ok_or(DecodeError::Truncated { at: self.buf.len() })?;
        let s = &self.buf[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], DecodeError> {
        let mut a = [0; N];
        a.copy_from_slice(self.take(N)?);
        Ok(a)
    }
    fn len_prefixed(&mut self, width: usize) -> Result<&'a [u8], DecodeError> {
        let n = match width {
            1 => self.next()? as usize,
            2 => u16::from_be_bytes(self.array()?) as usize,
            _ => u32::from_be_bytes(self.array()?) as usize,
        };
        self.take(n)
    }
    fn str(&mut self) -> Result<&'a [u8], DecodeError> {
        let at = self.at;
        match self.next()? {
            b @ 0xa0..=0xbf => self.take((b & 0x1f) as usize),
            0xd9 => self.len_prefixed(1),
            0xda => self.len_prefixed(2),
            0xdb => self.len_prefixed(4),
            byte => Err(DecodeError::Unexpected { byte, at }),
        }
    }
    fn bool(&mut self, field: &'static str) -> Result<bool, DecodeError> {
        match self.next()? {
            0xc2 => Ok(false),
            0xc3 => Ok(true),
            _ => Err(DecodeError::BadField { field }),
        }
    }
    fn opt_uint(&mut self, field: &'static str) -> Result<Option<u64>, DecodeError> {
        if self.peek()? == 0xc0 {
            self.at += 1;
            return Ok(None);
        }
        self.uint(field).map(Some)
    }
    /// A non-negative integer in any msgpack integer encoding.
    fn uint(&mut self, field: &'static str) -> Result<u64, DecodeError> {
        let bad = DecodeError::BadField { field };
        let v: i128 = match self.next()? {
            b @ 0x00..=0x7f => b as i128,
            b @ 0xe0..=0xff => (b as i8) as i128,
            0xcc => self.next()? as i128,
            0xcd => u16::from_be_bytes(self.array()?) as i128,
            0xce => u32::from_be_bytes(self.array()?) as i128,
            0xcf => u64::from_be_bytes(self.array()?) as i128,
            0xd0 => (self.next()? as i8) as i128,
            0xd1 => i16::from_be_bytes(self.array()?) as i128,
            0xd2 => i32::from_be_bytes(self.array()?) as i128,
            0xd3 => i64::from_be_bytes(self.array()?) as i128,
            _ => return Err(bad),
        };
        u64::try_from(v).map_err(|_| bad)
    }
    /// A number (python may send an int timestamp too).
    fn float(&mut self, field: &'static str) -> Result<f64, DecodeError> {
        match self.peek()? {
            0xcb => {
                self.at += 1;
                Ok(f64::from_be_bytes(self.array()?))
            }
            0xca => {
                self.at += 1;
                Ok(f32::from_be_bytes(self.array()?) as f64)
            }
            0xc0 => {
                self.at += 1;
                Ok(0.0)
            }
            _ => self.uint(field).map(|v| v as f64),
        }
    }
    /// `bin` (python `bytes`/`bytearray` with `use_bin_type=True`); nil reads as empty.
    fn bin(&mut self, field: &'static str) -> Result<&'a [u8], DecodeError> {
        match self.next()? {
            0xc4 => self.len_prefixed(1),
            0xc5 => self.len_prefixed(2),
            0xc6 => self.len_prefixed(4),
            0xc0 => Ok(&[]),
            _ => Err(DecodeError::BadField { field }),
        }
    }
    /// Skips one value of any type.
    fn skip(&mut self, depth: u32) -> Result<(), DecodeError> {
        if depth > MAX_DEPTH {
            return Err(DecodeError::TooDeep);
        }
        let at = self.at;
        let b = self.next()?;
        let (skip, items) = match b {
            0x00..=0x7f | 0xe0..=0xff | 0xc0 | 0xc2 | 0xc3 => (0, 0),
            0x80..=0x8f => (0, 2 * (b & 0x0f) as u64),
            0x90..=0x9f => (0, (b & 0x0f) as u64),
            0xa0..=0xbf => ((b & 0x1f) as usize, 0),
            0xc1 => return Err(DecodeError::Unexpected { byte: b, at }),
            0xc4 | 0xd9 => (self.next()? as usize, 0),
            0xc5 | 0xda => (u16::from_be_bytes(self.array()?) as usize, 0),
            0xc6 | 0xdb => (u32::from_be_bytes(self.array()?) as usize, 0),
            0xc7 => (self.next()? as usize + 1, 0),
            0xc8 => (u16::from_be_bytes(self.array()?) as usize + 1, 0),
            0xc9 => (u32::from_be_bytes(self.array()?) as usize + 1, 0),
            0xca => (4, 0),
            0xcb => (8, 0),
            0xcc | 0xd0 => (1, 0),
            0xcd | 0xd1 => (2, 0),
            0xce | 0xd2 => (4, 0),
            0xcf | 0xd3 => (8, 0),
            0xd4 => (2, 0),
            0xd5 => (3, 0),
            0xd6 => (5, 0),
            0xd7 => (9, 0),
            0xd8 => (17, 0),
            0xdc => (0, u16::from_be_bytes(self.array()?) as u64),
            0xdd => (0, u32::from_be_bytes(self.array()?) as u64),
            0xde => (0, 2 * u16::from_be_bytes(self.array()?) as u64),
            0xdf => (0, 2 * u32::from_be_bytes(self.array()?) as u64),
        };
        self.take(skip)?;
        for _ in 0..items {
            self.skip(depth + 1)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `msgpack.packb(can.Message(timestamp=1.5, arbitration_id=0x123,
    /// is_extended_id=False, data=[1, 2, 3]) as dict, use_bin_type=True)` from
    /// python-can 4.6.1 / msgpack 1.1.1 (see `pack_message`).
    const PYTHON_STD: &[u8] = b"\x8b\xa9timestamp\xcb\x3f\xf8\x00\x00\x00\x00\x00\x00\xaearbitration_id\xcd\x01\x23\xaeis_extended_id\xc2\xafis_remote_frame\xc2\xaeis_error_frame\xc2\xa7channel\xc0\xa3dlc\x03\xa4data\xc4\x03\x01\x02\x03\xa5is_fd\xc2\xaebitrate_switch\xc2\xb5error_state_indicator\xc2";

    #[test]
    fn encode_matches_python_byte_for_byte() {
        let f = CanFrame::standard(0x123, &[1, 2, 3]).unwrap();
        let mut buf = [0; MAX_ENCODED_LEN];
        assert_eq!(encode(&f, 1.5, &mut buf), PYTHON_STD);
        assert_eq!(
            decode(PYTHON_STD).unwrap(),
            Decoded::Frame {
                frame: f,
                timestamp: 1.5
            }
        );
    }

    #[test]
    fn round_trips() {
        let frames = [
            CanFrame::extended(0x1FFF_FFFF, &[0xFF; 8]).unwrap(),
            CanFrame::standard(0, &[]).unwrap(),
            CanFrame::remote(CanId::Standard(0x701), 4).unwrap(),
            CanFrame::remote(CanId::Extended(0x12345), 0).unwrap(),
            CanFrame::error(0x204, [1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        ];
        let mut buf = [0; MAX_ENCODED_LEN];
        for f in frames {
            let d = encode(&f, 12.25, &mut buf);
            assert!(d.len() <= 164, "{}", d.len());
            assert_eq!(
                decode(d).unwrap(),
                Decoded::Frame {
                    frame: f,
                    timestamp: 12.25
                }
            );
        }
    }

    #[test]
    fn unknown_keys_are_skipped_and_fd_is_flagged() {
        // {"x": [1, {"a": nil}], "arbitration_id": 5, "is_extended_id": false, "data": bin(1)}
        let m = b"\x84\xa1x\x92\x01\x81\xa1a\xc0\xaearbitration_id\x05\xaeis_extended_id\xc2\xa4data\xc4\x01\x09";
        let Decoded::Frame { frame, .. } = decode(m).unwrap() else {
            panic!()
        };
        assert_eq!(frame, CanFrame::standard(5, &[9]).unwrap());
        let fd = b"\x82\xaearbitration_id\x05\xa5is_fd\xc3";
        assert_eq!(decode(fd).unwrap(), Decoded::CanFd);
        // python's default is_extended_id is True
        let ext = b"\x81\xaearbitration_id\xcd\x08\x00";
        let Decoded::Frame { frame, .. } = decode(ext).unwrap() else {
            panic!()
        };
        assert_eq!(frame.id(), CanId::Extended(0x800));
    }

    #[test]
    fn bad_datagrams_are_errors() {
        let cases: &[&[u8]] = &[
            b"",
            b"hello",
            b"\x81",
            b"\x81\xaearbitration_id",
            b"\x80",                                                     // no id
            b"\x82\xaearbitration_id\xcd\x08\x00\xaeis_extended_id\xc2", // id > 11 bits
            b"\x82\xaearbitration_id\x01\xa3dlc\x02",                    // dlc != len(data)
            b"\x81\xaearbitration_id\xff",                               // negative
            b"\x81\xaearbitration_id\x01\x00",                           // trailing
            b"\x81\x01\x01",                                             // int key
            b"\x81\xa1x\xc1",                                            // reserved marker
            b"\x81\xa1x\xdf\xff\xff\xff\xff",                            // huge map, truncated
        ];
        for c in cases {
            assert!(decode(c).is_err(), "{c:?} decoded");
        }
        let mut deep = vec![0x81, 0xa1, b'x'];
        deep.extend(std::iter::repeat_n(0x91, 100));
        deep.push(0xc0);
        assert_eq!(decode(&deep), Err(DecodeError::TooDeep));
    }

    #[test]
    fn garbage_never_panics() {
        // A deterministic xorshift stream: random bytes and mutated valid messages.
        let mut s = 0x9E37_79B9_7F4A_7C15u64;
        let mut rnd = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut buf = [0u8; 64];
        for _ in 0..20_000 {
            let n = (rnd() % 64) as usize;
            for b in &mut buf[..n] {
                *b = rnd() as u8;
            }
            let _ = decode(&buf[..n]);
        }
        let mut m = PYTHON_STD.to_vec();
        for _ in 0..20_000 {
            let i = (rnd() as usize) % m.len();
            let old = m[i];
            m[i] = rnd() as u8;
            let _ = decode(&m);
            let _ = decode(&m[..i]);
            m[i] = old;
        }
    }
}
