//! [`Histogram`]: a preallocated log-linear histogram of ns values with bounded relative
//! error, and [`TimingStats`]: lateness, late wake-ups and overruns of a cycle loop.
//!
//! # Buckets (HdrHistogram-like)
//!
//! Values below `2^SUB_BITS` (256 ns) have one bucket each (exact). Above, each octave
//! `[2^e, 2^(e+1))` is split into 128 equal buckets of width `2^(e-7)`. A value is reported
//! as its bucket's midpoint, so the error is at most half a width: **relative error
//! < 1/256 (0.4 %)**. Values up to `2^40` ns (18 min) are resolved; larger ones go to the
//! last bucket (the exact maximum is kept apart). 4352 `u64` counters (34 KiB), allocated
//! and touched once at construction; recording is an index computation and an increment.

/// Precision bits: 2^SUB_BITS sub-buckets, relative error < 2^-SUB_BITS.
const SUB_BITS: u32 = 8;
const SUB: u64 = 1 << SUB_BITS; // 256
const HALF: u64 = SUB / 2; // 128 buckets per octave above SUB
/// Largest resolved value: 2^MAX_BITS ns.
const MAX_BITS: u32 = 40;
/// Number of buckets: SUB exact ones + HALF for each octave from SUB_BITS to MAX_BITS-1.
pub const BUCKETS: usize = (SUB + (MAX_BITS - SUB_BITS) as u64 * HALF) as usize;
/// Relative error bound of a reported percentile (midpoint of the bucket).
pub const RELATIVE_ERROR: f64 = 1.0 / SUB as f64;

/// Bucket index of a value.
#[inline]
fn bucket(v: u64) -> usize {
    if v < SUB {
        return v as usize;
    }
    let e = 63 - v.leading_zeros(); // msb position, >= SUB_BITS
    if e >= MAX_BITS {
        return BUCKETS - 1;
    }
    let shift = e - SUB_BITS + 1;
    let m = v >> shift; // in [HALF, SUB)
    (shift as u64 * HALF + m) as usize
}

/// Lowest value and width of a bucket.
#[inline]
fn bucket_range(i: usize) -> (u64, u64) {
    let i = i as u64;
    if i < SUB {
        return (i, 1);
    }
    let shift = (i - SUB) / HALF + 1;
    let m = i - shift * HALF;
    (m << shift, 1 << shift)
}

/// A log-linear histogram of `u64` values (ns), preallocated, relative error < 0.4 %.
#[derive(Clone)]
pub struct Histogram {
    counts: Box<[u64]>,
    n: u64,
    min: u64,
    max: u64,
    sum: u128,
}

impl std::fmt::Debug for Histogram {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Histogram")
            .field("n", &self.n)
            .field("min", &self.min)
            .field("max", &self.max)
            .finish_non_exhaustive()
    }
}

impl Default for Histogram {
    fn default() -> Self {
        Self::new()
    }
}

impl Histogram {
    /// An empty histogram; allocates and touches all its counters (no page faults later).
    pub fn new() -> Self {
        let mut counts = vec![1u64; BUCKETS].into_boxed_slice();
        for c in counts.iter_mut() {
            // SAFETY: c is a valid, aligned &mut u64; volatile so the pages are written now.
            unsafe { std::ptr::write_volatile(c, 0) };
        }
        Histogram {
            counts,
            n: 0,
            min: u64::MAX,
            max: 0,
            sum: 0,
        }
    }

    /// Records a value (ns). No allocation.
    #[inline]
    pub fn record(&mut self, v: u64) {
        self.counts[bucket(v)] += 1;
        self.n += 1;
        self.min = self.min.min(v);
        self.max = self.max.max(v);
        self.sum += v as u128;
    }

    /// Adds another histogram's counts.
    pub fn merge(&mut self, o: &Histogram) {
        for (a, b) in self.counts.iter_mut().zip(o.counts.iter()) {
            *a += b;
        }
        self.n += o.n;
        self.min = self.min.min(o.min);
        self.max = self.max.max(o.max);
        self.sum += o.sum;
    }

    /// Values recorded.
    pub fn len(&self) -> u64 {
        self.n
    }

    /// No value recorded.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// Exact maximum (0 when empty).
    pub fn max(&self) -> u64 {
        self.max
    }

    /// Exact minimum (0 when empty).
    pub fn min(&self) -> u64 {
        if self.n == 0 {
            0
        } else {
            self.min
        }
    }

    /// Exact mean (0 when empty).
    pub fn mean(&self) -> f64 {
        if self.n == 0 {
            0.0
        } else {
            self.sum as f64 / self.n as f64
        }
    }

    /// The `q`-quantile (`0 <= q <= 1`), nearest rank: the value of rank `ceil(q n)` in
    /// sorted order (rank 1 for q = 0), within [`RELATIVE_ERROR`] of it, clamped to the
    /// exact min and max. 0 when empty.
    pub fn quantile(&self, q: f64) -> u64 {
        if self.n == 0 {
            return 0;
        }
        let rank = ((q.clamp(0.0, 1.0) * self.n as f64).ceil() as u64).clamp(1, self.n);
        let mut cum = 0;
        for (i, &c) in self.counts.iter().enumerate() {
            cum += c;
            if cum >= rank {
                let (lo, w) = bucket_range(i);
                return (lo + (w - 1) / 2).clamp(self.min, self.max);
            }
        }
        self.max
    }

    /// p50, p99, p99.9, max, mean.
    pub fn summary(&self) -> LatencySummary {
        LatencySummary {
            count: self.n,
            p50_ns: self.quantile(0.5),
            p99_ns: self.quantile(0.99),
            p999_ns: self.quantile(0.999),
            max_ns: self.max,
            mean_ns: self.mean(),
        }
    }
}

pub use flexid_core::recording::LatencySummary;

/// Timing of a cycle loop: wake-up lateness, late wake-ups, overruns, and the body's
/// run time. Allocates once at construction, never while recording.
///
/// The lateness recorded is measured from the deadline the loop **waited for**: after an
/// overrun that skipped `missed` deadlines it is `missed * period + Tick::lateness_ns`, so
/// a 1.2-period stall shows as such (not as 0.2 period on the deadline served).
#[derive(Debug, Clone)]
pub struct TimingStats {
    /// Wake-up lateness from the deadline waited for, ns.
    pub lateness: Histogram,
    /// Run time of the loop body per cycle, ns.
    pub body: Histogram,
    /// The period, ns.
    pub period_ns: u64,
    /// A wake-up later than this (ns) counts as late: 10 % of the period by default.
    pub late_threshold_ns: u64,
    /// Wake-ups later than `late_threshold_ns`.
    pub late_wakeups: u64,
    /// Wake-ups after which deadlines were skipped.
    pub overruns: u64,
    /// Deadlines skipped in total.
    pub missed_deadlines: u64,
}

impl TimingStats {
    /// Empty statistics for a loop of period `period_ns`; late means later than 10 % of
    /// the period (change `late_threshold_ns` for another threshold).
    pub fn new(period_ns: u64) -> Self {
        TimingStats {
            lateness: Histogram::new(),
            body: Histogram::new(),
            period_ns,
            late_threshold_ns: period_ns / 10,
            late_wakeups: 0,
            overruns: 0,
            missed_deadlines: 0,
        }
    }

    /// Records one wake-up: its lateness on the deadline served (ns, `Tick::lateness_ns`)
    /// and the deadlines skipped before it (`Tick::missed`).
    #[inline]
    pub fn record_wakeup(&mut self, lateness_ns: u64, missed: u64) {
        let late = lateness_ns.saturating_add(missed.saturating_mul(self.period_ns));
        self.lateness.record(late);
        if late > self.late_threshold_ns {
            self.late_wakeups += 1;
        }
        if missed > 0 {
            self.overruns += 1;
            self.missed_deadlines += missed;
        }
    }

    /// Records the body's run time of one cycle, ns.
    #[inline]
    pub fn record_body(&mut self, ns: u64) {
        self.body.record(ns);
    }

    /// Adds another run's statistics (same threshold assumed).
    pub fn merge(&mut self, o: &TimingStats) {
        self.lateness.merge(&o.lateness);
        self.body.merge(&o.body);
        self.late_wakeups += o.late_wakeups;
        self.overruns += o.overruns;
        self.missed_deadlines += o.missed_deadlines;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn buckets_are_contiguous_and_cover() {
        let mut prev_end = 0;
        for i in 0..BUCKETS {
            let (lo, w) = bucket_range(i);
            assert_eq!(lo, prev_end, "bucket {i}");
            assert_eq!(bucket(lo), i);
            assert_eq!(bucket(lo + w - 1), i);
            assert!(w == 1 || (w as f64) / (lo as f64) <= 2.0 * RELATIVE_ERROR);
            prev_end = lo + w;
        }
        assert_eq!(prev_end, 1 << MAX_BITS);
        assert_eq!(bucket(u64::MAX), BUCKETS - 1);
    }

    fn naive(sorted: &[u64], q: f64) -> u64 {
        let n = sorted.len() as u64;
        let rank = ((q * n as f64).ceil() as u64).clamp(1, n);
        sorted[rank as usize - 1]
    }

    /// Percentiles against a sort on random data of several shapes (uniform small,
    /// log-uniform over 9 decades, a latency-like mix with a heavy tail).
    #[test]
    fn quantiles_match_sorted_reference_within_relative_error() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(7);
        for shape in 0..3 {
            for &n in &[1usize, 2, 10, 999, 20_000] {
                let mut v: Vec<u64> = (0..n)
                    .map(|_| match shape {
                        0 => rng.random_range(0..300),
                        1 => 10f64.powf(rng.random_range(0.0..9.0)) as u64,
                        _ => {
                            if rng.random_bool(0.995) {
                                rng.random_range(2_000..60_000)
                            } else {
                                rng.random_range(100_000..5_000_000)
                            }
                        }
                    })
                    .collect();
                let mut h = Histogram::new();
                for &x in &v {
                    h.record(x);
                }
                v.sort_unstable();
                for &q in &[0.0, 0.01, 0.25, 0.5, 0.9, 0.99, 0.999, 1.0] {
                    let r = naive(&v, q) as f64;
                    let got = h.quantile(q) as f64;
                    assert!(
                        (got - r).abs() <= r * RELATIVE_ERROR,
                        "shape {shape} n {n} q {q}: {got} vs {r}"
                    );
                }
                assert_eq!(h.max(), *v.last().unwrap());
                assert_eq!(h.min(), v[0]);
                let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n as f64;
                assert!((h.mean() - mean).abs() <= 1e-9 * mean.max(1.0));
            }
        }
    }

    #[test]
    fn merge_equals_recording_both() {
        let mut a = Histogram::new();
        let mut b = Histogram::new();
        let mut c = Histogram::new();
        for x in 0..5000u64 {
            let v = x * x % 100_003;
            if x % 3 == 0 {
                a.record(v)
            } else {
                b.record(v)
            }
            c.record(v);
        }
        a.merge(&b);
        assert_eq!(a.summary(), c.summary());
    }

    #[test]
    fn stats_count_late_and_overruns() {
        let mut s = TimingStats::new(1000);
        assert_eq!(s.late_threshold_ns, 100);
        s.record_wakeup(50, 0);
        s.record_wakeup(150, 0);
        s.record_wakeup(20, 3);
        s.record_wakeup(101, 1);
        assert_eq!(s.late_wakeups, 3);
        assert_eq!(s.lateness.max(), 3020);
        assert_eq!(s.overruns, 2);
        assert_eq!(s.missed_deadlines, 4);
        assert_eq!(s.lateness.len(), 4);
        assert_eq!(Histogram::new().summary(), LatencySummary::default());
    }
}
