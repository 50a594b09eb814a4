//! UDP multicast bus: two flexid handles exchange frames like CAN nodes; garbage is
//! counted and skipped.

mod common;

use std::net::{SocketAddr, UdpSocket};
use std::time::Duration;

use flexid_can::{BusError, CanBus, CanFrame, CanId, UdpConfig, UdpMulticastBus};

const WAIT: Duration = Duration::from_secs(5);

fn open(port: u16) -> UdpMulticastBus {
    UdpMulticastBus::open(UdpConfig::group_port(common::GROUP, port)).unwrap()
}

#[test]
fn two_handles_exchange_frames_and_skip_their_own() {
    if !common::loopback_multicast() {
        return;
    }
    let mut a = open(43201);
    let mut b = a.try_clone().unwrap();
    assert_ne!(a.local_addr(), b.local_addr());
    let frames = [
        CanFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        CanFrame::extended(0x1234_5678, &[0xAA]).unwrap(),
        CanFrame::remote(CanId::Standard(0x701), 1).unwrap(),
        CanFrame::standard(0x000, &[]).unwrap(),
    ];
    for f in &frames {
        a.send(f).unwrap();
    }
    for f in &frames {
        assert_eq!(
            b.recv_timeout(WAIT).unwrap().expect("frame from a").frame,
            *f
        );
    }
    let back = CanFrame::standard(0x201, &[9]).unwrap();
    b.send(&back).unwrap();
    assert_eq!(a.recv_timeout(WAIT).unwrap().unwrap().frame, back);
    // Neither received its own frames.
    assert!(a.recv_timeout(Duration::from_millis(50)).unwrap().is_none());
    assert!(b.recv_timeout(Duration::ZERO).unwrap().is_none());
    assert_eq!((a.stats().sent, a.stats().received), (4, 1));
    assert_eq!((b.stats().sent, b.stats().received), (1, 4));
}

#[test]
fn receive_own_gives_python_cans_behaviour() {
    if !common::loopback_multicast() {
        return;
    }
    let mut a = UdpMulticastBus::open(UdpConfig {
        receive_own: true,
        ..UdpConfig::group_port(common::GROUP, 43202)
    })
    .unwrap();
    let f = CanFrame::standard(0x123, &[1]).unwrap();
    a.send(&f).unwrap();
    assert_eq!(a.recv_timeout(WAIT).unwrap().unwrap().frame, f);
}

#[test]
fn malformed_datagrams_are_counted_and_skipped() {
    if !common::loopback_multicast() {
        return;
    }
    let port = 43203;
    let mut a = open(port);
    let raw = UdpSocket::bind("0.0.0.0:0").unwrap();
    let dest = SocketAddr::new(common::GROUP, port);
    raw.send_to(b"not msgpack at all", dest).unwrap();
    raw.send_to(&[0x81, 0xa1, b'x', 0xc1], dest).unwrap();
    raw.send_to(&[], dest).unwrap();
    // a valid python-can CAN FD message: ignored, not malformed
    raw.send_to(b"\x82\xaearbitration_id\x05\xa5is_fd\xc3", dest)
        .unwrap();
    let mut b = a.try_clone().unwrap();
    let f = CanFrame::standard(0x7E5, &[0x11, 0x22]).unwrap();
    b.send(&f).unwrap();
    assert_eq!(a.recv_timeout(WAIT).unwrap().unwrap().frame, f);
    let s = a.stats();
    assert_eq!((s.malformed, s.ignored, s.received), (3, 1, 1), "{s:?}");
}

#[test]
fn error_frames_arrive_as_reports() {
    if !common::loopback_multicast() {
        return;
    }
    let mut a = open(43204);
    let mut b = a.try_clone().unwrap();
    a.send(&CanFrame::error(0x40, [0; 8]).unwrap()).unwrap();
    let e = b.recv_timeout(WAIT).unwrap_err();
    assert!(matches!(e, BusError::BusOff { .. }), "{e}");
    assert!(e.is_report());
    assert!(e.to_string().contains("udp:239.74.163.2:43204"), "{e}");
}

#[test]
fn timeouts_return_none_in_time() {
    if !common::loopback_multicast() {
        return;
    }
    let mut a = open(43205);
    let t0 = std::time::Instant::now();
    assert!(a.recv_timeout(Duration::from_millis(30)).unwrap().is_none());
    let dt = t0.elapsed();
    assert!(
        dt >= Duration::from_millis(30) && dt < Duration::from_secs(5),
        "{dt:?}"
    );
    assert!(a.recv_timeout(Duration::ZERO).unwrap().is_none());
}

/// A wait that runs out ends at its deadline, not at the next scheduler tick: the cycle
/// waits for its TPDOs up to the end of a 250-1000 µs period. `SO_RCVTIMEO` rounds up to
/// whole jiffies (4 ms at HZ = 250); the median of 21 short waits must overshoot by less
/// than a millisecond (the median keeps a loaded host's odd stall out).
#[test]
fn short_timeouts_end_near_their_deadline() {
    if !common::loopback_multicast() {
        return;
    }
    let mut a = open(43206);
    let wait = Duration::from_micros(300);
    let mut over: Vec<Duration> = (0..21)
        .map(|_| {
            let t0 = std::time::Instant::now();
            assert!(a.recv_timeout(wait).unwrap().is_none());
            let dt = t0.elapsed();
            assert!(dt >= wait, "{dt:?}");
            dt - wait
        })
        .collect();
    over.sort();
    assert!(
        over[10] < Duration::from_millis(1),
        "median overshoot {:?}",
        over[10]
    );
}

#[test]
fn non_multicast_group_is_an_open_error() {
    let e = UdpMulticastBus::open(UdpConfig::group("127.0.0.1".parse().unwrap())).unwrap_err();
    assert!(matches!(e, BusError::Open { .. }), "{e}");
}
