//! The cycle against a simulated drive (double integrator): enable, SI feedback over
//! 1000 cycles, missing/late TPDOs, an EMCY mid-run, malformed and foreign frames.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{sim_drive, SimOptions, INERTIA};
use flexid_can::InprocBus;
use flexid_canopen::cia402::State;
use flexid_canopen::{
    bring_up, Configured, CyclicDrive, Drive, Enabled, MasterConfig, MasterError, ProfileSet,
};

const NODE: u8 = 3;

struct Rig {
    stop: Arc<AtomicBool>,
    sim: Option<std::thread::JoinHandle<std::collections::HashMap<(u16, u8), u32>>>,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.sim.take() {
            let _ = h.join();
        }
    }
}

fn configured(name: &str, opts: SimOptions) -> (Drive<InprocBus, Configured>, Rig) {
    configured_with(name, opts, MasterConfig::for_node(NODE))
}

/// A drive brought up with `cfg` (its SDO and boot timeouts shortened).
fn configured_with(
    name: &str,
    opts: SimOptions,
    cfg: MasterConfig,
) -> (Drive<InprocBus, Configured>, Rig) {
    let bus = InprocBus::new(name);
    let stop = Arc::new(AtomicBool::new(false));
    let sim = sim_drive(bus.handle(), NODE, 0.001, opts, stop.clone());
    let cfg = MasterConfig {
        sdo_timeout: Duration::from_millis(300),
        boot_timeout: Duration::from_secs(1),
        ..cfg
    };
    let d = bring_up(bus, cfg, &ProfileSet::builtin()).expect("bring-up");
    (
        d,
        Rig {
            stop,
            sim: Some(sim),
        },
    )
}

fn enabled(name: &str, opts: SimOptions) -> (Drive<InprocBus, Enabled>, Rig) {
    let (d, rig) = configured(name, opts);
    (d.enable().expect("enable"), rig)
}

fn soon() -> Instant {
    Instant::now() + Duration::from_millis(200)
}

#[test]
fn thousand_cycles_give_the_integrators_si_feedback() {
    let (mut d, _rig) = enabled("cyc-1000", SimOptions::default());
    let tq = 0.1; // N m on J = 0.01 kg m^2: 10 rad/s^2
    let a = tq / INERTIA;
    let dt = 0.001;
    let quantum = std::f64::consts::TAU / 1048576.0;
    let mut last = None;
    for k in 0..1000u64 {
        let fb = d.cycle(tq, soon()).expect("cycle");
        assert!(fb.fresh, "cycle {k} not fresh");
        assert_eq!(fb.cycle, k);
        assert_eq!(fb.state, Some(State::OperationEnabled));
        assert_eq!(fb.statusword & 0x6F, 0x27);
        assert!((fb.torque_nm - tq).abs() < 1e-12, "{}", fb.torque_nm);
        assert!((fb.torque_setpoint_nm - tq).abs() < 1e-12);
        let n = (k + 1) as f64;
        let v = a * dt * n;
        let p = a * dt * dt * n * (n + 1.0) / 2.0;
        assert!(
            (fb.velocity_rad_s - v).abs() <= quantum * 1.01,
            "k={k} v={} want {v}",
            fb.velocity_rad_s
        );
        assert!(
            (fb.position_rad - p).abs() <= quantum * 0.51,
            "k={k} p={} want {p}",
            fb.position_rad
        );
        last = Some(fb);
    }
    let fb = last.unwrap();
    // after 1 s at 10 rad/s^2: 10 rad/s and about 5 rad
    assert!((fb.velocity_rad_s - 10.0).abs() < 1e-4);
    assert!((fb.position_rad - 5.005).abs() < 1e-4);
    let c = d.counters();
    assert_eq!(
        (c.cycles, c.missed, c.late, c.lost, c.malformed),
        (1000, 0, 0, 0, 0)
    );
    assert_eq!(CyclicDrive::rated_torque_nm(&d), 1.0);
    let d = d.disable().expect("disable");
    assert_eq!(d.node(), NODE);
}

#[test]
fn saturated_setpoint_is_clamped_and_counted() {
    let (mut d, _rig) = enabled("cyc-sat", SimOptions::default());
    let fb = d.cycle(40.0, soon()).unwrap(); // 40 N m = 40000 per-mille > i16
    assert!(fb.saturated);
    assert!((fb.torque_setpoint_nm - 32.767).abs() < 1e-9);
    assert_eq!(fb.counters.saturated, 1);
    let e = d.cycle(f64::NAN, soon()).unwrap_err();
    assert!(
        matches!(e, MasterError::InvalidSetpoint { node: NODE, .. }),
        "{e}"
    );
}

#[test]
fn missing_tpdo_is_counted_lost_and_a_late_one_late() {
    let opts = SimOptions {
        // SYNC numbers count from NMT start; enable takes 4 cycles (0..=3: Disable
        // voltage while the state is unknown, Shutdown, Switch on, Enable operation)
        drop_tpdo2: [11u64].into_iter().collect(),
        late_tpdo1: [21u64].into_iter().collect(),
        late_by: Duration::from_millis(30),
        ..SimOptions::default()
    };
    let (mut d, _rig) = enabled("cyc-miss", opts);
    let mut not_fresh = Vec::new();
    let t0 = Instant::now();
    for k in 0..30u32 {
        // 40 ms slots, 20 ms deadline: a TPDO 30 ms late lands between cycles
        let slot = t0 + Duration::from_millis(40) * k;
        let now = Instant::now();
        if slot > now {
            std::thread::sleep(slot - now);
        }
        let fb = d
            .cycle(0.0, slot + Duration::from_millis(20))
            .expect("cycle");
        if !fb.fresh {
            not_fresh.push(fb.cycle);
        }
    }
    assert_eq!(not_fresh, vec![7, 17], "cycles without complete feedback");
    let c = d.counters();
    // SYNC 21: the sim holds TPDO1 and so also TPDO2 behind it: both late
    assert_eq!(c.missed, 3);
    assert_eq!(c.lost, 1, "TPDO2 of SYNC 11 never came");
    assert_eq!(
        c.late, 2,
        "TPDO1 and TPDO2 of SYNC 21 came after their deadline"
    );
}

/// Runs cycles with TPDO2 dropped from SYNC 5 on; returns the error and the number of
/// cycles that passed before it.
fn cycles_until_lost(name: &str, cfg: MasterConfig) -> (MasterError, u32) {
    let opts = SimOptions {
        drop_tpdo2: (5u64..400).collect(),
        ..SimOptions::default()
    };
    let (d, _rig) = configured_with(name, opts, cfg);
    let mut d = d.enable().expect("enable");
    for ok in 0..300u32 {
        if let Err(e) = d.cycle(0.0, Instant::now() + Duration::from_millis(5)) {
            return (e, ok);
        }
    }
    panic!("no error after 300 cycles without TPDO2");
}

#[test]
fn too_many_missing_cycles_fail() {
    // the count alone (no time floor): 10 cycles
    let cfg = MasterConfig {
        max_missed_time: Duration::ZERO,
        ..MasterConfig::for_node(NODE)
    };
    assert_eq!(cfg.missed_cycles_limit(), 10);
    let (e, ok) = cycles_until_lost("cyc-lost", cfg);
    assert!(
        matches!(
            e,
            MasterError::TpdoLost {
                node: NODE,
                consecutive: 10
            }
        ),
        "{e}"
    );
    assert_eq!(
        ok, 10,
        "one complete cycle, nine incomplete pass, the tenth fails"
    );
}

#[test]
fn the_missed_cycles_limit_is_at_least_max_missed_time() {
    // default: 10 cycles and at least 50 ms of them; at 1 ms: 50 cycles
    let cfg = MasterConfig::for_node(NODE);
    assert_eq!(cfg.missed_cycles_limit(), 50);
    let (e, ok) = cycles_until_lost("cyc-lost-time", cfg);
    assert!(
        matches!(
            e,
            MasterError::TpdoLost {
                node: NODE,
                consecutive: 50
            }
        ),
        "{e}"
    );
    assert_eq!(
        ok, 50,
        "one complete cycle, 49 incomplete pass, the 50th fails"
    );
    // 4 kHz: 200 cycles (not 2.5 ms, shorter than one stall of a non-real-time host)
    let fast = MasterConfig {
        cycle_period: Duration::from_micros(250),
        ..cfg
    };
    assert_eq!(fast.missed_cycles_limit(), 200);
    // slow cycles: the count governs (10 x 20 ms)
    let slow = MasterConfig {
        cycle_period: Duration::from_millis(20),
        ..cfg
    };
    assert_eq!(slow.missed_cycles_limit(), 10);
    // a time limit the drive's heartbeat consumer would beat is refused
    let late = MasterConfig {
        max_missed_time: cfg.heartbeat_consumer_time,
        ..cfg
    };
    let msg = late
        .validate()
        .expect_err("max_missed_time >= consumer time");
    assert!(msg.contains("max_missed_time"), "{msg}");
}

#[test]
fn emcy_mid_run_stops_the_cycle_with_the_decoded_error() {
    let opts = SimOptions {
        emcy_at: Some(504), // the 501st cycle after the 4 enable cycles
        ..SimOptions::default()
    };
    let (mut d, _rig) = enabled("cyc-emcy", opts);
    let mut n = 0;
    let e = loop {
        match d.cycle(0.05, soon()) {
            Ok(_) => n += 1,
            Err(e) => break e,
        }
        assert!(n < 1000, "no error");
    };
    assert_eq!(n, 500);
    match e {
        MasterError::Emergency {
            node,
            error_code,
            register,
            data,
            text,
        } => {
            assert_eq!(
                (node, error_code, register, data),
                (NODE, 0x2310, 0x03, [1, 2, 3, 4, 5])
            );
            assert_eq!(text, "continuous over current");
        }
        other => panic!("{other}"),
    }
    // the next cycle sees the Fault statusword: a Fault error with the EMCY's code
    let e = d.cycle(0.0, soon()).unwrap_err();
    assert!(
        matches!(
            e,
            MasterError::Fault {
                node: NODE,
                error_code: 0x2310,
                register: 0x03,
                ..
            }
        ),
        "{e}"
    );
    // disable walks through the fault reset (the sim's fault stays: reset fails)
    let _ = d.disable();
}

#[test]
fn malformed_and_foreign_frames_are_counted_and_ignored() {
    let opts = SimOptions {
        garbage_at: [9u64].into_iter().collect(),
        ..SimOptions::default()
    };
    let (mut d, _rig) = enabled("cyc-garbage", opts);
    for _ in 0..5 {
        d.cycle(0.0, soon()).unwrap();
    }
    let before = d.counters();
    let fb = d
        .cycle(0.0, soon())
        .expect("garbage must not fail the cycle");
    assert!(fb.fresh);
    let after = d.counters();
    // short TPDO1, 2-byte heartbeat
    assert_eq!(after.malformed - before.malformed, 2);
    // LSS 0x7E4, garbage on 0x583, EMCY of node 4, extended-id frame
    assert_eq!(after.ignored - before.ignored, 4);
    for _ in 0..5 {
        assert!(d.cycle(0.0, soon()).unwrap().fresh);
    }
}

#[test]
fn enable_resets_a_fault_first() {
    let opts = SimOptions {
        start_in_fault: true,
        ..SimOptions::default()
    };
    let log = opts.cw_log.clone();
    let (d, _rig) = configured("cyc-reset", opts);
    let mut d = d.enable().expect("enable through fault reset");
    assert_eq!(
        d.cycle(0.0, soon()).unwrap().state,
        Some(State::OperationEnabled)
    );
    let d = d.quick_stop().expect("quick stop");
    // and enable again from Switch on disabled, NMT pre-operational
    let mut d = d.enable().expect("re-enable");
    assert!(d.cycle(0.0, soon()).unwrap().fresh);
    let mut cws = log.lock().unwrap().clone();
    cws.dedup();
    // CiA 402 controlwords, by hand: Disable voltage (state not yet known), Fault
    // reset, Shutdown, Switch on, Enable operation; Quick stop, Disable voltage;
    // again Shutdown, Switch on, Enable operation.
    assert_eq!(
        cws,
        vec![0x0000, 0x0080, 0x0006, 0x0007, 0x000F, 0x0002, 0x0000, 0x0006, 0x0007, 0x000F]
    );
}

/// A sweep written against the CAN-free interface only.
fn generic_sweep<D: CyclicDrive>(d: &mut D, n: usize) -> Result<f64, D::Error> {
    let mut last = 0.0;
    for k in 0..n {
        let fb = d.cycle(
            0.01 * (k as f64).sin(),
            Instant::now() + Duration::from_millis(200),
        )?;
        last = fb.position_rad;
    }
    Ok(last)
}

#[test]
fn drive_is_usable_through_the_can_free_trait() {
    let (mut d, _rig) = enabled("cyc-trait", SimOptions::default());
    let p = generic_sweep(&mut d, 50).unwrap();
    assert!(p.is_finite());
    assert_eq!(d.cycle_period(), Duration::from_millis(1));
    assert_eq!(CyclicDrive::counters(&d).cycles, 50);
}

#[test]
fn unknown_drive_gets_the_generic_profile_with_units_read_from_it() {
    let opts = SimOptions {
        vendor: Some(0x0000_1234),
        ..SimOptions::default()
    };
    let (d, _rig) = configured("cyc-generic", opts);
    assert_eq!(d.profile().name, "generic-cia402");
    assert_eq!(d.scaling().increments_per_rev, 10_000.0);
    assert_eq!(d.scaling().rated_torque_nm, 2.5);
    let mut d = d.enable().unwrap();
    let fb = d.cycle(0.25, soon()).unwrap(); // 100 per-mille of 2.5 N m
    assert!((fb.torque_nm - 0.25).abs() < 1e-12);
}

#[test]
fn cycle_frames_and_master_heartbeat_on_the_wire() {
    use flexid_can::CanBus;
    let bus = InprocBus::new("cyc-wire");
    let mut spy = bus.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let sim = sim_drive(
        bus.handle(),
        NODE,
        0.001,
        SimOptions::default(),
        stop.clone(),
    );
    let _rig = Rig {
        stop,
        sim: Some(sim),
    };
    let cfg = MasterConfig {
        heartbeat_period: Duration::from_millis(20),
        ..MasterConfig::for_node(NODE)
    };
    let mut d = bring_up(bus, cfg, &ProfileSet::builtin())
        .unwrap()
        .enable()
        .unwrap();
    // forget the bring-up and enable traffic
    while let Ok(Some(_)) | Err(_) = spy.recv_timeout(Duration::ZERO).map(|r| r.map(|_| ())) {}
    let t0 = Instant::now();
    let mut k = 0u32;
    while t0.elapsed() < Duration::from_millis(70) {
        d.cycle(0.1, soon()).unwrap();
        k += 1;
        std::thread::sleep(Duration::from_millis(1));
    }
    let mut frames = Vec::new();
    while let Ok(Some(r)) = spy.recv_timeout(Duration::ZERO) {
        frames.push((r.frame.id().raw(), r.frame.data().to_vec()));
    }
    // master heartbeat 0x700 + 0x7F, Operational (0x05): about every 20 ms
    let hb = frames.iter().filter(|f| *f == &(0x77F, vec![0x05])).count();
    assert!((3..=5).contains(&hb), "{hb} heartbeats in 70 ms");
    // every cycle: RPDO1 0x203 [0x0F 0x00, 100 per-mille = 0x64 0x00], then SYNC
    let rpdo = (0x203u32, vec![0x0F, 0x00, 0x64, 0x00]);
    let n = frames
        .windows(2)
        .filter(|w| w[0] == rpdo && w[1] == (0x080, vec![]))
        .count();
    assert_eq!(n as u32, k);
}
