//! The physics through the protocol: the lock-step drive on an `InprocBus`, driven by a
//! torque sequence through RPDO1 + SYNC, against `flexid_core::sim::simulate_position`; and
//! the real-time clock.

mod common;
use common::*;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Duration;

use flexid_can::{CanBus, CanFrame, InprocBus};
use flexid_vdrive::{linear_drive, ClockMode, Runner};

fn recv_until(bus: &mut InprocBus, cob: u32) -> CanFrame {
    loop {
        let r = bus
            .recv_timeout(Duration::from_secs(5))
            .expect("bus")
            .unwrap_or_else(|| panic!("no frame 0x{cob:03X} within 5 s"));
        if r.frame.id().raw() == cob {
            return r.frame;
        }
    }
}

#[test]
fn lockstep_tpdo_positions_match_flexid_sim() {
    let p = plant("");
    let chain = p.plant.chain.clone();
    let drive = linear_drive(&p, ClockMode::LockStep).unwrap();
    let mut master = InprocBus::new("physics");
    let bus = master.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let stop2 = stop.clone();
    let th = std::thread::spawn(move || {
        let mut r = Runner::new(bus, drive);
        r.run(&stop2).unwrap();
    });
    assert_eq!(recv_until(&mut master, 0x705).data(), &[0x00], "boot-up");
    let send = |m: &mut InprocBus, cob: u16, d: &[u8]| m.send(&frame(cob, d)).unwrap();
    send(&mut master, 0x000, &[0x01, 0x05]);
    for cw in [0x0006u16, 0x0007, 0x000F] {
        let [a, b] = cw.to_le_bytes();
        send(&mut master, 0x205, &[a, b, 0, 0]);
    }
    // A torque sequence in per-mille of 1 N m: two sines and a small offset.
    let n = 4000;
    let permille: Vec<i16> = (0..n)
        .map(|k| {
            let t = k as f64 / 2000.0;
            (400.0 * (2.0 * std::f64::consts::PI * 7.0 * t).sin()
                + 250.0 * (2.0 * std::f64::consts::PI * 410.0 * t).sin()
                + 30.0)
                .round() as i16
        })
        .collect();
    let mut got_pos = Vec::with_capacity(n);
    let mut got_tq = Vec::with_capacity(n);
    for &tq in &permille {
        let [a, b] = tq.to_le_bytes();
        send(&mut master, 0x205, &[0x0F, 0x00, a, b]);
        send(&mut master, 0x080, &[]);
        let t1 = recv_until(&mut master, 0x185);
        let d = t1.data();
        assert_eq!(u16::from_le_bytes([d[0], d[1]]), 0x1237);
        got_pos.push(i32::from_le_bytes([d[2], d[3], d[4], d[5]]));
        got_tq.push(i16::from_le_bytes([d[6], d[7]]));
        recv_until(&mut master, 0x285);
    }
    stop.store(true, Ordering::Relaxed);
    th.join().unwrap();

    let torque_nm: Vec<f64> = permille.iter().map(|&t| f64::from(t) / 1000.0).collect();
    let opts = flexid_core::sim::SimOptions {
        sample_rate_hz: 2000.0,
        ..Default::default()
    };
    let want = flexid_core::sim::simulate_position(&chain, &torque_nm, &opts).unwrap();
    let inc = f64::from(1u32 << 20) / (2.0 * std::f64::consts::PI);
    let mut worst = 0.0f64;
    for k in 0..n {
        let err = (f64::from(got_pos[k]) - want[k] * inc).abs();
        worst = worst.max(err);
        assert!(
            err <= 0.5 + 1e-6,
            "sample {k}: {} vs {}",
            got_pos[k],
            want[k] * inc
        );
    }
    // The axis really moved (many increments), and TPDO k carries torque k-1.
    assert!(want.iter().map(|p| (p * inc).abs()).fold(0.0, f64::max) > 1000.0);
    assert_eq!(got_tq[0], 0);
    assert_eq!(&got_tq[1..], &permille[..n - 1]);
    eprintln!("worst position error {worst:.3} increments");
}

#[test]
fn realtime_clock_integrates_whole_elapsed_cycles() {
    let p = plant("");
    let chain = p.plant.chain.clone();
    let drive = linear_drive(&p, ClockMode::RealTime).unwrap();
    let mut d = Dut::from_drive(drive);
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    d.rpdo(0x000F, 200);
    // SYNCs at t = 0, 1.6 ms (3 cycles of 0.5 ms elapsed -> +2 extra), 1.7 ms (none due),
    // 5.0 ms.
    let times_us = [0u64, 1600, 1700, 5000];
    let mut pos = Vec::new();
    for t in times_us {
        d.now = Duration::from_micros(t);
        let out = d.sync();
        let f = out.iter().find(|f| f.id().raw() == 0x185).unwrap();
        pos.push(f.data()[2..6].to_vec());
    }
    // Plant cycles: SYNC0 samples cycle 0 then steps to 1; SYNC1 catches up to 3 and
    // samples 3 -> 4; SYNC2 samples 4 -> 5; SYNC3 catches up to 10, samples 10.
    assert_eq!(d.drive.stats().cycles, 11);
    let torque = vec![0.2; 11];
    let opts = flexid_core::sim::SimOptions {
        sample_rate_hz: 2000.0,
        ..Default::default()
    };
    let want = flexid_core::sim::simulate_position(&chain, &torque, &opts).unwrap();
    let inc = f64::from(1u32 << 20) / (2.0 * std::f64::consts::PI);
    for (i, k) in [0usize, 3, 4, 10].into_iter().enumerate() {
        let got = i32::from_le_bytes(pos[i].clone().try_into().unwrap());
        assert!(
            (f64::from(got) - want[k] * inc).abs() <= 0.5 + 1e-6,
            "SYNC {i}"
        );
    }
}

#[test]
fn master_sets_the_cycle_period_and_the_plant_follows() {
    // The master writes 0x1006 = 1000 us (1 kHz) while the plant file says 2 kHz.
    let p = plant("");
    let chain = p.plant.chain.clone();
    let mut d = Dut::with(&p);
    d.sdo_ok([0x23, 0x06, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00]);
    assert_eq!(
        d.sdo([0x40, 0x06, 0x10, 0x00, 0, 0, 0, 0]),
        [0x43, 0x06, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00]
    );
    // Out of range (10 us): 0x06090030.
    assert_eq!(
        d.sdo([0x23, 0x06, 0x10, 0x00, 0x0A, 0x00, 0x00, 0x00]),
        [0x80, 0x06, 0x10, 0x00, 0x30, 0x00, 0x09, 0x06]
    );
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    let permille: Vec<i16> = (0..500).map(|k| ((k * 37 % 200) as i16) - 60).collect();
    let mut got = Vec::new();
    for &t in &permille {
        d.rpdo(0x000F, t);
        let out = d.sync();
        let f = out.iter().find(|f| f.id().raw() == 0x185).unwrap();
        got.push(i32::from_le_bytes(f.data()[2..6].try_into().unwrap()));
    }
    let torque: Vec<f64> = permille.iter().map(|&t| f64::from(t) / 1000.0).collect();
    let opts = flexid_core::sim::SimOptions {
        sample_rate_hz: 1000.0,
        ..Default::default()
    };
    let want = flexid_core::sim::simulate_position(&chain, &torque, &opts).unwrap();
    let inc = f64::from(1u32 << 20) / (2.0 * std::f64::consts::PI);
    for k in 0..torque.len() {
        assert!(
            (f64::from(got[k]) - want[k] * inc).abs() <= 0.5 + 1e-6,
            "sample {k}"
        );
    }
    // Reset communication restores the plant file's 500 us.
    d.send(0x000, &[0x82, 0x05]);
    assert_eq!(
        d.sdo([0x40, 0x06, 0x10, 0x00, 0, 0, 0, 0]),
        [0x43, 0x06, 0x10, 0x00, 0xF4, 0x01, 0x00, 0x00]
    );
    assert_eq!(d.drive.config().cycle_hz, 2000.0);
}
