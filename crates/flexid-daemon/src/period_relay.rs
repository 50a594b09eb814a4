//! How the CANopen backend's cycle thread hands each finished period to the async side
//! without allocating or locking: [`PeriodRows`], a buffer of atomics sized before the
//! sweep (the cycle thread stores every row, then publishes how many rows are complete),
//! and [`spawn_relay`], a thread of its own that reads each published period, estimates
//! the FRF so far and sends [`SweepEvent::Period`] (rows and Bode estimate) to the daemon.
//!
//! The cycle thread never waits for the relay: it stores, publishes and unparks it.

use super::backend::{Counters, SampleBlock, SweepEvent};
use flexid_core::frf::{differenced_velocity_into, PeriodicEstimator};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;
use tokio::sync::mpsc;

/// Rows of a running sweep, written by the cycle thread and read by the relay. Rows are
/// published in blocks (whenever the sweep loop reports progress); the relay cuts them
/// into excitation periods.
#[derive(Debug)]
pub struct PeriodRows {
    torque_nm: Box<[AtomicU64]>,
    position_rad: Box<[AtomicU64]>,
    velocity_rad_s: Box<[AtomicU64]>,
    torque_actual_nm: Box<[AtomicU64]>,
    /// Rows readable by the relay (only whole blocks are published).
    published: AtomicUsize,
    /// Blocks (periods) published so far.
    blocks: AtomicUsize,
    /// `CLOCK_MONOTONIC` at the end of each block [ns], and the rows it ended at.
    block_end_ns: Box<[AtomicU64]>,
    block_rows: Box<[AtomicUsize]>,
    cycles: AtomicU64,
    late: AtomicU64,
    lost: AtomicU64,
    done: AtomicBool,
}

fn atomics(n: usize) -> Box<[AtomicU64]> {
    (0..n).map(|_| AtomicU64::new(0)).collect()
}

impl PeriodRows {
    /// Room for `rows` rows in at most `blocks` published blocks (allocated here, once).
    pub fn new(rows: usize, blocks: usize) -> Self {
        PeriodRows {
            torque_nm: atomics(rows),
            position_rad: atomics(rows),
            velocity_rad_s: atomics(rows),
            torque_actual_nm: atomics(rows),
            published: AtomicUsize::new(0),
            blocks: AtomicUsize::new(0),
            block_end_ns: atomics(blocks),
            block_rows: (0..blocks).map(|_| AtomicUsize::new(0)).collect(),
            cycles: AtomicU64::new(0),
            late: AtomicU64::new(0),
            lost: AtomicU64::new(0),
            done: AtomicBool::new(false),
        }
    }

    /// Store row `k` (ignored beyond the capacity: the ramp after the last row).
    #[inline]
    pub fn write(&self, k: usize, row: &flexid_sweep::Row) {
        let columns = [
            (&self.torque_nm, row.torque_setpoint_nm),
            (&self.position_rad, row.position_rad),
            (&self.velocity_rad_s, row.velocity_rad_s),
            (&self.torque_actual_nm, row.torque_actual_nm),
        ];
        for (column, v) in columns {
            if let Some(a) = column.get(k) {
                a.store(v.to_bits(), Ordering::Relaxed);
            }
        }
    }

    /// Make rows `..rows` readable: one more block, ended at `end_ns`.
    pub fn publish(&self, rows: usize, late: u64, lost: u64, end_ns: u64) {
        let b = self.blocks.load(Ordering::Relaxed);
        if let (Some(t), Some(r)) = (self.block_end_ns.get(b), self.block_rows.get(b)) {
            t.store(end_ns, Ordering::Relaxed);
            r.store(rows, Ordering::Relaxed);
        }
        self.cycles.store(rows as u64, Ordering::Relaxed);
        self.late.store(late, Ordering::Relaxed);
        self.lost.store(lost, Ordering::Relaxed);
        self.blocks.store(b + 1, Ordering::Relaxed);
        self.published
            .store(rows.min(self.torque_nm.len()), Ordering::Release);
    }

    /// No more blocks will be published.
    pub fn finish(&self) {
        self.done.store(true, Ordering::Release);
    }

    /// Rows `from..to` as a block (the four columns of the sweep loop's rows).
    fn read(&self, from: usize, to: usize) -> SampleBlock {
        let get = |v: &[AtomicU64]| -> Vec<f64> {
            v[from..to]
                .iter()
                .map(|a| f64::from_bits(a.load(Ordering::Relaxed)))
                .collect()
        };
        SampleBlock {
            first_sample: from,
            torque_cmd_nm: get(&self.torque_nm),
            position_rad: get(&self.position_rad),
            velocity_rad_s: get(&self.velocity_rad_s),
            torque_actual_nm: get(&self.torque_actual_nm),
        }
    }
}

/// What the relay needs to know about the sweep.
pub struct RelayPlan {
    /// Samples per excitation period; 0 when the excitation is not periodic (then each
    /// published block is sent as it is, without an FRF estimate).
    pub period_samples: usize,
    /// Cycle rate [Hz].
    pub sample_rate_hz: f64,
    /// The FRF estimator over the steady periods (periodic excitations).
    pub estimator: Option<PeriodicEstimator>,
}

/// Starts the relay thread: it sends one [`SweepEvent::Period`] per published period
/// (rows, FRF so far, counters) until [`PeriodRows::finish`] and then returns. Unpark the
/// returned thread after each [`PeriodRows::publish`] (it also polls every 20 ms).
pub fn spawn_relay(
    name: &str,
    rows: Arc<PeriodRows>,
    mut plan: RelayPlan,
    tx: mpsc::Sender<SweepEvent>,
) -> std::io::Result<JoinHandle<()>> {
    std::thread::Builder::new()
        .name(name.into())
        .spawn(move || {
            let mut sent = 0usize;
            let mut block = 0usize;
            let mut blk = 0usize;
            let mut prev_pos = None;
            let mut vel = Vec::new();
            loop {
                let done = rows.done.load(Ordering::Acquire);
                let avail = rows.published.load(Ordering::Acquire);
                while avail > sent {
                    let to = if plan.period_samples > 0 {
                        if avail - sent < plan.period_samples {
                            break;
                        }
                        sent + plan.period_samples
                    } else {
                        avail
                    };
                    let samples = rows.read(sent, to);
                    let mut frf_so_far = None;
                    if let Some(est) = plan.estimator.as_mut() {
                        let (u, p) = (&samples.torque_cmd_nm, &samples.position_rad);
                        vel.resize(u.len(), 0.0);
                        prev_pos =
                            differenced_velocity_into(p, plan.sample_rate_hz, prev_pos, &mut vel);
                        if est.push(u, &vel).is_ok() && est.periods_done() > 0 {
                            frf_so_far = est.estimate().ok().map(Arc::new);
                        }
                    }
                    // the first block that published the period's last row ended it
                    while rows
                        .block_rows
                        .get(blk)
                        .is_some_and(|r| r.load(Ordering::Relaxed) < to)
                    {
                        blk += 1;
                    }
                    let end_ns = rows
                        .block_end_ns
                        .get(blk)
                        .map_or(0, |a| a.load(Ordering::Relaxed));
                    let ev = SweepEvent::Period {
                        index: block,
                        samples,
                        frf_so_far,
                        elapsed_s: to as f64 / plan.sample_rate_hz,
                        counters: Counters {
                            cycles: to as u64,
                            late: rows.late.load(Ordering::Relaxed),
                            lost: rows.lost.load(Ordering::Relaxed),
                            period_end_mono_ns: end_ns,
                        },
                    };
                    if tx.blocking_send(ev).is_err() {
                        return; // nobody listens any more
                    }
                    sent = to;
                    block += 1;
                }
                if done {
                    return;
                }
                std::thread::park_timeout(Duration::from_millis(20));
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs a relay over `total` rows (row k: torque k, position `position(k)`) that a
    /// writer publishes every `step` rows (stamped `stamp(rows so far)`), with room for
    /// `blocks` blocks; returns the events the relay sent.
    fn relay(
        name: &str,
        (period, step, total, blocks): (usize, usize, usize, usize),
        position: impl Fn(usize) -> f64,
        stamp: impl Fn(usize) -> u64,
    ) -> Vec<SweepEvent> {
        let rows = Arc::new(PeriodRows::new(total, blocks));
        let (tx, mut rx) = mpsc::channel(16);
        let plan = RelayPlan {
            period_samples: period,
            sample_rate_hz: 1000.0,
            estimator: None,
        };
        let h = spawn_relay(name, rows.clone(), plan, tx).unwrap();
        for k in 0..total {
            let row = flexid_sweep::Row {
                torque_setpoint_nm: k as f64,
                position_rad: position(k),
                velocity_rad_s: 2.0 * k as f64,
                torque_actual_nm: 3.0 * k as f64,
            };
            rows.write(k, &row);
            if (k + 1) % step == 0 {
                rows.publish(k + 1, 0, 0, stamp(k + 1));
                h.thread().unpark();
            }
        }
        rows.finish();
        h.thread().unpark();
        h.join().unwrap();
        std::iter::from_fn(|| rx.try_recv().ok()).collect()
    }

    /// The leading period events, each checked to be the next whole period of
    /// `period` rows: their samples and counters, in order.
    fn whole_periods(events: Vec<SweepEvent>, period: usize) -> Vec<(SampleBlock, Counters)> {
        let mut out = Vec::new();
        for ev in events {
            let SweepEvent::Period {
                index,
                samples,
                counters,
                ..
            } = ev
            else {
                break;
            };
            let n = out.len();
            assert_eq!(index, n);
            assert_eq!(samples.first_sample, n * period);
            assert_eq!(samples.torque_cmd_nm.len(), period);
            assert_eq!(samples.velocity_rad_s.len(), period);
            assert_eq!(samples.torque_actual_nm.len(), period);
            out.push((samples, counters));
        }
        out
    }

    /// Periods published by a writer thread arrive in order, whole, with their rows.
    #[test]
    fn relays_every_published_period_in_order() {
        let period = 50;
        let events = relay(
            "t-relay",
            (period, period, 4 * period, 4),
            |k| -(k as f64),
            |n| 999 + n as u64,
        );
        let periods = whole_periods(events, period);
        for (n, (samples, counters)) in periods.iter().enumerate() {
            assert_eq!(samples.torque_cmd_nm[3], (n * period + 3) as f64);
            assert_eq!(samples.position_rad[3], -((n * period + 3) as f64));
            assert_eq!(
                counters.period_end_mono_ns,
                1000 + ((n + 1) * period - 1) as u64
            );
        }
        assert_eq!(periods.len(), 4);
    }

    /// Blocks published at another step than the period (a chirp reports every second):
    /// whole periods still arrive, each stamped with the block that completed it.
    #[test]
    fn cuts_unaligned_blocks_into_periods() {
        let (period, step) = (200, 300);
        let events = relay(
            "t-relay2",
            (period, step, 6 * step, 10),
            |_| 0.0,
            |n| n as u64,
        );
        let periods = whole_periods(events, period);
        for (n, (_, counters)) in periods.iter().enumerate() {
            let end = (n + 1) * period;
            let stamped = end.div_ceil(step) * step;
            assert_eq!(counters.period_end_mono_ns, stamped as u64, "period {n}");
        }
        assert_eq!(periods.len(), 6 * step / period);
    }
}

/// The sweep loop's one sink in the daemon: every row goes into [`PeriodRows`] (read by
/// the relay for the live estimate and the files) and nowhere else.
pub struct RowsSink<'a>(pub &'a PeriodRows);

impl flexid_sweep::RowSink for RowsSink<'_> {
    fn push(&mut self, k: usize, row: &flexid_sweep::Row) {
        self.0.write(k, row);
    }
}

impl PeriodRows {
    /// Rows `..n`, once the sweep has ended.
    pub fn columns(&self, n: usize) -> SampleBlock {
        self.read(0, n.min(self.torque_nm.len()))
    }
}
