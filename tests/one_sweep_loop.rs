//! One sweep loop, two transports: `flexid_sweep::run_sweep` on the CAN-free simulated
//! drive and on the CANopen master in front of the simulated CiA 402 drive
//! (`flexid-vdrive` on an in-process bus, lock-step) give the same rows for the same plant
//! and excitation: the same torque set-points (the excitation on the drive's per-mille
//! grid of its rated torque, so the bus's torque quantisation does not move it) and the
//! same positions within half an increment of the 20-bit encoder.
//!
//! The daemon's two backends, `flexid sweep` and the demo run this same function
//! (`crates/flexid-daemon/src/drive_sweep.rs`, `src/cli/sweep.rs`).

use flexid::excitation::MultisineDesign;
use flexid::sweep::{run_sweep, Pacing, SimulatedDrive, StopReason, SweepOutcome, SweepPlan};
use flexid_can::InprocBus;
use flexid_canopen::{bring_up, CyclicDrive, MasterConfig, ProfileSet};
use flexid_vdrive::{linear_drive, ClockMode, DrivePlant, Runner};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// The master's default cycle (1000 us): the vdrive re-discretises its plant to it.
const CYCLE_HZ: f64 = 1000.0;
/// The embedded plant's encoder: 20 bits.
const COUNTS_PER_REV: f64 = 1_048_576.0;

/// A multisine of 4 periods of 500 samples, 2-200 Hz, on the per-mille grid of 1 N m.
fn plan() -> SweepPlan {
    let mut d = MultisineDesign::new(CYCLE_HZ, 500, [2.0, 200.0], 0.4, 1.0);
    d.crest_iterations = 10;
    let ms = d.generate().expect("multisine");
    SweepPlan::from_multisine(CYCLE_HZ, &ms, 3, 1, 1000.0, Pacing::Lockstep)
}

fn sweep<D: CyclicDrive>(drive: &mut D, plan: &SweepPlan) -> SweepOutcome {
    let stop = AtomicBool::new(false);
    run_sweep(drive, plan, &stop, &mut |_| {})
}

#[test]
fn simulated_and_canopen_transports_give_the_same_rows() {
    let plant = DrivePlant::parse(flexid::plant::DEFAULT_PLANT, "embedded default plant")
        .expect("default plant");
    let chain = plant.plant.chain.clone();
    let plan = plan();

    // the CAN-free simulated drive
    let mut sim = SimulatedDrive::new(&chain, CYCLE_HZ)
        .expect("simulated drive")
        .with_encoder(COUNTS_PER_REV);
    let a = sweep(&mut sim, &plan);

    // the CANopen master in front of flexid-vdrive on an in-process bus
    let vdrive = linear_drive(&plant, ClockMode::LockStep).expect("vdrive");
    let bus = InprocBus::new("one-loop");
    let h = bus.handle();
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let slave = std::thread::spawn(move || Runner::new(h, vdrive).run(&s2).unwrap());
    let drive = bring_up(bus, MasterConfig::for_node(5), &ProfileSet::builtin()).expect("bring-up");
    let mut drive = drive.enable().expect("enable");
    assert_eq!(
        drive.rated_torque_nm(),
        1.0,
        "the per-mille grid of the plan"
    );
    let b = sweep(&mut drive, &plan);
    let _ = drive.disable();
    stop.store(true, Ordering::Relaxed);
    slave.join().unwrap();

    assert_eq!(a.reason, StopReason::Complete, "simulated: {:?}", a.reason);
    assert_eq!(b.reason, StopReason::Complete, "canopen: {:?}", b.reason);
    let (ra, rb) = (&a.recording, &b.recording);
    assert_eq!(ra.len(), rb.len(), "rows");
    assert!(
        ra.len() >= plan.torque_nm.len(),
        "every planned row recorded"
    );
    assert_eq!(ra.torque_cmd_nm, rb.torque_cmd_nm, "torque set-points");
    let (pa, pb) = (
        ra.position_rad.as_ref().expect("positions"),
        rb.position_rad.as_ref().expect("positions"),
    );
    let q = std::f64::consts::TAU / COUNTS_PER_REV;
    let worst = pa
        .iter()
        .zip(pb)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    let moved = pa.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    eprintln!(
        "{} rows; worst position difference {:.3} increments; largest excursion {:.0} increments",
        ra.len(),
        worst / q,
        moved / q
    );
    assert!(moved > 100.0 * q, "the axis moved ({moved} rad)");
    assert!(
        worst <= 0.5 * q + 1e-12,
        "positions within half an increment: {worst} rad"
    );
}
