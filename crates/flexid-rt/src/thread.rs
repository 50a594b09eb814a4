//! [`spawn_cycle_thread`]: a plain OS thread that applies an [`RtSetup`], paces a body at a
//! fixed period and returns its [`CycleReport`].

use std::ops::ControlFlow;
use std::thread::JoinHandle;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::clock;
use super::pacer::{check_period, Pacer, Tick};
use super::setup::{RtGranted, RtSetup};
use super::stats::{LatencySummary, TimingStats};
use super::RtError;

/// The timing report of a cycle thread (serialisable; the sweep's result carries it).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CycleReport {
    /// Thread name.
    pub name: String,
    /// Period, ns.
    pub period_ns: u64,
    /// Cycle rate, Hz.
    pub rate_hz: f64,
    /// What was asked for.
    pub setup: RtSetup,
    /// What was granted.
    pub granted: RtGranted,
    /// Body calls (cycles run).
    pub cycles: u64,
    /// Wake-up lateness from the deadline waited for, ns (includes skipped periods after
    /// an overrun; see [`TimingStats`]).
    pub lateness: LatencySummary,
    /// Run time of the body per cycle, ns.
    pub body: LatencySummary,
    /// A wake-up later than this (10 % of the period), ns, counts as late.
    pub late_threshold_ns: u64,
    /// Wake-ups later than `late_threshold_ns`.
    pub late_wakeups: u64,
    /// Wake-ups after which deadlines were skipped (overruns).
    pub overruns: u64,
    /// Deadlines skipped in total (skip policy: never caught up).
    pub missed_deadlines: u64,
    /// Wall time of the loop, ns.
    pub wall_ns: u64,
    /// CPU time of the thread during the loop, ns (`None` where not measurable).
    pub cpu_ns: Option<u64>,
    /// `cpu_ns / wall_ns`: the share of one core the cycle takes (0..1).
    pub cpu_share: Option<f64>,
    /// The full histograms (not serialised), e.g. to merge runs.
    #[serde(skip)]
    pub stats: Option<TimingStats>,
}

/// Spawns a thread named `name` (Linux shows 15 bytes) that applies `setup`, then calls
/// `body` once per `period` on absolute deadlines (first one a period after the setup)
/// until it returns [`ControlFlow::Break`]; joins to its [`CycleReport`].
///
/// The loop allocates nothing after start-up: what `body` does is its own business.
/// Errors: [`RtError::InvalidPeriod`], [`RtError::Spawn`]. A panic in `body` surfaces
/// from `join`.
pub fn spawn_cycle_thread<F>(
    name: &str,
    setup: RtSetup,
    period: Duration,
    body: F,
) -> Result<JoinHandle<CycleReport>, RtError>
where
    F: FnMut(&Tick) -> ControlFlow<()> + Send + 'static,
{
    check_period(period)?;
    let owned = name.to_string();
    let h = std::thread::Builder::new()
        .name(owned.clone())
        .spawn(move || {
            run_cycle_loop(&owned, setup, period, body).expect("period checked before spawn")
        })?;
    Ok(h)
}

/// The loop of [`spawn_cycle_thread`] on the calling thread (which `setup` then applies
/// to: it keeps the priority and affinity afterwards).
pub fn run_cycle_loop<F>(
    name: &str,
    setup: RtSetup,
    period: Duration,
    mut body: F,
) -> Result<CycleReport, RtError>
where
    F: FnMut(&Tick) -> ControlFlow<()>,
{
    let period_ns = check_period(period)?;
    let granted = setup.apply();
    tracing::info!(
        thread = name,
        period_ns,
        fifo = ?granted.fifo_priority,
        memory_locked = granted.memory_locked,
        cpu = ?granted.cpu,
        "cycle thread starting"
    );
    prefault_stack();
    let mut stats = TimingStats::new(period_ns);
    let mut pacer = Pacer::new(period)?;
    let cpu0 = clock::thread_cpu_ns();
    let t0 = clock::now_ns();
    let mut cycles = 0u64;
    loop {
        let tick = pacer.wait_next();
        stats.record_wakeup(tick.lateness_ns, tick.missed);
        let flow = body(&tick);
        cycles += 1;
        let woke = tick.deadline_ns + tick.lateness_ns;
        stats.record_body(clock::now_ns().saturating_sub(woke));
        if flow.is_break() {
            break;
        }
    }
    let wall_ns = clock::now_ns() - t0;
    let cpu_ns = match (cpu0, clock::thread_cpu_ns()) {
        (Some(a), Some(b)) => Some(b.saturating_sub(a)),
        _ => None,
    };
    let report = CycleReport {
        name: name.to_string(),
        period_ns,
        rate_hz: 1e9 / period_ns as f64,
        setup,
        granted,
        cycles,
        lateness: stats.lateness.summary(),
        body: stats.body.summary(),
        late_threshold_ns: stats.late_threshold_ns,
        late_wakeups: stats.late_wakeups,
        overruns: stats.overruns,
        missed_deadlines: stats.missed_deadlines,
        wall_ns,
        cpu_ns,
        cpu_share: cpu_ns.map(|c| c as f64 / wall_ns.max(1) as f64),
        stats: Some(stats),
    };
    tracing::info!(
        thread = name,
        cycles,
        p99_ns = report.lateness.p99_ns,
        max_ns = report.lateness.max_ns,
        late = report.late_wakeups,
        overruns = report.overruns,
        missed = report.missed_deadlines,
        "cycle thread done"
    );
    Ok(report)
}

/// Touches 64 KiB of stack so the loop does not fault pages in (locked by `mlockall`
/// when granted).
#[inline(never)]
fn prefault_stack() {
    let mut buf = [0u8; 64 * 1024];
    for i in (0..buf.len()).step_by(4096) {
        // SAFETY: in-bounds write to a local array.
        unsafe { std::ptr::write_volatile(&mut buf[i], 1) };
    }
    std::hint::black_box(&buf);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_until_break_and_reports() {
        let mut n = 0;
        let h = spawn_cycle_thread(
            "t-cycle",
            RtSetup::none(),
            Duration::from_micros(500),
            move |t| {
                assert_eq!(t.index, n + t.missed);
                n = t.index + 1;
                if t.index >= 199 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            },
        )
        .unwrap();
        let r = h.join().unwrap();
        assert!(r.cycles >= 1 && r.cycles <= 200);
        assert_eq!(r.lateness.count, r.cycles);
        assert_eq!(r.body.count, r.cycles);
        assert_eq!(r.period_ns, 500_000);
        assert!((r.rate_hz - 2000.0).abs() < 1e-9);
        // grid index 199 reached: wall time about 200 periods
        assert!(r.wall_ns >= 199 * 500_000, "{}", r.wall_ns);
        let json = serde_json::to_string(&r).unwrap();
        let back: CycleReport = serde_json::from_str(&json).unwrap();
        assert_eq!(back.cycles, r.cycles);
        assert!(back.stats.is_none());
    }

    /// An injected slow body: deadlines are skipped and counted, never caught up. (The
    /// host may stall the thread too, PREEMPT_NONE here: the checks hold whatever else
    /// it skips.)
    #[test]
    fn slow_body_overruns_are_counted_and_skipped() {
        let period = Duration::from_millis(2);
        let served = std::sync::Arc::new(std::sync::Mutex::new(Vec::new()));
        let log = served.clone();
        let h = spawn_cycle_thread("t-slow", RtSetup::none(), period, move |t| {
            log.lock().unwrap().push(t.index);
            if t.index == 5 {
                std::thread::sleep(Duration::from_millis(7)); // 3.5 periods
            }
            if t.index >= 30 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        })
        .unwrap();
        let r = h.join().unwrap();
        let served = served.lock().unwrap().clone();
        assert!(r.overruns >= 1);
        // 7 ms from deadline 5: deadlines 6 and 7 skipped (2.5 periods past), the next
        // served is 8 or later: never a burst of the missed ones
        let after5 = served[served.iter().position(|&i| i == 5).unwrap() + 1];
        assert!(after5 >= 8, "served after 5: {after5} ({served:?})");
        assert!(served.windows(2).all(|w| w[1] > w[0]), "{served:?}");
        assert!(r.missed_deadlines >= 2, "{}", r.missed_deadlines);
        // every grid slot up to the last served is either a cycle or a skipped deadline
        let last = *served.last().unwrap();
        assert_eq!(r.cycles, served.len() as u64);
        assert_eq!(r.cycles + r.missed_deadlines, last + 1, "{served:?}");
        assert!(r.late_wakeups >= 1);
        // the stall is visible in the lateness: >= 2 periods on the deadline waited for
        assert!(r.lateness.max_ns >= 4_000_000, "{}", r.lateness.max_ns);
    }

    #[test]
    fn zero_period_refused_before_spawn() {
        let e = spawn_cycle_thread("t", RtSetup::none(), Duration::ZERO, |_| {
            ControlFlow::Break(())
        });
        assert!(matches!(e, Err(RtError::InvalidPeriod { .. })));
    }
}
