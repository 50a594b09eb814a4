//! Wake-up lateness of the flexid cycle thread against a bare `clock_nanosleep` loop
//! (`scripts/bench.sh` runs it; see docs/benchmarks.md).
//!
//! At 1, 2 and 4 kHz, in the same process, interleaved in chunks so both share the
//! machine's noise:
//!
//! * **flexid**: `spawn_cycle_thread` with a light realistic body (a multisine sample of 8
//!   sines, the torque scaled to ‰ and packed into an RPDO1 frame with a SYNC, a TPDO1
//!   decoded, the position unwrapped and differenced, the sample stored in a preallocated
//!   recording);
//! * **bare**: a thread with the same real-time setup that only sleeps to the same kind of
//!   absolute deadlines (`clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME)` through
//!   `flexid::rt::clock`) and records its lateness.
//!
//! Reported: lateness (from the deadline each loop waited for, so a stall longer than a
//! period counts in full) p50, p99, p99.9, max; late wake-ups (> 10 % of the period);
//! overruns; the thread's CPU time per second of wall time (`CLOCK_THREAD_CPUTIME_ID`);
//! the ratio p99(flexid)/p99(bare). Printed and written to
//! `target/bench/cycle_timing.md`.
//!
//! Arguments: `[--quick] [--no-rt] [--out FILE]` (`--quick`: 1 s per rate and kind in 4
//! chunks instead of 4 s in 8; `--no-rt`: ask for no SCHED_FIFO/mlockall/affinity; other arguments, e.g.
//! cargo's `--bench`, are ignored).

use std::fmt::Write as _;
use std::hint::black_box;
use std::ops::ControlFlow;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use flexid::rt::{clock, spawn_cycle_thread, RtGranted, RtSetup, Tick, TimingStats};

const RATES_HZ: [u64; 3] = [1000, 2000, 4000];

/// One kind's pooled results at one rate.
struct Pooled {
    stats: TimingStats,
    cycles: u64,
    cpu_ns: u64,
    wall_ns: u64,
}

impl Pooled {
    fn new(period_ns: u64) -> Self {
        Pooled {
            stats: TimingStats::new(period_ns),
            cycles: 0,
            cpu_ns: 0,
            wall_ns: 0,
        }
    }
}

/// The light realistic body's state: excitation, frame packing, feedback decoding, and a
/// preallocated recording.
struct Body {
    amp: [f64; 8],
    w: [f64; 8],
    phi: [f64; 8],
    dt: f64,
    last_pos_inc: i32,
    turns: i64,
    rec: Vec<(f32, f64)>,
    cycles: u64,
}

impl Body {
    fn new(rate_hz: u64, cycles: u64) -> Self {
        let mut amp = [0.0; 8];
        let mut w = [0.0; 8];
        let mut phi = [0.0; 8];
        for j in 0..8 {
            amp[j] = 0.1 / (j as f64 + 1.0);
            w[j] = 2.0 * std::f64::consts::PI * 3.0 * (j as f64 + 1.0);
            phi[j] = std::f64::consts::PI * (j * j) as f64 / 8.0; // Schroeder-like
        }
        Body {
            amp,
            w,
            phi,
            dt: 1.0 / rate_hz as f64,
            last_pos_inc: 0,
            turns: 0,
            rec: Vec::with_capacity(cycles as usize + 8),
            cycles,
        }
    }

    #[inline(never)]
    fn step(&mut self, tick: &Tick) -> ControlFlow<()> {
        let t = tick.index as f64 * self.dt;
        // excitation sample, N m
        let mut torque = 0.0;
        for j in 0..8 {
            torque += self.amp[j] * (self.w[j] * t + self.phi[j]).sin();
        }
        // RPDO1: controlword 0x000F, target torque in ‰ of a 1.2 N m rated torque; then SYNC
        let permille = (torque / 1.2 * 1000.0).round().clamp(-32768.0, 32767.0) as i16;
        let mut rpdo = [0u8; 8];
        rpdo[0..2].copy_from_slice(&0x000Fu16.to_le_bytes());
        rpdo[2..4].copy_from_slice(&permille.to_le_bytes());
        let sync = [0u8; 0];
        black_box((&rpdo, 0x201u16, 4u8, &sync, 0x080u16));
        // a TPDO1 as the drive would answer: statusword, position (inc), torque actual
        let pos_inc = (tick.index as i64 * 37 % (1 << 20)) as i32;
        let mut tpdo = [0u8; 8];
        tpdo[0..2].copy_from_slice(&0x1237u16.to_le_bytes());
        tpdo[2..6].copy_from_slice(&pos_inc.to_le_bytes());
        tpdo[6..8].copy_from_slice(&permille.to_le_bytes());
        let tpdo = black_box(tpdo);
        let sw = u16::from_le_bytes([tpdo[0], tpdo[1]]);
        let p = i32::from_le_bytes([tpdo[2], tpdo[3], tpdo[4], tpdo[5]]);
        // multi-turn unwrap of a 20-bit encoder and position in rad
        let d = p.wrapping_sub(self.last_pos_inc);
        if d < -(1 << 19) {
            self.turns += 1;
        } else if d > (1 << 19) {
            self.turns -= 1;
        }
        self.last_pos_inc = p;
        let pos_rad = (self.turns as f64 * (1u64 << 20) as f64 + p as f64)
            * (2.0 * std::f64::consts::PI / (1u64 << 20) as f64);
        if sw & 0x6F == 0x27 && self.rec.len() < self.rec.capacity() {
            self.rec.push((torque as f32, pos_rad));
        }
        if self.rec.len() as u64 >= self.cycles || tick.index + 1 >= self.cycles {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

/// One chunk of the flexid cycle thread: `cycles` grid slots.
fn run_flexid(setup: RtSetup, rate: u64, cycles: u64, into: &mut Pooled) -> RtGranted {
    let mut body = Body::new(rate, cycles);
    let h = spawn_cycle_thread(
        "flexid-cycle",
        setup,
        Duration::from_nanos(1_000_000_000 / rate),
        move |t| body.step(t),
    )
    .expect("spawn");
    let r = h.join().expect("cycle thread");
    into.stats.merge(r.stats.as_ref().expect("stats"));
    into.cycles += r.cycles;
    into.cpu_ns += r.cpu_ns.unwrap_or(0);
    into.wall_ns += r.wall_ns;
    r.granted
}

/// One chunk of the bare loop: only absolute sleeps and the lateness recorded (same skip
/// policy as the pacer).
fn run_bare(setup: RtSetup, rate: u64, cycles: u64, into: &mut Pooled) {
    let period_ns = 1_000_000_000 / rate;
    let out = Arc::new(Mutex::new(None));
    let out2 = out.clone();
    std::thread::Builder::new()
        .name("bare-cycle".into())
        .spawn(move || {
            setup.apply();
            let mut stats = TimingStats::new(period_ns);
            let cpu0 = clock::thread_cpu_ns();
            let t0 = clock::now_ns();
            let first = t0 + period_ns;
            let mut k = 0u64;
            let mut n = 0u64;
            while k < cycles {
                let d = first + k * period_ns;
                clock::sleep_until_ns(d);
                let woke = clock::now_ns();
                let missed = (woke - d) / period_ns;
                let late = woke - (d + missed * period_ns);
                stats.record_wakeup(late, missed);
                k += missed + 1;
                n += 1;
            }
            let wall = clock::now_ns() - t0;
            let cpu = clock::thread_cpu_ns().zip(cpu0).map(|(b, a)| b - a);
            *out2.lock().unwrap() = Some((stats, n, cpu.unwrap_or(0), wall));
        })
        .expect("spawn")
        .join()
        .expect("bare thread");
    let (stats, n, cpu, wall) = out.lock().unwrap().take().unwrap();
    into.stats.merge(&stats);
    into.cycles += n;
    into.cpu_ns += cpu;
    into.wall_ns += wall;
}

fn us(ns: u64) -> String {
    format!("{:.1}", ns as f64 / 1000.0)
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "--quick");
    let no_rt = args.iter().any(|a| a == "--no-rt");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .unwrap_or_else(|| {
            PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("target/bench/cycle_timing.md")
        });
    let ncpu = std::thread::available_parallelism().map_or(1, |n| n.get());
    let setup = if no_rt {
        RtSetup::none()
    } else {
        RtSetup::realtime(80).on_cpu(ncpu - 1)
    };
    let secs_per_kind = if quick { 1.0 } else { 4.0 };
    let chunks = if quick { 4 } else { 8 };

    let mut granted = None;
    let mut rows = Vec::new();
    for &rate in &RATES_HZ {
        let period_ns = 1_000_000_000 / rate;
        let chunk_cycles = (secs_per_kind * rate as f64 / chunks as f64) as u64;
        let mut flex = Pooled::new(period_ns);
        let mut bare = Pooled::new(period_ns);
        for c in 0..chunks {
            // alternate which goes first so neither always follows the other
            if c % 2 == 0 {
                granted = Some(run_flexid(setup, rate, chunk_cycles, &mut flex));
                run_bare(setup, rate, chunk_cycles, &mut bare);
            } else {
                run_bare(setup, rate, chunk_cycles, &mut bare);
                granted = Some(run_flexid(setup, rate, chunk_cycles, &mut flex));
            }
        }
        rows.push((rate, flex, bare));
    }
    let granted = granted.unwrap();

    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease")
        .map(|s| s.trim().to_string())
        .unwrap_or_else(|_| "?".into());
    let rt_kernel = std::path::Path::new("/sys/kernel/realtime").exists();
    let mut md = String::new();
    writeln!(
        md,
        "Cycle thread wake-up lateness, {} s per rate and kind in {} interleaved chunks; \
         {} CPUs, kernel {} ({}).",
        secs_per_kind,
        chunks,
        ncpu,
        kernel,
        if rt_kernel {
            "PREEMPT_RT"
        } else {
            "no RT kernel"
        }
    )
    .unwrap();
    writeln!(
        md,
        "Asked: {:?}. Granted: SCHED_FIFO {}, mlockall {}, CPU {}.{}",
        setup,
        granted
            .fifo_priority
            .map_or("no".into(), |p| format!("priority {p}")),
        if granted.memory_locked { "yes" } else { "no" },
        granted.cpu.map_or("any".into(), |c| c.to_string()),
        if granted.refused.is_empty() {
            String::new()
        } else {
            format!(" Refused: {}", granted.refused.join("; "))
        }
    )
    .unwrap();
    writeln!(md).unwrap();
    writeln!(
        md,
        "| rate | loop | cycles | p50 µs | p99 µs | p99.9 µs | max µs | late (>10 % period) | overruns | CPU of the thread | body p50/p99 µs | p99 flexid/bare |"
    )
    .unwrap();
    writeln!(md, "|---|---|---|---|---|---|---|---|---|---|---|---|").unwrap();
    for (rate, flex, bare) in &rows {
        let f = flex.stats.lateness.summary();
        let b = bare.stats.lateness.summary();
        let ratio = f.p99_ns as f64 / b.p99_ns.max(1) as f64;
        for (name, p, s, last) in [
            ("flexid", flex, f, format!("**{ratio:.2}x**")),
            ("bare", bare, b, String::new()),
        ] {
            let body = if name == "flexid" {
                let bs = p.stats.body.summary();
                format!("{} / {}", us(bs.p50_ns), us(bs.p99_ns))
            } else {
                "-".into()
            };
            writeln!(
                md,
                "| {} kHz | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} % | {} | {} |",
                rate / 1000,
                name,
                p.cycles,
                us(s.p50_ns),
                us(s.p99_ns),
                us(s.p999_ns),
                us(s.max_ns),
                p.stats.late_wakeups,
                p.stats.overruns,
                100.0 * p.cpu_ns as f64 / p.wall_ns.max(1) as f64,
                body,
                last
            )
            .unwrap();
        }
    }
    print!("{md}");
    if let Some(dir) = out.parent() {
        std::fs::create_dir_all(dir).expect("create the report directory");
    }
    std::fs::write(&out, &md).expect("write the report");
    println!("written to {}", out.display());
}
