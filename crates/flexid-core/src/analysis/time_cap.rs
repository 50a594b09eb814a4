//! What the time cap of an identification did, for the report and the JSON.

use crate::identify::fit::FitBudget;
use serde::Serialize;

/// The time cap of an analysis and whether it stopped the identification early (then the
/// model is the best found before the cap, not necessarily the best the data allow).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TimeCap {
    /// The cap [s].
    pub max_seconds: f64,
    /// Whether the cap stopped a start or an order: the result is the best model so far.
    pub capped: bool,
    /// Seconds the analysis took up to the end of the fit.
    pub elapsed_s: f64,
    /// Starts (and refinements) of the multi-start fits skipped by the cap.
    pub starts_skipped: usize,
    /// Model orders (or, with a fixed order, choices of pairs) not tried because of it.
    pub orders_skipped: usize,
}

impl TimeCap {
    /// The state of `budget`; `None` when it has no cap.
    pub fn of(budget: &FitBudget) -> Option<TimeCap> {
        let s = budget.snapshot();
        Some(TimeCap {
            max_seconds: s.max_seconds?,
            capped: s.capped,
            elapsed_s: s.elapsed_s,
            starts_skipped: s.starts_skipped,
            orders_skipped: s.orders_skipped,
        })
    }

    /// One line for the report and the notes (only when capped).
    pub fn message(&self) -> Option<String> {
        self.capped.then(|| {
            format!(
                "TIME CAP: identification stopped after {:.1} s (time budget {} s): {} starts and {} model orders not tried; the model is the best found so far",
                self.elapsed_s, self.max_seconds, self.starts_skipped, self.orders_skipped
            )
        })
    }
}
