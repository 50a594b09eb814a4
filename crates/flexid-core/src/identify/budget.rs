//! A time cap and progress counters for the multi-start fits.
//!
//! A [`FitBudget`] travels in [`super::fit::FitOptions`] (shared by its clones, also across
//! the fit's worker threads). Every start and every refinement of a fit runs through a
//! [`StartGate`]: once the cap has passed, a start is skipped unless it would be the first
//! of its phase, so that a fit under way still ends with a model (the best of the starts
//! done); orders not yet begun are skipped by [`fit_each_order`]. Skips are counted and the
//! budget says it was capped. A watcher (the command line's progress bar) reads
//! [`FitBudget::snapshot`] from another thread.

use super::chain_fit::ChainFit;
use super::error::IdentifyError;
use crate::model::Chain;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Debug)]
struct State {
    began: Instant,
    cap: Option<Duration>,
    capped: AtomicBool,
    /// Bodies of the order being fitted (0 before the first fit).
    masses: AtomicUsize,
    /// Orders begun, and how many the selection will try.
    orders_begun: AtomicUsize,
    orders_total: AtomicUsize,
    /// Starts done and planned in the fit under way.
    starts_done: AtomicUsize,
    starts_total: AtomicUsize,
    /// Starts and orders skipped by the cap, over the whole analysis.
    starts_skipped: AtomicUsize,
    orders_skipped: AtomicUsize,
}

/// Time cap and progress of an identification, shared by its clones.
///
/// Equality is not about the budget: two `FitOptions` that differ only in it describe the
/// same problem, so `==` is always true.
#[derive(Debug, Clone)]
pub struct FitBudget(Arc<State>);

/// What a watcher sees of a [`FitBudget`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BudgetSnapshot {
    /// Seconds since the budget was made.
    pub elapsed_s: f64,
    /// The cap [s], if any.
    pub max_seconds: Option<f64>,
    /// Bodies of the order being fitted (0 before the first fit).
    pub masses: usize,
    /// Orders begun and planned (1-based position of the current order).
    pub orders_begun: usize,
    /// Orders the selection tries.
    pub orders_total: usize,
    /// Starts done in the fit under way.
    pub starts_done: usize,
    /// Starts planned in the fit under way.
    pub starts_total: usize,
    /// Starts skipped by the cap so far.
    pub starts_skipped: usize,
    /// Orders skipped by the cap so far.
    pub orders_skipped: usize,
    /// Whether the cap stopped anything.
    pub capped: bool,
}

impl Default for FitBudget {
    fn default() -> Self {
        Self::unlimited()
    }
}

impl PartialEq for FitBudget {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl FitBudget {
    /// No time cap (progress is still counted).
    pub fn unlimited() -> Self {
        Self::new(None)
    }

    /// Capped at `max_seconds` from now; a cap longer than a `Duration` holds (about 5.8e11
    /// years, `1e300`, infinity) is no cap; zero, a negative or a NaN cap has passed at once.
    pub fn with_cap_s(max_seconds: f64) -> Self {
        if max_seconds.is_nan() || max_seconds <= 0.0 {
            return Self::new(Some(Duration::ZERO));
        }
        Self::new(Duration::try_from_secs_f64(max_seconds).ok())
    }

    /// A fresh budget with the same cap, counting from now.
    pub fn restarted(&self) -> Self {
        Self::new(self.0.cap)
    }

    fn new(cap: Option<Duration>) -> Self {
        FitBudget(Arc::new(State {
            began: Instant::now(),
            cap,
            capped: AtomicBool::new(false),
            masses: AtomicUsize::new(0),
            orders_begun: AtomicUsize::new(0),
            orders_total: AtomicUsize::new(0),
            starts_done: AtomicUsize::new(0),
            starts_total: AtomicUsize::new(0),
            starts_skipped: AtomicUsize::new(0),
            orders_skipped: AtomicUsize::new(0),
        }))
    }

    /// Whether the cap has passed.
    pub fn expired(&self) -> bool {
        self.0.cap.is_some_and(|c| self.0.began.elapsed() >= c)
    }

    /// Whether the cap stopped a start or an order.
    pub fn capped(&self) -> bool {
        self.0.capped.load(Ordering::Relaxed)
    }

    /// The counters now.
    pub fn snapshot(&self) -> BudgetSnapshot {
        let s = &self.0;
        let ld = |a: &AtomicUsize| a.load(Ordering::Relaxed);
        BudgetSnapshot {
            elapsed_s: s.began.elapsed().as_secs_f64(),
            max_seconds: s.cap.map(|c| c.as_secs_f64()),
            masses: ld(&s.masses),
            orders_begun: ld(&s.orders_begun),
            orders_total: ld(&s.orders_total),
            starts_done: ld(&s.starts_done),
            starts_total: ld(&s.starts_total),
            starts_skipped: ld(&s.starts_skipped),
            orders_skipped: ld(&s.orders_skipped),
            capped: s.capped.load(Ordering::Relaxed),
        }
    }

    /// A fit of `masses` bodies with `starts` starts begins (for the watcher).
    pub fn begin_fit(&self, masses: usize, starts: usize) {
        let s = &self.0;
        s.masses.store(masses, Ordering::Relaxed);
        s.starts_done.store(0, Ordering::Relaxed);
        s.starts_total.store(starts, Ordering::Relaxed);
        s.orders_begun.fetch_add(1, Ordering::Relaxed);
    }

    /// `orders` fits are planned (for the watcher).
    pub fn plan_orders(&self, orders: usize) {
        self.0.orders_total.store(orders, Ordering::Relaxed);
        self.0.orders_begun.store(0, Ordering::Relaxed);
    }

    /// A gate for one phase of a fit; `counted` phases advance `starts_done`.
    pub(super) fn gate(&self, counted: bool) -> StartGate<'_> {
        StartGate {
            budget: self,
            done: AtomicUsize::new(0),
            counted,
        }
    }

    /// Record `n` starts of a search (outside the identification's own fits, e.g. the
    /// diagnosis's mode search) skipped because the cap has passed.
    pub fn skip_starts(&self, n: usize) {
        self.0.starts_skipped.fetch_add(n, Ordering::Relaxed);
        self.0.capped.store(true, Ordering::Relaxed);
    }

    /// Record a fit (an order, a choice of pairs) skipped because the cap has passed.
    pub fn skip_order(&self) {
        self.0.orders_skipped.fetch_add(1, Ordering::Relaxed);
        self.0.capped.store(true, Ordering::Relaxed);
    }
}

/// Admits the jobs of one phase of a fit (the starts, or the refinements) while the budget
/// lasts; the first job of the phase always runs.
pub(super) struct StartGate<'a> {
    budget: &'a FitBudget,
    done: AtomicUsize,
    counted: bool,
}

/// The reason of an order not tried because of the cap.
pub const NOT_TRIED: &str = "not tried: the time cap was reached";

/// The reason of a start skipped by the cap.
pub(super) const SKIPPED: &str = "skipped: the time cap was reached";

impl StartGate<'_> {
    /// `job()` unless the cap has passed and a job of this phase already ended.
    pub(super) fn run<T>(&self, job: impl FnOnce() -> Result<T, String>) -> Result<T, String> {
        if self.done.load(Ordering::Relaxed) > 0 && self.budget.expired() {
            let s = &self.budget.0;
            s.starts_skipped.fetch_add(1, Ordering::Relaxed);
            s.capped.store(true, Ordering::Relaxed);
            return Err(SKIPPED.into());
        }
        let out = job();
        self.done.fetch_add(1, Ordering::Relaxed);
        if self.counted {
            self.budget.0.starts_done.fetch_add(1, Ordering::Relaxed);
        }
        out
    }
}

/// `fit(c)` for every candidate order in turn, announcing each to the budget; once the cap
/// has passed, the orders not begun are skipped (an error saying so) as long as one fit
/// succeeded.
pub(super) fn fit_each_order(
    candidates: &[Chain],
    budget: &FitBudget,
    starts: usize,
    fit: impl Fn(&Chain) -> Result<ChainFit, IdentifyError>,
) -> Vec<Result<ChainFit, IdentifyError>> {
    budget.plan_orders(candidates.len());
    let mut out: Vec<Result<ChainFit, IdentifyError>> = Vec::with_capacity(candidates.len());
    for c in candidates {
        if budget.expired() && out.iter().any(|f| f.is_ok()) {
            budget.skip_order();
            out.push(Err(IdentifyError::FitFailed {
                masses: c.masses(),
                starts: 0,
                reason: NOT_TRIED.into(),
            }));
            continue;
        }
        budget.begin_fit(c.masses(), starts);
        out.push(fit(c));
    }
    out
}

#[cfg(test)]
mod tests {

    /// Issue 16: `--max-seconds 1e300` panicked in `Duration::from_secs_f64`.
    #[test]
    fn an_absurd_cap_is_no_cap_and_a_nonpositive_one_has_passed() {
        for huge in [1e300, f64::INFINITY, 1e20] {
            let b = FitBudget::with_cap_s(huge);
            assert!(!b.expired(), "{huge}");
            assert_eq!(b.snapshot().max_seconds, None, "{huge}");
        }
        for none in [0.0, -1.0, f64::NAN] {
            assert!(FitBudget::with_cap_s(none).expired(), "{none}");
        }
        let b = FitBudget::with_cap_s(3600.0);
        assert!(!b.expired());
        assert_eq!(b.snapshot().max_seconds, Some(3600.0));
    }

    use super::*;

    #[test]
    fn gate_runs_the_first_job_then_skips_after_the_cap() {
        let b = FitBudget::with_cap_s(0.0);
        let g = b.gate(true);
        assert_eq!(g.run(|| Ok::<_, String>(1)), Ok(1));
        assert_eq!(g.run(|| Ok::<_, String>(2)), Err(SKIPPED.to_string()));
        let s = b.snapshot();
        assert!(s.capped && b.capped());
        assert_eq!((s.starts_done, s.starts_skipped), (1, 1));
        // a new phase gets its first job again
        assert_eq!(b.gate(false).run(|| Ok::<_, String>(3)), Ok(3));
    }

    #[test]
    fn unlimited_budget_never_skips() {
        let b = FitBudget::unlimited();
        let g = b.gate(true);
        for i in 0..5 {
            assert_eq!(g.run(|| Ok::<_, String>(i)), Ok(i));
        }
        assert!(!b.capped() && !b.expired());
        assert_eq!(b.snapshot().starts_done, 5);
    }
}
