//! Bit-timing emulation: senders queue without sleeping, receivers get every frame at its
//! due time (end of transmission on the emulated wire), in wire order.

use std::time::{Duration, Instant};

use flexid_can::timing::{bits_duration, frame_bits, BusClock, Paced};
use flexid_can::{CanBus, CanFrame, InprocBus};

fn frame(id: u16, seq: u8) -> CanFrame {
    CanFrame::standard(id, &[seq, 0, 0, 0, 0, 0, 0, 0]).unwrap()
}

#[test]
fn a_burst_is_queued_at_once_and_delivered_at_its_due_times() {
    // 20 frames of 8 bytes at 125 kbit/s: 135 bits = 1080 us each, 21.6 ms in all.
    let mut tx = Paced::new(InprocBus::new("pace"), 125_000);
    let mut rx = Paced::with_clock(tx.inner().handle(), 125_000, tx.clock().clone());
    let t = bits_duration(frame_bits(8, false), 125_000);
    assert_eq!(t, Duration::from_micros(1080));
    let t0 = Instant::now();
    for i in 0..20 {
        tx.send(&frame(0x181, i)).unwrap();
    }
    let queued = t0.elapsed();
    // no sleep per frame: the 20 sends take far less than one frame's time each
    assert!(queued < 10 * t, "sending took {queued:?}");
    let mut prev: Option<Instant> = None;
    for i in 0..20 {
        let r = rx.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
        let now = Instant::now();
        assert_eq!(r.frame, frame(0x181, i), "order");
        assert!(
            now >= r.timestamp,
            "frame {i} delivered before its due time"
        );
        assert!(
            r.timestamp >= t0 + t * (i as u32 + 1),
            "frame {i} due too early"
        );
        if let Some(p) = prev {
            // queued while the wire was busy: back to back, exactly one frame time apart
            assert_eq!(r.timestamp - p, t, "frame {i}");
        }
        prev = Some(r.timestamp);
    }
    assert!(t0.elapsed() >= t * 20);
    assert_eq!(tx.clock().busy(), t * 20);
}

#[test]
fn senders_share_the_wire_and_order_is_kept() {
    // Two threads, 40 frames each, on one clock; a third handle sees all 80 in one
    // order, never overlapping on the wire, each sender's in its own order.
    let clock = BusClock::new();
    let a = Paced::with_clock(InprocBus::new("shared"), 250_000, clock.clone());
    let mut rx = a.try_clone().unwrap();
    let b = a.try_clone().unwrap();
    let t = bits_duration(135, 250_000);
    let threads: Vec<_> = [(a, 0x100u16), (b, 0x200)]
        .into_iter()
        .map(|(mut h, id)| {
            std::thread::spawn(move || {
                for i in 0..40 {
                    h.send(&frame(id, i)).unwrap();
                }
            })
        })
        .collect();
    let mut next = [0u8; 2];
    let mut prev: Option<Instant> = None;
    for _ in 0..80 {
        let r = rx.recv_timeout(Duration::from_secs(10)).unwrap().unwrap();
        assert!(Instant::now() >= r.timestamp);
        let who = (r.frame.id().raw() >> 9) as usize; // 0x100 -> 0, 0x200 -> 1
        assert_eq!(r.frame.data()[0], next[who], "sender {who} out of order");
        next[who] += 1;
        if let Some(p) = prev {
            assert!(r.timestamp >= p + t, "frames overlap on the wire");
        }
        prev = Some(r.timestamp);
    }
    for th in threads {
        th.join().unwrap();
    }
    assert_eq!(next, [40, 40]);
    assert_eq!(clock.busy(), t * 80);
    assert_eq!(clock.snapshot().frames(), 80);
}

#[test]
fn a_full_transmit_queue_makes_the_sender_wait() {
    // queue of 2 frames: the 10th send returns once the wire is booked at most 2 frames
    // ahead, i.e. 8 frame times after the first started
    let mut tx = Paced::new(InprocBus::new("queue"), 125_000).with_tx_queue(2);
    let _rx = tx.inner().handle();
    let t = bits_duration(135, 125_000);
    let t0 = Instant::now();
    for i in 0..10 {
        tx.send(&frame(0x300, i)).unwrap();
    }
    assert!(t0.elapsed() >= t * 8, "{:?}", t0.elapsed());
}

#[test]
fn a_frame_due_after_the_timeout_is_kept_for_the_next_call() {
    let mut tx = Paced::new(InprocBus::new("keep"), 10_000); // 135 bits = 13.5 ms
    let mut rx = Paced::with_clock(tx.inner().handle(), 10_000, tx.clock().clone());
    let t0 = Instant::now();
    tx.send(&frame(0x400, 1)).unwrap();
    assert!(rx.recv_timeout(Duration::from_millis(2)).unwrap().is_none());
    assert!(t0.elapsed() >= Duration::from_millis(2));
    let r = rx.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
    assert_eq!(r.frame, frame(0x400, 1));
    assert!(Instant::now() >= r.timestamp);
    assert!(r.timestamp >= t0 + Duration::from_micros(13_500));
}

#[test]
fn an_over_full_cycle_overruns() {
    // 1 kHz cycle at 125 kbit/s holds 125 bits/ms: one 8-byte frame (135 bits) already
    // does not fit. Five frames per "cycle" arrive > 5 cycles after they were queued.
    let load = flexid_can::timing::bus_load(
        &[flexid_can::timing::FrameShape::standard(8); 5],
        1000.0,
        125_000,
    );
    assert!(load > 5.0, "{load}");
    let mut tx = Paced::new(InprocBus::new("cycle"), 125_000);
    let mut rx = Paced::with_clock(tx.inner().handle(), 125_000, tx.clock().clone());
    let cycle = Duration::from_millis(1);
    let t0 = Instant::now();
    for i in 0..5 {
        tx.send(&frame(0x200, i)).unwrap();
    }
    let mut last = None;
    for _ in 0..5 {
        last = rx.recv_timeout(Duration::from_secs(5)).unwrap();
    }
    assert!(last.unwrap().timestamp > t0 + 5 * cycle);
    assert!(t0.elapsed() > 5 * cycle, "{:?}", t0.elapsed());
}
