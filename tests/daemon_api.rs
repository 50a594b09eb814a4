//! `flexid daemon`: the HTTP API against the real server on port 0 with the simulated
//! backend (shutdown injected).

mod daemon_common;

use daemon_common::*;
use std::time::Duration;

#[tokio::test]
async fn list_axes() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let r = auth(client().get(d.url("/api/v1/axes")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let v: serde_json::Value = r.json().await.unwrap();
    let axes = v["axes"].as_array().unwrap();
    assert_eq!(axes.len(), 2);
    assert_eq!(axes[0]["name"], "fast");
    assert_eq!(axes[0]["bus"], "vbus");
    assert_eq!(axes[0]["node"], 1);
    assert_eq!(axes[0]["state"], "idle");
    assert!(axes[0]["last_result_id"].is_null());
    d.stop().await;
}

#[tokio::test]
async fn sweep_streams_bode_every_period_and_the_result() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let id = start_sweep(&d, "fast", &body("multisine", 4, 5.0)).await;
    let evs = read_events(&d, &id, |_| false).await;
    let names: Vec<&str> = evs.iter().map(|e| e.event.as_str()).collect();
    assert_eq!(names.last(), Some(&"ended"), "{names:?}");
    // the history keeps only the latest bode estimate for late subscribers; a subscriber from
    // the start sees each: at least the final one, and every one it sees grows
    let bodes: Vec<_> = evs.iter().filter(|e| e.event == "bode").collect();
    assert!(!bodes.is_empty());
    let progress: Vec<_> = evs.iter().filter(|e| e.event == "progress").collect();
    assert_eq!(
        progress.len(),
        5,
        "one progress event per period (1 transient + 4)"
    );
    let ended = evs.iter().find(|e| e.event == "ended").unwrap();
    assert_eq!(ended.data["outcome"], "completed");
    let result = evs.iter().find(|e| e.event == "result").unwrap();
    let model = &result.data["model"];
    assert_eq!(model["masses"], 2, "{}", result.data);
    let j = model["inertia_kgm2"].as_array().unwrap();
    assert!((j[0].as_f64().unwrap() - 2e-3).abs() < 2e-4, "{j:?}");
    assert!((j[1].as_f64().unwrap() - 4e-3).abs() < 4e-4, "{j:?}");

    // status + result JSON as `flexid identify --json` writes it
    let st: serde_json::Value = get_json(&d.url(&format!("/api/v1/sweeps/{id}"))).await;
    assert_eq!(st["state"], "completed");
    assert_eq!(st["result"]["model"]["masses"], 2);
    assert!(st["result"]["frf"].is_object() || st["result"]["frf"].is_array());

    // the axis lists the result
    let axes: serde_json::Value = get_json(&d.url("/api/v1/axes")).await;
    assert_eq!(axes["axes"][0]["last_result_id"], id.as_str());
    assert_eq!(axes["axes"][0]["state"], "idle");

    // downloads
    for (file, starts) in [
        ("recording.csv", "time_s,torque_cmd_nm,position_rad"),
        ("frf.csv", "freq_hz,magnitude_db,phase_deg,coherence,std"),
        ("bode.svg", "<svg"),
        ("recording.json", "{"),
    ] {
        let r = auth(client().get(d.url(&format!("/api/v1/sweeps/{id}/{file}"))))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 200, "{file}");
        let text = r.text().await.unwrap();
        assert!(
            text.trim_start().starts_with(starts),
            "{file}: {}",
            &text[..80.min(text.len())]
        );
    }

    // the files on disk are complete
    let dir = tmp.path().join("data/fast").join(&id);
    let rec = flexid::recording::read_recording(dir.join("recording.csv")).unwrap();
    assert_eq!(rec.len(), 5000);
    assert_eq!(rec.sample_rate_hz, 1000.0);
    assert_eq!(rec.sidecar.excitation.as_ref().unwrap().periods, 4);
    for f in [
        "status.json",
        "result.json",
        "request.json",
        "recording.json",
    ] {
        let text = std::fs::read_to_string(dir.join(f)).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap_or_else(|e| panic!("{f}: {e}"));
    }
    let frf = std::fs::read_to_string(dir.join("frf.csv")).unwrap();
    assert!(frf.lines().skip(1).all(|l| l.split(',').count() == 5));
    assert!(frf.lines().count() > 100);
    assert!(!dir.join("running").exists());
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .filter(|e| e.file_name().to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty());
    d.stop().await;
}

#[tokio::test]
async fn bode_arrives_once_per_period_and_grows() {
    // real-time axis: subscribe before the first period ends and see every estimate
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let id = start_sweep(&d, "slow", &body("multisine", 4, 2.5)).await;
    let evs = read_events(&d, &id, |_| false).await;
    let bodes: Vec<_> = evs.iter().filter(|e| e.event == "bode").collect();
    let periods: Vec<u64> = bodes
        .iter()
        .map(|b| b.data["period"].as_u64().unwrap())
        .collect();
    assert_eq!(
        periods,
        vec![2, 3, 4, 5],
        "one bode per steady period: {periods:?}"
    );
    for b in &bodes {
        let n = b.data["freq_hz"].as_array().unwrap().len();
        assert!(n > 50);
        for k in ["magnitude_db", "phase_deg", "relative_std"] {
            assert_eq!(b.data[k].as_array().unwrap().len(), n, "{k}");
        }
    }
    // more periods: coherence appears from the second steady period on, and the mean
    // relative uncertainty shrinks as periods are averaged
    assert!(bodes[0].data["coherence"].is_null());
    assert!(bodes[1].data["coherence"].is_array());
    assert_eq!(evs.last().unwrap().data["outcome"], "completed");
    assert!(evs.iter().any(|e| e.event == "result"));
    d.stop().await;
}

#[tokio::test]
async fn two_axes_at_once_and_busy_axis() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let slow = start_sweep(&d, "slow", &body("chirp", 3, 3.0)).await;
    let fast = start_sweep(&d, "fast", &body("multisine", 3, 4.0)).await;
    // the slow axis is busy: 409, and the backend is not called again
    let calls = d.backend.calls();
    let r = auth(client().post(d.url("/api/v1/axes/slow/sweeps")))
        .body(body("multisine", 3, 3.0))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    let v: serde_json::Value = r.json().await.unwrap();
    assert!(v["error"].as_str().unwrap().contains("busy"));
    assert_eq!(d.backend.calls(), calls);
    let axes: serde_json::Value = get_json(&d.url("/api/v1/axes")).await;
    assert_eq!(axes["axes"][1]["state"], "sweeping");
    assert_eq!(axes["axes"][1]["sweep_id"], slow.as_str());
    let (a, b) = tokio::join!(
        read_events(&d, &slow, |_| false),
        read_events(&d, &fast, |_| false)
    );
    assert_eq!(a.last().unwrap().data["outcome"], "completed");
    assert_eq!(b.last().unwrap().data["outcome"], "completed");
    d.stop().await;
}

#[tokio::test]
async fn abort_mid_sweep_keeps_the_partial_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let id = start_sweep(&d, "slow", &body("multisine", 9, 20.0)).await;
    // wait for the first Bode estimate (period 2 of 10), then abort
    let first = read_events(&d, &id, |e| e.event == "bode").await;
    assert_eq!(first.last().unwrap().event, "bode");
    let r = auth(client().post(d.url(&format!("/api/v1/sweeps/{id}/abort"))))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    let evs = read_events(&d, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended");
    assert_eq!(ended.data["outcome"], "aborted");
    assert_eq!(ended.data["reason"], "operator abort");
    let st: serde_json::Value = get_json(&d.url(&format!("/api/v1/sweeps/{id}"))).await;
    assert_eq!(st["state"], "aborted");
    // the partial recording is downloadable and parses; the torque was ramped to zero
    // after its last row (the one sweep loop's ramp, 1 % of the cycle rate and at least 5
    // cycles, run in full; as on a CANopen drive, tests/daemon_kill.rs)
    let rec = get_recording(&d.url(""), &id).await;
    assert!(rec.len() >= 4000 && rec.len() < 20_000, "{}", rec.len());
    let end = rec.sidecar.end.as_ref().expect("end");
    let cycles = rec.sidecar.cycle_counters.expect("counters").cycles;
    assert!(!end.complete);
    assert!(
        rec.len() as u64 >= end.cycle,
        "{} rows, end {}",
        rec.len(),
        end.cycle
    );
    assert_eq!(
        cycles,
        rec.len() as u64 + 10,
        "ramp of 10 cycles at 1 kHz after the last row"
    );
    assert_eq!(rec.sidecar.ended_because.as_deref(), Some("operator abort"));
    // aborting again: 409 (not running)
    let r = auth(client().post(d.url(&format!("/api/v1/sweeps/{id}/abort"))))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 409);
    d.stop().await;
}

#[tokio::test]
async fn refused_requests_never_reach_the_backend() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let url = d.url("/api/v1/axes/fast/sweeps");
    let good = body("multisine", 4, 5.0);

    // no token, wrong token
    let r = client().post(&url).body(good.clone()).send().await.unwrap();
    assert_eq!(r.status(), 401);
    let r = client()
        .get(d.url("/api/v1/axes"))
        .header("Authorization", "Bearer wrong-token-0123456789")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);
    let v: serde_json::Value = r.json().await.unwrap();
    assert!(v["error"].is_string());
    let r = client()
        .get(d.url("/api/v1/axes"))
        .header("Authorization", format!("Basic {TOKEN}"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 401);

    // a 10 MB body
    let big = format!(
        r#"{{"excitation":"multisine","pad":"{}"}}"#,
        "x".repeat(10 * 1024 * 1024)
    );
    let r = auth(client().post(&url)).body(big).send().await;
    match r {
        Ok(r) => {
            assert_eq!(r.status(), 413);
            let v: serde_json::Value = r.json().await.unwrap();
            assert!(v["error"].as_str().unwrap().contains("larger"));
        }
        // the server may close the connection before the client finished sending
        Err(e) => assert!(e.is_request() || e.is_body(), "{e}"),
    }

    // field errors: (body, status, field)
    let cases = [
        (
            good.replace("\"amplitude_nm\":0.5", "\"amplitude_nm\":\"lots\""),
            422,
            Some("amplitude_nm"),
        ),
        (good.replace("[2,200]", "[2,600]"), 422, Some("band_hz")),
        (
            good.replace("\"amplitude_nm\":0.5", "\"amplitude_nm\":1.5"),
            422,
            Some("amplitude_nm"),
        ),
        (
            good.replace("\"periods\":4", "\"periods\":2.5"),
            422,
            Some("periods"),
        ),
        (
            good.replace("\"duration_s\":5", "\"duration_s\":600"),
            422,
            Some("duration_s"),
        ),
        (good.replace("multisine", "noise"), 422, Some("excitation")),
        ("{\"excitation\": ".to_string(), 400, None),
        ("[1,2]".to_string(), 400, None),
    ];
    for (b, status, field) in cases {
        let r = auth(client().post(&url))
            .body(b.clone())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), status, "{b}");
        let v: serde_json::Value = r.json().await.unwrap();
        assert_eq!(v["field"].as_str(), field, "{b}: {v}");
        assert!(v["error"].is_string());
    }
    // unknown axis, unknown sweep
    let r = auth(client().post(d.url("/api/v1/axes/nope/sweeps")))
        .body(good.clone())
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 404);
    for path in [
        "/api/v1/sweeps/nope",
        "/api/v1/sweeps/nope/events",
        "/api/v1/sweeps/..%2Fetc/bode.svg",
    ] {
        let r = auth(client().get(d.url(path))).send().await.unwrap();
        assert_eq!(r.status(), 404, "{path}");
    }
    assert_eq!(
        d.backend.calls(),
        0,
        "a refused request reached the backend"
    );
    d.stop().await;
}

#[tokio::test]
async fn token_file_readable_by_others_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o644);
    let cfg =
        flexid::daemon::Config::parse(&config_text(tmp.path(), &token, ""), "t.toml").unwrap();
    let backend = Counting::new();
    let e = match flexid::daemon::start(cfg, backend.clone(), async {}).await {
        Ok(_) => panic!("started with a 0644 token file"),
        Err(e) => e,
    };
    let msg = e.to_string();
    assert!(
        msg.contains(&token.display().to_string()) && msg.contains("0644"),
        "{msg}"
    );
    assert_eq!(e.exit_code(), 2);
    assert_eq!(backend.calls(), 0);
}

#[tokio::test]
async fn stored_sweep_after_restart_and_shutdown_aborts() {
    // a sweep running at shutdown is aborted (ramped down, saved); after a restart its
    // status, files and events come from disk
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let id = start_sweep(&d, "slow", &body("multisine", 9, 30.0)).await;
    tokio::time::sleep(Duration::from_millis(300)).await;
    d.stop().await;
    let d = TestDaemon::start(tmp.path(), "").await;
    let st: serde_json::Value = get_json(&d.url(&format!("/api/v1/sweeps/{id}"))).await;
    assert_eq!(st["state"], "aborted", "{st}");
    assert_eq!(st["reason"], "daemon shutdown");
    let evs = read_events(&d, &id, |_| false).await;
    assert_eq!(evs.last().unwrap().data["outcome"], "aborted");
    let axes: serde_json::Value = get_json(&d.url("/api/v1/axes")).await;
    assert_eq!(axes["axes"][1]["last_sweep_id"], id.as_str());
    d.stop().await;
}
