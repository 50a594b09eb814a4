//! Statusword bits 4 (voltage enabled), 9 (remote) and 12 (operation mode specific) per
//! CiA 402 (issue 16, item 7), through the TPDO and through SDO.

mod common;
use common::*;

#[test]
fn statusword_bits_4_9_and_12_follow_the_drive() {
    let mut d = Dut::new();
    d.start();
    // Bit 9 remote: the controlword is processed (the bus is this drive's only control).
    assert_eq!(d.sync_statusword(), 0x0240, "switch on disabled, remote");
    let walk = [
        // bit 4: voltage enabled from Ready to switch on ("shutdown" enables the voltage)
        (0x0006, 0x0231, "ready to switch on"),
        (0x0007, 0x0233, "switched on"),
        // bit 12 in CST: target torque used as the input of the torque loop
        (
            0x000F,
            0x1237,
            "operation enabled, CST: target torque followed",
        ),
        (0x0007, 0x0233, "disable operation: target ignored again"),
        (0x000F, 0x1237, "operation enabled"),
        (
            0x0002,
            0x0217,
            "quick stop active: voltage still on, target ignored",
        ),
    ];
    for (cw, sw, what) in walk {
        d.rpdo(cw, 0);
        assert_eq!(d.sync_statusword(), sw, "{what}");
    }
    d.rpdo(0x0000, 0);
    assert_eq!(d.sync_statusword(), 0x0240, "disable voltage: bit 4 off");
}

#[test]
fn bit_12_is_cs_mode_specific() {
    let mut d = Dut::new();
    // PT (4): bit 12 is reserved there; CSV (9) and CSP (8): target followed.
    for (mode, sw) in [(4u8, 0x0237), (9, 0x1237), (8, 0x1237), (10, 0x1237)] {
        d.send(0x000, &[0x80, 0x05]);
        d.sdo_ok([0x2F, 0x60, 0x60, 0x00, mode, 0, 0, 0]);
        d.start();
        d.rpdo(0x0006, 0);
        d.rpdo(0x000F, 0);
        assert_eq!(d.sync_statusword(), sw, "mode {mode}");
        d.rpdo(0x0000, 0);
    }
    // Fault: only the fault bit and remote.
    let mut p = plant("max_speed_rad_s = 10.0");
    p.plant.measurement.initial_velocity_rad_s = 12.0;
    let mut d = Dut::with(&p);
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x000F, 0);
    d.sync();
    assert_eq!(d.sync_statusword(), 0x0208);
}
