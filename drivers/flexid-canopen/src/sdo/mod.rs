//! Blocking SDO client (CiA 301 §7.2.4) over a [`CanBus`] handle of its own.
//!
//! The protocol is canopen-rs's sans-I/O [`canopen_rs::SdoClient`] (expedited and
//! segmented upload/download, toggle checking); this module adds only the I/O around it:
//! send the request on `0x600 + node`, wait for the response on `0x580 + node` until a
//! timeout, skip every other frame, and turn aborts into [`SdoError`]s whose text comes
//! from [`abort::abort_text`].
//!
//! Hand-written beside canopen-rs (which lacks them):
//! - the response multiplexer check (a stale response to an earlier, timed-out request
//!   for another object is skipped, not taken as this one's);
//! - expedited upload responses without the size bit (`0x42`), which CiA 301 allows and
//!   canopen-rs rejects: normalised to the sized form using the expected type's size;
//! - the abort frame the client must send when it gives up (timeout, toggle error).
//!
//! Give the SDO client its own handle ([`CanBus::try_clone`] of the cycle's bus) so that
//! the cycle never loses a PDO while an SDO transfer waits.
//!
//! Limit inherited from canopen-rs 0.6.1: segmented transfers carry at most
//! [`canopen_rs::MAX_STRING_LEN`] (32) bytes.

pub mod abort;

use std::time::{Duration, Instant};

use canopen_rs::sdo::{decode_abort, SdoPayload};
use canopen_rs::{Address, ByteString, DataType, NodeId, SdoClient, SdoEvent, Value};
use flexid_can::{BusError, CanBus, CanFrame};

pub use abort::abort_text;

/// Default time to wait for each SDO response.
pub const DEFAULT_TIMEOUT: Duration = Duration::from_millis(500);

/// Errors of the SDO layer; every variant names the node and the object.
#[derive(Debug, thiserror::Error)]
pub enum SdoError {
    /// The server aborted the transfer.
    #[error("node {node}: SDO abort on {index:#06x}:{subindex:02x}: {code:#010x} {text}")]
    SdoAbort {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// Raw abort code (CiA 301 Table 22).
        code: u32,
        /// The abort code's meaning.
        text: &'static str,
    },
    /// The client gave up on a response it could not accept (wrong command, toggle bit,
    /// length); it sent an abort with `code` to the server.
    #[error("node {node}: SDO protocol error on {index:#06x}:{subindex:02x}: {code:#010x} {text}")]
    Protocol {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// The abort code sent to the server.
        code: u32,
        /// The abort code's meaning.
        text: &'static str,
    },
    /// No response in time; an abort (0x05040000) was sent to the server.
    #[error("node {node}: no {waiting_for} for {index:#06x}:{subindex:02x} after {after:?}")]
    Timeout {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// What was awaited ("SDO upload response", "SDO download response", ...).
        waiting_for: &'static str,
        /// How long it waited.
        after: Duration,
    },
    /// The value read has another type than asked for.
    #[error("node {node}: {index:#06x}:{subindex:02x} holds {got:?}, expected {expected:?}")]
    Type {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// The type asked for.
        expected: DataType,
        /// The type received.
        got: DataType,
    },
    /// The value to write cannot be sent (e.g. a string over 32 bytes).
    #[error("node {node}: cannot write {index:#06x}:{subindex:02x}: {reason}")]
    Value {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// Why.
        reason: String,
    },
    /// The bus failed.
    #[error("node {node}: SDO transfer on {index:#06x}:{subindex:02x}: {source}")]
    Bus {
        /// Node-id of the server.
        node: u8,
        /// Object index.
        index: u16,
        /// Object subindex.
        subindex: u8,
        /// The bus error.
        #[source]
        source: BusError,
    },
}

impl SdoError {
    /// The abort code, for a server abort.
    pub fn abort_code(&self) -> Option<u32> {
        match self {
            Self::SdoAbort { code, .. } => Some(*code),
            _ => None,
        }
    }
}

/// Counters of an [`Sdo`] client.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SdoStats {
    /// Completed transfers.
    pub transfers: u64,
    /// Frames received that were not this server's SDO responses (skipped).
    pub skipped: u64,
    /// Responses on this server's COB-ID that were malformed (not 8 bytes) or stale
    /// (another object's multiplexer), skipped.
    pub malformed: u64,
}

/// A blocking SDO client for one node on its own bus handle.
#[derive(Debug)]
pub struct Sdo<B: CanBus> {
    bus: B,
    node: NodeId,
    timeout: Duration,
    clock: fn() -> Instant,
    stats: SdoStats,
}

impl<B: CanBus> Sdo<B> {
    /// A client for `node` (1..=127) on `bus` (give it its own handle), waiting up to
    /// `timeout` for each response, with `clock` as its time source.
    pub fn new(
        bus: B,
        node: u8,
        timeout: Duration,
        clock: fn() -> Instant,
    ) -> Result<Self, SdoError> {
        let node_id = NodeId::new(node).map_err(|_| SdoError::Value {
            node,
            index: 0,
            subindex: 0,
            reason: "node-id must be 1..=127".into(),
        })?;
        Ok(Self {
            bus,
            node: node_id,
            timeout,
            clock,
            stats: SdoStats::default(),
        })
    }

    /// The node-id of the server.
    pub fn node(&self) -> u8 {
        self.node.raw()
    }

    /// Counters.
    pub fn stats(&self) -> SdoStats {
        self.stats
    }

    /// The time waited for each response.
    pub fn timeout(&self) -> Duration {
        self.timeout
    }

    /// Sets the time waited for each response.
    pub fn set_timeout(&mut self, timeout: Duration) {
        self.timeout = timeout;
    }

    /// Reads (uploads) `index:subindex` as `data_type`.
    pub fn read(
        &mut self,
        index: u16,
        subindex: u8,
        data_type: DataType,
    ) -> Result<Value, SdoError> {
        let mut client = SdoClient::new(self.node);
        let first = client.read(Address::new(index, subindex), data_type);
        let v = self.run(&mut client, first, index, subindex, Some(data_type))?;
        let v = v.ok_or(SdoError::Protocol {
            node: self.node.raw(),
            index,
            subindex,
            code: abort::GENERAL_ERROR,
            text: abort_text(abort::GENERAL_ERROR),
        })?;
        if v.data_type() != data_type {
            return Err(SdoError::Type {
                node: self.node.raw(),
                index,
                subindex,
                expected: data_type,
                got: v.data_type(),
            });
        }
        Ok(v)
    }

    /// Writes (downloads) `value` to `index:subindex`; expedited up to 4 bytes,
    /// segmented above.
    pub fn write(&mut self, index: u16, subindex: u8, value: Value) -> Result<(), SdoError> {
        let mut client = SdoClient::new(self.node);
        let first = client.write(Address::new(index, subindex), value);
        self.run(&mut client, first, index, subindex, None)
            .map(|_| ())
    }

    /// Reads an UNSIGNED8.
    pub fn read_u8(&mut self, index: u16, subindex: u8) -> Result<u8, SdoError> {
        match self.read(index, subindex, DataType::Unsigned8)? {
            Value::Unsigned8(v) => Ok(v),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Reads an UNSIGNED16.
    pub fn read_u16(&mut self, index: u16, subindex: u8) -> Result<u16, SdoError> {
        match self.read(index, subindex, DataType::Unsigned16)? {
            Value::Unsigned16(v) => Ok(v),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Reads an UNSIGNED32.
    pub fn read_u32(&mut self, index: u16, subindex: u8) -> Result<u32, SdoError> {
        match self.read(index, subindex, DataType::Unsigned32)? {
            Value::Unsigned32(v) => Ok(v),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Reads an INTEGER8.
    pub fn read_i8(&mut self, index: u16, subindex: u8) -> Result<i8, SdoError> {
        match self.read(index, subindex, DataType::Integer8)? {
            Value::Integer8(v) => Ok(v),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Reads an INTEGER32.
    pub fn read_i32(&mut self, index: u16, subindex: u8) -> Result<i32, SdoError> {
        match self.read(index, subindex, DataType::Integer32)? {
            Value::Integer32(v) => Ok(v),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Reads a VISIBLE_STRING (at most 32 bytes; invalid UTF-8 replaced).
    pub fn read_string(&mut self, index: u16, subindex: u8) -> Result<String, SdoError> {
        match self.read(index, subindex, DataType::VisibleString)? {
            Value::VisibleString(s) => Ok(String::from_utf8_lossy(s.as_bytes()).into_owned()),
            _ => unreachable!("type checked in read"),
        }
    }

    /// Writes an UNSIGNED8.
    pub fn write_u8(&mut self, index: u16, subindex: u8, v: u8) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Unsigned8(v))
    }

    /// Writes an UNSIGNED16.
    pub fn write_u16(&mut self, index: u16, subindex: u8, v: u16) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Unsigned16(v))
    }

    /// Writes an UNSIGNED32.
    pub fn write_u32(&mut self, index: u16, subindex: u8, v: u32) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Unsigned32(v))
    }

    /// Writes an INTEGER8.
    pub fn write_i8(&mut self, index: u16, subindex: u8, v: i8) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Integer8(v))
    }

    /// Writes an INTEGER16.
    pub fn write_i16(&mut self, index: u16, subindex: u8, v: i16) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Integer16(v))
    }

    /// Writes an INTEGER32.
    pub fn write_i32(&mut self, index: u16, subindex: u8, v: i32) -> Result<(), SdoError> {
        self.write(index, subindex, Value::Integer32(v))
    }

    /// Writes a VISIBLE_STRING (at most 32 bytes; segmented above 4).
    pub fn write_string(&mut self, index: u16, subindex: u8, s: &str) -> Result<(), SdoError> {
        let bs = ByteString::from_str(s).map_err(|_| SdoError::Value {
            node: self.node.raw(),
            index,
            subindex,
            reason: format!(
                "string of {} bytes, at most {}",
                s.len(),
                canopen_rs::MAX_STRING_LEN
            ),
        })?;
        self.write(index, subindex, Value::VisibleString(bs))
    }

    fn run(
        &mut self,
        client: &mut SdoClient,
        first: SdoPayload,
        index: u16,
        subindex: u8,
        upload: Option<DataType>,
    ) -> Result<Option<Value>, SdoError> {
        let node = self.node.raw();
        // Whatever is queued predates this transfer (PDOs seen by this handle, stale
        // responses to transfers that timed out): drop it.
        for _ in 0..100_000 {
            match self.bus.recv_timeout(Duration::ZERO) {
                Ok(Some(_)) => self.stats.skipped += 1,
                Err(e) if e.is_report() => {}
                Ok(None) | Err(_) => break,
            }
        }
        let mut request = first;
        let mut initiate = true;
        loop {
            self.send(&request, index, subindex)?;
            let waiting_for = match (upload.is_some(), initiate) {
                (true, true) => "SDO upload response",
                (true, false) => "SDO upload segment",
                (false, true) => "SDO download response",
                (false, false) => "SDO download segment response",
            };
            let mut resp = self.wait_response(index, subindex, initiate, waiting_for)?;
            if initiate {
                if let Some(dt) = upload {
                    normalise_unsized_expedited(&mut resp, dt);
                }
            }
            match client.on_response(&resp) {
                SdoEvent::Send(next) => {
                    request = next;
                    initiate = false;
                }
                SdoEvent::Complete(v) => {
                    self.stats.transfers += 1;
                    return Ok(v);
                }
                SdoEvent::Aborted(code) => {
                    if decode_abort(&resp).is_ok() {
                        return Err(SdoError::SdoAbort {
                            node,
                            index,
                            subindex,
                            code,
                            text: abort_text(code),
                        });
                    }
                    // Detected by the client: tell the server (CiA 301: abort transfer).
                    let _ = self.send(&abort::encode(index, subindex, code), index, subindex);
                    return Err(SdoError::Protocol {
                        node,
                        index,
                        subindex,
                        code,
                        text: abort_text(code),
                    });
                }
            }
        }
    }

    fn send(&mut self, payload: &SdoPayload, index: u16, subindex: u8) -> Result<(), SdoError> {
        let frame = CanFrame::standard(crate::cob::sdo_rx(self.node.raw()), payload)
            .expect("8 bytes on an 11-bit id");
        self.bus.send(&frame).map_err(|source| SdoError::Bus {
            node: self.node.raw(),
            index,
            subindex,
            source,
        })
    }

    fn wait_response(
        &mut self,
        index: u16,
        subindex: u8,
        initiate: bool,
        waiting_for: &'static str,
    ) -> Result<SdoPayload, SdoError> {
        let node = self.node.raw();
        let start = (self.clock)();
        let deadline = start + self.timeout;
        let want = crate::cob::sdo_tx(node);
        loop {
            let left = deadline.saturating_duration_since((self.clock)());
            if left.is_zero() {
                let code = abort::PROTOCOL_TIMED_OUT;
                let _ = self.send(&abort::encode(index, subindex, code), index, subindex);
                return Err(SdoError::Timeout {
                    node,
                    index,
                    subindex,
                    waiting_for,
                    after: self.timeout,
                });
            }
            let received = match self.bus.recv_timeout(left) {
                Ok(Some(r)) => r,
                Ok(None) => continue,
                // Overruns and error frames on this handle: reports, keep waiting.
                Err(e) if e.is_report() => continue,
                Err(source) => {
                    return Err(SdoError::Bus {
                        node,
                        index,
                        subindex,
                        source,
                    })
                }
            };
            let f = received.frame;
            if f.is_remote() || f.id().is_extended() || f.id().raw() != want as u32 {
                self.stats.skipped += 1;
                continue;
            }
            let Ok(p) = <[u8; 8]>::try_from(f.data()) else {
                self.stats.malformed += 1;
                continue;
            };
            // Initiate responses and aborts carry the multiplexer: skip stale ones.
            let carries_mux = initiate || p[0] == 0x80;
            if carries_mux && (u16::from_le_bytes([p[1], p[2]]) != index || p[3] != subindex) {
                self.stats.malformed += 1;
                continue;
            }
            return Ok(p);
        }
    }
}

/// CiA 301 lets a server answer an expedited upload without the size bit (`0x42`):
/// canopen-rs 0.6.1 rejects that form, so it is rewritten to the sized form when the
/// expected type has a fixed size of 1..=4 bytes.
fn normalise_unsized_expedited(p: &mut SdoPayload, dt: DataType) {
    if p[0] == 0x42 {
        if let Some(n @ 1..=4) = dt.fixed_size() {
            p[0] = 0x43 | (((4 - n) as u8) << 2);
        }
    }
}
