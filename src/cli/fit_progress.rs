//! Progress of an identification on stderr while it runs: which model order is being
//! fitted, how many of its starts are done, the elapsed time and the cap. An `indicatif`
//! bar on a terminal, plain lines otherwise (one per order, one every few seconds, and one
//! at the end).

use crate::identify::fit::{BudgetSnapshot, FitBudget};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Seconds between the plain progress lines of one order.
const PLAIN_EVERY_S: f64 = 5.0;

fn describe(s: &BudgetSnapshot) -> String {
    let cap = s
        .max_seconds
        .map_or(String::new(), |c| format!(" (cap {c} s)"));
    if s.masses == 0 {
        return format!(
            "estimating the FRF and detecting pairs, {:.1} s{cap}",
            s.elapsed_s
        );
    }
    let order = if s.orders_total > 0 {
        format!(
            ", order {}/{}",
            s.orders_begun.min(s.orders_total),
            s.orders_total
        )
    } else {
        String::new()
    };
    format!(
        "fitting {} bodies{order}: {}/{} starts, {:.1} s{cap}",
        s.masses,
        s.starts_done.min(s.starts_total),
        s.starts_total,
        s.elapsed_s
    )
}

/// Run `work` while a watcher thread shows the progress of `budget` on stderr.
pub(crate) fn with_progress<T: Send>(
    budget: &FitBudget,
    prefix: &str,
    work: impl FnOnce() -> T + Send,
) -> T {
    let done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        scope.spawn(|| watch(budget, prefix, &done));
        let out = work();
        done.store(true, Ordering::Relaxed);
        out
    })
}

fn watch(budget: &FitBudget, prefix: &str, done: &AtomicBool) {
    let bar = indicatif::ProgressBar::new(1);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{prefix} {bar:30.cyan/blue} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.set_prefix(prefix.to_string());
    let plain = bar.is_hidden();
    let mut last_order = usize::MAX;
    let mut last_line = Instant::now();
    while !done.load(Ordering::Relaxed) {
        let s = budget.snapshot();
        if plain {
            let order = s.orders_begun * 100 + s.masses;
            if s.masses > 0
                && (order != last_order || last_line.elapsed().as_secs_f64() >= PLAIN_EVERY_S)
            {
                eprintln!("{prefix}: {}", describe(&s));
                last_order = order;
                last_line = Instant::now();
            }
        } else {
            bar.set_length(s.starts_total.max(1) as u64);
            bar.set_position(s.starts_done.min(s.starts_total) as u64);
            bar.set_message(describe(&s));
        }
        std::thread::sleep(Duration::from_millis(if plain { 25 } else { 100 }));
    }
    bar.finish_and_clear();
    let s = budget.snapshot();
    if plain {
        eprintln!(
            "{prefix}: done in {:.1} s ({} model orders fitted)",
            s.elapsed_s, s.orders_begun
        );
    }
    if s.capped {
        eprintln!(
            "{prefix}: time cap of {} s reached after {:.1} s: {} starts and {} orders skipped, returning the best model so far",
            s.max_seconds.unwrap_or(f64::NAN),
            s.elapsed_s,
            s.starts_skipped,
            s.orders_skipped
        );
    }
}
