//! CANopen COB-IDs of the predefined connection set (CiA 301 §7.3.5) and the
//! classification of received frames by identifier.
//!
//! canopen-rs has the bases spread over its modules (`nmt`, `sync`, `emcy`, `pdo`, `sdo`);
//! this module gathers them and adds [`classify`], which canopen-rs lacks.

use flexid_can::{CanFrame, CanId, FrameKind};

/// NMT node control, from the master (2 bytes: command, node-id).
pub const NMT: u16 = 0x000;
/// SYNC, from the SYNC producer (here the master), 0 bytes (or 1 with a counter).
pub const SYNC: u16 = 0x080;
/// EMCY base: a node's emergency object is `0x080 + node-id`.
pub const EMCY_BASE: u16 = 0x080;
/// TPDO1..4 bases (node to master): `0x180/0x280/0x380/0x480 + node-id`.
pub const TPDO_BASE: [u16; 4] = [0x180, 0x280, 0x380, 0x480];
/// RPDO1..4 bases (master to node): `0x200/0x300/0x400/0x500 + node-id`.
pub const RPDO_BASE: [u16; 4] = [0x200, 0x300, 0x400, 0x500];
/// SDO server-to-client (response) base: `0x580 + node-id`.
pub const SDO_TX_BASE: u16 = 0x580;
/// SDO client-to-server (request) base: `0x600 + node-id`.
pub const SDO_RX_BASE: u16 = 0x600;
/// Heartbeat / boot-up base: `0x700 + node-id`.
pub const HEARTBEAT_BASE: u16 = 0x700;

/// A node's EMCY COB-ID.
pub const fn emcy(node: u8) -> u16 {
    EMCY_BASE + node as u16
}

/// The COB-ID of TPDO `n` (1..=4) of `node`; `n` is clamped to 1..=4.
pub const fn tpdo(n: u8, node: u8) -> u16 {
    TPDO_BASE[pdo_slot(n)] + node as u16
}

/// The COB-ID of RPDO `n` (1..=4) of `node`; `n` is clamped to 1..=4.
pub const fn rpdo(n: u8, node: u8) -> u16 {
    RPDO_BASE[pdo_slot(n)] + node as u16
}

/// SDO response COB-ID (server to client) of `node`.
pub const fn sdo_tx(node: u8) -> u16 {
    SDO_TX_BASE + node as u16
}

/// SDO request COB-ID (client to server) of `node`.
pub const fn sdo_rx(node: u8) -> u16 {
    SDO_RX_BASE + node as u16
}

/// Heartbeat COB-ID of `node`.
pub const fn heartbeat(node: u8) -> u16 {
    HEARTBEAT_BASE + node as u16
}

const fn pdo_slot(n: u8) -> usize {
    match n {
        0 | 1 => 0,
        2 => 1,
        3 => 2,
        _ => 3,
    }
}

/// What a received frame is, by its identifier (node-ids 1..=127).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Cob {
    /// NMT node control.
    Nmt,
    /// SYNC.
    Sync,
    /// Emergency of a node.
    Emcy(u8),
    /// TPDO `n` (1..=4) of a node: `Tpdo(n, node)`.
    Tpdo(u8, u8),
    /// RPDO `n` (1..=4) of a node: `Rpdo(n, node)`.
    Rpdo(u8, u8),
    /// SDO response from a node's server.
    SdoTx(u8),
    /// SDO request to a node's server.
    SdoRx(u8),
    /// Heartbeat or boot-up of a node.
    Heartbeat(u8),
    /// Anything else: extended identifiers, remote and error frames, TIME (0x100), LSS,
    /// node-id 0 in a per-node range, ...
    Other,
}

/// Classifies a frame by its identifier (never by its content; never panics).
pub fn classify(frame: &CanFrame) -> Cob {
    if frame.kind() != FrameKind::Data {
        return Cob::Other;
    }
    match frame.id() {
        CanId::Standard(id) => classify_id(id),
        CanId::Extended(_) => Cob::Other,
    }
}

/// Classifies an 11-bit identifier.
pub fn classify_id(id: u16) -> Cob {
    if id == NMT {
        return Cob::Nmt;
    }
    if id == SYNC {
        return Cob::Sync;
    }
    let base = id & 0x780;
    let node = (id & 0x7F) as u8;
    if node == 0 {
        return Cob::Other;
    }
    match base {
        0x080 => Cob::Emcy(node),
        0x180 => Cob::Tpdo(1, node),
        0x280 => Cob::Tpdo(2, node),
        0x380 => Cob::Tpdo(3, node),
        0x480 => Cob::Tpdo(4, node),
        0x200 => Cob::Rpdo(1, node),
        0x300 => Cob::Rpdo(2, node),
        0x400 => Cob::Rpdo(3, node),
        0x500 => Cob::Rpdo(4, node),
        0x580 => Cob::SdoTx(node),
        0x600 => Cob::SdoRx(node),
        0x700 => Cob::Heartbeat(node),
        _ => Cob::Other,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_of_node_5() {
        assert_eq!(emcy(5), 0x085);
        assert_eq!(
            [tpdo(1, 5), tpdo(2, 5), tpdo(3, 5), tpdo(4, 5)],
            [0x185, 0x285, 0x385, 0x485]
        );
        assert_eq!(
            [rpdo(1, 5), rpdo(2, 5), rpdo(3, 5), rpdo(4, 5)],
            [0x205, 0x305, 0x405, 0x505]
        );
        assert_eq!((sdo_tx(5), sdo_rx(5), heartbeat(5)), (0x585, 0x605, 0x705));
    }

    #[test]
    fn classification() {
        assert_eq!(classify_id(0x000), Cob::Nmt);
        assert_eq!(classify_id(0x080), Cob::Sync);
        assert_eq!(classify_id(0x081), Cob::Emcy(1));
        assert_eq!(classify_id(0x1FF), Cob::Tpdo(1, 0x7F));
        assert_eq!(classify_id(0x282), Cob::Tpdo(2, 2));
        assert_eq!(classify_id(0x503), Cob::Rpdo(4, 3));
        assert_eq!(classify_id(0x5A0), Cob::SdoTx(0x20));
        assert_eq!(classify_id(0x620), Cob::SdoRx(0x20));
        assert_eq!(classify_id(0x77F), Cob::Heartbeat(0x7F));
        assert_eq!(classify_id(0x100), Cob::Other); // TIME
        assert_eq!(classify_id(0x7E5), Cob::Other); // LSS
        assert_eq!(classify_id(0x180), Cob::Other); // node 0
        let ext = CanFrame::extended(0x181, &[]).unwrap();
        assert_eq!(classify(&ext), Cob::Other);
        let rtr = CanFrame::remote(CanId::Standard(0x181), 8).unwrap();
        assert_eq!(classify(&rtr), Cob::Other);
    }
}
