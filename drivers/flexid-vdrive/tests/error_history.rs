//! The pre-defined error field 0x1003 (CiA 301) outlives a fault reset (issue 16,
//! item 9): a fault reset clears the error register 0x1001 and 0x603F and sends the EMCY
//! "error reset", but the history of what happened stays readable until the master writes
//! 0 to 0x1003:0.

mod common;
use common::*;
use flexid_vdrive::State;

fn read_u32(d: &mut Dut, index: u16, sub: u8) -> u32 {
    let [i0, i1] = index.to_le_bytes();
    let r = d.sdo([0x40, i0, i1, sub, 0, 0, 0, 0]);
    assert_eq!(r[0] & 0xE0, 0x40, "upload of {index:#06x}:{sub}: {r:02X?}");
    u32::from_le_bytes([r[4], r[5], r[6], r[7]])
}

/// Faults on the heartbeat consumer (EMCY 0x8130), then fault-resets.
fn heartbeat_fault_and_reset(d: &mut Dut) {
    d.send(0x701, &[0x05]);
    d.rpdo(0x0006, 0);
    d.rpdo(0x000F, 0);
    d.run_for(ms(60));
    assert_eq!(d.drive.state(), State::Fault);
    d.rpdo(0x0000, 0);
    let out = d.rpdo(0x0080, 0);
    assert_eq!(out, vec![frame(0x085, &[0; 8])], "EMCY error reset");
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);
}

#[test]
fn a_fault_reset_keeps_the_error_history() {
    let mut d = Dut::with(&plant(
        "heartbeat_consumer_ms = 50\nmaster_node_id = 1\nsync_loss_cycles = 0",
    ));
    d.start();
    heartbeat_fault_and_reset(&mut d);
    assert_eq!(read_u32(&mut d, 0x1001, 0), 0, "error register cleared");
    assert_eq!(read_u32(&mut d, 0x603F, 0), 0, "error code cleared");
    assert_eq!(read_u32(&mut d, 0x1003, 0), 1, "one error in the history");
    assert_eq!(read_u32(&mut d, 0x1003, 1), 0x8130);
    // A second fault goes on top, most recent first.
    heartbeat_fault_and_reset(&mut d);
    assert_eq!(read_u32(&mut d, 0x1003, 0), 2);
    assert_eq!(read_u32(&mut d, 0x1003, 1), 0x8130);
    assert_eq!(read_u32(&mut d, 0x1003, 2), 0x8130);
}

#[test]
fn only_writing_0_to_sub_0_clears_the_history() {
    let mut d = Dut::with(&plant(
        "heartbeat_consumer_ms = 50\nmaster_node_id = 1\nsync_loss_cycles = 0",
    ));
    d.start();
    heartbeat_fault_and_reset(&mut d);
    // Any other value: 0x06090030 (value range); the entries themselves are read-only.
    assert_eq!(
        d.sdo([0x2F, 0x03, 0x10, 0x00, 0x01, 0, 0, 0]),
        [0x80, 0x03, 0x10, 0x00, 0x30, 0x00, 0x09, 0x06]
    );
    assert_eq!(
        d.sdo([0x23, 0x03, 0x10, 0x01, 0, 0, 0, 0]),
        [0x80, 0x03, 0x10, 0x01, 0x02, 0x00, 0x01, 0x06]
    );
    assert_eq!(read_u32(&mut d, 0x1003, 0), 1);
    d.sdo_ok([0x2F, 0x03, 0x10, 0x00, 0x00, 0, 0, 0]);
    assert_eq!(read_u32(&mut d, 0x1003, 0), 0);
    assert_eq!(read_u32(&mut d, 0x1003, 1), 0);
    // A new error starts a new history.
    heartbeat_fault_and_reset(&mut d);
    assert_eq!(read_u32(&mut d, 0x1003, 0), 1);
    assert_eq!(read_u32(&mut d, 0x1003, 1), 0x8130);
}
