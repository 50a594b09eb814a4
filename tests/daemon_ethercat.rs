//! The daemon's EtherCAT backend end to end (issue 18): the real `flexid daemon` with an
//! `ethercat` bus emulated in its process (CiA 402 servos behind emulated ESCs in front of
//! plants/e2e_3mass.toml; no interface, no root), a sweep at 4 kHz through the HTTP API:
//! the axis listing carries the bus kind and the cycle rate, the event stream a Bode update
//! per period, and the results files are those of a CAN sweep (recording with its sidecar,
//! result.json, bode.svg) with every inertia and stiffness within 3 % of the plant file.
//! A sweep on an interface that cannot be opened fails with the interface and the
//! capability it needs named, before anything moves.

mod daemon_common;
mod e2e;

use daemon_common::process::DaemonProc;
use daemon_common::{get_json, read_events_at, start_sweep_at, token_file};
use e2e::*;
use std::path::Path;

/// A configuration with one emulated EtherCAT line of `plant_path()` and axis `e1` at 4 kHz
/// on its SubDevice 1, lock-step; `extra` appended.
fn ethercat_config(dir: &Path, token: &Path, extra: &str) -> std::path::PathBuf {
    let text = format!(
        "data_dir = \"{data}\"\n[api]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{token}\"\n\
         [backend]\nkind = \"drives\"\n\
         [[bus]]\nname = \"ecat0\"\nkind = \"ethercat\"\nemulated = true\nplant = \"{plant}\"\n\
         [[axis]]\nname = \"e1\"\nbus = \"ecat0\"\nnode = 1\ncycle_hz = 4000\n\
         clock = \"simulated\"\nlimits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 300.0, \
         position_window_rad = 1000.0, max_sweep_s = 120 }}\n{extra}",
        data = dir.join("data").display(),
        token = token.display(),
        plant = plant_path().display(),
    );
    let p = dir.join("flexid.toml");
    std::fs::write(&p, text).unwrap();
    p
}

#[tokio::test]
async fn an_ethercat_sweep_through_the_api_identifies_the_plant_within_3_percent() {
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = ethercat_config(tmp.path(), &token, "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let base = d.base.clone();
    let axes = get_json(&format!("{base}/api/v1/axes")).await;
    let e1 = &axes["axes"][0];
    assert_eq!(e1["bus_kind"], "ethercat", "{axes}");
    assert_eq!(e1["cycle_hz"], 4000.0, "{axes}");
    // 0.5 Hz lines (8000 samples per period), 1 transient + 4 periods, 1-500 Hz.
    let body = r#"{"excitation":"multisine","band_hz":[1,500],"amplitude_nm":0.5,"periods":4,"duration_s":10}"#;
    let id = start_sweep_at(&base, "e1", body).await;
    let evs = read_events_at(&base, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "completed", "{:?}", ended.data);
    let samples = ended.data["samples"].as_u64().unwrap();
    let bode = evs.iter().filter(|e| e.event == "bode").count();
    eprintln!("{samples} samples, {bode} Bode updates");
    assert!(bode >= 3, "a Bode update per measured period");
    let dir = tmp.path().join("data/e1").join(&id);
    assert_eq!(rows(&dir) as u64, samples);
    let sc = sidecar(&dir);
    assert_eq!(sc["end"]["complete"], true, "{sc}");
    assert_eq!(sc["sample_rate_hz"], 4000.0, "{sc}");
    let source = sc["source"].as_str().unwrap_or_default();
    assert!(source.contains("emulated EtherCAT line"), "{sc}");
    assert!(source.contains("profile flexid-vdrive"), "{sc}");
    assert!(dir.join("bode.svg").is_file());
    assert_identified(&dir, &plant_path(), 0.03);
}

#[tokio::test]
async fn an_interface_that_cannot_be_opened_fails_the_sweep_naming_it_and_cap_net_raw() {
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = ethercat_config(tmp.path(), &token, "");
    let text = std::fs::read_to_string(&cfg).unwrap().replace(
        &format!("emulated = true\nplant = \"{}\"\n", plant_path().display()),
        "interface = \"flexid-none0\"\n",
    );
    std::fs::write(&cfg, text).unwrap();
    let d = DaemonProc::start(FLEXID, &cfg);
    let body = r#"{"excitation":"multisine","band_hz":[1,500],"amplitude_nm":0.5,"periods":4,"duration_s":10}"#;
    let id = start_sweep_at(&d.base, "e1", body).await;
    let evs = read_events_at(&d.base, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "failed", "{:?}", ended.data);
    let reason = ended.data["reason"].as_str().unwrap_or_default();
    eprintln!("{reason}");
    assert!(
        reason.contains("EtherCAT interface flexid-none0"),
        "{reason}"
    );
    assert!(reason.contains("CAP_NET_RAW"), "{reason}");
}

/// The same EtherCAT axis from the web page in headless chromium (`tests/browser/ethercat.mjs`):
/// its line names EtherCAT, the SubDevice and the 4 kHz cycle; a multisine sweep started
/// from the page ends with the model drawn over the measurement and a parameter table whose
/// inertias and stiffnesses are the plant file's within 3 %.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn an_ethercat_sweep_from_the_web_page_shows_the_identified_plant() {
    use daemon_common::browser::{browser_available, result_value, run_script};
    if !browser_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = ethercat_config(tmp.path(), &token, "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let run = run_script(
        "ethercat.mjs",
        &d.base,
        "ethercat-sweep.png",
        &[("FLEXID_AXIS", "e1")],
    )
    .await;
    let (j, c) = plant_truth(&plant_path());
    for (prefix, truth) in [("J", &j), ("c", &c)] {
        for (k, want) in truth.iter().enumerate() {
            let name = format!("{prefix}{}", k + 1);
            let got = result_value(&run.stdout, &name);
            assert!(
                (got / want - 1.0).abs() < 0.03,
                "{name}: the page shows {got}, the plant has {want}"
            );
        }
    }
}
