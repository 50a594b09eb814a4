//! The `flexid-vdrive` program on the UDP multicast bus (skipped when 239.0.0.0/8 cannot
//! be kept on `lo`), and its exit codes.

mod common;
use common::*;

use std::io::{BufRead, BufReader};
use std::net::{IpAddr, Ipv4Addr};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use flexid_can::{CanBus, CanFrame, UdpConfig, UdpMulticastBus};

const BIN: &str = env!("CARGO_BIN_EXE_flexid-vdrive");
const PORT: u16 = 43177;

fn recv_until(bus: &mut UdpMulticastBus, cob: u32, within: Duration) -> CanFrame {
    let end = Instant::now() + within;
    loop {
        let left = end.saturating_duration_since(Instant::now());
        assert!(!left.is_zero(), "no frame 0x{cob:03X} within {within:?}");
        if let Ok(Some(r)) = bus.recv_timeout(left) {
            if r.frame.id().raw() == cob {
                return r.frame;
            }
        }
    }
}

#[test]
fn binary_on_udp_multicast_answers_nmt_and_sdo_and_exits_on_sigterm() {
    if !loopback_multicast() {
        return;
    }
    let mut child = Command::new(BIN)
        .args(["--bus", &format!("udp:239.74.163.2:{PORT}"), "--node", "7"])
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let ready = lines.next().expect("a ready line").unwrap();
    assert_eq!(
        ready,
        format!("flexid-vdrive: node 7 ready on udp:239.74.163.2:{PORT}")
    );
    let cfg = UdpConfig::group_port(IpAddr::V4(Ipv4Addr::new(239, 74, 163, 2)), PORT);
    let mut bus = UdpMulticastBus::open(cfg).unwrap();
    // Reset node -> boot-up 0x707 [00].
    bus.send(&frame(0x000, &[0x81, 0x07])).unwrap();
    let boot = recv_until(&mut bus, 0x707, Duration::from_secs(3));
    assert_eq!(boot.data(), &[0x00]);
    // SDO upload 0x1018:1 vendor id.
    bus.send(&frame(0x607, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]))
        .unwrap();
    let r = recv_until(&mut bus, 0x587, Duration::from_secs(3));
    assert_eq!(r.data(), &[0x43, 0x18, 0x10, 0x01, 0x1D, 0x0F, 0x00, 0x00]);
    // 0x1018:4 serial = node id.
    bus.send(&frame(0x607, &[0x40, 0x18, 0x10, 0x04, 0, 0, 0, 0]))
        .unwrap();
    let r = recv_until(&mut bus, 0x587, Duration::from_secs(3));
    assert_eq!(r.data(), &[0x43, 0x18, 0x10, 0x04, 0x07, 0x00, 0x00, 0x00]);

    unsafe {
        libc::kill(child.id() as i32, libc::SIGTERM);
    }
    let end = Instant::now() + Duration::from_secs(5);
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            panic!("flexid-vdrive did not exit within 5 s of SIGTERM");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    assert!(status.success(), "{status:?}");
}

#[test]
fn bad_plant_file_exits_2_with_a_message() {
    let dir = std::env::temp_dir().join(format!("vdrive-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.toml");
    std::fs::write(
        &path,
        format!(
            "{}\n[drive]\npeak_torque_nm = -1.0\n",
            flexid_core::plant::DEFAULT_PLANT
        ),
    )
    .unwrap();
    let out = Command::new(BIN)
        .args(["--bus", "udp:239.74.163.2:43178", "--plant"])
        .arg(&path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("peak_torque_nm"),
        "{err}"
    );
    let out = Command::new(BIN)
        .args(["--plant", "/nonexistent/plant.toml"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent/plant.toml"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fifo_priority_is_applied_or_its_refusal_named() {
    let out = Command::new(BIN)
        .args(["--bus", "udp:239.74.163.2:43179", "--fifo-priority", "0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--fifo-priority"));
    if !loopback_multicast() {
        return;
    }
    let mut child = Command::new(BIN)
        .args(["--bus", "udp:239.74.163.2:43179", "--fifo-priority", "50"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let ready = lines.next().expect("a ready line").unwrap();
    assert!(ready.contains("ready on"), "{ready}");
    // SAFETY: plain queries of another process's scheduling.
    let (policy, prio) = unsafe {
        let mut p = libc::sched_param { sched_priority: 0 };
        let pid = child.id() as libc::pid_t;
        (libc::sched_getscheduler(pid), {
            libc::sched_getparam(pid, &mut p);
            p.sched_priority
        })
    };
    let _ = child.kill();
    let out = child.wait_with_output().unwrap();
    if policy == libc::SCHED_FIFO {
        assert_eq!(prio, 50);
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("SCHED_FIFO priority 50 not granted"), "{err}");
    }
}

#[test]
fn ethercat_on_a_missing_interface_exits_1_naming_it_and_bad_options_exit_2() {
    let out = Command::new(BIN)
        .args(["--ethercat", "flexid-none0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    // As root: no such interface; otherwise: the capability it needs.
    assert!(
        err.contains("flexid-none0")
            && (err.contains("no such interface") || err.contains("CAP_NET_RAW")),
        "{err}"
    );
    for (args, says) in [
        (&["--ethercat", "x0", "--axes", "0"][..], "--axes 0"),
        (&["--ethercat", "x0", "--cycle-hz", "0"][..], "--cycle-hz 0"),
        (&["--ethercat", "x0", "--node", "5"][..], "--node"),
    ] {
        let out = Command::new(BIN).args(args).output().unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
