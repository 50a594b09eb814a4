//! CiA 402 state machine through the protocol, limits, faults, heartbeat consumer and
//! malformed input. Statusword and EMCY bytes are written from CiA 402 / CiA 301 (the
//! statuswords with bit 9 remote, bit 4 voltage enabled and, in CST, bit 12 "target
//! followed": tests/statusword_bits.rs).

mod common;
use common::*;
use flexid_vdrive::{FaultKind, State};

/// TPDO1 (default mapping) fields of a SYNC: (statusword, position, torque actual).
fn tpdo1(out: &[flexid_can::CanFrame]) -> (u16, i32, i16) {
    let f = out
        .iter()
        .find(|f| f.id().raw() == 0x185)
        .expect("TPDO1 on 0x185");
    let d = f.data();
    assert_eq!(d.len(), 8);
    (
        u16::from_le_bytes([d[0], d[1]]),
        i32::from_le_bytes([d[2], d[3], d[4], d[5]]),
        i16::from_le_bytes([d[6], d[7]]),
    )
}

fn enabled(d: &mut Dut) {
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    d.rpdo(0x000F, 0);
    assert_eq!(d.drive.state(), State::OperationEnabled);
}

#[test]
fn controlword_walk_gives_the_standard_statuswords() {
    let mut d = Dut::new();
    d.start();
    assert_eq!(d.sync_statusword(), 0x0240, "switch on disabled");
    let walk = [
        (0x0006, 0x0231, "shutdown -> ready to switch on"),
        (0x0007, 0x0233, "switch on -> switched on"),
        (0x000F, 0x1237, "enable operation -> operation enabled"),
        (0x0007, 0x0233, "disable operation -> switched on"),
        (0x000F, 0x1237, "enable operation"),
        (0x0006, 0x0231, "shutdown -> ready to switch on"),
        (0x0000, 0x0240, "disable voltage -> switch on disabled"),
        (
            0x000F,
            0x0240,
            "enable operation is not a transition from switch on disabled",
        ),
        (0x0006, 0x0231, "shutdown"),
        (0x000F, 0x1237, "switch on + enable operation (3 + 4)"),
        (0x0000, 0x0240, "disable voltage from operation enabled"),
    ];
    for (cw, sw, what) in walk {
        d.rpdo(cw, 0);
        assert_eq!(d.sync_statusword(), sw, "{what}");
    }
    // The statusword object reads the same over SDO (0x6041 = 0x0240).
    assert_eq!(
        d.sdo([0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x41, 0x60, 0x00, 0x40, 0x02, 0, 0]
    );
    // Controlword by SDO in pre-operational also drives the state machine.
    d.send(0x000, &[0x80, 0x05]);
    d.sdo_ok([0x2B, 0x40, 0x60, 0x00, 0x06, 0x00, 0, 0]);
    assert_eq!(
        d.sdo([0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x41, 0x60, 0x00, 0x31, 0x02, 0, 0]
    );
}

#[test]
fn torque_only_in_operation_enabled() {
    let mut d = Dut::new();
    d.start();
    d.rpdo(0x0007, 500);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.0, "switch on disabled");
    d.rpdo(0x0006, 500);
    d.rpdo(0x0007, 500);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.0, "switched on");
    d.rpdo(0x000F, 500);
    let out = d.sync();
    assert_eq!(tpdo1(&out).2, 0, "TPDO k: torque before set-point k");
    assert_eq!(d.drive.applied_torque_nm(), 0.5);
    assert_eq!(tpdo1(&d.sync()).2, 500);
}

#[test]
fn quick_stop_ramps_torque_to_zero() {
    // 100 N m/s slope at 2 kHz: 0.05 N m per cycle; from 1 N m: 20 cycles.
    let mut d = Dut::new();
    enabled(&mut d);
    d.rpdo(0x000F, 1000);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 1.0);
    d.rpdo(0x0002, 1000);
    let mut torques = Vec::new();
    let mut statuswords = Vec::new();
    for _ in 0..25 {
        let out = d.sync();
        statuswords.push(tpdo1(&out).0);
        torques.push(d.drive.applied_torque_nm());
    }
    assert_eq!(statuswords[0], 0x0217, "quick stop active");
    for w in torques.windows(2) {
        assert!(w[1] <= w[0] && w[0] - w[1] <= 0.05 + 1e-12, "{torques:?}");
    }
    assert!((torques[0] - 0.95).abs() < 1e-12);
    assert_eq!(torques[19], 0.0, "{torques:?}");
    assert_eq!(
        *statuswords.last().unwrap(),
        0x0240,
        "then switch on disabled"
    );
}

#[test]
fn torque_above_peak_is_clamped_with_internal_limit_bit() {
    let mut d = Dut::new(); // peak 3 N m, rated 1 N m
    enabled(&mut d);
    d.rpdo(0x000F, 5000);
    let out = d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 3.0);
    // bit 11 appears with the next publication (SYNC after the clamp).
    let _ = out;
    let (sw, _, tq) = tpdo1(&d.sync());
    assert_eq!(sw, 0x1A37);
    assert_eq!(tq, 3000, "0x0BB8");
    // 0x6072 max torque 1500 per-mille lowers the clamp.
    d.sdo_ok([0x2B, 0x72, 0x60, 0x00, 0xDC, 0x05, 0, 0]);
    d.rpdo(0x000F, -5000);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), -1.5);
    d.rpdo(0x000F, 100);
    d.sync();
    assert_eq!(tpdo1(&d.sync()).0, 0x1237, "limit bit cleared");
    assert_eq!(d.drive.fault(), None);
}

#[test]
fn overspeed_faults_with_emcy_8400_and_fault_reset_waits_for_the_cause() {
    let mut p = plant("max_speed_rad_s = 10.0");
    p.plant.measurement.initial_velocity_rad_s = 12.0;
    let mut d = Dut::with(&p);
    enabled(&mut d);
    let out = d.sync();
    // EMCY 0x085: code 0x8400 LE, error register generic | device profile = 0x21.
    assert_eq!(out[0], frame(0x085, &[0x00, 0x84, 0x21, 0, 0, 0, 0, 0]));
    assert_eq!(tpdo1(&out).0, 0x0208, "fault");
    assert_eq!(d.drive.fault(), Some(FaultKind::Overspeed));
    // 0x603F error code and 0x1001 error register.
    assert_eq!(
        d.sdo([0x40, 0x3F, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x3F, 0x60, 0x00, 0x00, 0x84, 0, 0]
    );
    assert_eq!(
        d.sdo([0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x01, 0x10, 0x00, 0x21, 0, 0, 0]
    );
    // Fault reset while still too fast: stays in Fault.
    d.rpdo(0x0080, 0);
    assert_eq!(d.sync_statusword(), 0x0208);
}

#[test]
fn fault_then_fault_reset() {
    let mut d = Dut::with(&plant("heartbeat_consumer_ms = 50\nmaster_node_id = 1"));
    enabled(&mut d);
    d.send(0x701, &[0x05]);
    d.run_for(ms(60));
    assert_eq!(d.drive.state(), State::Fault);
    assert_eq!(d.sync_statusword(), 0x0208);
    // Rising edge of bit 7 -> switch on disabled, EMCY "error reset" (all zero).
    let out = d.rpdo(0x0080, 0);
    assert_eq!(out, vec![frame(0x085, &[0; 8])]);
    assert_eq!(d.sync_statusword(), 0x0240);
    assert_eq!(
        d.sdo([0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x01, 0x10, 0x00, 0x00, 0, 0, 0]
    );
    // Holding bit 7 is no second reset; walking up works again.
    d.rpdo(0x0080, 0);
    d.rpdo(0x0006, 0);
    assert_eq!(d.sync_statusword(), 0x0231);
}

#[test]
fn heartbeat_consumer_loss_faults_within_the_consumer_time() {
    // The heartbeat consumer alone: SYNC-loss supervision (tests/sync_loss.rs) off, as no
    // SYNC comes while the heartbeats do.
    let mut d = Dut::with(&plant("sync_loss_cycles = 0"));
    // 0x1016:1 = (1 << 16) | 50 ms.
    d.sdo_ok([0x23, 0x16, 0x10, 0x01, 0x32, 0x00, 0x01, 0x00]);
    d.send(0x701, &[0x05]);
    enabled(&mut d);
    d.rpdo(0x000F, 500);
    d.sync();
    assert_eq!(d.drive.applied_torque_nm(), 0.5);
    // Heartbeats every 20 ms keep it alive.
    for _ in 0..5 {
        assert!(d.run_for(ms(20)).is_empty());
        d.send(0x701, &[0x05]);
    }
    let last = d.now;
    let got = d.run_for(ms(100));
    assert_eq!(got.len(), 1, "{got:?}");
    let (t, f) = got[0];
    // EMCY 0x8130, error register generic | communication = 0x11.
    assert_eq!(f, frame(0x085, &[0x30, 0x81, 0x11, 0, 0, 0, 0, 0]));
    let after = (t - last).as_millis();
    assert!(
        (50..=51).contains(&after),
        "detected {after} ms after the last heartbeat"
    );
    assert_eq!(d.drive.fault(), Some(FaultKind::HeartbeatLost));
    // Torque off: the next cycle holds zero, and the one after reports it.
    let out = d.sync();
    assert_eq!(tpdo1(&out).0, 0x0208);
    assert_eq!(d.drive.applied_torque_nm(), 0.0);
    assert_eq!(tpdo1(&d.sync()).2, 0);
}

#[test]
fn heartbeat_loss_outside_operation_enabled_is_no_fault() {
    let mut d = Dut::new();
    d.sdo_ok([0x23, 0x16, 0x10, 0x01, 0x32, 0x00, 0x01, 0x00]);
    d.send(0x701, &[0x05]);
    d.start();
    d.rpdo(0x0006, 0);
    d.run_for(ms(200));
    assert_eq!(d.drive.state(), State::ReadyToSwitchOn);
    // No deadline in the past for a runner to spin on.
    assert!(d.drive.next_deadline().is_none_or(|t| t > d.now));
    // Enabling with the master's heartbeat still missing faults at the next tick.
    d.rpdo(0x000F, 0);
    assert_eq!(d.run_for(ms(1)).len(), 1);
    assert_eq!(d.drive.state(), State::Fault);
}

#[test]
fn continuous_overcurrent_faults_with_emcy_2310() {
    let mut d = Dut::with(&plant(
        "continuous_torque_nm = 1.0\ni2t_time_constant_s = 0.1",
    ));
    enabled(&mut d);
    d.rpdo(0x000F, 2000);
    let mut emcy = None;
    for k in 0..2000 {
        if let Some(f) = d.sync().into_iter().find(|f| f.id().raw() == 0x085) {
            emcy = Some((k, f));
            break;
        }
    }
    let (k, f) = emcy.expect("i2t trip");
    // x = 4 (1 - exp(-t/0.1)) > 1 at t = 0.1 ln(4/3) = 28.8 ms = 57.5 cycles.
    assert!((56..=59).contains(&k), "{k}");
    // error register generic | current = 0x03.
    assert_eq!(f, frame(0x085, &[0x10, 0x23, 0x03, 0, 0, 0, 0, 0]));
}

#[test]
fn malformed_frames_never_panic_and_leave_the_drive_working() {
    let mut d = Dut::new();
    d.sdo_ok([0x2B, 0x17, 0x10, 0x00, 10, 0, 0, 0]);
    // Hand-picked: wrong DLCs, garbage SDO, NMT with junk, SYNC with 8 bytes, remote and
    // extended frames, error frames.
    let picks: Vec<flexid_can::CanFrame> = vec![
        frame(0x000, &[]),
        frame(0x000, &[0x01]),
        frame(0x000, &[0x01, 0x05, 0xFF]),
        frame(0x000, &[0x77, 0x05]),
        frame(0x605, &[0x40, 0x00, 0x10]),
        frame(0x605, &[]),
        frame(0x605, &[0xFF; 8]),
        frame(0x605, &[0x60, 0, 0, 0, 0, 0, 0, 0]),
        frame(0x605, &[0x00, 0, 0, 0, 0, 0, 0, 0]),
        frame(0x605, &[0x21, 0x08, 0x10, 0x00, 0xFF, 0xFF, 0xFF, 0xFF]),
        frame(0x605, &[0xC0, 0, 0, 0, 0, 0, 0, 0]),
        frame(0x605, &[0xA0, 0, 0, 0, 0, 0, 0, 0]),
        frame(0x080, &[1, 2, 3, 4, 5, 6, 7, 8]),
        frame(0x205, &[0x0F]),
        frame(0x205, &[0x0F, 0, 0, 0, 0, 0, 0, 0]),
        frame(0x7FF, &[0; 8]),
        frame(0x705, &[0x05, 0x05]),
        flexid_can::CanFrame::remote(flexid_can::CanId::Standard(0x605), 8).unwrap(),
        flexid_can::CanFrame::extended(0x605, &[0x40, 0, 0x10, 0, 0, 0, 0, 0]).unwrap(),
        flexid_can::CanFrame::error(0x40, [0; 8]).unwrap(),
    ];
    for f in &picks {
        d.drive.on_frame(f, d.now);
    }
    d.start();
    for f in &picks {
        d.drive.on_frame(f, d.now);
    }
    // Random frames, mostly on the drive's own COB-IDs.
    let mut x: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut rnd = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x
    };
    let cobs = [
        0x000, 0x080, 0x085, 0x185, 0x205, 0x285, 0x605, 0x585, 0x701, 0x705,
    ];
    for _ in 0..200_000 {
        let r = rnd();
        let cob = if r % 4 == 0 {
            (r >> 8) as u16 & 0x7FF
        } else {
            cobs[(r >> 8) as usize % cobs.len()]
        };
        let len = (r >> 24) as usize % 9;
        let data = rnd().to_le_bytes();
        let f = frame(cob, &data[..len]);
        d.now += std::time::Duration::from_micros(50);
        d.drive.on_frame(&f, d.now);
        d.drive.tick(d.now);
    }
    // Still working: reset node, boot-up, SDO, state machine, PDOs.
    assert_eq!(d.send(0x000, &[0x81, 0x05]), vec![frame(0x705, &[0x00])]);
    assert_eq!(
        d.sdo([0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
        [0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]
    );
    enabled(&mut d);
    assert_eq!(d.sync_statusword() & 0x6F, 0x27);
}

#[test]
fn csv_mode_tracks_a_target_velocity() {
    let mut d = Dut::new();
    d.sdo_ok([0x2F, 0x60, 0x60, 0x00, 9, 0, 0, 0]);
    // RPDO1 remapped to controlword + target velocity (0x60FF, 32 bit).
    d.sdo_ok([0x23, 0x00, 0x14, 0x01, 0x05, 0x02, 0x00, 0x80]);
    d.sdo_ok([0x2F, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
    d.sdo_ok([0x23, 0x00, 0x16, 0x02, 0x20, 0x00, 0xFF, 0x60]);
    d.sdo_ok([0x2F, 0x00, 0x16, 0x00, 2, 0, 0, 0]);
    d.sdo_ok([0x23, 0x00, 0x14, 0x01, 0x05, 0x02, 0x00, 0x00]);
    d.start();
    // 10 rad/s = 1668861 inc/s = 0x001976FD.
    let target = (10.0 * f64::from(1u32 << 20) / (2.0 * std::f64::consts::PI)).round() as i32;
    let [a, b, c, e] = target.to_le_bytes();
    for cw in [0x06u8, 0x07, 0x0F] {
        d.send(0x205, &[cw, 0, a, b, c, e]);
    }
    for _ in 0..4000 {
        d.sync();
    }
    let v = d.drive.last_sample().velocity_rad_s;
    assert!((v - 10.0).abs() < 0.2, "{v}");
    assert_eq!(d.drive.fault(), None);
}

#[test]
fn csp_mode_reaches_a_target_position() {
    let mut d = Dut::new();
    d.sdo_ok([0x2F, 0x60, 0x60, 0x00, 8, 0, 0, 0]);
    d.sdo_ok([0x23, 0x00, 0x14, 0x01, 0x05, 0x02, 0x00, 0x80]);
    d.sdo_ok([0x2F, 0x00, 0x16, 0x00, 0, 0, 0, 0]);
    d.sdo_ok([0x23, 0x00, 0x16, 0x02, 0x20, 0x00, 0x7A, 0x60]);
    d.sdo_ok([0x2F, 0x00, 0x16, 0x00, 2, 0, 0, 0]);
    d.sdo_ok([0x23, 0x00, 0x14, 0x01, 0x05, 0x02, 0x00, 0x00]);
    d.start();
    let target: i32 = 1 << 19; // half a revolution
    let [a, b, c, e] = target.to_le_bytes();
    for cw in [0x06u8, 0x07, 0x0F] {
        d.send(0x205, &[cw, 0, a, b, c, e]);
    }
    for _ in 0..6000 {
        d.sync();
    }
    let p = d.drive.last_sample().position_rad;
    assert!((p - std::f64::consts::PI).abs() < 0.02, "{p}");
}

#[test]
fn reset_communication_keeps_the_fault_and_reset_node_clears_it() {
    let mut d = Dut::with(&plant("heartbeat_consumer_ms = 50\nmaster_node_id = 1"));
    enabled(&mut d);
    d.send(0x701, &[0x05]);
    d.run_for(ms(60));
    assert_eq!(d.drive.state(), State::Fault);
    assert_eq!(d.send(0x000, &[0x82, 0x05]), vec![frame(0x705, &[0x00])]);
    assert_eq!(d.drive.state(), State::Fault);
    assert_eq!(
        d.sdo([0x40, 0x01, 0x10, 0x00, 0, 0, 0, 0]),
        [0x4F, 0x01, 0x10, 0x00, 0x11, 0, 0, 0]
    );
    assert_eq!(
        d.sdo([0x40, 0x3F, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x3F, 0x60, 0x00, 0x30, 0x81, 0, 0]
    );
    assert_eq!(d.send(0x000, &[0x81, 0x05]), vec![frame(0x705, &[0x00])]);
    assert_eq!(d.drive.state(), State::SwitchOnDisabled);
    assert_eq!(d.drive.fault(), None);
    assert_eq!(
        d.sdo([0x40, 0x41, 0x60, 0x00, 0, 0, 0, 0]),
        [0x4B, 0x41, 0x60, 0x00, 0x40, 0x02, 0, 0]
    );
}
