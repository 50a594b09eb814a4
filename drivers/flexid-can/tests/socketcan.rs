//! SocketCAN: only what can run without a CAN interface (this kernel may lack AF_CAN).
#![cfg(target_os = "linux")]

use flexid_can::{BusError, SocketCanBus};

#[test]
fn missing_interface_is_a_clear_error() {
    let e = SocketCanBus::open("flexidnone0").unwrap_err();
    let BusError::Open { interface, .. } = &e else {
        panic!("{e}")
    };
    assert_eq!(&**interface, "flexidnone0");
    let text = e.to_string();
    assert!(text.starts_with("cannot open flexidnone0"), "{text}");
    eprintln!("{text}");
}
