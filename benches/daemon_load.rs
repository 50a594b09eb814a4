//! The daemon under load (`scripts/bench.sh` runs it; see docs/benchmarks.md, "Daemon load"): the
//! real `flexid daemon` (CANopen backend, `clock = "monotonic"`) with one and then two axes
//! sweeping on real `flexid-vdrive`s (`--clock realtime`, each on its own UDP bus), against
//! the same daemon idle in the same run, at 1, 2 and 4 kHz.
//!
//! Reported per rate and number of sweeping axes:
//!
//! * the daemon process's CPU time per second of wall time (`/proc/PID/stat` utime+stime)
//!   and per axis `(share(N) - share(idle)) / N`;
//! * the time from the end of a period on the cycle thread (`CLOCK_MONOTONIC`, carried in
//!   the progress event's `counters.period_end_mono_ns`) to the arrival of that period's
//!   Bode update on the SSE stream at this client (same clock, same host): p50, p99;
//! * the wake-up lateness of the daemon's cycle thread (p50/p99/p99.9/max, from the
//!   sweep's sidecar `cycle_timing`; with two axes the worse axis per percentile) next to
//!   that of a **bare loop** in this process that only sleeps to absolute deadlines of the
//!   same period with the same skip policy, under the same real-time setup the daemon asks
//!   for its cycle thread (`SCHED_FIFO` 80, locked memory), over the same wall time as the
//!   sweeps (started before the first request, stopped after the last `ended` event);
//! * the host's stalls in the same window: the share of the bare loop's wake-ups more than
//!   half a period late (an overrun for the cycle, and its feedback likely lost);
//! * how each sweep ended (late wake-ups, overruns, lost TPDOs; the axes' stated budget
//!   `limits.max_lost_tpdos` is [`LOST_BUDGET_SHARE`] of the cycles). A measurement in which a
//!   sweep stopped (the feedback-loss supervisor on a host that stalls) is repeated up to
//!   2 times (`--quick`: once); the table shows the last attempt, the notes every earlier
//!   one.
//!
//! The drives: `flexid-vdrive` answers every SYNC from its receive path (no cycle timer of
//! its own) and serves its bus under `SCHED_FIFO` 85 (`--fifo-priority`), standing for a
//! drive's firmware. The bus: `udp` with `bitrate = 1000000` (classic CAN) where the
//! default mapping is admitted (1 kHz: 38 % load), else `bitrate = 100000000`, a udp bus
//! standing for an EtherCAT-class transport (2 and 4 kHz do not fit 1 Mbit/s: 76 % and
//! 145 %). The UDP bus emulates no wire time in either case.
//!
//! Printed and written to `target/bench/daemon_load.md`. Arguments: `[--quick]
//! [--rate-hz HZ]... [--out FILE]` (`--quick`: 3 s sweeps of 0.25 s periods instead of 10 s;
//! `--rate-hz` once or more: only those rates; other arguments, e.g. cargo's `--bench`,
//! are ignored). Skips (exit 0, a message) when 239.0.0.0/8 is not on `lo`.

#[path = "../tests/daemon_common/mod.rs"]
mod daemon_common;
#[path = "../tests/e2e/mod.rs"]
mod e2e;

use daemon_common::process::{canopen_config, CanAxis, DaemonProc, GROUP};
use daemon_common::{auth, client, start_sweep_at, token_file, Sse};
use e2e::{loopback_multicast, plant_path, VDrive, FLEXID};
use flexid::daemon::canopen_backend::CYCLE_FIFO_PRIORITY;
use flexid::rt::{clock, LatencySummary, RtGranted, RtSetup, TimingStats};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Cycle rates measured by default [Hz].
const RATES_HZ: [f64; 3] = [1000.0, 2000.0, 4000.0];
/// The drives' SYNC-loss window [s] (`flexid-vdrive --sync-loss-cycles`).
const SYNC_LOSS_WINDOW_S: f64 = 0.1;

/// `SCHED_FIFO` priority of the `flexid-vdrive` processes (above the cycle thread's 80: a
/// drive's firmware answers whatever the master's host does).
const VDRIVE_FIFO_PRIORITY: &str = "85";
/// The benchmark axes' lost-feedback budget (`limits.max_lost_tpdos`) as a share of a
/// sweep's cycles: the benchmark measures load and latency, not the supervisor, and a host
/// without a real-time kernel loses feedback in every scheduling stall (the daemon's
/// default, 0.5 % of the cycles, stops most sweeps on such a host).
const LOST_BUDGET_SHARE: f64 = 0.10;
/// Classic CAN [bit/s].
const CAN_BITRATE: u32 = 1_000_000;
/// A udp bus standing for an EtherCAT-class transport [bit/s].
const FAST_BITRATE: u32 = 100_000_000;

/// The kernel's preemption model: `CONFIG_PREEMPT_*` from `/proc/config.gz`, a `preempt=`
/// boot argument, `/sys/kernel/realtime`, else `uname -v`; with the kernel release.
fn preemption_model() -> String {
    let release = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default();
    let mut model = std::process::Command::new("zcat")
        .arg("/proc/config.gz")
        .output()
        .ok()
        .and_then(|o| {
            let text = String::from_utf8_lossy(&o.stdout).into_owned();
            [
                "PREEMPT_RT",
                "PREEMPT_NONE",
                "PREEMPT_VOLUNTARY",
                "PREEMPT_LAZY",
                "PREEMPT",
            ]
            .into_iter()
            .find(|m| text.lines().any(|l| l == format!("CONFIG_{m}=y")))
            .map(|m| format!("CONFIG_{m}"))
        });
    if std::fs::read_to_string("/sys/kernel/realtime").is_ok_and(|v| v.trim() == "1") {
        model = Some("PREEMPT_RT (/sys/kernel/realtime)".into());
    }
    let cmdline = std::fs::read_to_string("/proc/cmdline").unwrap_or_default();
    if let Some(p) = cmdline
        .split_whitespace()
        .find(|a| a.starts_with("preempt="))
    {
        model = Some(format!("{} ({p})", model.unwrap_or_default()));
    }
    let model = model.unwrap_or_else(|| {
        let v = std::fs::read_to_string("/proc/sys/kernel/version").unwrap_or_default();
        format!("unknown (uname -v: {})", v.trim())
    });
    format!("{model}, kernel {}", release.trim())
}

/// utime + stime of `pid` [ns].
fn process_cpu_ns(pid: u32) -> u64 {
    let text = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
    // fields after the command name (which may hold spaces): state is field 3
    let rest = text.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
    // utime, stime are fields 14 and 15 (1-based) = indexes 11, 12 after the name
    // SAFETY: sysconf has no preconditions.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as u64;
    (ticks(11) + ticks(12)) * 1_000_000_000 / hz
}

/// A bare loop on a thread of its own: sleeps to absolute deadlines of `period_ns` with
/// the sweep's skip policy (a wake-up more than half a period late restarts the slots
/// from now) and records the lateness from the deadline it waited for, until `stop`.
struct BareLoop {
    stop: Arc<AtomicBool>,
    thread: std::thread::JoinHandle<(TimingStats, RtGranted)>,
}

impl BareLoop {
    fn start(period_ns: u64, setup: RtSetup) -> BareLoop {
        let stop = Arc::new(AtomicBool::new(false));
        let flag = stop.clone();
        let thread = std::thread::Builder::new()
            .name("bare-loop".into())
            .spawn(move || {
                let granted = setup.apply();
                let mut stats = TimingStats::new(period_ns);
                let mut slot = clock::now_ns();
                while !flag.load(Ordering::Relaxed) {
                    let now = clock::now_ns();
                    if now > slot + period_ns / 2 {
                        slot = now;
                        stats.overruns += 1;
                    }
                    slot += period_ns;
                    clock::sleep_until_ns(slot);
                    stats.record_wakeup(clock::now_ns().saturating_sub(slot), 0);
                }
                (stats, granted)
            })
            .expect("spawn the bare loop");
        BareLoop { stop, thread }
    }

    fn stop(self) -> (TimingStats, RtGranted) {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.join().expect("bare loop")
    }
}

/// Reads one sweep's SSE stream; returns the end-of-period -> Bode latencies [ns] and the
/// `ended` event.
async fn follow(base: String, id: String) -> (Vec<u64>, Sse) {
    use futures_util::StreamExt;
    let r = auth(client().get(format!("{base}/api/v1/sweeps/{id}/events")))
        .send()
        .await
        .unwrap();
    let mut stream = r.bytes_stream();
    let mut buf = String::new();
    let mut period_end: std::collections::HashMap<u64, u64> = Default::default();
    let mut lat = Vec::new();
    while let Some(chunk) = stream.next().await {
        buf.push_str(&String::from_utf8_lossy(&chunk.unwrap()));
        while let Some(end) = buf.find("\n\n") {
            let block: String = buf.drain(..end + 2).collect();
            let now = clock::now_ns();
            let mut event = String::new();
            let mut data = String::new();
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("event:") {
                    event = v.trim().into();
                } else if let Some(v) = line.strip_prefix("data:") {
                    data.push_str(v.trim_start());
                }
            }
            let Ok(v) = serde_json::from_str::<serde_json::Value>(&data) else {
                continue;
            };
            let period = v["period"].as_u64().unwrap_or(0);
            match event.as_str() {
                "progress" => {
                    if let Some(t) = v["counters"]["period_end_mono_ns"].as_u64() {
                        period_end.insert(period, t);
                    }
                }
                "bode" => {
                    if let Some(t) = period_end.get(&period).filter(|t| **t > 0) {
                        lat.push(now.saturating_sub(*t));
                    }
                }
                "ended" => return (lat, Sse { event, data: v }),
                _ => {}
            }
        }
    }
    panic!("sweep {id}: the event stream closed before its end");
}

/// The `q` quantile of `sorted` [ns] as `"1.5 ms"`, or `"-"` when nothing was timed.
fn pct_ms(sorted: &[u64], q: f64) -> String {
    if sorted.is_empty() {
        return "-".to_string();
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    format!("{:.1} ms", sorted[i] as f64 / 1e6)
}

/// `p50 / p99 / p99.9 / max` in µs.
fn lateness_us(s: &LatencySummary) -> String {
    let us = |ns: u64| ns as f64 / 1e3;
    format!(
        "{:.0} / {:.0} / {:.0} / {:.0}",
        us(s.p50_ns),
        us(s.p99_ns),
        us(s.p999_ns),
        us(s.max_ns)
    )
}

/// The percentile-wise worse of two lateness summaries.
fn worse(a: LatencySummary, b: &LatencySummary) -> LatencySummary {
    LatencySummary {
        count: a.count + b.count,
        p50_ns: a.p50_ns.max(b.p50_ns),
        p99_ns: a.p99_ns.max(b.p99_ns),
        p999_ns: a.p999_ns.max(b.p999_ns),
        max_ns: a.max_ns.max(b.max_ns),
        mean_ns: a.mean_ns.max(b.mean_ns),
    }
}

/// One rate: vdrives and daemon started afresh; the table rows (idle, 1 axis, 2 axes).
async fn run_rate(rate_hz: f64, quick: bool, notes: &mut Vec<String>) -> String {
    let (duration_s, periods, idle_s, attempts) = if quick {
        (3.0, 11, 2.0, 2)
    } else {
        (10.0, 39, 5.0, 3)
    };
    let body = format!(
        r#"{{"excitation":"multisine","band_hz":[4,{hi}],"amplitude_nm":0.3,"periods":{periods},"duration_s":{duration_s}}}"#,
        hi = (0.3 * rate_hz).round()
    );
    let bitrate = if flexid::sweep::admission_check(rate_hz, CAN_BITRATE).is_ok() {
        CAN_BITRATE
    } else {
        FAST_BITRATE
    };
    let bus = if bitrate == CAN_BITRATE {
        "udp, 1 Mbit/s (CAN)".to_string()
    } else {
        "udp, 100 Mbit/s (EtherCAT-class)".to_string()
    };
    let max_lost = (LOST_BUDGET_SHARE * duration_s * rate_hz).ceil() as u64;
    // the drives' SYNC-loss window: 100 ms, so that one stall of a shared host shows up
    // as lateness here instead of ending the sweep (the 3-period supervision is tested in
    // tests/e2e_sweep.rs)
    let sync_loss_cycles = ((SYNC_LOSS_WINDOW_S * rate_hz).ceil() as u16).to_string();
    let ports = [43331u16, 43332];
    let _vds: Vec<VDrive> = ports
        .iter()
        .map(|p| {
            VDrive::start_with(
                &format!("udp:{GROUP}:{p}"),
                &plant_path(),
                "realtime",
                &[
                    "--fifo-priority",
                    VDRIVE_FIFO_PRIORITY,
                    "--sync-loss-cycles",
                    &sync_loss_cycles,
                ],
            )
        })
        .collect();
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let axes: Vec<CanAxis> = ["b1", "b2"]
        .iter()
        .zip(ports)
        .map(|(n, p)| {
            let mut a = CanAxis::new(n, p);
            a.clock = "monotonic";
            a.cycle_hz = rate_hz;
            a.bitrate = bitrate;
            a.max_lost_tpdos = Some(max_lost);
            a
        })
        .collect();
    let cfg = canopen_config(tmp.path(), &token, &axes, "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let pid = d.child.id();
    // let the start-up settle
    tokio::time::sleep(Duration::from_millis(500)).await;
    let rate = format!("{} kHz", rate_hz / 1000.0);

    let mut rows = String::new();
    let c0 = process_cpu_ns(pid);
    let t0 = Instant::now();
    tokio::time::sleep(Duration::from_secs_f64(idle_s)).await;
    let idle = (process_cpu_ns(pid) - c0) as f64 / t0.elapsed().as_nanos() as f64;
    let _ = writeln!(
        rows,
        "| {rate} | {bus} | 0 (idle) | {:.1} % | - | - | - | - | - | - | - | - |",
        100.0 * idle
    );
    let period_ns = (1e9 / rate_hz).round() as u64;
    for n in [1usize, 2] {
        let mut failed = Vec::new();
        let mut t = trial(&d, &axes[..n], &body, period_ns).await;
        while !t.all_completed() && failed.len() + 1 < attempts {
            failed.push(t.how.join("; "));
            t = trial(&d, &axes[..n], &body, period_ns).await;
        }
        let share = t.cpu_ns as f64 / t.wall.as_nanos() as f64;
        let bare_sum = t.bare.lateness.summary();
        let (cycle_txt, ratio) = match &t.cycle {
            Some(c) if c.count > 0 => (
                lateness_us(c),
                format!(
                    "**{:.2}x**",
                    c.p99_ns as f64 / bare_sum.p99_ns.max(1) as f64
                ),
            ),
            _ => ("-".to_string(), "-".to_string()),
        };
        let stalls = 100.0 * t.bare.overruns as f64 / bare_sum.count.max(1) as f64;
        let tries = if failed.is_empty() {
            String::new()
        } else {
            format!(" [attempt {} of {attempts}]", failed.len() + 1)
        };
        let _ = writeln!(
            rows,
            "| {rate} | {bus} | {n} | {:.1} % | {:.1} % | {} | {} | {cycle_txt} | {} | {ratio} | {stalls:.2} % | {}{tries} |",
            100.0 * share,
            100.0 * (share - idle) / n as f64,
            pct_ms(&t.bode_ns, 0.5),
            pct_ms(&t.bode_ns, 0.99),
            lateness_us(&bare_sum),
            t.how.join("; ")
        );
        let daemon_prio = t
            .fifo
            .iter()
            .map(|p| p.map_or("normal".to_string(), |p| format!("FIFO {p}")))
            .collect::<Vec<_>>()
            .join(", ");
        let mut note = format!(
            "{rate}, {n} axis: {} Bode updates timed; {} bare-loop wake-ups; cycle thread(s) \
             {daemon_prio}, bare loop {}; lost-feedback budget {max_lost} TPDOs per sweep",
            t.bode_ns.len(),
            bare_sum.count,
            t.bare_granted
                .fifo_priority
                .map_or("normal".to_string(), |p| format!("FIFO {p}")),
        );
        for (i, f) in failed.iter().enumerate() {
            let _ = write!(note, "; attempt {}: {f}", i + 1);
        }
        notes.push(note);
    }
    rows
}

/// One measurement: `axes` sweeping at once, a bare loop alongside.
struct Trial {
    /// Daemon CPU time over `wall` [ns].
    cpu_ns: u64,
    wall: Duration,
    /// Period end -> Bode latencies, sorted [ns].
    bode_ns: Vec<u64>,
    /// The cycle threads' lateness (the worse axis per percentile).
    cycle: Option<LatencySummary>,
    /// The cycle threads' `SCHED_FIFO` priorities.
    fifo: Vec<Option<u64>>,
    bare: TimingStats,
    bare_granted: RtGranted,
    /// How each sweep ended.
    how: Vec<String>,
    completed: usize,
}

impl Trial {
    fn all_completed(&self) -> bool {
        self.completed == self.how.len()
    }
}

async fn trial(d: &DaemonProc, axes: &[CanAxis<'_>], body: &str, period_ns: u64) -> Trial {
    let pid = d.child.id();
    let bare = BareLoop::start(period_ns, RtSetup::realtime(CYCLE_FIFO_PRIORITY));
    let mut ids = Vec::new();
    let c0 = process_cpu_ns(pid);
    let t0 = Instant::now();
    for a in axes {
        ids.push(start_sweep_at(&d.base, a.name, body).await);
    }
    let joins: Vec<_> = ids
        .iter()
        .map(|id| tokio::spawn(follow(d.base.clone(), id.clone())))
        .collect();
    let mut bode_ns = Vec::new();
    let mut ends = Vec::new();
    for j in joins {
        let (l, e) = j.await.unwrap();
        bode_ns.extend(l);
        ends.push(e);
    }
    let wall = t0.elapsed();
    let cpu_ns = process_cpu_ns(pid) - c0;
    let (bare, bare_granted) = bare.stop();
    bode_ns.sort_unstable();
    let mut t = Trial {
        cpu_ns,
        wall,
        bode_ns,
        cycle: None,
        fifo: Vec::new(),
        bare,
        bare_granted,
        how: Vec::new(),
        completed: 0,
    };
    for (id, e) in ids.iter().zip(&ends) {
        let sc: serde_json::Value =
            auth(client().get(d.url(&format!("/api/v1/sweeps/{id}/recording.json"))))
                .send()
                .await
                .unwrap()
                .json()
                .await
                .unwrap_or_default();
        let ct = &sc["cycle_timing"];
        if let Ok(s) = serde_json::from_value::<LatencySummary>(ct["lateness"].clone()) {
            t.cycle = Some(match t.cycle {
                Some(c) => worse(c, &s),
                None => s,
            });
        }
        t.fifo.push(ct["fifo_priority"].as_u64());
        let outcome = e.data["outcome"].as_str().unwrap_or("?");
        let why = if outcome == "completed" {
            t.completed += 1;
            String::new()
        } else {
            format!(
                ": {}",
                e.data["reason"].as_str().unwrap_or("?").replace('|', "/")
            )
        };
        t.how.push(format!(
            "{outcome}{why} ({} late, {} overruns, {} lost TPDOs)",
            ct["late_wakeups"], ct["overruns"], sc["cycle_counters"]["lost"],
        ));
    }
    t
}

#[tokio::main(flavor = "multi_thread", worker_threads = 2)]
async fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let quick = args.iter().any(|a| a == "--quick");
    let out = args
        .iter()
        .position(|a| a == "--out")
        .and_then(|i| args.get(i + 1))
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("target/bench/daemon_load.md"));
    if !loopback_multicast() {
        return;
    }
    let mut rates: Vec<f64> = args
        .windows(2)
        .filter(|w| w[0] == "--rate-hz")
        .filter_map(|w| w[1].parse().ok())
        .collect();
    if rates.is_empty() {
        rates = RATES_HZ.to_vec();
    }
    let load = std::fs::read_to_string("/proc/loadavg").unwrap_or_default();
    let master = flexid_canopen::MasterConfig::default();
    let cpus = std::thread::available_parallelism().map_or(0, |n| n.get());
    let mut report = String::new();
    let _ = writeln!(
        report,
        "# Daemon load (CANopen backend, real time; flexid-vdrive --clock realtime --fifo-priority {VDRIVE_FIFO_PRIORITY})\n\n\
         {} s sweeps; CPU = daemon process CPU time / wall time; lateness in µs \
         (p50 / p99 / p99.9 / max; 2 axes: the worse axis); host stalls = bare-loop wake-ups \
         more than half a period late; load average at the start: {}\n\n\
         Host: {cpus} CPUs, preemption model {}: without a real-time kernel a `SCHED_FIFO` \
         thread is held off its CPU now and then (the bare loop's lateness and host stalls \
         show how much in this run). Supervisors: lost-feedback budget \
         `limits.max_lost_tpdos` = {:.0} % of each sweep's cycles; the master fails a cycle \
         after {} consecutive cycles without feedback and at least {} ms of them; the drives \
         fault after {:.0} ms without SYNC.\n\n\
         | rate | bus | axes sweeping | daemon CPU | per axis (minus idle) | period end -> Bode p50 | p99 | cycle thread lateness | bare loop lateness | p99 cycle/bare | host stalls | sweeps |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|",
        if quick { 3 } else { 10 },
        load.split_whitespace().take(3).collect::<Vec<_>>().join(" "),
        preemption_model(),
        100.0 * LOST_BUDGET_SHARE,
        master.max_missed_cycles,
        master.max_missed_time.as_millis(),
        SYNC_LOSS_WINDOW_S * 1e3,
    );
    let mut notes = Vec::new();
    for r in rates {
        let rows = run_rate(r, quick, &mut notes).await;
        report.push_str(&rows);
    }
    let _ = writeln!(report, "\n{}.", notes.join(";\n"));
    print!("{report}");
    if let Some(dir) = out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    std::fs::write(&out, &report).unwrap();
    eprintln!("written to {}", out.display());
}
