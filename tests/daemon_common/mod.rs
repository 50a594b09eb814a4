//! Shared helpers of the daemon tests: a daemon on port 0 in-process (shutdown injected),
//! a backend that counts its calls, an HTTP client and an SSE reader.
#![allow(dead_code)]

pub mod broker;
pub mod browser;
pub mod process;

use flexid::daemon::{
    AxisBackend, AxisConfig, BackendError, Config, SimBackend, SweepHandle, SweepPlan,
};
use flexid::model::Chain;
use std::net::SocketAddr;
use std::os::unix::fs::PermissionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;

pub const TOKEN: &str = "test-token-0123456789abcdef";

/// A 2-mass chain: anti-resonance 35.6 Hz, resonance 61.6 Hz.
pub fn chain() -> Chain {
    Chain::new(vec![2e-3, 4e-3], vec![200.0], vec![0.02]).unwrap()
}

/// A plant file of [`chain`] for the `flexid daemon` binary.
pub const PLANT_TOML: &str = r#"
name = "test 2-mass chain"
[chain]
inertia_kgm2 = [2e-3, 4e-3]
stiffness_nm_per_rad = [200.0]
damping_nms_per_rad = [0.02]
"#;

/// The simulated backend, counting `start` calls.
pub struct Counting {
    pub inner: SimBackend,
    pub calls: AtomicUsize,
}

impl Counting {
    pub fn new() -> Arc<Counting> {
        Arc::new(Counting {
            inner: SimBackend::new(chain(), "test chain").unwrap(),
            calls: AtomicUsize::new(0),
        })
    }
    pub fn calls(&self) -> usize {
        self.calls.load(Ordering::SeqCst)
    }
}

impl AxisBackend for Counting {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        self.calls.fetch_add(1, Ordering::SeqCst);
        self.inner.start(axis, plan)
    }
}

/// Write a token file with `mode`.
pub fn token_file(dir: &Path, mode: u32) -> PathBuf {
    let p = dir.join("token");
    std::fs::write(&p, format!("{TOKEN}\n")).unwrap();
    std::fs::set_permissions(&p, std::fs::Permissions::from_mode(mode)).unwrap();
    p
}

/// Configuration text: axes `fast` (simulated clock) and `slow` (real time), both at 1 kHz,
/// 1 N m peak; `extra` is appended.
pub fn config_text(dir: &Path, token: &Path, extra: &str) -> String {
    format!(
        r#"
data_dir = "{data}"
[api]
listen = "127.0.0.1:0"
token_file = "{token}"
[[bus]]
name = "vbus"
kind = "udp"
group = "239.74.163.2"
port = 43113
bitrate = 1000000
[[axis]]
name = "fast"
bus = "vbus"
node = 1
cycle_hz = 1000
clock = "simulated"
limits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 1000.0, position_window_rad = 1000.0, max_sweep_s = 60 }}
[[axis]]
name = "slow"
bus = "vbus"
node = 2
cycle_hz = 1000
clock = "monotonic"
limits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 1000.0, position_window_rad = 1000.0, max_sweep_s = 60 }}
{extra}
"#,
        data = dir.join("data").display(),
        token = token.display(),
    )
}

/// A daemon running in-process.
pub struct TestDaemon {
    pub addr: SocketAddr,
    pub backend: Arc<Counting>,
    pub dir: PathBuf,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    running: Option<flexid::daemon::Running>,
}

impl TestDaemon {
    pub async fn start(dir: &Path, extra: &str) -> TestDaemon {
        let token = token_file(dir, 0o600);
        let cfg = Config::parse(&config_text(dir, &token, extra), "test.toml").unwrap();
        let backend = Counting::new();
        let (tx, rx) = tokio::sync::oneshot::channel::<()>();
        let running = flexid::daemon::start(cfg, backend.clone(), async move {
            let _ = rx.await;
        })
        .await
        .unwrap();
        TestDaemon {
            addr: running.addr,
            backend,
            dir: dir.into(),
            stop: Some(tx),
            running: Some(running),
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("http://{}{path}", self.addr)
    }

    /// The daemon's shared state.
    pub fn service(&self) -> std::sync::Arc<flexid::daemon::service::Service> {
        self.running.as_ref().expect("running").service.clone()
    }

    pub async fn stop(mut self) {
        if let Some(tx) = self.stop.take() {
            let _ = tx.send(());
        }
        if let Some(r) = self.running.take() {
            tokio::time::timeout(Duration::from_secs(20), r.wait())
                .await
                .expect("daemon stops in time")
                .unwrap();
        }
    }
}

pub fn client() -> reqwest::Client {
    reqwest::Client::builder()
        .timeout(Duration::from_secs(60))
        .build()
        .unwrap()
}

pub fn auth(rb: reqwest::RequestBuilder) -> reqwest::RequestBuilder {
    rb.header("Authorization", format!("Bearer {TOKEN}"))
}

/// GET `url` with the token: the body as text (whatever the status).
pub async fn get_text(url: &str) -> String {
    auth(client().get(url))
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
}

/// GET `url` with the token: the body as JSON.
pub async fn get_json(url: &str) -> serde_json::Value {
    let text = get_text(url).await;
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{url}: {e}: {text}"))
}

/// The recording of sweep `id` on the daemon at `base` (`http://ADDR`): its CSV and
/// sidecar downloaded and read back.
pub async fn get_recording(base: &str, id: &str) -> flexid::recording::Recording {
    let csv = get_text(&format!("{base}/api/v1/sweeps/{id}/recording.csv")).await;
    let side = get_text(&format!("{base}/api/v1/sweeps/{id}/recording.json")).await;
    flexid::recording::parse_recording(&csv, Some(&side))
        .unwrap()
        .recording
}

/// A sweep request body.
pub fn body(excitation: &str, periods: usize, duration_s: f64) -> String {
    format!(
        r#"{{"excitation":"{excitation}","band_hz":[2,200],"amplitude_nm":0.5,"periods":{periods},"duration_s":{duration_s}}}"#
    )
}

/// Start a sweep; returns its id (asserts 202).
pub async fn start_sweep(d: &TestDaemon, axis: &str, body: &str) -> String {
    start_sweep_at(&d.url(""), axis, body).await
}

/// [`start_sweep`] against a daemon at `base` (`http://ADDR`).
pub async fn start_sweep_at(base: &str, axis: &str, body: &str) -> String {
    let r = auth(client().post(format!("{base}/api/v1/axes/{axis}/sweeps")))
        .header("content-type", "application/json")
        .body(body.to_string())
        .send()
        .await
        .unwrap();
    let status = r.status();
    let text = r.text().await.unwrap();
    assert_eq!(status, 202, "{text}");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    v["sweep_id"].as_str().unwrap().to_string()
}

/// One server-sent event.
#[derive(Debug, Clone)]
pub struct Sse {
    pub event: String,
    pub data: serde_json::Value,
}

/// Read the event stream of a sweep until `ended` (or `stop_after` returns true), with a
/// timeout.
pub async fn read_events(
    d: &TestDaemon,
    id: &str,
    stop_after: impl FnMut(&Sse) -> bool,
) -> Vec<Sse> {
    read_events_at(&d.url(""), id, stop_after).await
}

/// [`read_events`] against a daemon at `base` (`http://ADDR`).
pub async fn read_events_at(
    base: &str,
    id: &str,
    mut stop_after: impl FnMut(&Sse) -> bool,
) -> Vec<Sse> {
    use futures_util::StreamExt;
    let r = auth(client().get(format!("{base}/api/v1/sweeps/{id}/events")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    let mut stream = r.bytes_stream();
    let mut buf = String::new();
    let mut out = Vec::new();
    let deadline = tokio::time::Instant::now() + Duration::from_secs(60);
    loop {
        let chunk = tokio::time::timeout_at(deadline, stream.next())
            .await
            .expect("events within 60 s");
        let Some(chunk) = chunk else { break };
        buf.push_str(&String::from_utf8_lossy(&chunk.unwrap()));
        while let Some(end) = buf.find("\n\n") {
            let block: String = buf[..end].to_string();
            buf.drain(..end + 2);
            let mut event = String::from("message");
            let mut data = String::new();
            for line in block.lines() {
                if let Some(v) = line.strip_prefix("event:") {
                    event = v.trim().to_string();
                } else if let Some(v) = line.strip_prefix("data:") {
                    data.push_str(v.trim_start());
                }
            }
            if data.is_empty() {
                continue; // keep-alive comment
            }
            let ev = Sse {
                event,
                data: serde_json::from_str(&data).unwrap(),
            };
            let done = ev.event == "ended" || stop_after(&ev);
            out.push(ev);
            if done {
                return out;
            }
        }
    }
    out
}
