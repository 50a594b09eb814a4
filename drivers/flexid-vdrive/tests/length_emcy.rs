//! PDOs and SYNCs of the wrong length (issue 16, item 5), CiA 301: an RPDO shorter than
//! its mapping is not processed, EMCY 0x8210; one longer is processed from its mapped
//! bytes, EMCY 0x8220; a SYNC whose length does not match the counter overflow value
//! (0x1019 absent: 0, no data) gives EMCY 0x8240. Each EMCY is sent once until a frame of
//! the right length clears the condition (no EMCY flood at the cycle rate).

mod common;
use common::*;
use flexid_vdrive::State;

fn emcys(out: &[flexid_can::CanFrame]) -> Vec<[u8; 8]> {
    out.iter()
        .filter(|f| f.id().raw() == 0x085)
        .map(|f| f.data().try_into().unwrap())
        .collect()
}

fn enabled() -> Dut {
    let mut d = Dut::new();
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x000F, 0);
    assert_eq!(d.drive.state(), State::OperationEnabled);
    d
}

#[test]
fn a_short_rpdo_is_not_processed_and_gives_emcy_8210() {
    let mut d = enabled();
    d.rpdo(0x000F, 300);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.3);
    // 3 bytes where 4 are mapped (controlword + target torque)
    let out = d.send(0x205, &[0x0F, 0x00, 0xE8]);
    // error register generic | communication
    assert_eq!(emcys(&out), vec![[0x10, 0x82, 0x11, 0, 0, 0, 0, 0]]);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.3, "not processed");
    assert!(
        emcys(&d.send(0x205, &[0x0F])).is_empty(),
        "once per condition"
    );
    // a right one clears the condition; the next short one reports again
    assert!(emcys(&d.rpdo(0x000F, 400)).is_empty());
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.4);
    assert_eq!(emcys(&d.send(0x205, &[0x0F, 0x00])).len(), 1);
    // a short controlword-only frame does not disable the drive either
    d.send(0x205, &[0x00, 0x00]);
    assert_eq!(d.drive.state(), State::OperationEnabled);
}

#[test]
fn a_long_rpdo_is_processed_and_gives_emcy_8220() {
    let mut d = enabled();
    let out = d.send(0x205, &[0x0F, 0x00, 0xF4, 0x01, 0xAA, 0xBB]);
    assert_eq!(emcys(&out), vec![[0x20, 0x82, 0x11, 0, 0, 0, 0, 0]]);
    d.sync();
    assert_eq!(
        d.drive.applied_torque_nm(),
        0.5,
        "the mapped bytes are used"
    );
}

#[test]
fn a_sync_with_data_gives_emcy_8240() {
    let mut d = enabled();
    assert!(emcys(&d.sync()).is_empty());
    // a SYNC counter the drive was not configured for: reported, still a SYNC
    let out = d.send(0x080, &[0x07]);
    assert_eq!(emcys(&out), vec![[0x40, 0x82, 0x11, 0, 0, 0, 0, 0]]);
    assert!(
        out.iter().any(|f| f.id().raw() == 0x185),
        "TPDO1 still sent"
    );
    // 2 bytes: no SYNC at all; the condition is still reported (no new EMCY)
    let out = d.send(0x080, &[0x07, 0x08]);
    assert!(out.is_empty(), "{out:?}");
    // a right SYNC clears it
    assert!(emcys(&d.sync()).is_empty());
    assert_eq!(emcys(&d.send(0x080, &[1, 2, 3, 4, 5, 6, 7, 8])).len(), 1);
}

#[test]
fn no_length_emcy_in_pre_operational_or_stopped() {
    let mut d = Dut::new();
    // pre-operational: PDOs are not processed at all, so they have no length to check
    assert!(d.send(0x205, &[0x0F]).is_empty());
    // stopped: no EMCY at all (CiA 301)
    d.send(0x000, &[0x02, 0x05]);
    assert!(d.send(0x080, &[0x07]).is_empty());
}
