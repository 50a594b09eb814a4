//! Faults end an EtherCAT sweep safely, with the cause in the report (issue 18, item 4), in
//! process: the one sweep loop over `EcatDrive` in front of emulated CiA 402 servos at
//! 4 kHz, each cause provoked as it happens on a line:
//!
//! | cause | provoked by | stop reason |
//! |---|---|---|
//! | SubDevice lost | a SubDevice taken off the line | bus error |
//! | working counter wrong | a SubDevice's output FMMU switched off by a write | bus error |
//! | AL error | process data stopped 150 ms: the sync manager watchdog (0x001B) | drive fault |
//! | DC out of sync | SYNC0 switched off under the running servo: Fatal SYNC error (0x002C) | drive fault |
//! | missed cycles | a servo taking 2 ms per frame at a 250 us cycle, real-time pacing | feedback lost |
//! | CiA 402 fault | torque beyond the peak for 20 cycles: excess torque (0x8311) | drive fault |
//!
//! Each test checks the sweep stopped without a panic, the reason names the cause and its
//! context (which SubDevice, expected and got, the AL status code, ...), the rows up to the
//! fault are kept (as many as the cycle it stopped at), no torque ramp was run against the
//! failed drive, and the reason is the recording's `end.reason`.

mod common;

use common::{bring_up, plan, servo, servo_segment, servo_segment_with, Rig, CYCLE_HZ};
use ethercrab::Command;
use flexid_ecat::servo::{object, ERROR_EXCESS_TORQUE, ERROR_SYNC};
use flexid_ecat::{Application, EcatConfig, ServoConfig, SubDevice};
use flexid_sweep::{run_sweep, Pacing, Progress, StopReason, SweepOutcome, SweepPlan};
use futures_lite::future::block_on;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Runs `plan` on the rig's drive, calling `at_period_2` once, after the second period.
fn sweep_with_fault(
    rig: &mut Rig,
    plan: &SweepPlan,
    mut at_period_2: impl FnMut(&Progress),
) -> (SweepOutcome, u64) {
    let stop = AtomicBool::new(false);
    let mut provoked_at = None;
    let outcome = run_sweep(&mut rig.drive, plan, &stop, &mut |p| {
        if p.periods_done == 2 && provoked_at.is_none() {
            at_period_2(p);
            provoked_at = Some(p.cycle);
        }
    });
    eprintln!("stopped: {}", outcome.reason.text());
    (outcome, provoked_at.expect("the fault was provoked"))
}

/// What every fault must leave: stopped early as a drive failure, the rows up to the stop
/// kept, no ramp against the failed drive, the reason in the recording's end.
fn assert_stopped_safely(outcome: &SweepOutcome, provoked_at: u64, plan: &SweepPlan) {
    assert!(!outcome.complete());
    assert!(outcome.reason.drive_failed(), "{:?}", outcome.reason);
    assert_eq!(outcome.ramp_cycles, 0, "no ramp against a failed drive");
    let rows = outcome.recording.len() as u64;
    assert_eq!(rows, outcome.end.cycle, "every row up to the stop kept");
    assert!(rows >= provoked_at, "{rows} rows, fault at {provoked_at}");
    assert!(rows < plan.torque_nm.len() as u64);
    assert!(!outcome.end.complete);
    assert_eq!(outcome.end.reason, outcome.reason.text());
    let sidecar_end = outcome.recording.sidecar.end.as_ref().expect("end");
    assert_eq!(sidecar_end.reason, outcome.reason.text());
}

/// An FPWR of `value` to `register` of the SubDevice at station `address`, as any
/// MainDevice write on the line.
fn write_register(md: &ethercrab::MainDevice<'_>, address: u16, register: u16, value: u8) {
    block_on(Command::fpwr(address, register).send(md, value)).expect("register written");
}

/// The servo's error code 0x603F as the emulated dictionary holds it.
fn error_code(segment: &flexid_ecat::inprocess::SharedSegment, position: usize) -> u16 {
    let seg = segment.lock().expect("segment");
    let od = seg.subdevice(position).expect("servo").dictionary();
    od.get(object::ERROR_CODE, 0)
        .and_then(|b| b.try_into().ok())
        .map_or(0, u16::from_le_bytes)
}

#[test]
fn a_subdevice_lost_is_a_bus_error_naming_it_and_the_working_counter() {
    // Two servos; the sweep drives the first, the second is pulled off the line.
    let seg = servo_segment(2);
    let mut rig = bring_up(seg.clone());
    let plan = plan(400, 6);
    let (outcome, at) = sweep_with_fault(&mut rig, &plan, |_| {
        assert!(seg.lock().expect("segment").remove(1).is_some());
    });
    let StopReason::BusError(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    assert!(text.contains("SubDevice lost"), "{text}");
    assert!(text.contains("SubDevice 1 (0x1001)"), "{text}");
    assert!(text.contains("working counter 3, expected 6"), "{text}");
    assert_eq!(outcome.recording.len() as u64, at, "rows up to the drop");
    assert_stopped_safely(&outcome, at, &plan);
}

#[test]
fn a_wrong_working_counter_is_a_bus_error_with_expected_and_got() {
    // Both servos stay in OP, but the second one's output FMMU (FMMU 0) is switched off:
    // its outputs are no longer written, the LRW counts 2 less.
    let seg = servo_segment(2);
    let mut rig = bring_up(seg);
    let md = rig.md;
    let plan = plan(400, 6);
    let (outcome, at) = sweep_with_fault(&mut rig, &plan, |_| {
        write_register(md, 0x1001, 0x060C, 0);
    });
    let StopReason::BusError(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    assert!(text.contains("working counter 4, expected 6"), "{text}");
    assert!(text.contains("2 SubDevices"), "{text}");
    assert_eq!(outcome.end.cycle, at, "stopped at the first wrong exchange");
    assert_stopped_safely(&outcome, at, &plan);
}

#[test]
fn process_data_stopped_past_the_watchdog_is_an_al_error_with_its_code() {
    let seg = servo_segment(1);
    // A real ESC's power-up watchdog: 1000 units of 100 us.
    seg.lock()
        .expect("segment")
        .subdevice_mut(0)
        .expect("servo")
        .set_sm_watchdog_time(1000);
    let mut rig = bring_up(seg.clone());
    let plan = plan(400, 6);
    // The master stalls 150 ms: longer than the ESC's 100 ms sync manager watchdog.
    let (outcome, at) = sweep_with_fault(&mut rig, &plan, |_| {
        std::thread::sleep(Duration::from_millis(150))
    });
    let StopReason::DriveFault(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    assert!(text.contains("AL error"), "{text}");
    assert!(text.contains("SubDevice 0 (0x1000) left OP"), "{text}");
    assert!(text.contains("AL status code 0x001b"), "{text}");
    assert_stopped_safely(&outcome, at, &plan);
    // The servo dropped its torque: Fault with the synchronisation's error code.
    assert_eq!(error_code(&seg, 0), ERROR_SYNC);
}

#[test]
fn sync0_lost_under_the_running_servo_is_dc_out_of_sync() {
    let seg = servo_segment(1);
    let mut rig = bring_up(seg.clone());
    let md = rig.md;
    let plan = plan(400, 6);
    // SYNC0 switched off (sync activation 0x0981 = 0): the servo's SYNC0 signal stops.
    let (outcome, at) = sweep_with_fault(&mut rig, &plan, |_| {
        write_register(md, 0x1000, 0x0981, 0);
    });
    let StopReason::DriveFault(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    assert!(text.contains("DC out of sync"), "{text}");
    assert!(text.contains("SubDevice 0 (0x1000)"), "{text}");
    assert!(text.contains("AL status code 0x002c"), "{text}");
    assert_eq!(outcome.end.cycle, at, "stopped at the first exchange after");
    assert_stopped_safely(&outcome, at, &plan);
    assert_eq!(error_code(&seg, 0), ERROR_SYNC);
}

/// A servo that takes `delay_us` (shared, 0 at first) to latch its inputs: a drive whose
/// process-data handling outlasts the cycle.
#[derive(Debug)]
struct Slow {
    inner: Box<dyn Application>,
    delay_us: Arc<Mutex<u64>>,
}

impl Application for Slow {
    fn latch_inputs(&mut self, device: &mut SubDevice) {
        let us = *self.delay_us.lock().expect("delay");
        if us > 0 {
            std::thread::sleep(Duration::from_micros(us));
        }
        self.inner.latch_inputs(device);
    }

    fn apply_outputs(&mut self, device: &mut SubDevice) {
        self.inner.apply_outputs(device);
    }
}

#[test]
fn exchanges_ending_after_their_deadline_in_a_row_are_missed_cycles() {
    let (mut device, servo) = servo(&ServoConfig::from_plant(&common::plant()), 0);
    device.set_sm_watchdog_time(flexid_ecat::emulated::LOCKSTEP_WATCHDOG_UNITS);
    let delay_us = Arc::new(Mutex::new(0));
    let mut segment = flexid_ecat::Segment::new();
    segment.push_with(
        device,
        Box::new(Slow {
            inner: servo,
            delay_us: delay_us.clone(),
        }),
    );
    let mut rig = bring_up(Arc::new(Mutex::new(segment)));
    let mut plan = plan(400, 6);
    plan.pacing = Pacing::Realtime;
    let (outcome, at) = sweep_with_fault(&mut rig, &plan, |_| {
        *delay_us.lock().expect("delay") = 2_000;
    });
    let StopReason::FeedbackLost(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    // the budget: 50 ms of cycles at 4 kHz (the count alone, 10, is shorter)
    let budget = EcatConfig::at_hz(CYCLE_HZ).missed_cycles_limit();
    assert_eq!(budget, 200);
    assert!(
        text.contains(&format!(
            "missed cycles: {} exchanges in a row ended after their deadline",
            budget + 1
        )),
        "{text}"
    );
    assert!(
        text.contains(&format!("budget {budget}, cycle 250 us")),
        "{text}"
    );
    assert_stopped_safely(&outcome, at, &plan);
    assert!(outcome.counters.missed > u64::from(budget));
    assert_eq!(CYCLE_HZ, 4000.0);
}

#[test]
fn torque_beyond_the_peak_for_too_long_is_a_cia402_fault_with_its_error_code() {
    let config = ServoConfig {
        overtorque_cycles: 20,
        ..ServoConfig::from_plant(&common::plant())
    };
    let seg = servo_segment_with(1, &config);
    let mut rig = bring_up(seg.clone());
    let mut plan = plan(400, 6);
    // From cycle 1000 on the set-point asks 5 N m of a drive with a 3 N m peak.
    for t in &mut plan.torque_nm[1000..] {
        *t = 5.0;
    }
    let stop = AtomicBool::new(false);
    let outcome = run_sweep(&mut rig.drive, &plan, &stop, &mut |_| {});
    eprintln!("stopped: {}", outcome.reason.text());
    let StopReason::DriveFault(text) = &outcome.reason else {
        panic!("stop reason {:?}", outcome.reason);
    };
    assert!(text.contains("drive fault"), "{text}");
    assert!(text.contains("error code 0x603F = 0x8311"), "{text}");
    // 20 clamped cycles, then Fault reaction active shows in the next statusword.
    assert!(
        (1020..=1022).contains(&outcome.end.cycle),
        "stopped at {}",
        outcome.end.cycle
    );
    assert_stopped_safely(&outcome, 1000, &plan);
    assert_eq!(error_code(&seg, 0), ERROR_EXCESS_TORQUE);
}
