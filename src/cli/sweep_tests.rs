//! The sweep loop over the CAN-free simulated drive.

use crate::analysis::{analyze, AnalysisOptions};
use crate::cli::sweep::{admit, plan, SweepArgs};
use crate::cli::{Cli, Command};
use crate::model::Chain;
use crate::recording::{parse_sidecar, read_recording, write_recording};
use clap::Parser;
use flexid_sweep::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// The chain of `plants/e2e_3mass.toml`: AR/R 15/25 Hz and 150/240 Hz, J = 0.01 kg m^2.
fn e2e_chain() -> Chain {
    Chain::new(
        vec![1.406e-3, 2.284e-3, 6.309e-3],
        vec![1971.0, 57.7],
        vec![0.03, 0.01],
    )
    .unwrap()
}

fn args(extra: &[&str]) -> SweepArgs {
    let mut v = vec![
        "flexid",
        "sweep",
        "--bus",
        "udp",
        "--clock",
        "lockstep",
        "--cycle-hz",
        "1000",
    ];
    v.extend_from_slice(extra);
    match Cli::try_parse_from(v).unwrap().command {
        Command::Sweep(a) => a,
        _ => unreachable!(),
    }
}

fn quiet(_: &Progress) {}

/// The recording identifies `chain` as 3 masses, every inertia and stiffness within 3 %.
fn assert_identifies_within_3_percent(rec: &crate::recording::Recording, chain: &Chain) {
    let an = analyze(
        rec,
        &AnalysisOptions {
            masses: Some(3),
            ..AnalysisOptions::default()
        },
    )
    .unwrap();
    let m = an.model.expect("a model");
    for (got, want) in m.inertia_kgm2.iter().zip(&chain.inertia_kgm2).chain(
        m.stiffness_nm_per_rad
            .iter()
            .zip(&chain.stiffness_nm_per_rad),
    ) {
        assert!(
            ((got - want) / want).abs() < 0.03,
            "identified {got}, true {want}"
        );
    }
}

#[test]
fn sweep_over_simulated_drive_identifies_three_mass_chain() {
    let chain = e2e_chain();
    let p = plan(&args(&[])).unwrap();
    assert_eq!(p.excitation.period_samples, 2000);
    assert_eq!(p.torque_nm.len(), 9 * 2000);
    let mut drive = SimulatedDrive::new(&chain, 1000.0)
        .unwrap()
        .with_encoder(1048576.0);
    let stop = AtomicBool::new(false);
    let mut reports = 0;
    let out = run_sweep(&mut drive, &p, &stop, &mut |_| reports += 1);
    assert!(out.complete(), "{:?}", out.reason);
    assert_eq!(reports, 9);
    assert_eq!(out.recording.len(), 18000);
    assert_eq!(out.ramp_cycles, p.ramp_cycles);
    assert_eq!(out.counters.cycles, 18000 + p.ramp_cycles as u64);
    let end = out.recording.sidecar.end.clone().unwrap();
    assert!(end.complete);
    assert_eq!(end.cycle, 18000);
    // row k = (torque_k, position before torque k): the first row is at rest
    assert_eq!(out.recording.position_rad.as_ref().unwrap()[0], 0.0);
    assert_identifies_within_3_percent(&out.recording, &chain);
}

#[test]
fn fault_mid_sweep_keeps_the_rows_and_says_why() {
    let p = plan(&args(&["--periods", "2"])).unwrap();
    let mut drive = SimulatedDrive::new(&e2e_chain(), 1000.0)
        .unwrap()
        .fault_at(1234);
    let stop = AtomicBool::new(false);
    let out = run_sweep(&mut drive, &p, &stop, &mut quiet);
    assert!(!out.complete());
    assert!(
        matches!(out.reason, StopReason::DriveFault(_)),
        "{:?}",
        out.reason
    );
    assert_eq!(out.recording.len(), 1234);
    assert_eq!(out.ramp_cycles, 0, "no ramp on a faulted drive");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.csv");
    write_recording(&path, &out.recording).unwrap();
    let back = read_recording(&path).unwrap();
    assert_eq!(back.len(), 1234);
    assert_eq!(back.torque_actual_nm.as_ref().unwrap().len(), 1234);
    let end = back.sidecar.end.unwrap();
    assert!(!end.complete);
    assert_eq!(end.cycle, 1234);
    assert!(
        end.reason.starts_with("drive fault: ") && end.reason.contains("EMCY 0x8400"),
        "{}",
        end.reason
    );
    let json = std::fs::read_to_string(dir.path().join("rec.json")).unwrap();
    assert!(json.contains("\"complete\": false"), "{json}");
}

#[test]
fn interrupt_stops_after_the_current_cycle_and_ramps_down() {
    let p = plan(&args(&["--periods", "3"])).unwrap();
    let mut drive = SimulatedDrive::new(&e2e_chain(), 1000.0).unwrap();
    let stop = AtomicBool::new(false);
    let out = run_sweep(&mut drive, &p, &stop, &mut |pr| {
        if pr.periods_done == 1 {
            stop.store(true, Ordering::Relaxed);
        }
    });
    assert_eq!(out.reason, StopReason::Interrupted);
    assert_eq!(out.recording.len(), 2000);
    assert_eq!(out.end.cycle, 2000);
    assert_eq!(out.ramp_cycles, p.ramp_cycles);
    assert!(out.end.reason.contains("interrupted"));
}

#[test]
fn overspeed_stops_the_sweep() {
    let mut p = plan(&args(&["--periods", "2"])).unwrap();
    p.max_speed_rad_s = 1e-3;
    let mut drive = SimulatedDrive::new(&e2e_chain(), 1000.0).unwrap();
    let out = run_sweep(&mut drive, &p, &AtomicBool::new(false), &mut quiet);
    assert!(matches!(out.reason, StopReason::Overspeed { .. }));
    assert_eq!(out.recording.len() as u64, out.end.cycle + 1);
    assert!(
        out.end.reason.starts_with("speed limit"),
        "{}",
        out.end.reason
    );
}

#[test]
fn duration_limit_stops_the_sweep() {
    let mut p = plan(&args(&[])).unwrap();
    p.max_duration = Some(std::time::Duration::ZERO);
    let mut drive = SimulatedDrive::new(&e2e_chain(), 1000.0).unwrap();
    let out = run_sweep(&mut drive, &p, &AtomicBool::new(false), &mut quiet);
    assert!(matches!(out.reason, StopReason::DurationLimit(_)));
    assert_eq!(out.recording.len(), 0);
}

#[test]
fn bus_load_refusal_says_what_would_fit() {
    assert!(admit(1000.0, 1_000_000).is_ok());
    let e = admit(4000.0, 1_000_000).unwrap_err();
    assert_eq!(e.code, 2);
    assert!(
        e.message.contains("refused before touching the bus"),
        "{}",
        e.message
    );
    assert!(
        e.message.contains("lower the cycle rate to at most"),
        "{}",
        e.message
    );
    assert!(
        e.message.contains("raise the bitrate to at least"),
        "{}",
        e.message
    );
    let e = admit(1000.0, 125_000).unwrap_err();
    assert!(e.message.contains("125000 bit/s"), "{}", e.message);
}

#[test]
fn chirp_and_bad_arguments() {
    let p = plan(&args(&["--excitation", "chirp", "--periods", "2"])).unwrap();
    assert_eq!(p.excitation.kind, crate::excitation::ExcitationKind::Chirp);
    assert_eq!(p.torque_nm.len(), 6000);
    let a = args(&["--resolution-hz", "0.5"]);
    assert_eq!((a.periods, a.transient_periods), (8, 1));
    for bad in [
        &["--band", "10", "5"][..],
        &["--band", "1", "600"],
        &["--periods", "0"],
        &["--peak-nm", "0"],
        &["--resolution-hz", "0"],
    ] {
        let e = plan(&args(bad)).unwrap_err();
        assert_eq!(e.code, 2, "{bad:?}: {}", e.message);
    }
}

#[test]
fn old_sidecars_stay_readable() {
    let old = r#"{"sample_rate_hz": 2000.0, "io_delay_samples": 0, "ended_because": "x"}"#;
    let s = parse_sidecar(old, std::path::Path::new("old.json")).unwrap();
    assert_eq!(s.end, None);
    assert_eq!(s.ended_because.as_deref(), Some("x"));
    let new = r#"{"sample_rate_hz": 1000.0,
        "end": {"complete": false, "reason": "drive fault: EMCY 0x8130", "cycle": 1234},
        "drive": {"bus": "udp", "node": 5, "profile": "p"},
        "cycle_counters": {"cycles": 10, "lost": 1}}"#;
    let s = parse_sidecar(new, std::path::Path::new("new.json")).unwrap();
    assert_eq!(s.end.unwrap().cycle, 1234);
    assert_eq!(s.drive.unwrap().node, 5);
    assert_eq!(s.cycle_counters.unwrap().lost, 1);
}

/// A drive that answers at once, except that cycle `stall_at` takes `stall` (a preempted
/// master or a slow host); records how long every cycle had for its feedback.
struct StallingDrive {
    inner: SimulatedDrive,
    stall_at: usize,
    stall: std::time::Duration,
    k: usize,
    time_left: Vec<std::time::Duration>,
}

impl flexid_canopen::CyclicDrive for StallingDrive {
    type Error = SimulatedFault;
    fn cycle(
        &mut self,
        torque_nm: f64,
        deadline: std::time::Instant,
    ) -> Result<flexid_canopen::Feedback, SimulatedFault> {
        self.time_left
            .push(deadline.saturating_duration_since(std::time::Instant::now()));
        if self.k == self.stall_at {
            std::thread::sleep(self.stall);
        }
        self.k += 1;
        self.inner.cycle(torque_nm, deadline)
    }
    fn cycle_period(&self) -> std::time::Duration {
        self.inner.cycle_period()
    }
    fn rated_torque_nm(&self) -> f64 {
        self.inner.rated_torque_nm()
    }
    fn counters(&self) -> flexid_canopen::Counters {
        self.inner.counters()
    }
}

#[test]
fn realtime_schedule_restarts_after_a_stall_instead_of_bursting() {
    // 200 Hz, 5 ms slots; cycle 3 stalls for 4 periods. Without the restart, cycles 4..7
    // would be fired back to back with deadlines already past (no time for feedback).
    let a = match Cli::try_parse_from([
        "flexid",
        "sweep",
        "--bus",
        "udp",
        "--clock",
        "realtime",
        "--cycle-hz",
        "200",
        "--periods",
        "1",
        "--resolution-hz",
        "10",
        "--band",
        "10",
        "50",
    ])
    .unwrap()
    .command
    {
        Command::Sweep(a) => a,
        _ => unreachable!(),
    };
    let mut p = plan(&a).unwrap();
    p.pacing = Pacing::Realtime;
    let period = p.period();
    let mut drive = StallingDrive {
        inner: SimulatedDrive::new(&e2e_chain(), 200.0).unwrap(),
        stall_at: 3,
        stall: period * 4,
        k: 0,
        time_left: Vec::new(),
    };
    let out = run_sweep(&mut drive, &p, &AtomicBool::new(false), &mut quiet);
    assert!(out.complete(), "{}", out.end.reason);
    assert!(out.overruns >= 1, "the stall must be counted as an overrun");
    assert_eq!(
        out.recording.sidecar.cycle_counters.unwrap().overruns,
        out.overruns
    );
    // Every recorded cycle after the stall got more than a third of a period to answer
    // (a loaded test host may cost a little of it; a burst would give zero).
    let starved: Vec<_> = drive.time_left[4..out.recording.len()]
        .iter()
        .enumerate()
        .filter(|(_, d)| **d < period / 3)
        .map(|(i, d)| (i + 4, *d))
        .collect();
    assert!(
        starved.len() <= 2,
        "cycles without time for their feedback: {starved:?}"
    );
}

/// Records each cycle's deadline and thread.
struct DeadlineDrive {
    inner: SimulatedDrive,
    deadlines: Vec<std::time::Instant>,
    thread: Option<std::thread::ThreadId>,
}

impl flexid_canopen::CyclicDrive for DeadlineDrive {
    type Error = SimulatedFault;
    fn cycle(
        &mut self,
        torque_nm: f64,
        deadline: std::time::Instant,
    ) -> Result<flexid_canopen::Feedback, SimulatedFault> {
        self.deadlines.push(deadline);
        self.thread = Some(std::thread::current().id());
        self.inner.cycle(torque_nm, deadline)
    }
    fn cycle_period(&self) -> std::time::Duration {
        self.inner.cycle_period()
    }
    fn rated_torque_nm(&self) -> f64 {
        self.inner.rated_torque_nm()
    }
    fn counters(&self) -> flexid_canopen::Counters {
        self.inner.counters()
    }
}

#[test]
fn realtime_sweep_runs_on_a_cycle_thread_on_absolute_deadlines() {
    // 500 Hz: every deadline is exactly one period after the previous one (absolute
    // schedule on the monotonic clock), except where an overrun restarted the schedule;
    // the loop runs on its own thread, and the caller's scheduling is untouched.
    let mut a = args(&[
        "--periods",
        "1",
        "--resolution-hz",
        "10",
        "--band",
        "10",
        "50",
    ]);
    a.cycle_hz = 500.0;
    let mut p = plan(&a).unwrap();
    p.pacing = Pacing::Realtime;
    let period = p.period();
    let mut drive = DeadlineDrive {
        inner: SimulatedDrive::new(&e2e_chain(), 500.0).unwrap(),
        deadlines: Vec::new(),
        thread: None,
    };
    let t0 = std::time::Instant::now();
    let (out, granted) = run_sweep_on_cycle_thread(
        &mut drive,
        &p,
        &AtomicBool::new(false),
        &mut quiet,
        crate::rt::RtSetup::none(),
    );
    assert!(out.complete(), "{}", out.end.reason);
    assert_eq!(granted, crate::rt::RtGranted::default());
    assert_ne!(drive.thread, Some(std::thread::current().id()));
    let n = out.recording.len();
    assert!(n >= 100, "{n}");
    let d = &drive.deadlines[..n];
    let off_grid = d.windows(2).filter(|w| w[1] - w[0] != period).count() as u64;
    assert_eq!(off_grid, out.overruns, "deadlines off the grid vs overruns");
    // and the schedule kept time: the last deadline is where the grid puts it
    assert!(d[n - 1] >= t0 + period * n as u32);
}

/// A drive whose every `every`-th cycle's feedback is counted lost (as the CANopen
/// master counts a TPDO that never came): the sweep's lost-feedback budget.
struct LossyDrive {
    inner: SimulatedDrive,
    every: u64,
    lost: u64,
}

impl flexid_canopen::CyclicDrive for LossyDrive {
    type Error = <SimulatedDrive as flexid_canopen::CyclicDrive>::Error;
    fn cycle(
        &mut self,
        torque_nm: f64,
        deadline: std::time::Instant,
    ) -> Result<flexid_canopen::Feedback, Self::Error> {
        let mut fb = self.inner.cycle(torque_nm, deadline)?;
        if fb.cycle % self.every == self.every - 1 {
            self.lost += 1;
        }
        fb.counters.lost = self.lost;
        fb.counters.missed = self.lost;
        Ok(fb)
    }
    fn cycle_period(&self) -> std::time::Duration {
        self.inner.cycle_period()
    }
    fn rated_torque_nm(&self) -> f64 {
        self.inner.rated_torque_nm()
    }
    fn counters(&self) -> flexid_canopen::Counters {
        let mut c = self.inner.counters();
        c.lost = self.lost;
        c
    }
}

/// The default budget (0.5 % of the cycles, at least 20) stops a sweep that loses one
/// TPDO in 50 at the 91st loss (18000 cycles: budget 90); `--max-lost` moves that limit.
#[test]
fn the_lost_feedback_budget_stops_the_sweep_and_max_lost_moves_it() {
    let lossy = || LossyDrive {
        inner: SimulatedDrive::new(&e2e_chain(), 1000.0).unwrap(),
        every: 50,
        lost: 0,
    };
    let stop = AtomicBool::new(false);
    let p = plan(&args(&[])).unwrap();
    assert_eq!(p.max_lost_tpdos, 90);
    let out = run_sweep(&mut lossy(), &p, &stop, &mut quiet);
    assert!(
        matches!(out.reason, StopReason::FeedbackLost(_)),
        "{:?}",
        out.reason
    );
    // the 91st loss is in cycle 91 * 50 - 1
    assert_eq!(out.recording.len(), 91 * 50);
    let p = plan(&args(&["--max-lost", "400"])).unwrap();
    assert_eq!(p.max_lost_tpdos, 400);
    let out = run_sweep(&mut lossy(), &p, &stop, &mut quiet);
    assert!(out.complete(), "{:?}", out.reason);
    assert_eq!(out.recording.len(), 18000);
}

/// Lost feedback does not spoil the identification: the rows recorded from a lost
/// feedback (the previous values) are filled from their neighbours, within linear
/// interpolation's error bound, and the 3-mass chain is identified as without loss. (A single held row in a CAN demo turned a pair's phase rise from 180 to 37 deg and
/// the identification reported two bodies.)
#[test]
fn lost_feedback_rows_are_filled_and_the_chain_still_identified() {
    let chain = e2e_chain();
    let p = plan(&args(&[])).unwrap();
    let lose = vec![5003, 9001, 9002, 15500];
    let clean = {
        let mut d = SimulatedDrive::new(&chain, 1000.0)
            .unwrap()
            .with_encoder(1048576.0);
        run_sweep(&mut d, &p, &AtomicBool::new(false), &mut quiet)
    };
    let mut drive = LosingDrive::new(
        SimulatedDrive::new(&chain, 1000.0)
            .unwrap()
            .with_encoder(1048576.0),
        lose.clone(),
    );
    let out = run_sweep(&mut drive, &p, &AtomicBool::new(false), &mut quiet);
    assert!(out.complete(), "{:?}", out.reason);
    let (x, x0) = (
        out.recording.position_rad.as_ref().unwrap(),
        clean.recording.position_rad.as_ref().unwrap(),
    );
    for &k in &lose {
        // linear interpolation between the fresh rows a and b either side: its error is at
        // most (b - a)²/8 times the largest second difference of the true position there
        let a = (0..k).rev().find(|j| !lose.contains(j)).unwrap();
        let b = (k + 1..x0.len()).find(|j| !lose.contains(j)).unwrap();
        let curvature = (a + 1..b)
            .map(|j| (x0[j + 1] - 2.0 * x0[j] + x0[j - 1]).abs())
            .fold(0.0, f64::max);
        let bound = ((b - a) as f64).powi(2) / 8.0 * curvature;
        assert!(
            (x[k] - x0[k]).abs() <= 1.01 * bound + 1e-9,
            "row {k}: filled {} true {} (bound {bound})",
            x[k],
            x0[k]
        );
    }
    assert_identifies_within_3_percent(&out.recording, &chain);
}

/// Rows shared between the sweep loop's sink and its progress hook (as the daemon's
/// pre-allocated rows are shared with its relay).
#[derive(Clone, Default)]
struct SharedRows(std::rc::Rc<std::cell::RefCell<Vec<Row>>>);

impl RowSink for SharedRows {
    fn push(&mut self, k: usize, row: &Row) {
        let mut rows = self.0.borrow_mut();
        match rows.get_mut(k) {
            Some(old) => *old = *row,
            None => rows.push(*row),
        }
    }
}

/// Whatever a progress report publishes is final: a row recorded from a lost feedback is
/// filled before the report that covers it, also when it is the last row of a period
/// (the report waits one cycle for the fresh row after it). The daemon streams the rows
/// of each report to its files and the live Bode, never to be rewritten.
#[test]
fn progress_reports_publish_only_filled_rows() {
    let chain = e2e_chain();
    let p = plan(&args(&[])).unwrap();
    let period = p.excitation.period_samples;
    assert!(period > 0);
    let lose = vec![period - 1, 2 * period - 2, 2 * period - 1, 3 * period + 7];
    let mut drive = LosingDrive::new(SimulatedDrive::new(&chain, 1000.0).unwrap(), lose.clone());
    let sink = SharedRows::default();
    let seen = sink.0.clone();
    let mut snapshots: Vec<Vec<Row>> = Vec::new();
    let mut progress = |pr: &Progress| {
        snapshots.push(seen.borrow()[..pr.cycle as usize].to_vec());
    };
    let end = run_sweep_into(
        &mut drive,
        &p,
        &AtomicBool::new(false),
        &mut progress,
        &mut sink.clone(),
    );
    assert!(end.reason == StopReason::Complete, "{:?}", end.reason);
    assert_eq!(end.held_rows, lose.len() as u64);
    let rows = sink.0.borrow();
    assert!(snapshots.len() >= 4);
    for (i, snap) in snapshots.iter().enumerate() {
        for (k, r) in snap.iter().enumerate() {
            assert_eq!(r, &rows[k], "report {i}: row {k} published before its fill");
        }
    }
    for &k in &lose {
        assert_ne!(
            rows[k].position_rad,
            rows[k - 1].position_rad,
            "row {k} held"
        );
    }
}
