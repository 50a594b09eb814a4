//! The EtherCAT veth tier (issue 18): `flexid-vdrive --ethercat` serving an emulated CiA
//! 402 servo in front of `plants/e2e_3mass.toml` on one end of a veth pair inside a network
//! namespace this test creates, ethercrab's stock `std::tx_rx_task` on the other end in
//! this process, and flexid's EtherCAT transport (`flexid_ecat::EcatDrive`) over it, at
//! 4 kHz:
//!
//! * bring-up, then a lock-step sweep (the servo steps one cycle per process-data frame);
//! * bring-up, then a real-time sweep on the real-time cycle thread (the servo on its SYNC0
//!   clock, the sweep's cycles on the SYNC0 grid the drive located), with the missed
//!   cycles and working-counter errors reported;
//!
//! each identifying the plant's inertias and stiffnesses within 3 %. Skips when not root
//! or without `ip`; fails instead under `FLEXID_VETH_REQUIRED=1` or `CI=true`.

mod veth;

use flexid_canopen::CyclicDrive;
use flexid_core::analysis::{analyze, AnalysisOptions};
use flexid_core::excitation::MultisineDesign;
use flexid_core::plant::PlantFile;
use flexid_core::recording::Recording;
use flexid_ecat::{EcatConfig, EcatDrive};
use flexid_sweep::{realtime_setup, run_sweep, run_sweep_on_cycle_thread, Pacing, StopReason};
use flexid_sweep::{SweepOutcome, SweepPlan};
use std::sync::atomic::AtomicBool;
use std::sync::Mutex;
use std::time::Instant;
use veth::{counter, main_device, Emulator, Veth, MAX_PDI, MAX_SUBDEVICES};

/// The cycle rate of both sweeps: out of CAN's reach.
const CYCLE_HZ: f64 = 4000.0;
/// One veth test at a time (they time real cycles on a shared machine).
static SERIAL: Mutex<()> = Mutex::new(());

fn plant() -> PlantFile {
    let text = std::fs::read_to_string(veth::plant_path()).expect("plant file");
    PlantFile::parse(&text, "plants/e2e_3mass.toml").expect("plant file")
}

/// A multisine at 4 kHz on the per-mille grid of 1 N m: 0.5 Hz lines (8000 samples),
/// 1 transient + 4 periods, 1-500 Hz.
fn plan(pacing: Pacing) -> SweepPlan {
    let (period, periods) = (8000, 4);
    let mut design = MultisineDesign::new(CYCLE_HZ, period, [1.0, 500.0], 0.8, 0.4);
    design.crest_iterations = 10;
    let ms = design.generate().expect("multisine");
    SweepPlan::from_multisine(CYCLE_HZ, &ms, periods, 1, 1000.0, pacing)
}

/// The drive brought up over the veth pair's host end.
fn bring_up(veth: &Veth, config: EcatConfig) -> EcatDrive<'static, MAX_SUBDEVICES, MAX_PDI> {
    let md = main_device(&veth.host, 85);
    let t0 = Instant::now();
    let group = futures_lite::future::block_on(
        md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercrab::std::ethercat_now),
    )
    .expect("discovery over the veth pair");
    assert_eq!(group.len(), 1, "one emulated servo");
    let drive = EcatDrive::bring_up(md, group, config).expect("bring-up over the veth pair");
    {
        let sd = drive.group().subdevice(md, 0).expect("SubDevice 0");
        let id = sd.identity();
        assert_eq!(
            (id.vendor_id, id.product_id),
            (
                flexid_vdrive::ethercat::VENDOR_ID,
                flexid_vdrive::ethercat::PRODUCT_CODE
            )
        );
        assert_eq!(sd.name(), "FLEXID-SERVO0");
    }
    eprintln!(
        "bring-up over {} in {:.0} ms: {} process-data exchanges to Operation enabled, SYNC0 \
         located from a {:?} round trip",
        veth.host,
        t0.elapsed().as_secs_f64() * 1e3,
        drive.exchanges(),
        drive.sync0_round_trip()
    );
    assert_eq!(drive.rated_torque_nm(), 1.0);
    assert_eq!(drive.scaling().increments_per_rev, 1_048_576.0);
    drive
}

/// Identifies the 3-mass chain from `rec` and checks every J and c within `tol`.
fn assert_identified(rec: &Recording, tol: f64) {
    let analysis = analyze(
        rec,
        &AnalysisOptions {
            masses: Some(3),
            ..AnalysisOptions::default()
        },
    )
    .expect("analysis");
    let model = analysis.model.expect("a model");
    let want = plant().chain;
    flexid_core::model::truth::assert_within(
        (&model.inertia_kgm2, &model.stiffness_nm_per_rad),
        (&want.inertia_kgm2, &want.stiffness_nm_per_rad),
        tol,
    );
}

fn report(what: &str, outcome: &SweepOutcome) {
    let c = outcome.counters;
    eprintln!(
        "{what}: {} cycles in {:.2} s ({:.0} cycles/s), {}; master: feedback missed {} (late \
         {}, lost {}), schedule overruns {}; working-counter errors: {}; frames that passed \
         the drive after their cycle {}, in the cycle before {}; held rows {}",
        outcome.recording.len(),
        outcome.elapsed.as_secs_f64(),
        outcome.cycles_per_s(),
        outcome.reason.text(),
        c.missed,
        c.late,
        c.lost,
        outcome.overruns,
        // EcatDrive stops the sweep at the first wrong working counter.
        if outcome.complete() {
            "0".to_string()
        } else {
            format!("stopped: {}", outcome.reason.text())
        },
        outcome.placement.late_passes,
        outcome.placement.replaced_setpoints,
        outcome.held_rows,
    );
}

/// The drive, recording where in the SYNC0 cycle each exchange's frame passed the servo.
struct Phased<'a> {
    drive: &'a mut EcatDrive<'static, MAX_SUBDEVICES, MAX_PDI>,
    phases_us: Vec<u32>,
}

impl CyclicDrive for Phased<'_> {
    type Error = flexid_ecat::EcatError;
    fn cycle(
        &mut self,
        torque_nm: f64,
        deadline: Instant,
    ) -> Result<flexid_canopen::Feedback, Self::Error> {
        let fb = self.drive.cycle(torque_nm, deadline);
        if self.phases_us.len() < self.phases_us.capacity() {
            self.phases_us
                .push((self.drive.last_sync0_phase_ns() / 1000) as u32);
        }
        fb
    }
    fn cycle_period(&self) -> std::time::Duration {
        self.drive.cycle_period()
    }
    fn rated_torque_nm(&self) -> f64 {
        self.drive.rated_torque_nm()
    }
    fn counters(&self) -> flexid_canopen::Counters {
        self.drive.counters()
    }
    fn cycle_grid(&self) -> Option<Instant> {
        self.drive.cycle_grid()
    }
    fn grid_io_delay_cycles(&self) -> u32 {
        self.drive.grid_io_delay_cycles()
    }
}

#[test]
fn veth_bring_up_and_a_lockstep_sweep_at_4_khz_identify_the_plant() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(veth) = Veth::create_or_skip("lock-step sweep over veth") else {
        return;
    };
    let mut emulator = Emulator::start(&veth, &["--cycle-hz", "4000", "--clock", "lockstep"]);
    let plan = plan(Pacing::Lockstep);
    let mut drive = bring_up(&veth, EcatConfig::at_hz(CYCLE_HZ));
    let stop = AtomicBool::new(false);
    let outcome = run_sweep(&mut drive, &plan, &stop, &mut |_| {});
    report("lock-step sweep over veth", &outcome);
    assert_eq!(outcome.reason, StopReason::Complete, "{:?}", outcome.reason);
    assert_eq!(outcome.counters.missed, 0);
    drive.disable().expect("disable");
    let stderr = emulator.stop();
    eprintln!("emulator: {}", stderr.trim());
    // Every exchange answered: the frames returned are those received.
    let (received, returned) = (
        counter(&stderr, "frames received").expect("received"),
        counter(&stderr, "returned").expect("returned"),
    );
    assert_eq!(received, returned, "{stderr}");
    assert!(
        counter(&stderr, "cycles").expect("cycles") >= plan.torque_nm.len() as u64,
        "{stderr}"
    );
    assert_identified(&outcome.recording, 0.03);
}

#[test]
fn veth_bring_up_and_a_realtime_sweep_at_4_khz_on_the_sync0_clock_identify_the_plant() {
    let _serial = SERIAL.lock().unwrap_or_else(|e| e.into_inner());
    let Some(veth) = Veth::create_or_skip("real-time sweep over veth") else {
        return;
    };
    let mut emulator = Emulator::start(
        &veth,
        &[
            "--cycle-hz",
            "4000",
            "--clock",
            "realtime",
            "--fifo-priority",
            "90",
        ],
    );
    let plan = plan(Pacing::Realtime);
    // On the SYNC0 clock the statusword changes once per pulse, not per exchange: the walk
    // may take many exchanges.
    let config = EcatConfig {
        enable_exchanges: 2000,
        ..EcatConfig::at_hz(CYCLE_HZ)
    };
    let mut drive = bring_up(&veth, config);
    assert!(drive.cycle_grid().is_some(), "SYNC0 located");
    let stop = AtomicBool::new(false);
    let mut phased = Phased {
        drive: &mut drive,
        phases_us: Vec::with_capacity(plan.torque_nm.len() + 1000),
    };
    let (outcome, granted) =
        run_sweep_on_cycle_thread(&mut phased, &plan, &stop, &mut |_| {}, realtime_setup());
    let mut ph = phased.phases_us.clone();
    ph.sort_unstable();
    let q = |f: f64| ph[((ph.len() - 1) as f64 * f) as usize];
    eprintln!(
        "frame arrival after SYNC0 (us): min {} p1 {} p50 {} p99 {} max {}",
        q(0.0),
        q(0.01),
        q(0.5),
        q(0.99),
        q(1.0)
    );
    eprintln!("cycle thread: SCHED_FIFO {:?}", granted.fifo_priority);
    report("real-time sweep over veth", &outcome);
    let _ = drive.disable();
    let stderr = emulator.stop();
    eprintln!("emulator: {}", stderr.trim());
    assert_eq!(outcome.reason, StopReason::Complete, "{:?}", outcome.reason);
    let cycles = plan.torque_nm.len() as u64;
    let pulses = counter(&stderr, "SYNC0 pulses").expect("pulses");
    let missed = counter(&stderr, "missed cycles").expect("missed");
    let overwritten = counter(&stderr, "overwritten set-points").expect("overwritten");
    eprintln!(
        "servo: {pulses} SYNC0 pulses, {missed} missed cycles ({:.3} % of {cycles}), \
         {overwritten} overwritten set-points",
        100.0 * missed as f64 / cycles as f64
    );
    // The plant ran on the SYNC0 clock: one cycle per pulse over the sweep's wall time,
    // whatever the frames did.
    assert!(pulses >= cycles, "{pulses} pulses for {cycles} cycles");
    // Missed cycles (a SYNC0 pulse with no frame since the last: the servo holds its
    // torque) are the host's, not the code's: 1.3-2.2 % on this VM, 3.2 % on a loaded
    // 2-core CI runner. No fixed share is asserted. What bounds them is the servo's own
    // watchdog (a run of `--fault-after-missed` faults it and the sweep would not be
    // `Complete`, checked above); what makes them harmless is that the recording says
    // what the servo did: each frame's DC time places it at its SYNC0 cycle
    // (`Feedback::drive_cycle`), so the cycles a late frame let pass are held rows with
    // the held torque (held rows ~ missed cycles, printed above). Before that, 2 % missed
    // cycles left J3 up to 2.9 % off; since, within 0.7 %. The outcome below: the plant
    // identified within 3 % from what the sweep recorded.
    // Inputs latched at SYNC0 pulse k are read by the frame after it, which carries the
    // torque pulse k + 1 applies: one cycle of I/O delay, which the drive reports
    // (`grid_io_delay_cycles`), the sweep writes into the recording and the analysis takes
    // out (measured once: with 0 or 2 instead, J2 came out 3.1 and 3.4 % off; with 1,
    // every J and c within 0.22 %).
    let rec = &outcome.recording;
    assert_eq!(rec.sidecar.io_delay_samples, Some(1));
    assert_identified(rec, 0.03);
}
