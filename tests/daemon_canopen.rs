//! The daemon's CANopen backend end to end: the real `flexid-vdrive` (a CiA 402 drive in
//! front of plants/e2e_3mass.toml, lock-step) on the UDP multicast bus and the real
//! `flexid daemon` with `backend.kind = "canopen"`. Skipped when 239.0.0.0/8 cannot be kept
//! on `lo` (fails under CI=true).

mod daemon_common;
mod e2e;

use daemon_common::{auth, client, read_events_at, token_file};
use e2e::*;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

#[tokio::test]
async fn canopen_backend_sweeps_the_simulated_drive() {
    if !loopback_multicast() {
        return;
    }
    let port = 43297;
    let _vd = VDrive::start(&format!("udp:239.74.163.2:{port}"), &plant_path());
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = tmp.path().join("flexid.toml");
    std::fs::write(
        &cfg,
        format!(
            r#"
data_dir = "{data}"
[api]
listen = "127.0.0.1:0"
token_file = "{token}"
[backend]
kind = "canopen"
[[bus]]
name = "bench"
kind = "udp"
group = "239.74.163.2"
port = {port}
bitrate = 1000000
[[axis]]
name = "a5"
bus = "bench"
node = 5
cycle_hz = 1000
clock = "simulated"
limits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 300.0, position_window_rad = 1000.0, max_sweep_s = 60 }}
"#,
            data = tmp.path().join("data").display(),
            token = token.display()
        ),
    )
    .unwrap();
    let mut child = Command::new(FLEXID)
        .args(["daemon", "--config"])
        .arg(&cfg)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let base = format!("http://{}", line.trim().rsplit(' ').next().unwrap());
    let r = auth(client().post(format!("{base}/api/v1/axes/a5/sweeps")))
        .body(r#"{"excitation":"multisine","band_hz":[1,300],"amplitude_nm":0.5,"periods":4,"duration_s":10}"#)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    let v: serde_json::Value = r.json().await.unwrap();
    let id = v["sweep_id"].as_str().unwrap().to_string();
    let evs = read_events_at(&base, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "completed", "{:?}", ended.data);
    assert_eq!(ended.data["samples"], 10_000);
    let result = evs.iter().find(|e| e.event == "result").unwrap();
    let model = &result.data["model"];
    assert!(model["masses"].as_u64().unwrap() >= 2, "{}", result.data);
    let csv = auth(client().get(format!("{base}/api/v1/sweeps/{id}/recording.csv")))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert_eq!(csv.lines().count(), 10_001);
    let _ = child.kill();
    let _ = child.wait();
}
