//! Keeping the user-space bus on this machine: the [`crate::UdpMulticastBus`] sends IPv4
//! multicast, which must never leave through a real network interface on a test bench.

use std::net::Ipv4Addr;
use std::process::Command;

/// Whether the kernel routes `group` to the loopback interface (`ip route get`).
pub fn multicast_routed_to_lo(group: Ipv4Addr) -> bool {
    Command::new("ip")
        .args(["route", "get", &group.to_string()])
        .output()
        .is_ok_and(|o| {
            o.status.success() && String::from_utf8_lossy(&o.stdout).contains(" dev lo ")
        })
}

/// Makes sure IPv4 multicast to 239.0.0.0/8 (the administratively scoped range the
/// user-space bus uses) stays on `lo`, setting it up when allowed (root, CAP_NET_ADMIN)
/// and not done yet; idempotent:
///
/// ```text
/// ip link set lo multicast on
/// ip route add 239.0.0.0/8 dev lo
/// ```
///
/// `Err` says what to run when `group` would leave through another interface; callers
/// then do not use the bus (nothing is sent onto a real network).
pub fn keep_multicast_on_loopback(group: Ipv4Addr) -> Result<(), String> {
    if multicast_routed_to_lo(group) {
        return Ok(());
    }
    let _ = Command::new("ip")
        .args(["link", "set", "lo", "multicast", "on"])
        .status();
    let _ = Command::new("ip")
        .args(["route", "add", "239.0.0.0/8", "dev", "lo"])
        .status();
    if multicast_routed_to_lo(group) {
        return Ok(());
    }
    Err(format!(
        "{group} is not routed to lo (as root: `ip link set lo multicast on && \
         ip route add 239.0.0.0/8 dev lo`); the user-space bus is not sent onto a real network"
    ))
}
