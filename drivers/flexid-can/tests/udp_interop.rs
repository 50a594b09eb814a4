//! Interop with python-can's `udp_multicast` interface: frames sent by flexid arrive in a
//! python-can process unchanged, and python-can's frames arrive here unchanged.
//!
//! Needs `.venv-interop` (made by `scripts/pyenv-interop.sh`); without it the test says
//! so and passes.

mod common;

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use flexid_can::{CanBus, CanFrame, CanId, UdpConfig, UdpMulticastBus};

fn python() -> Option<PathBuf> {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = root.join(".venv-interop/bin/python");
    py.exists().then_some(py)
}

#[test]
fn frames_cross_between_flexid_and_python_can() {
    let Some(py) = python() else {
        eprintln!("skipped: run scripts/pyenv-interop.sh");
        return;
    };
    if !common::loopback_multicast() {
        return;
    }
    let port = 43210;
    let mut bus = UdpMulticastBus::open(UdpConfig::group_port(common::GROUP, port)).unwrap();
    let sent = [
        CanFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap(),
        CanFrame::extended(0x0123_4567, &[0xAA, 0xBB]).unwrap(),
        CanFrame::remote(CanId::Standard(0x601), 4).unwrap(),
        CanFrame::standard(0x100, &[]).unwrap(),
    ];
    // What python-can must print for them, and answer.
    let expect_rx = [
        "rx 181 0 0 8 0102030405060708",
        "rx 1234567 1 0 2 aabb",
        "rx 601 0 1 4 ",
        "rx 100 0 0 0 ",
    ];
    let expect_back = [
        CanFrame::standard(0x182, &[8, 7, 6, 5, 4, 3, 2, 1]).unwrap(),
        CanFrame::extended(0x0123_4568, &[0xBB, 0xAA]).unwrap(),
        CanFrame::standard(0x681, &[0, 1, 2, 3]).unwrap(),
        CanFrame::standard(0x101, &[]).unwrap(),
    ];

    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/interop/pycan_peer.py");
    let mut child = Command::new(&py)
        .arg(&script)
        .args([
            &common::GROUP.to_string(),
            &port.to_string(),
            &sent.len().to_string(),
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .expect("start python");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut next_line = || lines.next().map(|l| l.unwrap()).unwrap_or_default();
    assert_eq!(next_line(), "ready");

    for f in &sent {
        bus.send(f).unwrap();
    }
    for want in expect_rx {
        let got = next_line();
        assert_eq!(got.trim_end(), want.trim_end());
    }
    assert_eq!(next_line(), "done");

    let deadline = Instant::now() + Duration::from_secs(10);
    let mut back = Vec::new();
    while back.len() < expect_back.len() && Instant::now() < deadline {
        if let Some(r) = bus.recv_timeout(Duration::from_millis(200)).unwrap() {
            back.push(r.frame);
        }
    }
    assert_eq!(back, expect_back);
    assert!(child.wait().unwrap().success());
    assert_eq!(bus.stats().malformed, 0);
}
