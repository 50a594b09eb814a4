//! How a bus is named on a command line or in a configuration: `udp[:GROUP[:PORT]]`,
//! `socketcan:IFACE` or a bare SocketCAN interface name (`vcan0`, `can1`).

use crate::UdpConfig;
use std::net::IpAddr;

/// Which bus `--bus` names.
#[derive(Debug, Clone, PartialEq)]
pub enum BusSpec {
    /// User-space UDP multicast (python-can `udp_multicast` compatible).
    Udp(UdpConfig),
    /// A SocketCAN interface.
    SocketCan(String),
}

impl BusSpec {
    /// Parse `udp[:GROUP[:PORT]]`, `socketcan:IFACE`, or a bare SocketCAN interface name
    /// (`vcan0`, `can1`).
    pub fn parse(s: &str) -> Result<Self, String> {
        if let Some(iface) = s.strip_prefix("socketcan:") {
            if iface.is_empty() {
                return Err("--bus socketcan:IFACE needs an interface".into());
            }
            return Ok(BusSpec::SocketCan(iface.into()));
        }
        let Some(rest) = s.strip_prefix("udp") else {
            if !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                return Ok(BusSpec::SocketCan(s.into()));
            }
            return Err(format!(
                "--bus {s}: expected udp[:GROUP[:PORT]], vcan0 or socketcan:IFACE"
            ));
        };
        if rest.is_empty() {
            return Ok(BusSpec::Udp(UdpConfig::default()));
        }
        let bad = || format!("--bus {s}: expected udp[:GROUP[:PORT]] (IPv6: udp:[GROUP]:PORT)");
        let rest = rest.strip_prefix(':').ok_or_else(bad)?;
        let (group, port) = if let Some(r) = rest.strip_prefix('[') {
            let (g, p) = r.split_once(']').ok_or_else(bad)?;
            (g, p.strip_prefix(':'))
        } else if rest.parse::<IpAddr>().is_ok() {
            (rest, None)
        } else {
            match rest.rsplit_once(':') {
                Some((g, p)) => (g, Some(p)),
                None => (rest, None),
            }
        };
        let group: IpAddr = group.parse().map_err(|_| bad())?;
        if !group.is_multicast() {
            return Err(format!("--bus {s}: {group} is not a multicast group"));
        }
        let mut cfg = UdpConfig::group(group);
        if let Some(p) = port {
            cfg.port = p.parse().map_err(|_| bad())?;
        }
        Ok(BusSpec::Udp(cfg))
    }

    /// How it is written in `--bus`.
    pub fn describe(&self) -> String {
        match self {
            BusSpec::Udp(c) => match c.group {
                IpAddr::V4(g) => format!("udp:{g}:{}", c.port),
                IpAddr::V6(g) => format!("udp:[{g}]:{}", c.port),
            },
            BusSpec::SocketCan(i) => format!("socketcan:{i}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bus_specs() {
        assert!(matches!(BusSpec::parse("udp"), Ok(BusSpec::Udp(c)) if c == UdpConfig::default()));
        match BusSpec::parse("udp:239.74.163.2:5000") {
            Ok(BusSpec::Udp(c)) => {
                assert_eq!((c.group.to_string(), c.port), ("239.74.163.2".into(), 5000))
            }
            other => panic!("{other:?}"),
        }
        match BusSpec::parse("udp:239.1.2.3") {
            Ok(BusSpec::Udp(c)) => assert_eq!(c.port, 43113),
            other => panic!("{other:?}"),
        }
        match BusSpec::parse("udp:[ff15::1]:7") {
            Ok(BusSpec::Udp(c)) => assert_eq!(c.port, 7),
            other => panic!("{other:?}"),
        }
        assert!(
            matches!(BusSpec::parse("socketcan:vcan0"), Ok(BusSpec::SocketCan(i)) if i == "vcan0")
        );
        assert!(matches!(BusSpec::parse("can1"), Ok(BusSpec::SocketCan(i)) if i == "can1"));
        assert!(BusSpec::parse("udp:10.0.0.1").is_err());
        assert!(BusSpec::parse("tcp:10.0.0.1").is_err());
        assert!(BusSpec::parse("socketcan:").is_err());
        assert!(BusSpec::parse("udp:239.1.2.3:x").is_err());
    }

    #[test]
    fn describe_parses_back() {
        for s in [
            "udp:239.74.163.2:5000",
            "udp:[ff15::1]:7",
            "socketcan:vcan0",
        ] {
            let spec = BusSpec::parse(s).unwrap();
            assert_eq!(spec.describe(), s);
            assert_eq!(BusSpec::parse(&spec.describe()).unwrap(), spec);
        }
    }
}
