//! The cycle path (RPDO1 + SYNC -> TPDOs, tick, SDO read) does not allocate.

mod common;
use common::*;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static COUNTING: Cell<bool> = const { Cell::new(false) };
    static ALLOCS: Cell<u64> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, l: Layout) -> *mut u8 {
        if COUNTING.with(|c| c.get()) {
            ALLOCS.with(|a| a.set(a.get() + 1));
        }
        unsafe { System.alloc(l) }
    }
    unsafe fn dealloc(&self, p: *mut u8, l: Layout) {
        unsafe { System.dealloc(p, l) }
    }
}

#[global_allocator]
static A: Counting = Counting;

#[test]
fn cycle_path_does_not_allocate() {
    let mut d = Dut::new();
    d.start();
    d.rpdo(0x0006, 0);
    d.rpdo(0x0007, 0);
    d.rpdo(0x000F, 0);
    let rpdo = frame(0x205, &[0x0F, 0x00, 0x2C, 0x01]);
    let sync = frame(0x080, &[]);
    let sdo = frame(0x605, &[0x40, 0x64, 0x60, 0x00, 0, 0, 0, 0]);
    let mut sent = 0usize;
    COUNTING.with(|c| c.set(true));
    for k in 0..10_000u64 {
        let now = std::time::Duration::from_micros(500 * k);
        sent += d.drive.on_frame(&rpdo, now).len();
        sent += d.drive.on_frame(&sync, now).len();
        sent += d.drive.tick(now).len();
        if k % 100 == 0 {
            sent += d.drive.on_frame(&sdo, now).len();
        }
    }
    COUNTING.with(|c| c.set(false));
    assert_eq!(sent, 20_000 + 100);
    assert_eq!(ALLOCS.with(|a| a.get()), 0, "allocations in the cycle path");
}
