//! The error-frame policy (issue 16, item 10): a single CAN error frame does not stop the
//! cycle; error passive, bus-off, or a burst of more than `max_frames` within `window`
//! does.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{sim_drive, SimOptions};
use flexid_can::{CanBus, CanFrame, InprocBus};
use flexid_canopen::{
    bring_up, Drive, Enabled, ErrorFramePolicy, MasterConfig, MasterError, ProfileSet,
};

const NODE: u8 = 3;

struct Rig {
    stop: Arc<AtomicBool>,
    sim: Option<std::thread::JoinHandle<std::collections::HashMap<(u16, u8), u32>>>,
    /// A third node on the bus: it "receives" the error frames the controller reports.
    injector: InprocBus,
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.sim.take() {
            let _ = h.join();
        }
    }
}

fn enabled(name: &str, policy: ErrorFramePolicy) -> (Drive<InprocBus, Enabled>, Rig) {
    let bus = InprocBus::new(name);
    let injector = bus.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let sim = sim_drive(
        bus.handle(),
        NODE,
        0.001,
        SimOptions::default(),
        stop.clone(),
    );
    let cfg = MasterConfig {
        sdo_timeout: Duration::from_millis(300),
        boot_timeout: Duration::from_secs(1),
        error_frames: policy,
        ..MasterConfig::for_node(NODE)
    };
    let d = bring_up(bus, cfg, &ProfileSet::builtin()).expect("bring-up");
    let d = d.enable().expect("enable");
    let rig = Rig {
        stop,
        sim: Some(sim),
        injector,
    };
    (d, rig)
}

fn soon() -> Instant {
    Instant::now() + Duration::from_millis(200)
}

/// A protocol-violation error frame with the controller still error active.
fn protocol_error() -> CanFrame {
    CanFrame::error(0x008, [0, 0, 0x08, 0x19, 0, 0, 0, 0]).unwrap()
}

#[test]
fn a_single_error_frame_does_not_stop_the_cycle() {
    let (mut d, mut rig) = enabled("ef-single", ErrorFramePolicy::default());
    for _ in 0..5 {
        d.cycle(0.0, soon()).unwrap();
    }
    rig.injector.send(&protocol_error()).unwrap();
    for _ in 0..20 {
        d.cycle(0.0, soon())
            .expect("one error frame is no reason to stop");
    }
    assert_eq!(d.counters().bus_errors, 1, "counted");
}

#[test]
fn error_passive_stops_the_cycle() {
    let (mut d, mut rig) = enabled("ef-passive", ErrorFramePolicy::default());
    d.cycle(0.0, soon()).unwrap();
    // controller class + counters: TX error passive, tec 130
    let passive = CanFrame::error(0x204, [0, 0x20, 0, 0, 0, 0, 130, 5]).unwrap();
    rig.injector.send(&passive).unwrap();
    let e = (0..5)
        .find_map(|_| d.cycle(0.0, soon()).err())
        .expect("error passive must stop the cycle");
    assert!(
        matches!(e, MasterError::Bus { .. }) && e.to_string().contains("error-passive"),
        "{e}"
    );
}

#[test]
fn bus_off_stops_the_cycle() {
    let (mut d, mut rig) = enabled("ef-off", ErrorFramePolicy::default());
    d.cycle(0.0, soon()).unwrap();
    rig.injector
        .send(&CanFrame::error(0x040, [0; 8]).unwrap())
        .unwrap();
    let e = (0..5)
        .find_map(|_| d.cycle(0.0, soon()).err())
        .expect("bus-off must stop the cycle");
    assert!(e.to_string().contains("bus-off"), "{e}");
}

#[test]
fn a_burst_over_the_threshold_stops_the_cycle_and_a_spread_one_does_not() {
    let policy = ErrorFramePolicy {
        max_frames: 3,
        window: Duration::from_millis(50),
    };
    // 3 frames, each 30 ms apart: never more than 3 (never even 3) within 50 ms
    let (mut d, mut rig) = enabled("ef-spread", policy);
    for _ in 0..3 {
        rig.injector.send(&protocol_error()).unwrap();
        let t = Instant::now();
        while t.elapsed() < Duration::from_millis(30) {
            d.cycle(0.0, soon())
                .expect("spread error frames are tolerated");
            std::thread::sleep(Duration::from_millis(1));
        }
    }
    drop((d, rig));
    // 4 frames at once: more than 3 within 50 ms
    let (mut d, mut rig) = enabled("ef-burst", policy);
    d.cycle(0.0, soon()).unwrap();
    for _ in 0..4 {
        rig.injector.send(&protocol_error()).unwrap();
    }
    let e = (0..5)
        .find_map(|_| d.cycle(0.0, soon()).err())
        .expect("a burst must stop the cycle");
    assert!(
        matches!(e, MasterError::ErrorFrameBurst { frames: 4, .. }),
        "{e}"
    );
    assert!(
        e.to_string().contains("4 CAN error frames within 50ms"),
        "{e}"
    );
}
