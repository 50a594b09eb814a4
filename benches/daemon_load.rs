//! The daemon under load (`scripts/bench.sh` runs it; see the README's daemon section):
//! the real `flexid daemon` (CANopen backend, real-time clock, 1 kHz unless `--rate-hz`) with one and then
//! two axes sweeping on real `flexid-vdrive`s (`--clock realtime`, each on its own UDP
//! bus), against the same daemon idle in the same run.
//!
//! Reported:
//!
//! * the daemon process's CPU time per second of wall time (`/proc/PID/stat` utime+stime)
//!   while idle, with 1 axis and with 2 axes sweeping, and per axis
//!   `(share(N) - share(idle)) / N`;
//! * the time from the end of a period on the cycle thread (`CLOCK_MONOTONIC`, carried in
//!   the progress event's `counters.period_end_mono_ns`) to the arrival of that period's
//!   Bode update on the SSE stream at this client (same clock, same host): p50, p99, max;
//! * how each sweep ended and its cycle timing (late wake-ups, overruns, lost TPDOs).
//!
//! Printed and written to `target/bench/daemon_load.md`. Arguments: `[--quick]
//! [--rate-hz HZ] [--out FILE]`
//! (`--quick`: 3 s sweeps of 0.25 s periods instead of 10 s; other arguments, e.g. cargo's
//! `--bench`, are ignored). Skips (exit 0, a message) when 239.0.0.0/8 is not on `lo`.

#[path = "../tests/daemon_common/mod.rs"]
mod daemon_common;
#[path = "../tests/e2e/mod.rs"]
mod e2e;

use daemon_common::process::{canopen_config, CanAxis, DaemonProc, GROUP};
use daemon_common::{auth, client, start_sweep_at, token_file, Sse};
use e2e::{loopback_multicast, plant_path, VDrive, FLEXID};
use flexid::rt::clock;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Default cycle rate [Hz] (`--rate-hz` changes it).
const RATE_HZ: f64 = 1000.0;

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

fn pct(sorted: &[u64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * q).round() as usize;
    sorted[i] as f64 / 1e6
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
    let rate_hz: f64 = args
        .iter()
        .position(|a| a == "--rate-hz")
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(RATE_HZ);
    let (duration_s, periods) = if quick { (3.0, 11) } else { (10.0, 39) };
    let body = format!(
        r#"{{"excitation":"multisine","band_hz":[4,{hi}],"amplitude_nm":0.3,"periods":{periods},"duration_s":{duration_s}}}"#,
        hi = (0.3 * rate_hz).round()
    );
    let ports = [43331u16, 43332];
    let _vds: Vec<VDrive> = ports
        .iter()
        .map(|p| VDrive::start_clocked(&format!("udp:{GROUP}:{p}"), &plant_path(), "realtime"))
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
            a
        })
        .collect();
    let cfg = canopen_config(tmp.path(), &token, &axes, "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let pid = d.child.id();
    // let the start-up settle
    tokio::time::sleep(Duration::from_millis(500)).await;

    let mut report = String::new();
    let _ = writeln!(
        report,
        "# Daemon load (CANopen backend, {rate_hz} Hz real time, flexid-vdrive --clock realtime)\n\n\
         {duration_s} s sweeps of {periods}+1 periods; CPU = daemon process CPU time / wall time.\n"
    );
    // idle reference
    let c0 = process_cpu_ns(pid);
    let t0 = Instant::now();
    tokio::time::sleep(Duration::from_secs_f64(duration_s)).await;
    let idle = (process_cpu_ns(pid) - c0) as f64 / t0.elapsed().as_nanos() as f64;
    let _ = writeln!(
        report,
        "| axes sweeping | daemon CPU share | per axis (minus idle) | period end -> Bode p50 | p99 | max | sweeps |\n\
         |---|---|---|---|---|---|---|\n| 0 (idle) | {:.2} % | - | - | - | - | - |",
        100.0 * idle
    );
    let mut notes = Vec::new();
    for n in [1usize, 2] {
        let mut ids = Vec::new();
        let c0 = process_cpu_ns(pid);
        let t0 = Instant::now();
        for a in &axes[..n] {
            ids.push(start_sweep_at(&d.base, a.name, &body).await);
        }
        let joins: Vec<_> = ids
            .iter()
            .map(|id| tokio::spawn(follow(d.base.clone(), id.clone())))
            .collect();
        let mut lat = Vec::new();
        let mut ends = Vec::new();
        for j in joins {
            let (l, e) = j.await.unwrap();
            lat.extend(l);
            ends.push(e);
        }
        let wall = t0.elapsed();
        let share = (process_cpu_ns(pid) - c0) as f64 / wall.as_nanos() as f64;
        lat.sort_unstable();
        let mut how = Vec::new();
        for (id, e) in ids.iter().zip(&ends) {
            let sc: serde_json::Value =
                auth(client().get(d.url(&format!("/api/v1/sweeps/{id}/recording.json"))))
                    .send()
                    .await
                    .unwrap()
                    .json()
                    .await
                    .unwrap_or_default();
            let t = &sc["cycle_timing"];
            how.push(format!(
                "{} ({} late wake-ups, {} overruns, {} lost TPDOs, p99 lateness {:.0} us)",
                e.data["outcome"].as_str().unwrap_or("?"),
                t["late_wakeups"],
                t["overruns"],
                sc["cycle_counters"]["lost"],
                t["lateness"]["p99_ns"].as_f64().unwrap_or(f64::NAN) / 1e3
            ));
        }
        let _ = writeln!(
            report,
            "| {n} | {:.2} % | {:.2} % | {:.2} ms | {:.2} ms | {:.2} ms | {} |",
            100.0 * share,
            100.0 * (share - idle) / n as f64,
            pct(&lat, 0.5),
            pct(&lat, 0.99),
            pct(&lat, 1.0),
            how.join("; ")
        );
        notes.push(format!("{} Bode updates timed with {n} axes", lat.len()));
    }
    let _ = writeln!(report, "\n{}.", notes.join("; "));
    print!("{report}");
    if let Some(dir) = out.parent() {
        let _ = std::fs::create_dir_all(dir);
    }
    std::fs::write(&out, &report).unwrap();
    eprintln!("written to {}", out.display());
}
