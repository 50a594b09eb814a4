//! NMT state changes and communication errors stop the torque as configured (issue 16,
//! item 4): 0x6007 abort connection option code (CiA 402) on leaving NMT Operational or
//! a communication reset while the power stage is on, 0x1029:1 error behaviour (CiA 301)
//! on a communication error (heartbeat or SYNC lost).

mod common;
use common::*;
use flexid_vdrive::{FaultKind, State};

fn enabled_at(d: &mut Dut, permille: i16) {
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    d.rpdo(0x000F, permille);
    d.sync();
    assert_eq!(d.drive.state(), State::OperationEnabled);
    assert_eq!(d.drive.applied_torque_nm(), f64::from(permille) / 1000.0);
}

/// 0x6007 = `code` by SDO (INTEGER16, expedited 2 bytes).
fn abort_option(d: &mut Dut, code: i16) {
    let [a, b] = code.to_le_bytes();
    d.sdo_ok([0x2B, 0x07, 0x60, 0x00, a, b, 0, 0]);
}

fn statusword_by_sdo(d: &mut Dut) -> u16 {
    let r = d.sdo([0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]);
    u16::from_le_bytes([r[4], r[5]])
}

#[test]
fn the_defaults_read_back() {
    let mut d = Dut::new();
    // 0x6007 = 2 (disable voltage), 0x1029:0 = 1, 0x1029:1 = 1 (no NMT state change).
    assert_eq!(
        d.sdo([0x40, 0x07, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x07, 0x60, 0x00, 0x02, 0x00, 0, 0]
    );
    assert_eq!(
        d.sdo([0x40, 0x29, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x29, 0x10, 0x00, 0x01, 0, 0, 0]
    );
    assert_eq!(
        d.sdo([0x40, 0x29, 0x10, 0x01, 0, 0, 0, 0]),
        [0x4F, 0x29, 0x10, 0x01, 0x01, 0, 0, 0]
    );
    // Codes outside 0..=3 and error behaviours outside 0..=2 are refused (0x06090030).
    assert_eq!(
        d.sdo([0x2B, 0x07, 0x60, 0x00, 0x04, 0x00, 0, 0]),
        [0x80, 0x07, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06]
    );
    assert_eq!(
        d.sdo([0x2F, 0x29, 0x10, 0x01, 0x03, 0, 0, 0]),
        [0x80, 0x29, 0x10, 0x01, 0x30, 0x00, 0x09, 0x06]
    );
}

#[test]
fn pre_operational_while_enabled_disables_the_voltage_by_default() {
    let mut d = Dut::new();
    enabled_at(&mut d, 500);
    assert!(d.send(0x000, &[0x80, 0x05]).is_empty());
    assert_eq!(d.drive.applied_torque_nm(), 0.0, "torque off at once");
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);
    assert_eq!(statusword_by_sdo(&mut d) & 0x006F, 0x0040);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.0);
}

#[test]
fn reset_communication_while_enabled_disables_the_voltage() {
    let mut d = Dut::new();
    enabled_at(&mut d, 500);
    let out = d.send(0x000, &[0x82, 0x05]);
    assert_eq!(out, vec![frame(0x705, &[0x00])], "boot-up");
    assert_eq!(d.drive.applied_torque_nm(), 0.0);
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);
    d.start();
    d.rpdo(0x000F, 500);
    d.sync();
    assert_eq!(
        d.drive.applied_torque_nm(),
        0.0,
        "no torque without a new enable"
    );
}

#[test]
fn option_1_is_a_fault_with_emcy() {
    let mut d = Dut::new();
    abort_option(&mut d, 1);
    enabled_at(&mut d, 500);
    let out = d.send(0x000, &[0x80, 0x05]);
    // EMCY 0x8100 (communication), error register generic | communication.
    assert_eq!(out, vec![frame(0x085, &[0x00, 0x81, 0x11, 0, 0, 0, 0, 0])]);
    assert_eq!(d.drive.fault(), Some(FaultKind::ConnectionAborted));
    assert_eq!(d.drive.state(), State::Fault);
    assert_eq!(d.drive.applied_torque_nm(), 0.0);
    // A fault reset clears it: the connection is back.
    d.start();
    d.rpdo(0x0000, 0);
    d.rpdo(0x0080, 0);
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);
}

#[test]
fn option_3_is_a_quick_stop_and_option_0_keeps_the_torque() {
    let mut d = Dut::new();
    abort_option(&mut d, 3);
    enabled_at(&mut d, 500);
    d.send(0x000, &[0x02, 0x05]); // NMT stop
    assert_eq!(d.drive.state(), State::QuickStopActive);
    for _ in 0..20 {
        d.sync();
    }
    assert_eq!(d.drive.applied_torque_nm(), 0.0, "ramped to zero");
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);

    let mut d = Dut::new();
    abort_option(&mut d, 0);
    enabled_at(&mut d, 500);
    d.send(0x000, &[0x80, 0x05]);
    assert_eq!(
        d.drive.state(),
        State::OperationEnabled,
        "no action, as configured"
    );
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.5);
}

#[test]
fn a_communication_error_changes_the_nmt_state_as_0x1029_says() {
    // (0x1029:1, heartbeat state byte after the heartbeat-consumer fault)
    for (behaviour, nmt) in [(None, 0x05), (Some(0u8), 0x7F), (Some(2), 0x04)] {
        let mut d = Dut::with(&plant("sync_loss_cycles = 0\nheartbeat_producer_ms = 10"));
        if let Some(b) = behaviour {
            d.sdo_ok([0x2F, 0x29, 0x10, 0x01, b, 0, 0, 0]);
        }
        // 0x1016:1 = (1 << 16) | 50 ms; the master's heartbeat once.
        d.sdo_ok([0x23, 0x16, 0x10, 0x01, 0x32, 0x00, 0x01, 0x00]);
        d.send(0x701, &[0x05]);
        enabled_at(&mut d, 500);
        let got = d.run_for(ms(100));
        assert!(
            got.iter()
                .any(|(_, f)| f.id().raw() == 0x085 && f.data()[..2] == [0x30, 0x81]),
            "EMCY 0x8130: {got:?}"
        );
        assert_eq!(d.drive.applied_torque_nm(), 0.0);
        let last_hb = got
            .iter()
            .rev()
            .find(|(_, f)| f.id().raw() == 0x705)
            .unwrap();
        assert_eq!(last_hb.1.data(), &[nmt], "0x1029:1 = {behaviour:?}");
    }
}
