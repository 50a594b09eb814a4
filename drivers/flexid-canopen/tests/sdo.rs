//! The blocking SDO client against scripted servers. Frames written by hand from
//! CiA 301 §7.2.4.3 (command specifiers, toggle/size/last bits).

mod common;

use std::time::{Duration, Instant};

use common::{raw, scripted_drive, Raw};
use flexid_can::InprocBus;
use flexid_canopen::sdo::{Sdo, SdoError};

const NODE: u8 = 0x10; // requests on 0x610, responses on 0x590

fn client(bus: &InprocBus, timeout_ms: u64) -> Sdo<InprocBus> {
    Sdo::new(
        bus.handle(),
        NODE,
        Duration::from_millis(timeout_ms),
        Instant::now,
    )
    .unwrap()
}

fn run<T>(
    script: Vec<(Raw, Vec<Raw>)>,
    f: impl FnOnce(&mut Sdo<InprocBus>) -> T,
) -> (T, Vec<Raw>, Vec<Raw>) {
    let bus = InprocBus::new("sdo");
    let expected: Vec<Raw> = script.iter().map(|(e, _)| e.clone()).collect();
    let server = scripted_drive(bus.handle(), script, Duration::from_millis(500));
    let mut c = client(&bus, 300);
    let out = f(&mut c);
    drop(c);
    (out, server.join().unwrap(), expected)
}

#[test]
fn expedited_upload_and_download() {
    let script = vec![
        (
            raw(0x610, &[0x40, 0x18, 0x10, 0x01, 0, 0, 0, 0]),
            vec![raw(
                0x590,
                &[0x43, 0x18, 0x10, 0x01, 0x78, 0x56, 0x34, 0x12],
            )],
        ),
        (
            raw(0x610, &[0x2B, 0x71, 0x60, 0x00, 0x9C, 0xFF, 0x00, 0x00]), // i16 -100
            vec![raw(0x590, &[0x60, 0x71, 0x60, 0x00, 0, 0, 0, 0])],
        ),
        (
            raw(0x610, &[0x2F, 0x60, 0x60, 0x00, 0x0A, 0x00, 0x00, 0x00]), // u8 10
            vec![raw(0x590, &[0x60, 0x60, 0x60, 0x00, 0, 0, 0, 0])],
        ),
        (
            raw(0x610, &[0x23, 0x06, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00]), // u32 1000
            vec![raw(0x590, &[0x60, 0x06, 0x10, 0x00, 0, 0, 0, 0])],
        ),
        (
            raw(0x610, &[0x23, 0x7A, 0x60, 0x00, 0x00, 0xFF, 0xFF, 0xFF]), // i32 -256
            vec![raw(0x590, &[0x60, 0x7A, 0x60, 0x00, 0, 0, 0, 0])],
        ),
        (
            raw(0x610, &[0x2B, 0x17, 0x10, 0x00, 0x64, 0x00, 0x00, 0x00]), // u16 100
            vec![raw(0x590, &[0x60, 0x17, 0x10, 0x00, 0, 0, 0, 0])],
        ),
        // expedited upload without size indication (0x42): 4 bytes taken
        (
            raw(0x610, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
            vec![raw(
                0x590,
                &[0x42, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00],
            )],
        ),
    ];
    let (r, got, expected) = run(script, |c| {
        let v = c.read_u32(0x1018, 1)?;
        c.write_i16(0x6071, 0, -100)?;
        c.write_u8(0x6060, 0, 10)?;
        c.write_u32(0x1006, 0, 1000)?;
        c.write_i32(0x607A, 0, -256)?;
        c.write_u16(0x1017, 0, 100)?;
        let dt = c.read_u32(0x1000, 0)?;
        Ok::<_, SdoError>((v, dt))
    });
    assert_eq!(r.unwrap(), (0x1234_5678, 0x0002_0192));
    assert_eq!(got, expected);
}

#[test]
fn segmented_upload_of_the_device_name() {
    // "flexid virtual drive": 20 bytes = 7 + 7 + 6
    let script = vec![
        (
            raw(0x610, &[0x40, 0x08, 0x10, 0x00, 0, 0, 0, 0]),
            vec![raw(0x590, &[0x41, 0x08, 0x10, 0x00, 20, 0, 0, 0])],
        ),
        (
            raw(0x610, &[0x60, 0, 0, 0, 0, 0, 0, 0]),
            vec![raw(0x590, b"\x00flexid ")],
        ),
        (
            raw(0x610, &[0x70, 0, 0, 0, 0, 0, 0, 0]),
            vec![raw(0x590, b"\x10virtual")],
        ),
        // last: toggle 0, n = 1 unused byte, c = 1 -> 0x03
        (
            raw(0x610, &[0x60, 0, 0, 0, 0, 0, 0, 0]),
            vec![raw(0x590, b"\x03 drive\x00")],
        ),
    ];
    let (r, got, expected) = run(script, |c| c.read_string(0x1008, 0));
    assert_eq!(r.unwrap(), "flexid virtual drive");
    assert_eq!(got, expected);
}

#[test]
fn segmented_download_of_a_string() {
    // "hello world": 11 bytes = 7 + 4
    let script = vec![
        (
            raw(0x610, &[0x21, 0x00, 0x20, 0x00, 11, 0, 0, 0]),
            vec![raw(0x590, &[0x60, 0x00, 0x20, 0x00, 0, 0, 0, 0])],
        ),
        (
            raw(0x610, b"\x00hello w"),
            vec![raw(0x590, &[0x20, 0, 0, 0, 0, 0, 0, 0])],
        ),
        // toggle 1, n = 3, c = 1 -> 0x17
        (
            raw(0x610, b"\x17orld\x00\x00\x00"),
            vec![raw(0x590, &[0x30, 0, 0, 0, 0, 0, 0, 0])],
        ),
    ];
    let (r, got, expected) = run(script, |c| c.write_string(0x2000, 0, "hello world"));
    r.unwrap();
    assert_eq!(got, expected);
}

#[test]
fn abort_becomes_an_error_with_its_text() {
    let script = vec![(
        raw(0x610, &[0x40, 0x01, 0x20, 0x00, 0, 0, 0, 0]),
        vec![raw(
            0x590,
            &[0x80, 0x01, 0x20, 0x00, 0x00, 0x00, 0x02, 0x06],
        )],
    )];
    let (r, _, _) = run(script, |c| c.read_u32(0x2001, 0));
    let e = r.unwrap_err();
    match &e {
        SdoError::SdoAbort {
            node,
            index,
            subindex,
            code,
            text,
        } => {
            assert_eq!(
                (*node, *index, *subindex, *code),
                (NODE, 0x2001, 0, 0x0602_0000)
            );
            assert_eq!(*text, "object does not exist in the object dictionary");
        }
        other => panic!("{other}"),
    }
    assert_eq!(
        e.to_string(),
        "node 16: SDO abort on 0x2001:00: 0x06020000 object does not exist in the object dictionary"
    );
}

#[test]
fn timeout_names_what_it_waited_for_and_aborts() {
    let bus = InprocBus::new("sdo-timeout");
    let mut spy = bus.handle();
    let mut c = client(&bus, 40);
    let t0 = Instant::now();
    let e = c.read_u32(0x1018, 2).unwrap_err();
    assert!(t0.elapsed() >= Duration::from_millis(40));
    assert!(
        matches!(
            e,
            SdoError::Timeout {
                node: NODE,
                index: 0x1018,
                subindex: 2,
                waiting_for: "SDO upload response",
                ..
            }
        ),
        "{e}"
    );
    assert_eq!(
        e.to_string(),
        "node 16: no SDO upload response for 0x1018:02 after 40ms"
    );
    use flexid_can::CanBus;
    let z = Duration::ZERO;
    assert_eq!(
        spy.recv_timeout(z).unwrap().unwrap().frame.data(),
        &[0x40, 0x18, 0x10, 0x02, 0, 0, 0, 0]
    );
    // abort 0x05040000 (SDO protocol timed out) sent to the server
    let abort = spy.recv_timeout(z).unwrap().unwrap().frame;
    assert_eq!(abort.id().raw(), 0x610);
    assert_eq!(
        abort.data(),
        &[0x80, 0x18, 0x10, 0x02, 0x00, 0x00, 0x04, 0x05]
    );
    // a download waits for a download response
    let e = c.write_u8(0x6060, 0, 10).unwrap_err();
    assert!(
        e.to_string()
            .contains("no SDO download response for 0x6060:00"),
        "{e}"
    );
}

#[test]
fn stale_malformed_and_foreign_frames_are_skipped() {
    let script = vec![(
        raw(0x610, &[0x40, 0x17, 0x10, 0x00, 0, 0, 0, 0]),
        vec![
            raw(0x590, &[0x4B, 0x16, 0x10, 0x01, 0x11, 0x22, 0, 0]), // other object: stale
            raw(0x590, &[0x4B, 0x17]),                               // short
            raw(0x185, &[0; 8]),                                     // a PDO
            raw(0x591, &[0x4B, 0x17, 0x10, 0x00, 0x99, 0x00, 0, 0]), // another server
            raw(0x590, &[0x4B, 0x17, 0x10, 0x00, 0x64, 0x00, 0, 0]),
        ],
    )];
    let (r, _, _) = run(script, |c| (c.read_u16(0x1017, 0), c.stats()));
    let (v, stats) = r;
    assert_eq!(v.unwrap(), 100);
    assert_eq!(stats.malformed, 2);
    assert_eq!(stats.skipped, 2);
}

#[test]
fn wrong_size_response_is_a_protocol_error_and_aborts() {
    // u32 asked, the server sends 2 bytes: the client aborts with general error
    let script = vec![
        (
            raw(0x610, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]),
            vec![raw(0x590, &[0x4B, 0x00, 0x10, 0x00, 0x92, 0x01, 0, 0])],
        ),
        (
            raw(0x610, &[0x80, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x08]),
            vec![],
        ),
    ];
    let (r, got, expected) = run(script, |c| c.read_u32(0x1000, 0));
    assert!(
        matches!(
            r,
            Err(SdoError::Protocol {
                code: 0x0800_0000,
                ..
            })
        ),
        "{r:?}"
    );
    assert_eq!(got, expected);
}
