//! Process data: the default PDO mapping, the SDO sequence that writes it, the
//! allocation-free pack/unpack of the cyclic frames, and the bus-load admission check.
//!
//! From canopen-rs: [`MappingEntry`] (the `0xIIIISSLL` mapping value) and
//! [`TransmissionType`]. Hand-written: a `Copy` PDO description (canopen-rs's
//! `PdoMapping` is not `Clone` and its `pack`/`unpack` go through an object dictionary,
//! which a master does not have), the configuration sequence and the fixed-layout codecs.
//!
//! # Default mapping (transmission type 1: every SYNC)
//!
//! | PDO | COB-ID | bytes | content |
//! |---|---|---|---|
//! | RPDO1 | 0x200 + id | 4 | controlword 0x6040 u16, target torque 0x6071 i16 (‰ rated) |
//! | TPDO1 | 0x180 + id | 8 | statusword 0x6041 u16, position actual 0x6064 i32 (inc), torque actual 0x6077 i16 (‰) |
//! | TPDO2 | 0x280 + id | 4 | velocity actual 0x606C i32 (velocity unit) |
//!
//! RPDO2-4 and TPDO3-4 are disabled (COB-ID bit 31) unless the profile has the
//! `keep-unused-pdos` quirk. All little-endian, in mapping order.

use std::time::Duration;

use canopen_rs::{MappingEntry, PdoKind, TransmissionType, Value};
use flexid_can::timing::{frame_bits, FrameShape};

use crate::cob;
use crate::objects::comm;
use crate::profile::ObjectMap;

/// Bit 31 of a PDO COB-ID: PDO not valid (disabled).
pub const COB_ID_INVALID: u32 = 0x8000_0000;

/// One PDO: its direction, number, mapped entries and transmission type. `Copy`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Pdo {
    /// Receive (master to drive) or transmit (drive to master).
    pub kind: PdoKind,
    /// PDO number, 1..=4 (others are taken as the nearest).
    pub number: u8,
    entries: [MappingEntry; 8],
    len: u8,
    /// Transmission type (1: synchronous, every SYNC).
    pub transmission: TransmissionType,
}

impl Pdo {
    /// A PDO of up to 8 entries (more are dropped; check with [`Pdo::len`]).
    pub fn new(
        kind: PdoKind,
        number: u8,
        entries: &[MappingEntry],
        transmission: TransmissionType,
    ) -> Self {
        let mut e = [MappingEntry::new(0, 0, 0); 8];
        let n = entries.len().min(8);
        e[..n].copy_from_slice(&entries[..n]);
        Self {
            kind,
            number,
            entries: e,
            len: n as u8,
            transmission,
        }
    }

    /// The mapped entries, in frame order.
    pub fn entries(&self) -> &[MappingEntry] {
        &self.entries[..self.len as usize]
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.len as usize
    }

    /// Whether no entry is mapped.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Frame length, bytes (bit lengths summed, rounded up).
    pub fn data_len(&self) -> u8 {
        let bits: u32 = self.entries().iter().map(|e| e.bit_length as u32).sum();
        bits.div_ceil(8).min(8) as u8
    }

    /// The COB-ID of this PDO for `node` (predefined connection set).
    pub fn cob_id(&self, node: u8) -> u16 {
        match self.kind {
            PdoKind::Receive => cob::rpdo(self.number, node),
            PdoKind::Transmit => cob::tpdo(self.number, node),
        }
    }

    /// The communication parameter index (0x1400/0x1800 + number - 1).
    pub fn comm_index(&self) -> u16 {
        comm_base(self.kind) + (self.number.clamp(1, 4) as u16 - 1)
    }

    /// The mapping parameter index (0x1600/0x1A00 + number - 1).
    pub fn mapping_index(&self) -> u16 {
        mapping_base(self.kind) + (self.number.clamp(1, 4) as u16 - 1)
    }
}

fn comm_base(kind: PdoKind) -> u16 {
    match kind {
        PdoKind::Receive => comm::RPDO_COMM,
        PdoKind::Transmit => comm::TPDO_COMM,
    }
}

fn mapping_base(kind: PdoKind) -> u16 {
    match kind {
        PdoKind::Receive => comm::RPDO_MAPPING,
        PdoKind::Transmit => comm::TPDO_MAPPING,
    }
}

/// The process data of one drive: the PDOs in use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ProcessDataMapping {
    /// PDOs in use (the master sends the RPDOs and expects the TPDOs every SYNC).
    pub pdos: Vec<Pdo>,
}

/// The default mapping (see the module docs), with the indices of `objects`.
pub fn default_mapping(objects: &ObjectMap) -> ProcessDataMapping {
    let sync = TransmissionType::SynchronousCyclic(1);
    ProcessDataMapping {
        pdos: vec![
            Pdo::new(
                PdoKind::Receive,
                1,
                &[
                    MappingEntry::new(objects.controlword, 0, 16),
                    MappingEntry::new(objects.target_torque, 0, 16),
                ],
                sync,
            ),
            Pdo::new(
                PdoKind::Transmit,
                1,
                &[
                    MappingEntry::new(objects.statusword, 0, 16),
                    MappingEntry::new(objects.position_actual, 0, 32),
                    MappingEntry::new(objects.torque_actual, 0, 16),
                ],
                sync,
            ),
            Pdo::new(
                PdoKind::Transmit,
                2,
                &[MappingEntry::new(objects.velocity_actual, 0, 32)],
                sync,
            ),
        ],
    }
}

/// One SDO write of a configuration sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SdoWrite {
    /// Object index.
    pub index: u16,
    /// Subindex.
    pub subindex: u8,
    /// Value (its type gives the width).
    pub value: Value,
    /// An abort "object/sub-index does not exist" is not an error (disabling a PDO the
    /// drive does not have).
    pub missing_ok: bool,
}

impl SdoWrite {
    const fn new(index: u16, subindex: u8, value: Value) -> Self {
        Self {
            index,
            subindex,
            value,
            missing_ok: false,
        }
    }
}

impl ProcessDataMapping {
    /// The PDOs of one direction.
    pub fn of(&self, kind: PdoKind) -> impl Iterator<Item = &Pdo> {
        self.pdos.iter().filter(move |p| p.kind == kind)
    }

    /// The largest number of entries in one PDO.
    pub fn max_entries(&self) -> usize {
        self.pdos.iter().map(Pdo::len).max().unwrap_or(0)
    }

    /// The SDO writes that configure this mapping on `node` (CiA 301 §7.5.2.35-38):
    /// for each PDO, COB-ID with bit 31 (disable), mapping count 0, the entries
    /// (`0xIIIISSLL`), the count, the transmission type, the COB-ID without bit 31
    /// (enable). With `disable_unused`, the other RPDOs/TPDOs 1..=4 are then disabled
    /// (COB-ID with bit 31; a drive without them may abort, which is tolerated).
    pub fn sdo_writes(&self, node: u8, disable_unused: bool) -> Vec<SdoWrite> {
        let mut w = Vec::new();
        for p in &self.pdos {
            let cob = p.cob_id(node) as u32;
            w.push(SdoWrite::new(
                p.comm_index(),
                1,
                Value::Unsigned32(COB_ID_INVALID | cob),
            ));
            w.push(SdoWrite::new(p.mapping_index(), 0, Value::Unsigned8(0)));
            for (i, e) in p.entries().iter().enumerate() {
                w.push(SdoWrite::new(
                    p.mapping_index(),
                    i as u8 + 1,
                    Value::Unsigned32(e.to_u32()),
                ));
            }
            w.push(SdoWrite::new(p.mapping_index(), 0, Value::Unsigned8(p.len)));
            w.push(SdoWrite::new(
                p.comm_index(),
                2,
                Value::Unsigned8(p.transmission.to_byte()),
            ));
            w.push(SdoWrite::new(p.comm_index(), 1, Value::Unsigned32(cob)));
        }
        if disable_unused {
            for kind in [PdoKind::Receive, PdoKind::Transmit] {
                for n in 1..=4u8 {
                    if self.of(kind).any(|p| p.number == n) {
                        continue;
                    }
                    let probe = Pdo::new(kind, n, &[], TransmissionType::SynchronousCyclic(1));
                    let cob = probe.cob_id(node) as u32;
                    w.push(SdoWrite {
                        missing_ok: true,
                        ..SdoWrite::new(
                            probe.comm_index(),
                            1,
                            Value::Unsigned32(COB_ID_INVALID | cob),
                        )
                    });
                }
            }
        }
        w
    }

    /// The frames of one cycle: SYNC and every PDO.
    pub fn cycle_frames(&self) -> Vec<FrameShape> {
        let mut f = vec![FrameShape::standard(0)];
        f.extend(self.pdos.iter().map(|p| FrameShape::standard(p.data_len())));
        f
    }

    /// Worst-case bits of one cycle (SYNC + PDOs), stuffing and interframe space
    /// included ([`frame_bits`]).
    pub fn cycle_bits(&self) -> u32 {
        self.cycle_frames()
            .iter()
            .map(|f| frame_bits(f.data_len, f.extended))
            .sum()
    }
}

/// RPDO1 data of the default mapping: controlword, target torque (‰ rated).
pub fn pack_rpdo1(controlword: u16, target_torque_permille: i16) -> [u8; 4] {
    let c = controlword.to_le_bytes();
    let t = target_torque_permille.to_le_bytes();
    [c[0], c[1], t[0], t[1]]
}

/// TPDO1 of the default mapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Tpdo1 {
    /// Statusword 0x6041.
    pub statusword: u16,
    /// Position actual 0x6064, increments.
    pub position: i32,
    /// Torque actual 0x6077, ‰ rated.
    pub torque: i16,
}

/// TPDO2 of the default mapping.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Tpdo2 {
    /// Velocity actual 0x606C, velocity units.
    pub velocity: i32,
}

/// A PDO shorter than its mapping (CiA 301: the receiver ignores it; a longer one is
/// used, its extra bytes ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("PDO of {got} bytes, mapping needs {expected}")]
pub struct ShortPdo {
    /// Bytes the mapping needs.
    pub expected: u8,
    /// Bytes received.
    pub got: u8,
}

impl Tpdo1 {
    /// Bytes of TPDO1.
    pub const LEN: u8 = 8;

    /// Decodes TPDO1 data.
    pub fn unpack(d: &[u8]) -> Result<Self, ShortPdo> {
        if d.len() < Self::LEN as usize {
            return Err(ShortPdo {
                expected: Self::LEN,
                got: d.len() as u8,
            });
        }
        Ok(Self {
            statusword: u16::from_le_bytes([d[0], d[1]]),
            position: i32::from_le_bytes([d[2], d[3], d[4], d[5]]),
            torque: i16::from_le_bytes([d[6], d[7]]),
        })
    }

    /// Encodes TPDO1 data (for simulated drives and tests).
    pub fn pack(&self) -> [u8; 8] {
        let s = self.statusword.to_le_bytes();
        let p = self.position.to_le_bytes();
        let t = self.torque.to_le_bytes();
        [s[0], s[1], p[0], p[1], p[2], p[3], t[0], t[1]]
    }
}

impl Tpdo2 {
    /// Bytes of TPDO2.
    pub const LEN: u8 = 4;

    /// Decodes TPDO2 data.
    pub fn unpack(d: &[u8]) -> Result<Self, ShortPdo> {
        if d.len() < Self::LEN as usize {
            return Err(ShortPdo {
                expected: Self::LEN,
                got: d.len() as u8,
            });
        }
        Ok(Self {
            velocity: i32::from_le_bytes([d[0], d[1], d[2], d[3]]),
        })
    }

    /// Encodes TPDO2 data.
    pub fn pack(&self) -> [u8; 4] {
        self.velocity.to_le_bytes()
    }
}

/// Worst-case bits per second of heartbeats (1 data byte each) with these periods.
fn heartbeat_bits_per_s(heartbeats: &[Duration]) -> f64 {
    heartbeats
        .iter()
        .filter(|p| !p.is_zero())
        .map(|p| frame_bits(1, false) as f64 / p.as_secs_f64())
        .sum()
}

/// Worst-case bus load (fraction of capacity, 1.0 = saturated) of the cyclic traffic
/// of `mapping` at `cycle_hz` (SYNC + RPDOs + TPDOs every cycle) plus heartbeats
/// produced with `heartbeats` periods (master's and drive's), on `bitrate` (bits/s).
/// SDOs and EMCYs are not counted: keep a margin (≤ 0.7).
pub fn bus_load(
    mapping: &ProcessDataMapping,
    heartbeats: &[Duration],
    cycle_hz: f64,
    bitrate: u32,
) -> f64 {
    let frames = mapping.cycle_frames();
    flexid_can::timing::bus_load(&frames, cycle_hz, bitrate)
        + heartbeat_bits_per_s(heartbeats) / bitrate.max(1) as f64
}

/// The highest cycle rate, Hz, at which [`bus_load`] stays at or below `max_load`
/// (0 when the heartbeats alone exceed it).
pub fn max_cycle_rate_hz(
    mapping: &ProcessDataMapping,
    heartbeats: &[Duration],
    bitrate: u32,
    max_load: f64,
) -> f64 {
    let free = max_load * bitrate as f64 - heartbeat_bits_per_s(heartbeats);
    (free / mapping.cycle_bits() as f64).max(0.0)
}

/// The cycle would overload the bus.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error(
    "bus load {:.1} % at {cycle_hz} Hz on {bitrate} bit/s exceeds {:.0} %: lower the cycle rate to at most {:.0} Hz or raise the bitrate to at least {min_bitrate} bit/s{}",
    load * 100.0, max_load * 100.0, max_rate_hz.floor(),
    if *min_bitrate > 1_000_000 { " (above the 1 Mbit/s of classic CAN)" } else { "" }
)]
pub struct BusLoadError {
    /// The cycle rate asked for, Hz.
    pub cycle_hz: f64,
    /// The bitrate, bits/s.
    pub bitrate: u32,
    /// The load it would give (fraction).
    pub load: f64,
    /// The admissible load (fraction).
    pub max_load: f64,
    /// The highest admissible cycle rate at this bitrate, Hz.
    pub max_rate_hz: f64,
    /// The lowest bitrate that admits this cycle rate, bits/s.
    pub min_bitrate: u32,
}

/// Admission check: the load of [`bus_load`], or why it is refused.
pub fn check_bus_load(
    mapping: &ProcessDataMapping,
    heartbeats: &[Duration],
    cycle_hz: f64,
    bitrate: u32,
    max_load: f64,
) -> Result<f64, BusLoadError> {
    let load = bus_load(mapping, heartbeats, cycle_hz, bitrate);
    if load <= max_load {
        return Ok(load);
    }
    let bits_per_s = mapping.cycle_bits() as f64 * cycle_hz + heartbeat_bits_per_s(heartbeats);
    Err(BusLoadError {
        cycle_hz,
        bitrate,
        load,
        max_load,
        max_rate_hz: max_cycle_rate_hz(mapping, heartbeats, bitrate, max_load),
        min_bitrate: (bits_per_s / max_load).ceil() as u32,
    })
}
