//! The daemon's web page: served without a token and leaking nothing; and driven in a real
//! headless browser (Debian's chromium through playwright-core, `tests/browser/bode.mjs`)
//! against the real daemon with the simulated backend: login, a live sweep whose Bode plot
//! grows, abort, a sweep to its end with the parameter table. The screenshot of the live
//! page is kept under `target/browser/`.

mod daemon_common;

use daemon_common::*;
use std::path::{Path, PathBuf};
use std::process::Command;

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

fn browser_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/browser")
}

/// Why the browser test cannot run here, if it cannot.
fn missing_tools() -> Option<String> {
    let chromium = std::env::var("CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return Some(format!(
            "{chromium} is absent (apt-get install -y chromium)"
        ));
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Some("node is absent (apt-get install -y nodejs npm)".into());
    }
    if !browser_dir()
        .join("node_modules/playwright-core/package.json")
        .exists()
    {
        return Some("tests/browser/node_modules is absent (npm ci in tests/browser)".into());
    }
    None
}

/// A `NAME=value` number from the script's `browser: result ...` line.
fn result_value(out: &str, name: &str) -> f64 {
    let line = out
        .lines()
        .find(|l| l.starts_with("browser: result "))
        .unwrap_or_else(|| panic!("no result line in:\n{out}"));
    line.split_whitespace()
        .find_map(|w| w.strip_prefix(&format!("{name}=")))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {name} in {line}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn browser_watches_the_bode_plot_grow_aborts_and_reads_the_parameters() {
    if let Some(why) = missing_tools() {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!("browser test needs: {why}");
        }
        eprintln!("skipped: browser test: {why}");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let shots = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/browser");
    std::fs::create_dir_all(&shots).unwrap();
    let shot = shots.join("bode-live.png");
    let _ = std::fs::remove_file(&shot);
    let mut cmd = Command::new("node");
    cmd.arg("bode.mjs")
        .current_dir(browser_dir())
        .env("FLEXID_URL", d.url(""))
        .env("FLEXID_TOKEN", TOKEN)
        .env("FLEXID_SCREENSHOT", &shot)
        .env("FLEXID_LIVE_AXIS", "slow")
        .env("FLEXID_DONE_AXIS", "fast");
    let out = tokio::task::spawn_blocking(move || cmd.output())
        .await
        .unwrap()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(out.status.success(), "the browser script failed:\n{stderr}");
    assert!(stdout.contains("browser: ok"), "{stdout}");
    // the screenshot of the live Bode page is there and is a PNG
    let png = std::fs::read(&shot).expect("screenshot written");
    assert!(
        png.starts_with(b"\x89PNG") && png.len() > 10_000,
        "{}",
        png.len()
    );
    println!("screenshot of the live Bode page: {}", shot.display());
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
    if let Some(why) = missing_tools() {
        if std::env::var("CI").as_deref() == Ok("true") {
            panic!("browser test needs: {why}");
        }
        eprintln!("skipped: browser test: {why}");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(
        tmp.path(),
        "[robot]\nname = \"arm\"\nperiods = 2\ntransient_periods = 1\n",
    )
    .await;
    let shots = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/browser");
    std::fs::create_dir_all(&shots).unwrap();
    let shot = shots.join("robot-bode-matrix.png");
    let _ = std::fs::remove_file(&shot);
    let mut cmd = Command::new("node");
    cmd.arg("robot.mjs")
        .current_dir(browser_dir())
        .env("FLEXID_URL", d.url(""))
        .env("FLEXID_TOKEN", TOKEN)
        .env("FLEXID_SCREENSHOT", &shot);
    let out = tokio::task::spawn_blocking(move || cmd.output())
        .await
        .unwrap()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&out.stdout).to_string();
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!("{stdout}");
    eprintln!("{stderr}");
    assert!(out.status.success(), "the browser script failed:\n{stderr}");
    assert!(stdout.contains("browser: ok"), "{stdout}");
    let png = std::fs::read(&shot).expect("screenshot written");
    assert!(png.starts_with(b"\x89PNG") && png.len() > 10_000);
    println!("screenshot of the Bode matrix: {}", shot.display());
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
