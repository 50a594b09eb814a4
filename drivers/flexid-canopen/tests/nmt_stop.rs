//! NMT stop mid-run (issue 16, item 11): a stopped node answers no PDO and no SDO, so the
//! master, told so by the drive's heartbeat (state 0x04), ends the run and its disable
//! promptly instead of walking the CiA 402 state machine into its 2 s timeout.

mod common;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use common::{sim_drive, SimOptions};
use flexid_can::{CanBus, CanFrame, InprocBus};
use flexid_canopen::{bring_up, MasterConfig, MasterError, ProfileSet};

const NODE: u8 = 3;

#[test]
fn a_stopped_drive_ends_the_run_and_the_disable_promptly() {
    let bus = InprocBus::new("nmt-stop");
    let mut other = bus.handle(); // another node: sends the NMT stop, plays the heartbeat
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
        ..MasterConfig::for_node(NODE)
    };
    let d = bring_up(bus, cfg, &ProfileSet::builtin()).expect("bring-up");
    let mut d = d.enable().expect("enable");
    for _ in 0..5 {
        d.cycle(0.0, Instant::now() + Duration::from_millis(200))
            .unwrap();
    }
    // NMT stop to the drive, and its heartbeat from then on: stopped (0x04)
    other
        .send(&CanFrame::standard(0x000, &[0x02, NODE]).unwrap())
        .unwrap();
    other
        .send(&CanFrame::standard(0x700 + u16::from(NODE), &[0x04]).unwrap())
        .unwrap();
    let e = (0..20)
        .find_map(|_| {
            d.cycle(0.0, Instant::now() + Duration::from_millis(20))
                .err()
        })
        .expect("the run ends");
    assert!(
        matches!(e, MasterError::NmtStateChanged { state: 0x04, .. }),
        "{e}"
    );
    let t = Instant::now();
    let r = d.disable();
    let took = t.elapsed();
    let e = r.expect_err("a stopped drive cannot be walked to Switch on disabled");
    assert!(matches!(e, MasterError::NmtStopped { node: NODE }), "{e}");
    assert!(e.to_string().contains("NMT stopped"), "{e}");
    assert!(
        took < Duration::from_millis(200),
        "disable took {took:?} (the state timeout is 2 s)"
    );
    stop.store(true, Ordering::Relaxed);
    let _ = sim.join();
}
