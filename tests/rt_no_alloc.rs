//! The cycle thread allocates nothing per cycle after start-up: a counting global
//! allocator (per thread) around `spawn_cycle_thread` + `Pacer` + `TimingStats`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ops::ControlFlow;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use flexid::rt::{spawn_cycle_thread, Pacer, RtSetup, TimingStats};

struct Counting;

thread_local! {
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

fn bump() {
    // try_with: the thread-local may be gone while the thread exits.
    let _ = ALLOCS.try_with(|c| c.set(c.get() + 1));
}

fn allocs_here() -> u64 {
    ALLOCS.with(|c| c.get())
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        bump();
        System.alloc(l)
    }
    unsafe fn alloc_zeroed(&self, l: Layout) -> *mut u8 {
        bump();
        System.alloc_zeroed(l)
    }
    unsafe fn realloc(&self, p: *mut u8, l: Layout, n: usize) -> *mut u8 {
        bump();
        System.realloc(p, l, n)
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        bump();
        System.dealloc(p, l)
    }
}

#[global_allocator]
static A: Counting = Counting;

/// Allocations (and frees) on the cycle thread between cycle 10 and the last of 1000
/// cycles at 4 kHz: zero. The report is built after the loop (allowed to allocate).
#[test]
fn cycle_thread_allocates_nothing_per_cycle() {
    let at_10 = Arc::new(AtomicU64::new(u64::MAX));
    let at_end = Arc::new(AtomicU64::new(u64::MAX));
    let (a, b) = (at_10.clone(), at_end.clone());
    let mut n = 0u64;
    let h = spawn_cycle_thread(
        "noalloc",
        RtSetup::none(),
        Duration::from_micros(250),
        move |_tick| {
            n += 1;
            if n == 10 {
                a.store(allocs_here(), Ordering::Relaxed);
            }
            if n == 1000 {
                b.store(allocs_here(), Ordering::Relaxed);
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    )
    .unwrap();
    let r = h.join().unwrap();
    assert_eq!(r.cycles, 1000);
    let (s, e) = (
        at_10.load(Ordering::Relaxed),
        at_end.load(Ordering::Relaxed),
    );
    assert!(s != u64::MAX && e != u64::MAX);
    assert_eq!(e - s, 0, "{} allocations in 990 cycles", e - s);
}

/// The same for a `Pacer` and `TimingStats` driven by hand on this thread.
#[test]
fn pacer_and_stats_allocate_nothing() {
    let mut p = Pacer::new(Duration::from_micros(250)).unwrap();
    let mut s = TimingStats::new(250_000);
    let before = allocs_here();
    for _ in 0..500 {
        let t = p.wait_next();
        s.record_wakeup(t.lateness_ns, t.missed);
        s.record_body(123);
    }
    let _ = s.lateness.summary();
    assert_eq!(allocs_here() - before, 0);
    assert_eq!(s.lateness.len(), 500);
}

/// The counter works: a body that allocates once per cycle is seen.
#[test]
fn an_allocating_body_is_detected() {
    let at_10 = Arc::new(AtomicU64::new(0));
    let at_end = Arc::new(AtomicU64::new(0));
    let (a, b) = (at_10.clone(), at_end.clone());
    let mut n = 0u64;
    let h = spawn_cycle_thread(
        "alloc",
        RtSetup::none(),
        Duration::from_micros(250),
        move |_| {
            n += 1;
            std::hint::black_box(Box::new(n));
            if n == 10 {
                a.store(allocs_here(), Ordering::Relaxed);
            }
            if n == 100 {
                b.store(allocs_here(), Ordering::Relaxed);
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        },
    )
    .unwrap();
    h.join().unwrap();
    // one alloc + one free per cycle
    assert_eq!(
        at_end.load(Ordering::Relaxed) - at_10.load(Ordering::Relaxed),
        2 * 90
    );
}
