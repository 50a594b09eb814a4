//! One EtherCAT session end to end (`flexid_ecat::with_drive`): over the emulated line the
//! drive comes up, runs and the link stops (the call returns: nothing left running); an
//! interface that cannot be opened is an error naming it and the capability it needs.

mod common;

use flexid_canopen::{CyclicDrive, ProfileSet};
use flexid_ecat::emulated::servo_line;
use flexid_ecat::{with_drive, EcatConfig, Link, SessionError};
use std::time::{Duration, Instant};

#[test]
fn a_session_on_the_emulated_line_runs_the_drive_and_stops_its_link() {
    let segment = servo_line(&common::plant(), 2, 4000.0).expect("line");
    let config = EcatConfig {
        axis: 1,
        ..EcatConfig::at_hz(4000.0)
    };
    let t0 = Instant::now();
    let positions = with_drive(
        Link::Emulated(segment.clone()),
        config,
        &ProfileSet::builtin(),
        |mut d| {
            let mut p = Vec::new();
            for _ in 0..400 {
                let fb = d
                    .cycle(0.5, Instant::now() + Duration::from_millis(200))
                    .expect("cycle");
                p.push(fb.position_rad);
            }
            d.disable().expect("disable");
            p
        },
    )
    .expect("session");
    eprintln!(
        "session of 400 cycles in {:.0} ms",
        t0.elapsed().as_secs_f64() * 1e3
    );
    // 0.5 N m for 0.1 s accelerates the chain: the position grows.
    assert!(positions[399] > positions[100] && positions[100] > 0.0);
    // Axis 1 moved, axis 0 stayed.
    let seg = segment.lock().expect("segment");
    let position = |i: usize| {
        seg.subdevice(i)
            .and_then(|d| d.dictionary().get(0x6064, 0))
            .and_then(|b| b.try_into().ok())
            .map_or(0, i32::from_le_bytes)
    };
    assert_eq!(position(0), 0);
    assert!(position(1) > 0);
}

#[test]
fn an_interface_that_cannot_be_opened_names_it_and_cap_net_raw() {
    let r = with_drive(
        Link::Interface("flexid-none0".into()),
        EcatConfig::at_hz(4000.0),
        &ProfileSet::builtin(),
        |_| (),
    );
    let Err(e) = r else {
        panic!("an interface that does not exist opened");
    };
    assert!(matches!(e, SessionError::Interface { .. }), "{e:?}");
    let text = e.to_string();
    eprintln!("{text}");
    assert!(text.contains("EtherCAT interface flexid-none0"), "{text}");
    assert!(text.contains("CAP_NET_RAW"), "{text}");
}

#[test]
fn a_panic_in_the_session_stops_the_link_and_reaches_the_caller() {
    let segment = servo_line(&common::plant(), 1, 4000.0).expect("line");
    let caught = std::panic::catch_unwind(|| {
        with_drive(
            Link::Emulated(segment),
            EcatConfig::at_hz(4000.0),
            &ProfileSet::builtin(),
            |_| panic!("the caller's code failed"),
        )
    });
    let panic = caught.expect_err("the panic reaches the caller");
    assert_eq!(
        panic.downcast_ref::<&str>().copied(),
        Some("the caller's code failed")
    );
}
