//! Test helpers: keeping the UDP multicast bus on loopback.

#![allow(dead_code)]

use std::net::{IpAddr, Ipv4Addr};

/// A group inside 239.0.0.0/8 (routed to `lo` by [`loopback_multicast`]); tests use
/// their own ports so that they can run in parallel.
pub const GROUP: IpAddr = IpAddr::V4(Ipv4Addr::new(239, 74, 163, 2));

/// Keeps 239.0.0.0/8 on `lo` ([`flexid_can::keep_multicast_on_loopback`]). False: the
/// test skips with a message; under `CI=true` it fails instead.
pub fn loopback_multicast() -> bool {
    match flexid_can::keep_multicast_on_loopback(Ipv4Addr::new(239, 74, 163, 2)) {
        Ok(()) => true,
        Err(msg) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("loopback multicast required under CI=true: {msg}")
        }
        Err(msg) => {
            eprintln!("skipped: {msg}");
            false
        }
    }
}
