//! The files under `systemd/`: the example configuration parses with the real loader, and
//! `systemd-analyze verify` accepts the unit (skipped when the tool is missing).

use std::path::Path;
use std::process::Command;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

#[test]
fn example_configuration_parses() {
    let p = Path::new(ROOT).join("systemd/flexid.toml.example");
    let cfg = flexid::daemon::Config::load(&p).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(cfg.api.listen.to_string(), "127.0.0.1:8642");
    assert!(cfg.api.listen.ip().is_loopback());
    assert_eq!(cfg.data_dir, Path::new("/var/lib/flexid"));
    assert!(cfg.mqtt.is_some());
    assert!(cfg.axis.len() >= 2);
    // issue 18: an EtherCAT line on its own interface
    assert!(cfg.bus.iter().any(|b| {
        b.kind == flexid::daemon::config::BusKind::Ethercat
            && b.interface.as_deref() == Some("eth1")
    }));
}

#[test]
fn unit_has_the_hardening_and_notify_settings() {
    let unit = std::fs::read_to_string(Path::new(ROOT).join("systemd/flexid.service")).unwrap();
    for line in [
        "Type=notify",
        "WatchdogSec=",
        "Restart=on-failure",
        "User=flexid",
        "AmbientCapabilities=CAP_NET_RAW CAP_SYS_NICE",
        "CapabilityBoundingSet=CAP_NET_RAW CAP_SYS_NICE",
        "ProtectSystem=strict",
        "ReadWritePaths=/var/lib/flexid",
        "StateDirectory=flexid",
        "ProtectHome=yes",
        "PrivateTmp=yes",
        "NoNewPrivileges=yes",
        // issue 18: EtherCAT's raw sockets (AF_PACKET)
        "RestrictAddressFamilies=AF_UNIX AF_INET AF_INET6 AF_CAN AF_NETLINK AF_PACKET",
        "LimitRTPRIO=",
        "LimitMEMLOCK=",
        // issue 16: descriptors for the connection limit plus the store's reserve
        "LimitNOFILE=",
    ] {
        assert!(unit.lines().any(|l| l.starts_with(line)), "missing {line}");
    }
    let can = std::fs::read_to_string(Path::new(ROOT).join("systemd/can0.network")).unwrap();
    assert!(can.contains("[CAN]") && can.contains("BitRate=1M"));
    let netdev = std::fs::read_to_string(Path::new(ROOT).join("systemd/vcan0.netdev")).unwrap();
    assert!(netdev.contains("Kind=vcan"));
}

#[test]
fn systemd_analyze_verify_accepts_the_unit() {
    if Command::new("systemd-analyze")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("skipped: systemd-analyze is not installed");
        return;
    }
    // verify checks that ExecStart exists: point it at the binary under test
    let tmp = tempfile::tempdir().unwrap();
    let unit = std::fs::read_to_string(Path::new(ROOT).join("systemd/flexid.service"))
        .unwrap()
        .replace("/usr/local/bin/flexid", env!("CARGO_BIN_EXE_flexid"));
    let p = tmp.path().join("flexid.service");
    std::fs::write(&p, unit).unwrap();
    let out = Command::new("systemd-analyze")
        .args(["verify", "--man=no"])
        .arg(&p)
        .output()
        .unwrap();
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{text}");
    // unknown keys or bad values are only warnings: fail on any remark about the file
    let remarks: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("flexid.service"))
        .collect();
    assert!(remarks.is_empty(), "{}", remarks.join("\n"));
}
