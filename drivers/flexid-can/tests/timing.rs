//! Bit-timing emulation: senders block for the frames' time on the bus.

use std::time::{Duration, Instant};

use flexid_can::timing::{bits_duration, frame_bits, BusClock, Paced};
use flexid_can::{CanBus, CanFrame, InprocBus};

#[test]
fn a_sender_is_paced_at_the_bitrate() {
    // 20 frames of 8 bytes at 125 kbit/s: 20 * 135 bits = 21.6 ms at least.
    let mut tx = Paced::new(InprocBus::new("pace"), 125_000);
    let mut rx = tx.inner().handle();
    let f = CanFrame::standard(0x181, &[0; 8]).unwrap();
    let t0 = Instant::now();
    for _ in 0..20 {
        tx.send(&f).unwrap();
    }
    let dt = t0.elapsed();
    let min = bits_duration(20 * frame_bits(8, false), 125_000);
    assert_eq!(min, Duration::from_micros(21_600));
    assert!(dt >= min, "{dt:?} < {min:?}");
    assert!(dt < min * 50, "{dt:?}"); // generous: only a sanity bound
    for _ in 0..20 {
        assert!(rx.recv_timeout(Duration::ZERO).unwrap().is_some());
    }
}

#[test]
fn senders_share_the_in_process_bus() {
    // Two threads, 10 frames each, on one clock: 20 frame times at least, where either
    // alone would need 10.
    let clock = BusClock::new();
    let a = Paced::with_clock(InprocBus::new("shared"), 250_000, clock.clone());
    let b = a.try_clone().unwrap();
    let f = CanFrame::standard(0x100, &[0; 8]).unwrap();
    let t0 = Instant::now();
    let threads: Vec<_> = [a, b]
        .into_iter()
        .map(|mut h| {
            std::thread::spawn(move || {
                for _ in 0..10 {
                    h.send(&f).unwrap();
                }
            })
        })
        .collect();
    for t in threads {
        t.join().unwrap();
    }
    let dt = t0.elapsed();
    let min = bits_duration(20 * 135, 250_000);
    assert!(dt >= min, "{dt:?} < {min:?}");
}

#[test]
fn an_over_full_cycle_overruns() {
    // 1 kHz cycle at 125 kbit/s holds 125 bits/ms: one 8-byte frame (135 bits) already
    // does not fit. Five frames per "cycle" take > 5 cycles.
    let load = flexid_can::timing::bus_load(
        &[flexid_can::timing::FrameShape::standard(8); 5],
        1000.0,
        125_000,
    );
    assert!(load > 5.0, "{load}");
    let mut tx = Paced::new(InprocBus::new("cycle"), 125_000);
    let cycle = Duration::from_millis(1);
    let t0 = Instant::now();
    for _ in 0..5 {
        tx.send(&CanFrame::standard(0x200, &[0; 8]).unwrap())
            .unwrap();
    }
    assert!(t0.elapsed() > 5 * cycle, "{:?}", t0.elapsed());
}
