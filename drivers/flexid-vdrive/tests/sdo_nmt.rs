//! CiA 301 services: SDO (expedited, segmented, aborts), NMT, heartbeat producer, PDO
//! re-mapping. Expected bytes are written from the CiA 301 frame layouts.

mod common;
use common::*;

#[test]
fn sdo_expedited_reads_of_device_type_and_identity() {
    let mut d = Dut::new();
    // 0x1000 device type 0x00020192: scs=2, e=1, s=1, n=0 -> 0x43.
    assert_eq!(
        d.sdo([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]
    );
    // 0x1018:0 = 4 (u8: n=3 -> 0x4F).
    assert_eq!(
        d.sdo([0x40, 0x18, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x18, 0x10, 0x00, 0x04, 0, 0, 0]
    );
    let identity = [
        (1, [0x1D, 0x0F, 0x00, 0x00]),
        (2, [0x02, 0x04, 0x00, 0x00]),
        (3, [0x00, 0x00, 0x01, 0x00]),
        (4, [0x05, 0x00, 0x00, 0x00]),
    ];
    for (sub, v) in identity {
        assert_eq!(
            d.sdo([0x40, 0x18, 0x10, sub, 0, 0, 0, 0]),
            [0x43, 0x18, 0x10, sub, v[0], v[1], v[2], v[3]],
            "0x1018:{sub}"
        );
    }
    // 0x6502 supported modes: PT bit 3, CSP bit 7, CSV bit 8, CST bit 9 = 0x388.
    assert_eq!(
        d.sdo([0x40, 0x02, 0x65, 0x00, 0, 0, 0, 0]),
        [0x43, 0x02, 0x65, 0x00, 0x88, 0x03, 0, 0]
    );
    // 0x6076 rated torque 1000 mN m.
    assert_eq!(
        d.sdo([0x40, 0x76, 0x60, 0x00, 0, 0, 0, 0]),
        [0x43, 0x76, 0x60, 0x00, 0xE8, 0x03, 0, 0]
    );
}

#[test]
fn sdo_segmented_upload_of_device_name() {
    let mut d = Dut::new();
    // Initiate: scs=2, e=0, s=1 -> 0x41, size 13.
    assert_eq!(
        d.sdo([0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]),
        [0x41, 0x08, 0x10, 0x00, 13, 0, 0, 0]
    );
    // Segment 1: ccs=3, t=0 -> 0x60; answer t=0, n=0, c=0 -> 0x00 + 7 bytes.
    assert_eq!(d.sdo([0x60, 0, 0, 0, 0, 0, 0, 0]), *b"\x00flexid-");
    // Segment 2: ccs=3, t=1 -> 0x70; answer t=1, n=1 (6 bytes), c=1 -> 0x13.
    assert_eq!(d.sdo([0x70, 0, 0, 0, 0, 0, 0, 0]), *b"\x13vdrive\x00");
}

#[test]
fn sdo_write_and_read_back_modes_of_operation() {
    let mut d = Dut::new();
    // Default CST (10).
    assert_eq!(
        d.sdo([0x40, 0x60, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x60, 0x60, 0x00, 10, 0, 0, 0]
    );
    // Write CSV (9): ccs=1, e=1, s=1, n=3 -> 0x2F.
    d.sdo_ok([0x2F, 0x60, 0x60, 0x00, 9, 0, 0, 0]);
    assert_eq!(
        d.sdo([0x40, 0x60, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x60, 0x60, 0x00, 9, 0, 0, 0]
    );
    // 0x6061 displays it.
    assert_eq!(
        d.sdo([0x40, 0x61, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x61, 0x60, 0x00, 9, 0, 0, 0]
    );
    // An unsupported mode (1 = profile position): 0x06090030 value range.
    assert_eq!(
        d.sdo([0x2F, 0x60, 0x60, 0x00, 1, 0, 0, 0]),
        [0x80, 0x60, 0x60, 0x00, 0x30, 0x00, 0x09, 0x06]
    );
}

#[test]
fn sdo_abort_codes() {
    let mut d = Dut::new();
    // Missing object 0x2000: 0x06020000.
    assert_eq!(
        d.sdo([0x40, 0x00, 0x20, 0x00, 0, 0, 0, 0]),
        [0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06]
    );
    // Missing sub-index 0x1018:7: 0x06090011.
    assert_eq!(
        d.sdo([0x40, 0x18, 0x10, 0x07, 0, 0, 0, 0]),
        [0x80, 0x18, 0x10, 0x07, 0x11, 0x00, 0x09, 0x06]
    );
    // Write to read-only 0x1000: 0x06010002.
    assert_eq!(
        d.sdo([0x23, 0x00, 0x10, 0x00, 1, 2, 3, 4]),
        [0x80, 0x00, 0x10, 0x00, 0x02, 0x00, 0x01, 0x06]
    );
    // Write to read-only statusword 0x6041: 0x06010002.
    assert_eq!(
        d.sdo([0x2B, 0x41, 0x60, 0x00, 1, 0, 0, 0]),
        [0x80, 0x41, 0x60, 0x00, 0x02, 0x00, 0x01, 0x06]
    );
    // 4 bytes to the u16 controlword: length too high 0x06070012.
    assert_eq!(
        d.sdo([0x23, 0x40, 0x60, 0x00, 6, 0, 0, 0]),
        [0x80, 0x40, 0x60, 0x00, 0x12, 0x00, 0x07, 0x06]
    );
    // 1 byte to the u16 controlword: length too low 0x06070013.
    assert_eq!(
        d.sdo([0x2F, 0x40, 0x60, 0x00, 6, 0, 0, 0]),
        [0x80, 0x40, 0x60, 0x00, 0x13, 0x00, 0x07, 0x06]
    );
    // Unknown command specifier (ccs 7): 0x05040001.
    assert_eq!(
        d.sdo([0xE0, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        [0x80, 0x00, 0x10, 0x00, 0x01, 0x00, 0x04, 0x05]
    );
    // The drive still serves reads.
    assert_eq!(
        d.sdo([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]
    );
}

#[test]
fn nmt_reset_node_and_communication_give_boot_up() {
    let mut d = Dut::new();
    d.start();
    d.sdo_ok([0x2F, 0x60, 0x60, 0x00, 9, 0, 0, 0]);
    // Reset communication (0x82): boot-up 0x705 [00]; application objects kept.
    assert_eq!(d.send(0x000, &[0x82, 0x05]), vec![frame(0x705, &[0x00])]);
    assert_eq!(d.drive.nmt(), canopen_rs::NmtState::PreOperational);
    assert_eq!(d.sdo([0x40, 0x60, 0x60, 0x00, 0, 0, 0, 0])[4], 9);
    // Reset node (0x81), broadcast: boot-up, defaults back.
    assert_eq!(d.send(0x000, &[0x81, 0x00]), vec![frame(0x705, &[0x00])]);
    assert_eq!(d.sdo([0x40, 0x60, 0x60, 0x00, 0, 0, 0, 0])[4], 10);
    // Another node's reset: nothing.
    assert!(d.send(0x000, &[0x81, 0x06]).is_empty());
}

#[test]
fn heartbeat_is_produced_at_the_0x1017_period() {
    let mut d = Dut::new();
    assert!(d.run_for(ms(500)).is_empty(), "0x1017 = 0: no heartbeat");
    // 0x1017 = 100 ms: ccs=1, n=2 -> 0x2B.
    d.sdo_ok([0x2B, 0x17, 0x10, 0x00, 100, 0, 0, 0]);
    let t0 = d.now;
    let got = d.run_for(ms(350));
    let times: Vec<u64> = got
        .iter()
        .map(|(t, _)| (*t - t0).as_millis() as u64)
        .collect();
    assert_eq!(times, vec![100, 200, 300]);
    for (_, f) in &got {
        assert_eq!(*f, frame(0x705, &[0x7F]), "pre-operational heartbeat");
    }
    d.start();
    let got = d.run_for(ms(100));
    assert_eq!(got.len(), 1);
    assert_eq!(got[0].1, frame(0x705, &[0x05]), "operational heartbeat");
    // From the plant file's [drive] section.
    let mut d = Dut::with(&plant("heartbeat_producer_ms = 20"));
    assert_eq!(d.run_for(ms(100)).len(), 5);
}

#[test]
fn pdo_remapping_by_sdo_then_sync() {
    let mut d = Dut::new();
    // Refusals: mapping while TPDO1 is valid, and mapping a non-mappable object.
    assert_eq!(
        d.sdo([0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x6C, 0x60]),
        [0x80, 0x00, 0x1A, 0x01, 0x00, 0x00, 0x01, 0x06]
    );
    // 1. TPDO1 invalid: 0x1800:1 = 0x80000185.
    d.sdo_ok([0x23, 0x00, 0x18, 0x01, 0x85, 0x01, 0x00, 0x80]);
    // 2. count 0.
    d.sdo_ok([0x2F, 0x00, 0x1A, 0x00, 0, 0, 0, 0]);
    // Not mappable: 0x1000 device type: 0x06040041.
    assert_eq!(
        d.sdo([0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x00, 0x10]),
        [0x80, 0x00, 0x1A, 0x01, 0x41, 0x00, 0x04, 0x06]
    );
    // Wrong length for 0x6041 (32 bits): 0x06040041.
    assert_eq!(
        d.sdo([0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x41, 0x60]),
        [0x80, 0x00, 0x1A, 0x01, 0x41, 0x00, 0x04, 0x06]
    );
    // 3. entries: velocity actual (0x606C, 32 bit), statusword (0x6041, 16 bit).
    d.sdo_ok([0x23, 0x00, 0x1A, 0x01, 0x20, 0x00, 0x6C, 0x60]);
    d.sdo_ok([0x23, 0x00, 0x1A, 0x02, 0x10, 0x00, 0x41, 0x60]);
    // 4. count 2; transmission type 2 (every 2nd SYNC).
    d.sdo_ok([0x2F, 0x00, 0x1A, 0x00, 2, 0, 0, 0]);
    d.sdo_ok([0x2F, 0x00, 0x18, 0x02, 2, 0, 0, 0]);
    // 5. valid again.
    d.sdo_ok([0x23, 0x00, 0x18, 0x01, 0x85, 0x01, 0x00, 0x00]);
    // Changing count while valid is refused.
    assert_eq!(
        d.sdo([0x2F, 0x00, 0x1A, 0x00, 1, 0, 0, 0]),
        [0x80, 0x00, 0x1A, 0x00, 0x00, 0x00, 0x01, 0x06]
    );
    // No PDOs in pre-operational.
    assert!(d.sync().is_empty());
    d.start();
    // Mapping in operational: 0x08000022.
    assert_eq!(
        d.sdo([0x2F, 0x00, 0x1A, 0x00, 0, 0, 0, 0]),
        [0x80, 0x00, 0x1A, 0x00, 0x22, 0x00, 0x00, 0x08]
    );
    // At rest: velocity 0, statusword 0x0240 (switch on disabled, remote); TPDO2 unchanged.
    let s1 = d.sync();
    assert_eq!(
        s1,
        vec![frame(0x285, &[0, 0, 0, 0])],
        "TPDO1 only every 2nd SYNC"
    );
    let s2 = d.sync();
    assert_eq!(
        s2,
        vec![
            frame(0x185, &[0, 0, 0, 0, 0x40, 0x02]),
            frame(0x285, &[0, 0, 0, 0])
        ]
    );
}

#[test]
fn velocity_layout_with_a_moving_axis() {
    // 1 rad/s initial velocity = 2^20 / (2 pi) = 166886.05 inc/s -> 166886 = 0x00028BE6.
    let mut p = plant("");
    p.plant.measurement.initial_velocity_rad_s = 1.0;
    let mut d = Dut::with(&p);
    d.start();
    let out = d.sync();
    assert_eq!(out[1], frame(0x285, &[0xE6, 0x8B, 0x02, 0x00]));
    // TPDO1 at the first SYNC: position 0, torque 0.
    assert_eq!(out[0], frame(0x185, &[0x40, 0x02, 0, 0, 0, 0, 0, 0]));
}
