//! `PlantSim::step` and `PlantSim::sample` do not allocate (a real-time drive calls them
//! every cycle): counted with a global allocator, on the measuring thread only (the test
//! harness's own thread may allocate meanwhile: it did once on a loaded CI host).

use flexid::plant::PlantSim;
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicUsize, Ordering};

struct Counting;

static ALLOCS: AtomicUsize = AtomicUsize::new(0);

thread_local! {
    /// Set on the thread whose allocations are counted (const: no allocation to access).
    static COUNTED: Cell<bool> = const { Cell::new(false) };
}

fn count() {
    if COUNTED.try_with(Cell::get).unwrap_or(false) {
        ALLOCS.fetch_add(1, Ordering::SeqCst);
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count();
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count();
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

#[test]
fn step_and_sample_do_not_allocate() {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/scara_all_effects.toml");
    let plant = flexid::plant_file::load_plant_file(Some(&path)).unwrap();
    let mut sim = PlantSim::new(&plant.spec(), 4000.0, 10, 1).unwrap();
    let mut acc = 0.0;
    COUNTED.with(|c| c.set(true));
    let before = ALLOCS.load(Ordering::SeqCst);
    for k in 0..20_000 {
        let s = sim.sample();
        acc += s.position_rad + s.torque_nm;
        sim.step(0.5 * (k as f64 * 1e-2).sin());
        if k == 10_000 {
            sim.reset();
        }
    }
    let after = ALLOCS.load(Ordering::SeqCst);
    COUNTED.with(|c| c.set(false));
    assert!(acc.is_finite());
    assert_eq!(after - before, 0, "allocations in step/sample/reset");
}
