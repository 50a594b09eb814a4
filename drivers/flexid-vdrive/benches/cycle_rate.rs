//! Highest clean cycle rate of one axis at 1 Mbit/s with the default PDO mapping.
//!
//! The CANopen master of `flexid-canopen` and `flexid-vdrive` (real-time clock mode) run
//! in one process on an [`InprocBus`] whose two handles are wrapped in [`Paced`] at
//! 1 000 000 bit/s sharing one [`BusClock`]: every frame of either side occupies the
//! emulated wire for its worst-case stuffed length, and frames serialise as on a real
//! 1 Mbit/s bus. For each cycle rate the drive is brought up and enabled at that rate
//! (`MasterConfig::cycle_period`), then cycled for 2 s (0.5 s with `--quick`) on absolute
//! deadlines ([`flexid::rt::Pacer`]) with a small sine torque. A cycle is an overrun when
//! its TPDOs were not all in before the next cycle's deadline (the master's `Counters`:
//! `missed` = `late` + `lost`) or when the pacer woke after a further deadline had passed.
//!
//! The admission limit of the master is lifted to 100 % load for the sweep (the default
//! is 70 %), so that the emulated bus itself shows where it saturates; rates above 100 %
//! are refused by the admission check and reported as such.
//!
//! ```text
//! cargo bench -p flexid-vdrive --bench cycle_rate -- [--quick] [--rt] [--out FILE]
//! ```

use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use flexid::rt::{Pacer, RtSetup};
use flexid_can::timing::{BusClock, Paced};
use flexid_can::InprocBus;
use flexid_canopen::pdo::{bus_load, default_mapping, max_cycle_rate_hz};
use flexid_canopen::profile::ObjectMap;
use flexid_canopen::{bring_up, MasterConfig, MasterError, ProfileSet};
use flexid_vdrive::{linear_drive, ClockMode, DrivePlant, Runner};

const BITRATE: u32 = 1_000_000;
const NODE: u8 = 5;
const RATES_HZ: [u32; 13] = [
    500, 1000, 1100, 1200, 1300, 1400, 1500, 1800, 2000, 2200, 2400, 2600, 2700,
];
/// Overruns tolerated for the "within budget" result (fraction of cycles).
const BUDGET: f64 = 0.001;

#[derive(Debug, Default)]
struct Row {
    rate: u32,
    load: f64,
    cycles: u64,
    late: u64,
    lost: u64,
    missed: u64,
    pacer_overruns: u64,
    achieved_hz: f64,
    /// Why the rate could not be run (admission refusal, bring-up or cycle error).
    error: Option<String>,
}

impl Row {
    fn overruns(&self) -> u64 {
        self.missed + self.pacer_overruns
    }
    fn ran(&self) -> bool {
        self.error.is_none() && self.cycles > 0
    }
    fn clean(&self) -> bool {
        self.ran() && self.overruns() == 0
    }
    fn within_budget(&self) -> bool {
        self.ran() && (self.overruns() as f64) <= BUDGET * self.cycles as f64
    }
}

/// Timer slack of 1 ns for the calling thread (Linux default: 50 us, which every
/// emulated frame's sleep in `Paced::send` would otherwise add).
fn tight_timer_slack() {
    #[cfg(target_os = "linux")]
    // SAFETY: PR_SET_TIMERSLACK takes an integer argument and affects the calling thread only.
    unsafe {
        libc::prctl(libc::PR_SET_TIMERSLACK, 1 as libc::c_ulong, 0, 0, 0);
    }
}

fn plant() -> DrivePlant {
    let text = format!(
        "{}\n[drive]\nnode_id = {NODE}\n",
        flexid::cli::plant::DEFAULT_PLANT
    );
    DrivePlant::parse(&text, "default plant").expect("default plant")
}

fn config(rate: u32) -> MasterConfig {
    MasterConfig {
        cycle_period: Duration::from_nanos(1_000_000_000 / rate as u64),
        bitrate: BITRATE,
        max_bus_load: 1.0,
        ..MasterConfig::for_node(NODE)
    }
}

fn run_rate(rate: u32, seconds: f64, rt: &RtSetup, load: f64) -> Row {
    let mut row = Row {
        rate,
        load,
        ..Row::default()
    };
    let bus = InprocBus::new("cycle-rate");
    let clock = BusClock::new();
    let drive_bus = Paced::with_clock(bus.handle(), BITRATE, clock.clone());
    let master_bus = Paced::with_clock(bus, BITRATE, clock);
    let drive = linear_drive(&plant(), ClockMode::RealTime).expect("drive");
    let stop = Arc::new(AtomicBool::new(false));
    let s2 = stop.clone();
    let rt2 = rt.clone();
    let th = std::thread::spawn(move || {
        rt2.apply();
        Runner::new(drive_bus, drive).run(&s2)
    });
    let result = (|| -> Result<(), MasterError> {
        let d = bring_up(master_bus, config(rate), &ProfileSet::builtin())?;
        let mut d = d.enable()?;
        let n = (seconds * rate as f64).round() as u64;
        let period = Duration::from_nanos(1_000_000_000 / rate as u64);
        let mut pacer = Pacer::new(period).expect("period");
        let mut first = None;
        let mut last = None;
        let mut res = Ok(());
        let trace = std::env::var_os("CYCLE_RATE_TRACE").is_some();
        for _ in 0..n {
            let tick = pacer.wait_next();
            first.get_or_insert(tick.deadline);
            // small sine, 3 Hz, on the deadline grid
            let t = tick.index as f64 * period.as_secs_f64();
            let tq = 0.05 * (std::f64::consts::TAU * 3.0 * t).sin();
            let r = d.cycle(tq, tick.next_deadline);
            if trace && tick.index < 40 {
                eprintln!(
                    "  tick {} late {} us, cycle returned after {} us, {:?}",
                    tick.index,
                    tick.lateness_ns / 1000,
                    Instant::now().duration_since(tick.deadline).as_micros(),
                    r.as_ref().map(|f| f.fresh)
                );
            }
            match r {
                Ok(_) => {}
                Err(e) => {
                    res = Err(e);
                    break;
                }
            }
            last = Some(Instant::now());
        }
        // the last cycle's late TPDOs are only classified when a cycle follows: the
        // counters above are those after the last cycle (late/lost of the last one
        // show up in `missed`).
        let c = d.counters();
        row.cycles = c.cycles;
        row.late = c.late;
        row.lost = c.lost;
        row.missed = c.missed;
        row.pacer_overruns = pacer.missed_deadlines();
        if let (Some(f), Some(l)) = (first, last) {
            let dt = l.duration_since(f).as_secs_f64();
            if dt > 0.0 {
                row.achieved_hz = row.cycles as f64 / dt;
            }
        }
        let _ = d.disable();
        res
    })();
    if let Err(e) = result {
        row.error = Some(e.to_string());
    }
    stop.store(true, Ordering::Relaxed);
    let _ = th.join();
    row
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let want_rt = args.iter().any(|a| a == "--rt");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../target/bench/cycle_rate.md")
        });
    let seconds = if quick { 0.5 } else { 2.0 };
    // Normal scheduling by default: on the shared 2-core VM this was measured, SCHED_FIFO
    // for both threads (`--rt`: master = this thread, drive = its runner, not pinned)
    // gave more overruns, not fewer.
    let rt = if want_rt {
        RtSetup::realtime(80)
    } else {
        RtSetup::none()
    };
    let granted = rt.apply();
    tight_timer_slack();

    let mapping = default_mapping(&ObjectMap::default());
    let base = config(1000);
    let heartbeats = [base.heartbeat_period, base.drive_heartbeat_period];
    let limit_100 = max_cycle_rate_hz(&mapping, &heartbeats, BITRATE, 1.0);
    let limit_70 = max_cycle_rate_hz(&mapping, &heartbeats, BITRATE, 0.7);

    let mut rows = Vec::new();
    for &rate in &RATES_HZ {
        let load = bus_load(&mapping, &heartbeats, rate as f64, BITRATE);
        let row = if load > 1.0 {
            Row {
                rate,
                load,
                error: Some("refused: bus load above 100 %".into()),
                ..Row::default()
            }
        } else {
            run_rate(rate, seconds, &rt, load)
        };
        eprintln!(
            "{} Hz: load {:.1} %, cycles {}, late {}, lost {}, missed {}, pacer overruns {}, achieved {:.1} Hz{}",
            row.rate,
            row.load * 100.0,
            row.cycles,
            row.late,
            row.lost,
            row.missed,
            row.pacer_overruns,
            row.achieved_hz,
            row.error.as_deref().map(|e| format!(" ({e})")).unwrap_or_default()
        );
        rows.push(row);
    }

    let clean = rows.iter().filter(|r| r.clean()).map(|r| r.rate).max();
    let budget = rows
        .iter()
        .filter(|r| r.within_budget())
        .map(|r| r.rate)
        .max();
    let mut md = String::new();
    let _ = writeln!(
        md,
        "One axis (flexid-vdrive, real-time clock mode) and the CANopen master in one \
         process on an in-process bus paced at {} bit/s (shared bus clock, worst-case \
         stuffed frame lengths); default mapping: SYNC + RPDO1 (4 B) + TPDO1 (8 B) + \
         TPDO2 (4 B) = {} bits per cycle, heartbeats every {} ms from both nodes. {} s per \
         rate{}. Real-time setup: {}.\n",
        BITRATE,
        mapping.cycle_bits(),
        base.heartbeat_period.as_millis(),
        seconds,
        if quick { " (--quick)" } else { "" },
        if !want_rt {
            "normal scheduling (no --rt), timer slack 1 ns".to_string()
        } else if granted.fifo_priority.is_some() {
            format!(
                "SCHED_FIFO {} granted",
                granted.fifo_priority.unwrap_or_default()
            )
        } else {
            "SCHED_FIFO refused, normal scheduling".to_string()
        }
    );
    let _ = writeln!(
        md,
        "| rate (Hz) | bus load | cycles | late | lost | missed | pacer overruns | achieved (Hz) | result |"
    );
    let _ = writeln!(md, "|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for r in &rows {
        let result = match &r.error {
            Some(e) => e.clone(),
            None if r.clean() => "clean".into(),
            None => format!(
                "{:.2} % overruns",
                100.0 * r.overruns() as f64 / r.cycles.max(1) as f64
            ),
        };
        let _ = writeln!(
            md,
            "| {} | {:.1} % | {} | {} | {} | {} | {} | {:.1} | {} |",
            r.rate,
            r.load * 100.0,
            r.cycles,
            r.late,
            r.lost,
            r.missed,
            r.pacer_overruns,
            r.achieved_hz,
            result
        );
    }
    let fmt = |x: Option<u32>| x.map_or("none".to_string(), |r| format!("{r} Hz"));
    let _ = writeln!(
        md,
        "\nhighest clean rate: {}; theoretical bus limit for the default mapping at 1 Mbit/s: \
         {:.0} Hz (100 % load), {:.0} Hz (at the 70 % admission limit)",
        fmt(clean),
        limit_100.floor(),
        limit_70.floor()
    );
    let _ = writeln!(
        md,
        "highest rate within a {:.1} % overrun budget: {}",
        BUDGET * 100.0,
        fmt(budget)
    );
    print!("{md}");
    if let Some(dir) = out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    match std::fs::write(&out, &md) {
        Ok(()) => eprintln!("cycle_rate: wrote {}", out.display()),
        Err(e) => eprintln!("cycle_rate: could not write {}: {e}", out.display()),
    }
}
