//! flexid-vdrive against a python-can process (udp_multicast): NMT reset -> boot-up, SDO
//! upload, RPDO + SYNC -> TPDO. Needs `.venv-interop` (scripts/pyenv-interop.sh) and
//! loopback multicast; skips (and says so) without them.

mod common;

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_flexid-vdrive");

#[test]
fn python_can_master_talks_to_the_binary() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = root.join(".venv-interop/bin/python");
    if !py.exists() {
        common::skip("no .venv-interop: run scripts/pyenv-interop.sh");
        return;
    }
    if !common::loopback_multicast() {
        return;
    }
    let port = "43179";
    let mut drive = Command::new(BIN)
        .args(["--bus", &format!("udp:239.74.163.2:{port}"), "--node", "9"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(drive.stdout.take().unwrap()).lines();
    assert!(lines.next().unwrap().unwrap().contains("node 9 ready"));
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/interop/pycan_master.py");
    let out = Command::new(&py)
        .arg(script)
        .args(["239.74.163.2", port, "9"])
        .output()
        .unwrap();
    unsafe {
        libc::kill(drive.id() as i32, libc::SIGTERM);
    }
    let status = drive.wait().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let want = [
        "boot 00",
        "sdo1000 4300100092010200",
        // SYNC 0: operation enabled 0x1237 (CiA 402: remote, voltage enabled, CST target
        // followed), position 0, torque 0;
        // SYNC 1: torque actual 250 per-mille (0x00FA), position moved.
        "tpdo1 3712000000000000",
    ];
    let got: Vec<&str> = stdout.lines().collect();
    assert_eq!(got[0], want[0]);
    assert_eq!(got[1], want[1]);
    assert!(got[2].starts_with(want[2]), "{}", got[2]);
    let second = got[2].split(' ').nth(2).unwrap();
    assert!(
        second.starts_with("3712") && second.ends_with("fa00"),
        "{second}"
    );
    assert_ne!(&second[4..12], "00000000", "the axis moved");
    assert_eq!(got[3], "done");
    assert!(status.success());
}
