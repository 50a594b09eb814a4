//! Cycle timing of the EtherCAT exchange on the veth tier (issue 18; `scripts/bench.sh`
//! runs it, see docs/benchmarks.md and docs/ethercat.md).
//!
//! At 4 and 8 kHz, each on a fresh network namespace and veth pair: an emulated CiA 402
//! servo on its SYNC0 clock (flexid-vdrive's `ethercat` module, served in this process
//! from a thread inside the namespace, so its counters can be read per chunk), ethercrab's
//! stock `tx_rx_task` on the host end, `flexid_ecat::EcatDrive` brought up to Operation
//! enabled in CST with SYNC0 at the rate. Then, interleaved in chunks (alternating which
//! goes first) on a thread with the same real-time setup:
//!
//! * **ethercat**: sleeps to absolute deadlines on the drive's SYNC0 grid
//!   (`CyclicDrive::cycle_grid`) and makes one process-data exchange per cycle through
//!   ethercrab over the veth pair (`EcatDrive::cycle`, a small torque sine);
//! * **bare**: sleeps to the same kind of absolute deadlines and does nothing else.
//!
//! Reported per rate and loop: wake-up lateness from the deadline waited for (p50, p99,
//! p99.9, max), late wake-ups (> 10 % of the period), overruns (deadlines skipped); for the
//! exchange: its duration (p50, p99), responses after the cycle's end, working-counter
//! errors, frames not answered (ethercrab timeouts) and other exchange errors, frames sent
//! and answered by the emulated segment, the servo's missed cycles (SYNC0 pulses with no
//! frame) and overwritten set-points during the exchange chunks; the ratio p99(ethercat)
//! / p99(bare), and the machine's load average. Printed and written to
//! `target/bench/ecat_cycle_timing.md`.
//!
//! Needs root and `ip` (the veth tier); otherwise it says so and writes the reason.
//! Arguments: `[--quick] [--out FILE]` (`--quick`: 1 s per rate and loop in 4 chunks
//! instead of 4 s in 8; other arguments, e.g. cargo's `--bench`, are ignored).

#[path = "../tests/veth/mod.rs"]
mod veth;

use flexid_canopen::CyclicDrive;
use flexid_ecat::{CycleStats, EcatConfig, EcatDrive, EcatError, ServoClock};
use flexid_rt::{clock, RtSetup, TimingStats};
use flexid_vdrive::ethercat::EthercatOptions;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;
use veth::{main_device, InProcessEmulator, Veth, MAX_PDI, MAX_SUBDEVICES};

const RATES_HZ: [u64; 2] = [4000, 8000];

type Drive = EcatDrive<'static, MAX_SUBDEVICES, MAX_PDI>;

/// One loop's pooled results at one rate.
struct Pooled {
    /// The loop thread's `SCHED_FIFO` priority as granted (the last chunk's).
    granted_fifo: Option<u8>,
    stats: TimingStats,
    cycles: u64,
    late_responses: u64,
    wkc_errors: u64,
    timeouts: u64,
    other_errors: u64,
    servo: CycleStats,
}

impl Pooled {
    fn new(period_ns: u64) -> Self {
        Pooled {
            granted_fifo: None,
            stats: TimingStats::new(period_ns),
            cycles: 0,
            late_responses: 0,
            wkc_errors: 0,
            timeouts: 0,
            other_errors: 0,
            servo: CycleStats::default(),
        }
    }
}

/// The grid's phase on the monotonic clock (ns modulo `period_ns`).
fn grid_phase_ns(grid: Option<Instant>, period_ns: u64) -> u64 {
    let Some(grid) = grid else { return 0 };
    let (now_ns, now) = (clock::now_ns(), Instant::now());
    let g = if grid >= now {
        now_ns as i128 + (grid - now).as_nanos() as i128
    } else {
        now_ns as i128 - (now - grid).as_nanos() as i128
    };
    g.rem_euclid(i128::from(period_ns)) as u64
}

/// The first deadline on the grid at least a period from now.
fn first_deadline(phase_ns: u64, period_ns: u64) -> u64 {
    let now = clock::now_ns() + period_ns;
    now + (phase_ns + period_ns - now % period_ns) % period_ns
}

/// Sleeps to deadline `d`; the lateness recorded and the deadlines skipped (as the pacer
/// and benches/cycle_timing.rs's bare loop).
fn wake(stats: &mut TimingStats, d: u64, period_ns: u64) -> u64 {
    clock::sleep_until_ns(d);
    let woke = clock::now_ns();
    let missed = (woke - d) / period_ns;
    stats.record_wakeup(woke - (d + missed * period_ns), missed);
    missed
}

/// One chunk of the EtherCAT loop: `cycles` grid slots, one exchange each.
fn run_ethercat(
    setup: RtSetup,
    drive: &mut Drive,
    emulator: &InProcessEmulator,
    period_ns: u64,
    cycles: u64,
    into: &mut Pooled,
) {
    let phase = grid_phase_ns(drive.cycle_grid(), period_ns);
    let map = clock::InstantMap::calibrate();
    let mut stats = TimingStats::new(period_ns);
    let mut servo_from = None;
    let (mut late, mut wkc, mut timeouts, mut other, mut n) = (0, 0, 0, 0, 0u64);
    let mut granted = None;
    std::thread::scope(|s| {
        s.spawn(|| {
            granted = setup.apply().fifo_priority;
            let first = first_deadline(phase, period_ns);
            let mut k = 0u64;
            while k < cycles {
                let d = first + k * period_ns;
                let missed = wake(&mut stats, d, period_ns);
                k += missed;
                let t = (k as f64) * 2e-3;
                let t0 = clock::now_ns();
                let deadline = map.instant(first + (k + 1) * period_ns);
                match drive.cycle(0.05 * t.sin(), deadline) {
                    Ok(fb) => late += u64::from(!fb.fresh),
                    Err(EcatError::WorkingCounter { .. } | EcatError::SubDeviceLost { .. }) => {
                        wkc += 1
                    }
                    Err(EcatError::Exchange {
                        source: ethercrab::error::Error::Timeout(_),
                        ..
                    }) => timeouts += 1,
                    Err(_) => other += 1,
                }
                stats.record_body(clock::now_ns() - t0);
                if servo_from.is_none() {
                    // Pulses before the chunk's first frame (the idle time between chunks)
                    // are not this chunk's.
                    servo_from = Some(emulator.servo_stats());
                }
                k += 1;
                n += 1;
            }
        });
    });
    let (a, b) = (servo_from.unwrap_or_default(), emulator.servo_stats());
    into.servo.missed += b.missed - a.missed;
    into.servo.overwritten += b.overwritten - a.overwritten;
    into.servo.longest_missed_run = into.servo.longest_missed_run.max(b.longest_missed_run);
    into.granted_fifo = granted;
    into.stats.merge(&stats);
    into.cycles += n;
    into.late_responses += late;
    into.wkc_errors += wkc;
    into.timeouts += timeouts;
    into.other_errors += other;
}

/// One chunk of the bare loop: the same deadlines, nothing else.
fn run_bare(setup: RtSetup, phase: u64, period_ns: u64, cycles: u64, into: &mut Pooled) {
    let mut stats = TimingStats::new(period_ns);
    let mut n = 0;
    let mut granted = None;
    std::thread::scope(|s| {
        s.spawn(|| {
            granted = setup.apply().fifo_priority;
            let first = first_deadline(phase, period_ns);
            let mut k = 0u64;
            while k < cycles {
                k += wake(&mut stats, first + k * period_ns, period_ns) + 1;
                n += 1;
            }
        });
    });
    into.granted_fifo = granted;
    into.stats.merge(&stats);
    into.cycles += n;
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1000.0)
}

/// The results of one rate.
struct Rate {
    hz: u64,
    ecat: Pooled,
    bare: Pooled,
    bring_up: String,
    frames: String,
}

fn measure(rate: u64, setup: RtSetup, secs: f64, chunks: u64) -> Result<Rate, String> {
    let veth = Veth::create()?;
    let mut emulator = InProcessEmulator::start(
        &veth,
        EthercatOptions {
            axes: 1,
            cycle_hz: rate as f64,
            clock: ServoClock::Sync0,
            // The bare chunks leave the servo without frames: hold, never fault.
            fault_after_missed_cycles: 0,
        },
        90,
    );
    let md = main_device(&veth.host, 85);
    let group = futures_lite::future::block_on(
        md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(ethercrab::std::ethercat_now),
    )
    .map_err(|e| format!("discovery over {}: {e}", veth.host))?;
    let config = EcatConfig {
        enable_exchanges: 4000,
        ..EcatConfig::at_hz(rate as f64)
    };
    let mut drive = EcatDrive::bring_up(md, group, config).map_err(|e| e.to_string())?;
    let bring_up = format!(
        "{} exchanges to Operation enabled, SYNC0 located from a {:.0} µs round trip",
        drive.exchanges(),
        drive.sync0_round_trip().unwrap_or_default().as_secs_f64() * 1e6
    );
    let period_ns = 1_000_000_000 / rate;
    let phase = grid_phase_ns(drive.cycle_grid(), period_ns);
    let chunk_cycles = (secs * rate as f64 / chunks as f64) as u64;
    let mut ecat = Pooled::new(period_ns);
    let mut bare = Pooled::new(period_ns);
    for c in 0..chunks {
        if c % 2 == 0 {
            run_ethercat(
                setup,
                &mut drive,
                &emulator,
                period_ns,
                chunk_cycles,
                &mut ecat,
            );
            run_bare(setup, phase, period_ns, chunk_cycles, &mut bare);
        } else {
            run_bare(setup, phase, period_ns, chunk_cycles, &mut bare);
            run_ethercat(
                setup,
                &mut drive,
                &emulator,
                period_ns,
                chunk_cycles,
                &mut ecat,
            );
        }
    }
    let _ = drive.disable();
    let served = emulator.stop();
    let frames = served.map_or("?".into(), |s| {
        format!(
            "{} received, {} returned, {} rejected",
            s.link.received, s.link.returned, s.link.rejected
        )
    });
    Ok(Rate {
        hz: rate,
        ecat,
        bare,
        bring_up,
        frames,
    })
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR"))
                .join("../../target/bench/ecat_cycle_timing.md")
        });
    let (secs, chunks) = if quick { (1.0, 4) } else { (4.0, 8) };
    let setup = RtSetup {
        lock_memory: false,
        ..RtSetup::realtime(80)
    };
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let load: Vec<&str> = load.split_whitespace().take(3).collect();
    let ncpu = std::thread::available_parallelism().map_or(1, |n| n.get());
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "?".into());
    let mut md = String::new();
    let _ = writeln!(
        md,
        "EtherCAT cycle timing on the veth tier: {secs} s per rate and loop in {chunks} \
         interleaved chunks; {ncpu} CPUs, kernel {kernel}, load average {} at the start. \
         Asked: loops SCHED_FIFO 80; ethercrab's tx/rx thread 85; the emulated segment and \
         its SYNC0 clock 90.",
        load.join(" ")
    );
    let mut results = Vec::new();
    for rate in RATES_HZ {
        match measure(rate, setup, secs, chunks) {
            Ok(r) => results.push(r),
            Err(why) => {
                let _ = writeln!(md, "\n{} kHz: not measured: {why}", rate / 1000);
                eprintln!("ecat_cycle_timing: {} kHz not measured: {why}", rate / 1000);
            }
        }
    }
    for r in &results {
        let fifo = |p: Option<u8>| {
            p.map_or("normal priority (refused)".into(), |p| {
                format!("SCHED_FIFO {p}")
            })
        };
        let _ = writeln!(
            md,
            "\n{} kHz: bring-up {}; frames at the segment: {}; loops granted: ethercat {}, \
             bare {}.",
            r.hz / 1000,
            r.bring_up,
            r.frames,
            fifo(r.ecat.granted_fifo),
            fifo(r.bare.granted_fifo)
        );
    }
    let _ = writeln!(md);
    let _ = writeln!(
        md,
        "| rate | loop | cycles | p50 µs | p99 µs | p99.9 µs | max µs | late (>10 % period) | overruns | exchange p50/p99 µs | responses after the cycle | WKC errors | frames unanswered (timeouts) | other errors | servo missed cycles | overwritten set-points | p99 ethercat/bare |"
    );
    let _ = writeln!(
        md,
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    );
    for r in &results {
        let e = r.ecat.stats.lateness.summary();
        let b = r.bare.stats.lateness.summary();
        let ratio = e.p99_ns as f64 / b.p99_ns.max(1) as f64;
        for (name, p, s) in [("ethercat", &r.ecat, e), ("bare", &r.bare, b)] {
            let ecat = name == "ethercat";
            let x = p.stats.body.summary();
            let cols = if ecat {
                format!(
                    "{} / {} | {} | {} | {} | {} | {} | {} | **{ratio:.2}x** |",
                    us(x.p50_ns),
                    us(x.p99_ns),
                    p.late_responses,
                    p.wkc_errors,
                    p.timeouts,
                    p.other_errors,
                    p.servo.missed,
                    p.servo.overwritten
                )
            } else {
                "- | - | - | - | - | - | - | - |".into()
            };
            let _ = writeln!(
                md,
                "| {} kHz | {name} | {} | {} | {} | {} | {} | {} | {} | {cols}",
                r.hz / 1000,
                p.cycles,
                us(s.p50_ns),
                us(s.p99_ns),
                us(s.p999_ns),
                us(s.max_ns),
                p.stats.late_wakeups,
                p.stats.missed_deadlines,
            );
        }
    }
    print!("{md}");
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir).expect("create the report directory");
    }
    std::fs::write(&out, &md).expect("write the report");
    println!("written to {}", out.display());
}
