//! The daemon's two-level sweep end to end: `levels_nm` in the request runs the same
//! excitation at the low then the high peak torque, then the gap diagnosis on the pair.
//!
//! * CANopen backend: the real `flexid-vdrive` (lock-step clock) in front of
//!   plants/e2e_backlash.toml, and separately plants/e2e_friction.toml, on the UDP
//!   multicast bus, and the real `flexid daemon` with `backend.kind = "canopen"`; the
//!   verdict must name the plant's effect. Skipped when 239.0.0.0/8 cannot be kept on `lo`
//!   (fails under CI=true).
//! * Simulated backend (in-process, a plant file with backlash simulated by `PlantSim`):
//!   the same sweep, the same verdict, and the request errors of two-level sweeps.

mod daemon_common;
mod e2e;

use daemon_common::process::{canopen_config, CanAxis, DaemonProc, GROUP};
use daemon_common::{auth, client, get_json, get_text, read_events_at, token_file, Sse};
use e2e::*;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The two-level request of these tests: 1-400 Hz at 1 kHz, 0.5 Hz lines, 1 + 4 periods of
/// 2 s per level, 0.1 and 0.5 N m peak (the plant files explain their effect's size
/// against these levels).
const REQUEST: &str = r#"{"excitation":"multisine","band_hz":[1,400],"levels_nm":[0.1,0.5],"periods":4,"duration_s":10,"masses":3}"#;

fn plant(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("plants")
        .join(name)
}

/// Run the two-level sweep on the daemon at `base`, check what it stored and reported,
/// and return the diagnosis.
async fn two_level_sweep(base: &str, axis: &str) -> Value {
    let t0 = Instant::now();
    let r = auth(client().post(format!("{base}/api/v1/axes/{axis}/sweeps")))
        .body(REQUEST)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202, "{}", r.text().await.unwrap());
    let v: Value = r.json().await.unwrap();
    let id = v["sweep_id"].as_str().unwrap().to_string();
    let evs: Vec<Sse> = read_events_at(base, &id, |_| false).await;
    eprintln!(
        "two-level sweep and diagnosis: {:.1} s",
        t0.elapsed().as_secs_f64()
    );
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "completed", "{:?}", ended.data);
    assert_eq!(ended.data["samples"], 20_000, "two levels of 10 000 cycles");
    let levels: Vec<_> = evs.iter().filter(|e| e.event == "level").collect();
    assert_eq!(levels.len(), 2);
    assert_eq!(levels[0].data["amplitude_nm"], 0.1);
    assert_eq!(levels[1].data["amplitude_nm"], 0.5);
    assert!(
        evs.iter()
            .any(|e| e.event == "progress" && e.data["phase"] == "diagnosis"),
        "no diagnosis progress event"
    );
    let diag = &evs
        .iter()
        .find(|e| e.event == "diagnosis")
        .expect("a diagnosis event")
        .data;
    assert!(diag.get("error").is_none(), "diagnosis failed: {diag}");
    // each level's recording is stored, at its own peak torque
    for (n, peak) in [(1, 0.1), (2, 0.5)] {
        let csv = get_text(&format!(
            "{base}/api/v1/sweeps/{id}/recording.csv?level={n}"
        ))
        .await;
        let torque: Vec<f64> = csv
            .lines()
            .skip(1)
            .map(|l| l.split(',').nth(1).unwrap().parse().unwrap())
            .collect();
        assert_eq!(torque.len(), 10_000, "level {n}");
        let max = torque.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(
            (max - peak).abs() < 1e-3 * peak,
            "level {n}: peak {max} N m"
        );
    }
    // the result endpoint and the result event hold the same report
    let r = auth(client().get(format!("{base}/api/v1/sweeps/{id}/diagnosis")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let stored: Value = r.json().await.unwrap();
    assert_eq!(stored["verdict"], diag["verdict"]);
    let result = &evs.iter().find(|e| e.event == "result").unwrap().data;
    assert_eq!(result["diagnosis"]["verdict"], diag["verdict"]);
    assert_eq!(result["levels"].as_array().unwrap().len(), 2);
    let st: Value = get_json(&format!("{base}/api/v1/sweeps/{id}")).await;
    assert_eq!(st["has_diagnosis"], true, "{st}");
    assert_eq!(st["result"]["diagnosis"]["verdict"], diag["verdict"]);
    let gap = &diag["gap"];
    eprintln!(
        "verdict {} ({:?}); gap {} -> {} dB; ranking {:?}; {} s",
        diag["verdict"],
        diag["effect_params"],
        gap["before_rms_db"],
        gap["after_rms_db"],
        diag["ranking"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| format!("{}:{}", r["effect"], r["score"]))
            .collect::<Vec<_>>(),
        diag["seconds"]
    );
    let (before, after) = (
        gap["before_rms_db"].as_f64().unwrap(),
        gap["after_rms_db"].as_f64().unwrap(),
    );
    assert!(
        after < before,
        "the named effect must shrink the gap: {before} -> {after} dB"
    );
    diag.clone()
}

/// The daemon binary with the CANopen backend on the vdrive's bus.
async fn canopen_verdict(plant_file: &str, port: u16) -> Value {
    let _vd = VDrive::start(&format!("udp:{GROUP}:{port}"), &plant(plant_file));
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = canopen_config(tmp.path(), &token, &[CanAxis::new("a5", port)], "");
    let daemon = DaemonProc::start(FLEXID, &cfg);
    two_level_sweep(&daemon.base, "a5").await
}

#[tokio::test]
async fn canopen_two_level_sweep_names_backlash() {
    if !loopback_multicast() {
        return;
    }
    let d = canopen_verdict("e2e_backlash.toml", 43311).await;
    assert_eq!(d["verdict"], "backlash", "{d}");
}

#[tokio::test]
async fn canopen_two_level_sweep_names_friction() {
    if !loopback_multicast() {
        return;
    }
    let d = canopen_verdict("e2e_friction.toml", 43313).await;
    assert_eq!(d["verdict"], "coulomb_friction", "{d}");
}

#[tokio::test]
async fn sim_backend_two_level_sweep_names_backlash() {
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let text = daemon_common::config_text(tmp.path(), &token, "");
    let cfg = flexid::daemon::Config::parse(&text, "test.toml").unwrap();
    let backend =
        flexid::daemon::SimBackend::from_plant_file(Some(&plant("e2e_backlash.toml"))).unwrap();
    assert!(
        backend.plant.effects.is_some(),
        "the plant's backlash is simulated"
    );
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let running = flexid::daemon::start(cfg, std::sync::Arc::new(backend), async move {
        let _ = rx.await;
    })
    .await
    .unwrap();
    let base = format!("http://{}", running.addr);
    // two-level request errors name their field
    for (body, field) in [
        (REQUEST.replace("[0.1,0.5]", "[0.5,0.1]"), "levels_nm"),
        (REQUEST.replace("\"masses\":3", "\"masses\":9"), "masses"),
        (
            REQUEST.replace("\"levels_nm\"", "\"amplitude_nm\":0.3,\"levels_nm\""),
            "amplitude_nm",
        ),
        (
            REQUEST.replace("\"levels_nm\":[0.1,0.5],", "\"amplitude_nm\":0.3,"),
            "masses",
        ),
    ] {
        let r = auth(client().post(format!("{base}/api/v1/axes/fast/sweeps")))
            .body(body.clone())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 422, "{body}");
        let e: Value = r.json().await.unwrap();
        assert_eq!(e["field"], field, "{body}: {e}");
    }
    let d = two_level_sweep(&base, "fast").await;
    assert_eq!(d["verdict"], "backlash", "{d}");
    let _ = tx.send(());
    running.wait().await.unwrap();
}
