//! `flexid sweep` over EtherCAT (issue 18): `--bus ethercat:emulated:PLANT` runs the same
//! measurement, files and identification as over CAN on the emulated servo at 4 kHz
//! (lock-step; SubDevice 2 of a line of two), within 3 % of the plant file; an interface
//! that cannot be opened exits 1 naming it and CAP_NET_RAW.

mod e2e;

use e2e::*;
use std::time::Duration;

#[test]
fn flexid_sweep_over_the_emulated_ethercat_line_identifies_the_plant_within_3_percent() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sweep");
    let bus = format!("ethercat:emulated:{}", plant_path().display());
    let o = flexid(
        &[
            "sweep",
            "--bus",
            &bus,
            "--node",
            "2",
            "--cycle-hz",
            "4000",
            "--clock",
            "lockstep",
            "--band",
            "1",
            "500",
            "--periods",
            "4",
            "--peak-nm",
            "0.5",
            "--masses",
            "3",
            "--out",
            out.to_str().unwrap(),
        ],
        Duration::from_secs(300),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    eprintln!("{stderr}");
    assert!(o.status.success(), "{stderr}");
    assert!(
        stderr.contains("emulated EtherCAT line (in process), SubDevice 2"),
        "{stderr}"
    );
    assert!(stderr.contains("profile flexid-vdrive"), "{stderr}");
    let sc = sidecar(&out);
    assert_eq!(sc["sample_rate_hz"], 4000.0, "{sc}");
    assert_eq!(sc["drive"]["vendor_id"], 0x0A1D, "{sc}");
    assert!(out.join("bode.svg").is_file());
    assert_identified(&out, &plant_path(), 0.03);
}

#[test]
fn flexid_sweep_on_an_interface_that_cannot_be_opened_exits_1_naming_it() {
    let tmp = tempfile::tempdir().unwrap();
    let o = flexid(
        &[
            "sweep",
            "--bus",
            "ethercat:flexid-none0",
            "--node",
            "1",
            "--cycle-hz",
            "4000",
            "--out",
            tmp.path().to_str().unwrap(),
        ],
        Duration::from_secs(60),
    );
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("EtherCAT interface flexid-none0"),
        "{stderr}"
    );
    assert!(stderr.contains("CAP_NET_RAW"), "{stderr}");
}
