//! The daemon's robot (issue 17): a `[robot]` section (the reference arm, simulated by
//! `flexid-vdrive`'s drives on an in-process bus), multi-axis sweeps at its two
//! identification poses through the API, their N x N FRF matrices and Bode-matrix
//! pictures, an identification of the 24 flexibility parameters that finds the simulated
//! robot's springs (which deviate from the file's by up to 30 %), and the API's errors:
//! no robot, unknown pose, busy, abort.

mod daemon_common;

use daemon_common::*;
use std::time::{Duration, Instant};

/// Two averaged periods after one settling period per experiment: 18 s of robot time per
/// pose (lock-step, a few seconds of wall time).
pub const ROBOT: &str = "[robot]\nname = \"arm\"\nperiods = 2\ntransient_periods = 1\n";

async fn post(d: &TestDaemon, path: &str, body: &str) -> reqwest::Response {
    auth(client().post(d.url(path)))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap()
}

/// Waits until job `id` is no longer running (at most `limit`); its final view.
async fn wait_job(d: &TestDaemon, id: &str, limit: Duration) -> serde_json::Value {
    let t0 = Instant::now();
    loop {
        let j = get_json(&d.url(&format!("/api/v1/robot/jobs/{id}"))).await;
        if j["state"] != "running" {
            return j;
        }
        assert!(t0.elapsed() < limit, "job {id} still running: {j}");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

async fn sweep(d: &TestDaemon, pose: &str) -> String {
    let r = post(
        d,
        "/api/v1/robot/sweeps",
        &format!("{{\"pose\": \"{pose}\"}}"),
    )
    .await;
    assert_eq!(r.status(), 202);
    let v: serde_json::Value = r.json().await.unwrap();
    v["job_id"].as_str().unwrap().to_string()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_daemon_sweeps_the_robot_and_identifies_its_flexibilities() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), ROBOT).await;
    let info = get_json(&d.url("/api/v1/robot")).await;
    assert_eq!(info["axes"], 6);
    assert_eq!(info["nodes"], serde_json::json!([2, 3, 4, 5, 6, 7]));
    assert_eq!(info["poses"].as_array().unwrap().len(), 14);
    assert_eq!(info["parameters"].as_array().unwrap().len(), 24);

    // an unknown pose names the field; an identification with no sweep is refused
    let r = post(&d, "/api/v1/robot/sweeps", r#"{"pose": "nowhere"}"#).await;
    assert_eq!(r.status(), 422);
    let e: serde_json::Value = r.json().await.unwrap();
    assert_eq!(e["field"], "pose");
    assert!(e["error"].as_str().unwrap().contains("id-1"), "{e}");
    let r = post(&d, "/api/v1/robot/identifications", "").await;
    assert_eq!(r.status(), 422);

    // a sweep at each identification pose; a second job while one runs is refused
    let mut ids = Vec::new();
    for pose in ["id-1", "id-2"] {
        let id = sweep(&d, pose).await;
        if pose == "id-1" {
            let r = post(&d, "/api/v1/robot/sweeps", r#"{"pose": "id-2"}"#).await;
            assert_eq!(r.status(), 409);
        }
        let j = wait_job(&d, &id, Duration::from_secs(300)).await;
        eprintln!("{pose}: {j}");
        assert_eq!(j["state"], "completed", "{j}");
        assert_eq!(j["cycle"], j["cycles"]);
        assert!(
            j["message"]
                .as_str()
                .unwrap()
                .contains("0 feedback messages lost"),
            "{j}"
        );
        let m = get_json(&d.url(&format!("/api/v1/robot/jobs/{id}/frf_matrix.json"))).await;
        assert_eq!(m["pose"], pose);
        let mag = m["magnitude_db"].as_array().unwrap();
        assert_eq!(mag.len(), 6);
        assert!(mag.iter().all(|row| row.as_array().unwrap().len() == 6));
        assert_eq!(
            m["freq_hz"].as_array().unwrap().len(),
            299,
            "2-300 Hz at 1 Hz"
        );
        let svg = get_text(&d.url(&format!("/api/v1/robot/jobs/{id}/bode_matrix.svg"))).await;
        assert!(
            svg.starts_with("<svg") || svg.starts_with("<?xml"),
            "{}",
            &svg[..60]
        );
        ids.push(id);
    }

    // the identification from both sweeps (the default: the latest of each
    // identification pose) finds the simulated robot's springs, not the file's
    let r = post(&d, "/api/v1/robot/identifications", r#"{"starts": 4}"#).await;
    assert_eq!(r.status(), 202);
    let id: serde_json::Value = r.json().await.unwrap();
    let id = id["job_id"].as_str().unwrap().to_string();
    let j = wait_job(&d, &id, Duration::from_secs(600)).await;
    eprintln!("identification: {j}");
    assert_eq!(j["state"], "completed", "{j}");
    assert_eq!(j["sweeps"], serde_json::json!(ids));
    let result = get_json(&d.url(&format!("/api/v1/robot/jobs/{id}/identification.json"))).await;
    let svc = d.service();
    let robot = svc.robot.as_ref().unwrap();
    let truth = robot.simulated_springs();
    let nominal = &robot.robot.nominal;
    let params = result["parameters"].as_array().unwrap();
    for (j, p) in params.iter().take(12).enumerate() {
        let (k, t, n) = (
            p["value"].as_f64().unwrap(),
            truth.stiffness_nm_per_rad[j],
            nominal.stiffness_nm_per_rad[j],
        );
        eprintln!(
            "{}: {k:.4e} (simulated {t:.4e}, file {n:.4e}): {:+.3} %",
            p["name"],
            100.0 * (k / t - 1.0)
        );
        assert!((k / t - 1.0).abs() < 0.05, "{p}");
        assert_eq!(p["identifiable"], true, "{p}");
    }
    // the file's values are not the answer: the simulated robot deviates from them
    assert!(truth
        .stiffness_nm_per_rad
        .iter()
        .zip(&nominal.stiffness_nm_per_rad)
        .any(|(t, n)| (t / n - 1.0).abs() > 0.1));
    let models = result["models"].as_array().unwrap();
    assert_eq!(models.len(), 2);
    assert_eq!(models[0]["magnitude_db"].as_array().unwrap().len(), 6);

    // abort: a sweep stops, its torques ramp down, the job says aborted
    let id = sweep(&d, "val-1").await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    let r = post(&d, &format!("/api/v1/robot/jobs/{id}/abort"), "").await;
    assert_eq!(r.status(), 202);
    let j = wait_job(&d, &id, Duration::from_secs(60)).await;
    assert_eq!(j["state"], "aborted", "{j}");
    assert!(
        j["message"].as_str().unwrap().contains("interrupted"),
        "{j}"
    );
    let r = auth(client().get(d.url(&format!("/api/v1/robot/jobs/{id}/frf_matrix.json"))))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    d.stop().await;
}

#[tokio::test]
async fn without_a_robot_the_routes_say_so() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let r = auth(client().get(d.url("/api/v1/robot")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    let e: serde_json::Value = r.json().await.unwrap();
    assert!(e["error"].as_str().unwrap().contains("[robot]"), "{e}");
    // and the token is still needed
    let r = client().get(d.url("/api/v1/robot")).send().await.unwrap();
    assert_eq!(r.status(), 401);
    d.stop().await;
}
