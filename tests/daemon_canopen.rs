//! The daemon's CANopen backend end to end: the real `flexid-vdrive` (a CiA 402 drive in
//! front of plants/e2e_3mass.toml, lock-step) on the UDP multicast bus and the real
//! `flexid daemon` with `backend.kind = "canopen"`. Skipped when 239.0.0.0/8 cannot be kept
//! on `lo` (fails under CI=true).

mod daemon_common;
mod e2e;

use daemon_common::process::{canopen_config, CanAxis, DaemonProc};
use daemon_common::{get_text, read_events_at, start_sweep_at, token_file};
use e2e::*;

#[tokio::test]
async fn canopen_backend_sweeps_the_simulated_drive() {
    if !loopback_multicast() {
        return;
    }
    let port = 43297;
    let _vd = VDrive::start(&format!("udp:239.74.163.2:{port}"), &plant_path());
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = canopen_config(tmp.path(), &token, &[CanAxis::new("a5", port)], "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let base = d.base.clone();
    let body = r#"{"excitation":"multisine","band_hz":[1,300],"amplitude_nm":0.5,"periods":4,"duration_s":10}"#;
    let id = start_sweep_at(&base, "a5", body).await;
    let evs = read_events_at(&base, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "completed", "{:?}", ended.data);
    assert_eq!(ended.data["samples"], 10_000);
    let result = evs.iter().find(|e| e.event == "result").unwrap();
    let model = &result.data["model"];
    assert!(model["masses"].as_u64().unwrap() >= 2, "{}", result.data);
    let csv = get_text(&format!("{base}/api/v1/sweeps/{id}/recording.csv")).await;
    assert_eq!(csv.lines().count(), 10_001);
    // the columns of `flexid sweep` (issue 16, item 3)
    assert_eq!(
        csv.lines().next().unwrap(),
        "time_s,torque_cmd_nm,position_rad,velocity_rad_s,torque_actual_nm"
    );
    assert!(csv.lines().skip(1).all(|l| l.split(',').count() == 5));
}
