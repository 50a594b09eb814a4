//! The daemon's web page: served without a token and leaking nothing; and driven in a real
//! headless browser (Debian's chromium through playwright-core, `tests/browser/bode.mjs`)
//! against the real daemon with the simulated backend: login, a live sweep whose Bode plot
//! grows, abort, a sweep to its end with the parameter table. The screenshot of the live
//! page is kept under `target/browser/`.

mod daemon_common;

use daemon_common::browser::{browser_available, result_value, run_script};
use daemon_common::*;

#[tokio::test]
async fn the_page_is_served_without_a_token_and_holds_no_secret() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    for (path, mime) in [
        ("/", "text/html"),
        ("/index.html", "text/html"),
        ("/app.js", "text/javascript"),
        ("/bode.js", "text/javascript"),
        ("/style.css", "text/css"),
    ] {
        let r = client().get(d.url(path)).send().await.unwrap();
        assert_eq!(r.status(), 200, "{path}");
        let h = r.headers().clone();
        assert!(
            h["content-type"].to_str().unwrap().starts_with(mime),
            "{path}"
        );
        let csp = h["content-security-policy"].to_str().unwrap();
        assert!(
            csp.contains("default-src 'none'") && csp.contains("connect-src 'self'"),
            "{csp}"
        );
        assert_eq!(h["x-content-type-options"], "nosniff");
        assert!(
            h.get("access-control-allow-origin").is_none(),
            "no CORS on {path}"
        );
        let text = r.text().await.unwrap();
        // nothing of the token, the configuration or the axes is in the static files
        for secret in [TOKEN, "fast", "slow", "vbus", "239.74.163.2"] {
            assert!(!text.contains(secret), "{path} contains {secret:?}");
        }
        // and no resource from elsewhere (the machine has no internet at run time)
        let text = text.replace("'http://www.w3.org/2000/svg'", "SVG_NS");
        assert!(
            !text.contains("http://") && !text.contains("https://"),
            "{path} refers to another origin"
        );
    }
    // the API keeps its rules: no token, no data; other paths are not static files
    let r = client().get(d.url("/api/v1/axes")).send().await.unwrap();
    assert_eq!(r.status(), 401);
    for path in [
        "/app.js/../api/v1/axes",
        "/secret",
        "/data/token",
        "/index.htm",
    ] {
        let r = client().get(d.url(path)).send().await.unwrap();
        assert!(
            r.status() == 401 || r.status() == 404,
            "{path}: {}",
            r.status()
        );
        let text = r.text().await.unwrap();
        assert!(
            !text.contains("fast") && !text.contains(TOKEN),
            "{path}: {text}"
        );
    }
    // the page's API calls carry the bearer token; the event stream is read with fetch
    let app = client()
        .get(d.url("/app.js"))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    assert!(app.contains("Authorization: 'Bearer ' + state.token"));
    assert!(app.contains("sessionStorage"));
    assert!(!app.contains("new EventSource"));
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn browser_watches_the_bode_plot_grow_aborts_and_reads_the_parameters() {
    if !browser_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let run = run_script(
        "bode.mjs",
        &d.url(""),
        "bode-live.png",
        &[("FLEXID_LIVE_AXIS", "slow"), ("FLEXID_DONE_AXIS", "fast")],
    )
    .await;
    let stdout = run.stdout;
    // the table the browser read holds the simulated chain (2e-3, 4e-3 kg m^2, 200 N m/rad)
    let (j1, j2, c1) = (
        result_value(&stdout, "J1"),
        result_value(&stdout, "J2"),
        result_value(&stdout, "c1"),
    );
    let ch = chain();
    for (got, want, name) in [
        (j1, ch.inertia_kgm2[0], "J1"),
        (j2, ch.inertia_kgm2[1], "J2"),
        (c1, ch.stiffness_nm_per_rad[0], "c1"),
    ] {
        assert!(
            (got - want).abs() < 0.1 * want,
            "{name}: page shows {got}, plant has {want}"
        );
    }
    // the aborted sweep is on disk with the operator's reason
    let r = auth(client().get(d.url("/api/v1/axes")))
        .send()
        .await
        .unwrap();
    let axes: serde_json::Value = r.json().await.unwrap();
    let slow_last = axes["axes"][1]["last_sweep_id"]
        .as_str()
        .unwrap()
        .to_string();
    let st: serde_json::Value = get_json(&d.url(&format!("/api/v1/sweeps/{slow_last}"))).await;
    assert_eq!(st["state"], "aborted");
    assert_eq!(st["reason"], "operator abort");
    d.stop().await;
}

/// Issue 17: the robot section in the browser: two multi-axis sweeps through the daemon
/// (the reference arm simulated by flexid-vdrive's drives), the 6 x 6 Bode matrix drawn
/// with a measured trace in every element, the identification's table and the model over
/// every element; the stiffnesses the page shows are the simulated robot's within 5 %.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn browser_shows_the_robots_bode_matrix_and_its_identified_model() {
    if !browser_available() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(
        tmp.path(),
        "[robot]\nname = \"arm\"\nperiods = 2\ntransient_periods = 1\n",
    )
    .await;
    let run = run_script("robot.mjs", &d.url(""), "robot-bode-matrix.png", &[]).await;
    let stdout = run.stdout;
    let svc = d.service();
    let robot = svc.robot.as_ref().unwrap();
    for (j, name) in robot.robot.parameter_names().iter().take(12).enumerate() {
        let shown = result_value(&stdout, name);
        let truth = robot.simulated_springs().stiffness_nm_per_rad[j];
        assert!(
            (shown / truth - 1.0).abs() < 0.05,
            "{name}: the page shows {shown}, the simulated robot has {truth}"
        );
    }
    d.stop().await;
}
