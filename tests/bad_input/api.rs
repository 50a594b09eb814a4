//! Bad API requests against an in-process daemon: the documented status, a JSON body
//! `{"error", "field"}` naming what is wrong, nothing reaches the backend, nothing is
//! written under `data_dir`. And a client that never finishes its request header is
//! disconnected after the header-read timeout.

use super::daemon_common::{auth, body, client, TestDaemon, TOKEN};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

pub const KINDS: usize = 26;

/// (what, method, path, body, status, field or a word of the error)
type ApiCase = (
    &'static str,
    &'static str,
    String,
    Option<String>,
    u16,
    &'static str,
);

pub fn cases() -> Vec<ApiCase> {
    let good = body("multisine", 4, 5.0);
    let sweeps = "/api/v1/axes/fast/sweeps".to_string();
    let post =
        |what, b: String, status, says| (what, "POST", sweeps.clone(), Some(b), status, says);
    vec![
        post(
            "a body that is no JSON",
            "{\"excitation\": ".into(),
            400,
            "JSON",
        ),
        post("a JSON array", "[1,2]".into(), 400, "object"),
        post("an empty body", String::new(), 400, "JSON"),
        post(
            "an unknown field",
            good.replace("\"periods\"", "\"pad\":1,\"periods\""),
            422,
            "pad",
        ),
        post(
            "no excitation",
            good.replace("\"excitation\":\"multisine\",", ""),
            422,
            "excitation",
        ),
        post(
            "an unknown excitation",
            good.replace("multisine", "noise"),
            422,
            "excitation",
        ),
        post(
            "a band above Nyquist",
            good.replace("[2,200]", "[2,600]"),
            422,
            "band_hz",
        ),
        post(
            "a reversed band",
            good.replace("[2,200]", "[200,2]"),
            422,
            "band_hz",
        ),
        post(
            "a band of three numbers",
            good.replace("[2,200]", "[2,20,200]"),
            422,
            "band_hz",
        ),
        post(
            "a negative band",
            good.replace("[2,200]", "[-2,200]"),
            422,
            "band_hz",
        ),
        post(
            "an amplitude above the axis's limit",
            good.replace("\"amplitude_nm\":0.5", "\"amplitude_nm\":1.5"),
            422,
            "amplitude_nm",
        ),
        post(
            "an amplitude that is a word",
            good.replace("\"amplitude_nm\":0.5", "\"amplitude_nm\":\"lots\""),
            422,
            "amplitude_nm",
        ),
        post(
            "a fractional period count",
            good.replace("\"periods\":4", "\"periods\":2.5"),
            422,
            "periods",
        ),
        post(
            "zero periods",
            good.replace("\"periods\":4", "\"periods\":0"),
            422,
            "periods",
        ),
        post(
            "a period count of 1e30",
            good.replace("\"periods\":4", "\"periods\":1e30"),
            422,
            "periods",
        ),
        post(
            "a duration beyond max_sweep_s",
            good.replace("\"duration_s\":5", "\"duration_s\":600"),
            422,
            "duration_s",
        ),
        post(
            "a negative duration",
            good.replace("\"duration_s\":5", "\"duration_s\":-5"),
            422,
            "duration_s",
        ),
        post(
            "levels in the wrong order",
            good.replace("\"periods\"", "\"levels_nm\":[0.5,0.2],\"periods\""),
            422,
            "levels_nm",
        ),
        post(
            "masses 0",
            good.replace(
                "\"periods\"",
                "\"levels_nm\":[0.2,0.5],\"masses\":0,\"periods\"",
            ),
            422,
            "masses",
        ),
        (
            "an unknown axis",
            "POST",
            "/api/v1/axes/nope/sweeps".into(),
            Some(good.clone()),
            404,
            "nope",
        ),
        (
            "an unknown sweep",
            "GET",
            "/api/v1/sweeps/nope".into(),
            None,
            404,
            "nope",
        ),
        (
            "a path escaping the store",
            "GET",
            "/api/v1/sweeps/..%2F..%2Fetc/bode.svg".into(),
            None,
            404,
            "sweep",
        ),
        (
            "a level that is a word",
            "GET",
            "/api/v1/sweeps/20260101T000000Z-abcdef/bode.svg?level=abc".into(),
            None,
            400,
            "level",
        ),
        (
            "a level of 3",
            "GET",
            "/api/v1/sweeps/20260101T000000Z-abcdef/bode.svg?level=3".into(),
            None,
            404,
            "sweep",
        ),
        (
            "a wrong method",
            "DELETE",
            "/api/v1/axes".into(),
            None,
            405,
            "Method Not Allowed",
        ),
        (
            "an unknown route",
            "GET",
            "/api/v2/everything".into(),
            None,
            404,
            "no such route",
        ),
    ]
}

#[tokio::test]
async fn bad_requests_get_json_errors_and_never_reach_the_backend() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let data = tmp.path().join("data");
    let before = files_under(&data);
    let cases = cases();
    assert_eq!(cases.len(), KINDS);
    let mut failed = Vec::new();
    for (what, method, path, b, status, says) in cases {
        let mut rb = client().request(method.parse().unwrap(), d.url(&path));
        if let Some(b) = b {
            rb = rb.header("content-type", "application/json").body(b);
        }
        let r = auth(rb).send().await.unwrap();
        let got = r.status().as_u16();
        let ctype = r
            .headers()
            .get("content-type")
            .map(|v| v.to_str().unwrap_or("").to_string())
            .unwrap_or_default();
        let text = r.text().await.unwrap();
        let v: Option<serde_json::Value> = serde_json::from_str(&text).ok();
        let error = v.as_ref().and_then(|v| v["error"].as_str()).unwrap_or("");
        let field = v.as_ref().and_then(|v| v["field"].as_str()).unwrap_or("");
        let mut why = Vec::new();
        if got != status {
            why.push(format!("status {got}, want {status}"));
        }
        if !ctype.starts_with("application/json") || v.is_none() || error.is_empty() {
            why.push(format!("not a JSON error ({ctype}): {text:?}"));
        }
        if !(field == says || error.contains(says)) {
            why.push(format!("does not name {says:?}: {text}"));
        }
        if !why.is_empty() {
            failed.push(format!("{what} ({method} {path}): {}", why.join("; ")));
        }
    }
    // a 10 MB body: 413 in JSON (or the connection closed while sending)
    let big = format!(
        r#"{{"excitation":"multisine","pad":"{}"}}"#,
        "x".repeat(10 << 20)
    );
    if let Ok(r) = auth(client().post(d.url("/api/v1/axes/fast/sweeps")))
        .body(big)
        .send()
        .await
    {
        assert_eq!(r.status(), 413);
        let v: serde_json::Value = r.json().await.unwrap();
        assert!(v["error"].as_str().unwrap().contains("larger"));
    }
    // no token: 401 in JSON
    let r = client().get(d.url("/api/v1/axes")).send().await.unwrap();
    assert_eq!(r.status(), 401);
    let v: serde_json::Value = r.json().await.unwrap();
    assert!(v["error"].as_str().unwrap().contains("token"));
    assert!(
        failed.is_empty(),
        "{} case(s):\n{}",
        failed.len(),
        failed.join("\n")
    );
    assert_eq!(
        d.backend.calls(),
        0,
        "a refused request reached the backend"
    );
    assert_eq!(
        files_under(&data),
        before,
        "a refused request wrote under data_dir"
    );
    d.stop().await;
}

fn files_under(dir: &std::path::Path) -> Vec<String> {
    let mut v = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            if e.path().is_dir() {
                stack.push(e.path());
            }
            v.push(e.path().display().to_string());
        }
    }
    v.sort();
    v
}

/// A client that sends half a request header and then nothing is disconnected after the
/// header-read timeout (it held its connection for ever).
#[tokio::test]
async fn a_request_header_never_finished_is_cut_off() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let mut s = tokio::net::TcpStream::connect(d.addr).await.unwrap();
    s.write_all(
        format!("GET /api/v1/axes HTTP/1.1\r\nAuthorization: Bearer {TOKEN}\r\n").as_bytes(),
    )
    .await
    .unwrap();
    let t0 = Instant::now();
    let mut buf = [0u8; 256];
    let limit = flexid::daemon::connections::HEADER_READ_TIMEOUT + Duration::from_secs(5);
    let n = tokio::time::timeout(limit, s.read(&mut buf))
        .await
        .expect("the daemon closes a connection whose header never ends");
    // closed (0 bytes) or answered 408, and not before the timeout
    if let Ok(n) = n {
        let text = String::from_utf8_lossy(&buf[..n]);
        assert!(n == 0 || text.contains("408"), "{text}");
    }
    assert!(
        t0.elapsed()
            >= flexid::daemon::connections::HEADER_READ_TIMEOUT - Duration::from_millis(500)
    );
    d.stop().await;
}
