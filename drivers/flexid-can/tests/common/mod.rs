//! Test helpers: keeping the UDP multicast bus on loopback.

#![allow(dead_code)]

use std::net::{IpAddr, Ipv4Addr};
use std::process::Command;

/// A group inside 239.0.0.0/8 (routed to `lo` by [`loopback_multicast`]); tests use
/// their own ports so that they can run in parallel.
pub const GROUP: IpAddr = IpAddr::V4(Ipv4Addr::new(239, 74, 163, 2));

fn routed_to_lo() -> bool {
    Command::new("ip")
        .args(["route", "get", "239.74.163.2"])
        .output()
        .is_ok_and(|o| {
            o.status.success() && String::from_utf8_lossy(&o.stdout).contains(" dev lo ")
        })
}

/// Makes sure IPv4 multicast to 239.0.0.0/8 stays on this machine (`lo`), setting it up
/// when run as root and not done yet (idempotent):
///
/// ```text
/// ip link set lo multicast on
/// ip route add 239.0.0.0/8 dev lo
/// ```
///
/// Returns false (and the test should skip) when the group would leave through another
/// interface: tests never send multicast onto a real network.
pub fn loopback_multicast() -> bool {
    if routed_to_lo() {
        return true;
    }
    let _ = Command::new("ip")
        .args(["link", "set", "lo", "multicast", "on"])
        .status();
    let _ = Command::new("ip")
        .args(["route", "add", "239.0.0.0/8", "dev", "lo"])
        .status();
    if routed_to_lo() {
        return true;
    }
    eprintln!(
        "skipped: 239.0.0.0/8 is not routed to lo; as root run \
         `ip link set lo multicast on && ip route add 239.0.0.0/8 dev lo`"
    );
    false
}
