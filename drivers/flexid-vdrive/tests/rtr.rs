//! Remote frames (issue 16, item 6). The drive does not serve PDOs by RTR, and says so:
//! bit 30 of its TPDO COB-IDs ("no RTR allowed", CiA 301) is set by default and stays set
//! whatever a master writes. Node guarding (RTR on 0x700 + id) is answered.

mod common;
use common::*;

fn read_u32(d: &mut Dut, index: u16, sub: u8) -> u32 {
    let [i0, i1] = index.to_le_bytes();
    let r = d.sdo([0x40, i0, i1, sub, 0, 0, 0, 0]);
    u32::from_le_bytes([r[4], r[5], r[6], r[7]])
}

fn remote(cob: u16) -> flexid_can::CanFrame {
    flexid_can::CanFrame::remote(flexid_can::CanId::Standard(cob), 8).unwrap()
}

#[test]
fn tpdos_do_not_advertise_rtr_and_ignore_it() {
    let mut d = Dut::new();
    assert_eq!(
        read_u32(&mut d, 0x1800, 1),
        0x4000_0185,
        "TPDO1: no RTR allowed"
    );
    assert_eq!(
        read_u32(&mut d, 0x1801, 1),
        0x4000_0285,
        "TPDO2: no RTR allowed"
    );
    // A master that asks for RTR (bit 30 clear, as the flexid master and python-canopen
    // write it): the PDO is configured, the bit reads back set.
    d.sdo_ok([0x23, 0x00, 0x18, 0x01, 0x85, 0x01, 0x00, 0x80]);
    d.sdo_ok([0x23, 0x00, 0x18, 0x01, 0x85, 0x01, 0x00, 0x00]);
    assert_eq!(read_u32(&mut d, 0x1800, 1), 0x4000_0185);
    d.start();
    let out = d.sync();
    assert!(out.iter().any(|f| f.id().raw() == 0x185), "TPDO1 on SYNC");
    // An RTR on a TPDO's COB-ID is not answered.
    let out = d.drive.on_frame(&remote(0x185), d.now);
    assert!(out.is_empty(), "{:?}", out.iter().collect::<Vec<_>>());
    // Node guarding is: toggle bit + operational.
    let out = d.drive.on_frame(&remote(0x705), d.now);
    assert_eq!(out.len(), 1);
    assert_eq!(out.iter().next().unwrap().data()[0] & 0x7F, 0x05);
}
