//! flexid-vdrive driven by python-canopen's CiA 402 node class (`canopen.BaseNode402`, an
//! implementation no one on flexid wrote) over python-can's udp_multicast bus, using the
//! drive's EDS (`eds/flexid-vdrive.eds`): NMT, expedited and segmented SDO, the PDO
//! configuration uploaded by SDO, SYNC, the state machine walked through RPDO controlwords,
//! a torque through the RPDO and the motion in the TPDOs, and the heartbeat consumer
//! faulting the drive when the master's heartbeat stops.
//!
//! Needs `.venv-interop` with python-canopen (scripts/pyenv-interop.sh) and loopback
//! multicast; skips (and says so) without them, fails under `CI=true`.

mod common;

use std::io::{BufRead, BufReader};
use std::path::PathBuf;
use std::process::{Command, Stdio};

const BIN: &str = env!("CARGO_BIN_EXE_flexid-vdrive");

fn value<'a>(lines: &'a [String], key: &str) -> &'a str {
    lines
        .iter()
        .find_map(|l| l.strip_prefix(key).and_then(|r| r.strip_prefix(' ')))
        .unwrap_or_else(|| {
            panic!(
                "no `{key}` line in the python output:\n{}",
                lines.join("\n")
            )
        })
}

#[test]
fn python_canopen_402_master_drives_the_binary() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = root.join(".venv-interop/bin/python");
    let has_canopen = py.exists()
        && Command::new(&py)
            .args(["-c", "import canopen"])
            .status()
            .is_ok_and(|s| s.success());
    if !has_canopen {
        common::skip("python canopen missing: run scripts/pyenv-interop.sh");
        return;
    }
    if !common::loopback_multicast() {
        return;
    }
    let port = "43181";
    let node = "12";
    let mut drive = Command::new(BIN)
        .args(["--bus", &format!("udp:239.74.163.2:{port}"), "--node", node])
        .args(["--clock", "realtime"])
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    let mut lines = BufReader::new(drive.stdout.take().unwrap()).lines();
    assert!(lines.next().unwrap().unwrap().contains("node 12 ready"));
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let out = Command::new(&py)
        .arg(dir.join("tests/interop/canopen402_master.py"))
        .args(["239.74.163.2", port, node])
        .arg(dir.join("eds/flexid-vdrive.eds"))
        .output()
        .unwrap();
    unsafe {
        libc::kill(drive.id() as i32, libc::SIGTERM);
    }
    let status = drive.wait().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    let got: Vec<String> = stdout.lines().map(str::to_owned).collect();
    assert!(
        out.status.success(),
        "python-canopen master failed:\n{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(value(&got, "bootup"), "ok");
    assert_eq!(value(&got, "device_type"), "0x20192");
    assert_eq!(value(&got, "vendor_id"), "0xf1d");
    assert_eq!(value(&got, "product_code"), "0x402");
    assert_eq!(value(&got, "device_name"), "flexid-vdrive");
    assert_eq!(value(&got, "mode_display"), "10");
    assert_eq!(value(&got, "rated_torque_mnm"), "1000");
    assert_eq!(value(&got, "tpdo1"), "0x6041,0x6064,0x6077");
    assert_eq!(value(&got, "rpdo1"), "0x6040,0x6071");
    assert_eq!(value(&got, "state0"), "SWITCH_ON_DISABLED");
    assert_eq!(value(&got, "state1"), "OPERATION_ENABLED");
    // 0.2 N m on the 25.9e-3 kg m^2 default axis for about 1 s: tens of radians, i.e.
    // millions of increments at 2^20 per revolution; positive torque, positive motion.
    let moved: i64 = value(&got, "moved_increments").parse().unwrap();
    assert!(moved > 100_000, "moved {moved} increments");
    let v: i64 = value(&got, "velocity_increments_s").parse().unwrap();
    assert!(v > 0, "velocity {v}");
    assert_eq!(value(&got, "torque_actual_permille"), "200");
    assert_eq!(value(&got, "state2"), "SWITCH_ON_DISABLED");
    assert_eq!(value(&got, "state3"), "OPERATION_ENABLED");
    assert_eq!(value(&got, "state4"), "FAULT");
    let after: u64 = value(&got, "fault_after_ms").parse().unwrap();
    assert!(
        after <= 400 + 300,
        "fault {after} ms after the last heartbeat"
    );
    assert!(
        value(&got, "emcy").contains("0x8130"),
        "{}",
        value(&got, "emcy")
    );
    assert_eq!(value(&got, "done"), "ok");
    assert!(status.success());
}
