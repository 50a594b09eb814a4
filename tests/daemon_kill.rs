//! The daemon's CANopen path when things go wrong, against the real `flexid-vdrive`
//! (lock-step, plants/e2e_3mass.toml) on the user-space UDP bus:
//!
//! * the daemon killed with SIGKILL mid-sweep: the drive stops the motor on the lost SYNC
//!   (EMCY 0x8700, before its heartbeat consumer time), and the restarted daemon reports
//!   the sweep as interrupted with its rows up to the last period on disk, and those
//!   periods counted;
//! * the drive faulting (EMCY), a bus error, an operator abort and the position window each
//!   end the sweep with the reason, the rows measured so far kept.
//!
//! Skipped when 239.0.0.0/8 cannot be kept on `lo` (fails under CI=true).

mod daemon_common;
mod e2e;

use daemon_common::process::{canopen_config, CanAxis, DaemonProc, GROUP};
use daemon_common::{
    auth, client, get_json, get_text, read_events_at, start_sweep_at, token_file, Sse,
};
use e2e::*;
use flexid::daemon::canopen_backend::{open_udp, CanopenBackend};
use flexid::daemon::config::BusConfig;
use flexid::daemon::{AxisBackend, AxisConfig, BackendError, Config, SweepHandle, SweepPlan};
use flexid_can::{BusError, CanBus, CanFrame, Received, UdpConfig, UdpMulticastBus};
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// 40 measured periods of 1 s plus a transient one: long enough to act on mid-sweep.
const LONG: &str = r#"{"excitation":"multisine","band_hz":[2,300],"amplitude_nm":0.5,"periods":40,"duration_s":41}"#;
const PERIOD_SAMPLES: u64 = 1000;

/// Read events until the `n`-th progress event (or the end).
async fn until_period(base: &str, id: &str, n: u64) -> Vec<Sse> {
    read_events_at(base, id, |e| {
        e.event == "progress" && e.data["period"].as_u64() >= Some(n)
    })
    .await
}

async fn status(base: &str, id: &str) -> serde_json::Value {
    get_json(&format!("{base}/api/v1/sweeps/{id}")).await
}

/// The sweep ended as `outcome` with a reason starting with `reason`; its rows are on disk
/// (as many as the event says, at least `min_rows`), the sidecar says why.
fn check_ended(
    evs: &[Sse],
    data: &Path,
    at: (&str, &str),
    outcome: &str,
    reason: &str,
    min_rows: usize,
) {
    let (axis, id) = at;
    let ended = evs.last().unwrap();
    assert_eq!(ended.event, "ended", "{evs:?}");
    assert_eq!(ended.data["outcome"], outcome, "{:?}", ended.data);
    let why = ended.data["reason"].as_str().unwrap();
    assert!(why.starts_with(reason), "reason {why:?}, wanted {reason:?}");
    let dir = data.join(axis).join(id);
    let n = rows(&dir);
    assert_eq!(ended.data["samples"].as_u64().unwrap() as usize, n);
    assert!(n >= min_rows, "{n} rows");
    assert!(n < 41 * PERIOD_SAMPLES as usize, "{n} rows");
    let sc = sidecar(&dir);
    assert_eq!(sc["end"]["complete"], false, "{sc}");
    assert_eq!(sc["ended_because"].as_str(), Some(why), "{sc}");
    assert!(!dir.join("running").exists());
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sigkill_mid_sweep_the_drive_stops_and_the_restart_reports_the_saved_periods() {
    if !loopback_multicast() {
        return;
    }
    let port = 43321;
    let _vd = VDrive::start(&format!("udp:{GROUP}:{port}"), &plant_path());
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = canopen_config(tmp.path(), &token, &[CanAxis::new("k1", port)], "");
    let mut d = DaemonProc::start(FLEXID, &cfg);
    let mut watch =
        UdpMulticastBus::open(UdpConfig::group_port(GROUP.parse().unwrap(), port)).unwrap();
    let id = start_sweep_at(&d.base, "k1", LONG).await;
    let evs = until_period(&d.base, &id, 3).await;
    assert_eq!(evs.last().unwrap().event, "progress", "{evs:?}");
    while watch.recv_timeout(Duration::ZERO).unwrap().is_some() {}
    d.kill();
    let killed = Instant::now();
    let emcy = first_emcy(&mut watch, killed, Duration::from_secs(3));
    let (after, code) = emcy.expect("no EMCY from the drive within 3 s of the daemon's death");
    assert_eq!(code, 0x8700, "EMCY {code:#06x}, not SYNC lost");
    eprintln!(
        "drive faulted {} ms after the daemon was killed",
        after.as_millis()
    );
    // the lock-step drive's SYNC window is 50 ms from the last SYNC before the kill (the
    // heartbeat consumer's 300 ms would come later); margin for a loaded host
    assert!(after <= Duration::from_millis(250), "{after:?}");

    // restart: the sweep is reported interrupted, with whole periods saved
    let d2 = DaemonProc::start(FLEXID, &cfg);
    let st = status(&d2.base, &id).await;
    assert_eq!(st["state"], "interrupted", "{st}");
    let samples = st["samples"].as_u64().unwrap();
    assert!(samples >= 3 * PERIOD_SAMPLES, "{st}");
    assert_eq!(
        samples % PERIOD_SAMPLES,
        0,
        "rows up to a period's end: {st}"
    );
    assert_eq!(
        st["periods_done"].as_u64().unwrap(),
        samples / PERIOD_SAMPLES,
        "the whole periods on disk counted: {st}"
    );
    let dir = tmp.path().join("data/k1").join(&id);
    assert_eq!(rows(&dir) as u64, samples);
    let csv = get_text(&d2.url(&format!("/api/v1/sweeps/{id}/recording.csv"))).await;
    assert_eq!(csv.lines().count() as u64, samples + 1);
    // the axis is free again and the drive usable after its fault: a new sweep starts
    let r = auth(client().get(d2.url("/api/v1/axes")))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
}

#[tokio::test]
async fn drive_fault_mid_sweep_ends_the_sweep_and_says_why() {
    if !loopback_multicast() {
        return;
    }
    // the drive trips on overspeed (EMCY 0x8400) once the axis moves faster than 2 rad/s
    let tmp = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(plant_path())
        .unwrap()
        .replace("max_speed_rad_s = 314.0", "max_speed_rad_s = 2.0");
    assert!(text.contains("max_speed_rad_s = 2.0"));
    let plant = tmp.path().join("tripping.toml");
    std::fs::write(&plant, text).unwrap();
    let port = 43322;
    let _vd = VDrive::start(&format!("udp:{GROUP}:{port}"), &plant);
    let token = token_file(tmp.path(), 0o600);
    let cfg = canopen_config(tmp.path(), &token, &[CanAxis::new("f1", port)], "");
    let d = DaemonProc::start(FLEXID, &cfg);
    // low frequencies first: the speed builds up over the first periods
    let body = r#"{"excitation":"chirp","band_hz":[1,300],"amplitude_nm":0.8,"periods":40,"duration_s":41}"#;
    let id = start_sweep_at(&d.base, "f1", body).await;
    let evs = read_events_at(&d.base, &id, |_| false).await;
    let why = evs.last().unwrap().data["reason"]
        .as_str()
        .unwrap()
        .to_string();
    assert!(why.contains("0x8400"), "{why}");
    check_ended(
        &evs,
        &tmp.path().join("data"),
        ("f1", &id),
        "failed",
        "drive fault:",
        1,
    );
}

#[tokio::test]
async fn operator_abort_and_position_window_end_the_sweep_and_keep_the_rows() {
    if !loopback_multicast() {
        return;
    }
    let (pa, pw) = (43323, 43324);
    let _va = VDrive::start(&format!("udp:{GROUP}:{pa}"), &plant_path());
    let _vw = VDrive::start(&format!("udp:{GROUP}:{pw}"), &plant_path());
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let mut narrow = CanAxis::new("w1", pw);
    narrow.position_window_rad = 0.02;
    let cfg = canopen_config(tmp.path(), &token, &[CanAxis::new("a1", pa), narrow], "");
    let d = DaemonProc::start(FLEXID, &cfg);
    let data = tmp.path().join("data");

    let id = start_sweep_at(&d.base, "a1", LONG).await;
    let evs = until_period(&d.base, &id, 3).await;
    assert_eq!(evs.last().unwrap().event, "progress");
    let r = auth(client().post(d.url(&format!("/api/v1/sweeps/{id}/abort"))))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 202);
    let evs = read_events_at(&d.base, &id, |_| false).await;
    check_ended(&evs, &data, ("a1", &id), "aborted", "operator abort", 3000);
    // the torque was ramped to zero after the last recorded row
    let sc = sidecar(&data.join("a1").join(&id));
    assert!(
        sc["cycle_counters"]["cycles"].as_u64().unwrap() > sc["end"]["cycle"].as_u64().unwrap(),
        "{sc}"
    );

    // a chirp from 1 Hz with 0.5 N m leaves a 0.02 rad window within the first seconds
    let body = r#"{"excitation":"chirp","band_hz":[1,300],"amplitude_nm":0.5,"periods":40,"duration_s":41}"#;
    let id = start_sweep_at(&d.base, "w1", body).await;
    let evs = read_events_at(&d.base, &id, |_| false).await;
    let ended = evs.last().unwrap();
    assert_eq!(ended.data["outcome"], "failed", "{:?}", ended.data);
    let why = ended.data["reason"].as_str().unwrap();
    assert!(why.starts_with("position window:"), "{why}");
    let dir = data.join("w1").join(&id);
    let sc = sidecar(&dir);
    assert_eq!(sc["end"]["cycle"].as_u64().unwrap() as usize, rows(&dir));
    assert!(
        sc["cycle_counters"]["cycles"].as_u64().unwrap() > sc["end"]["cycle"].as_u64().unwrap(),
        "ramped: {sc}"
    );
}

/// A bus that fails every send after the shared budget of frames is spent.
struct FailingBus {
    inner: UdpMulticastBus,
    sent: Arc<AtomicU64>,
    fail_after: u64,
}

impl CanBus for FailingBus {
    fn send(&mut self, frame: &CanFrame) -> Result<(), BusError> {
        if self.sent.fetch_add(1, Ordering::SeqCst) >= self.fail_after {
            return Err(BusError::Io {
                interface: self.inner.interface().into(),
                op: "send",
                source: std::io::Error::from_raw_os_error(100), // ENETDOWN
            });
        }
        self.inner.send(frame)
    }
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<Received>, BusError> {
        self.inner.recv_timeout(timeout)
    }
    fn try_clone(&self) -> Result<Self, BusError> {
        Ok(FailingBus {
            inner: self.inner.try_clone()?,
            sent: self.sent.clone(),
            fail_after: self.fail_after,
        })
    }
    fn interface(&self) -> &str {
        self.inner.interface()
    }
}

/// The CANopen backend over a [`FailingBus`].
struct Failing {
    inner: CanopenBackend,
    fail_after: u64,
}

impl AxisBackend for Failing {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        let fail_after = self.fail_after;
        self.inner.start_on(axis, plan, move |bus: &BusConfig| {
            Ok(FailingBus {
                inner: open_udp(bus)?,
                sent: Arc::new(AtomicU64::new(0)),
                fail_after,
            })
        })
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bus_error_mid_sweep_ends_the_sweep_and_says_why() {
    if !loopback_multicast() {
        return;
    }
    let port = 43325;
    let _vd = VDrive::start(&format!("udp:{GROUP}:{port}"), &plant_path());
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let path = canopen_config(tmp.path(), &token, &[CanAxis::new("b1", port)], "");
    let cfg = Config::load(&path).unwrap();
    // bring-up takes a few hundred frames; the bus fails about 5 periods (2 frames/cycle) in
    let backend = Arc::new(Failing {
        inner: CanopenBackend::new(&cfg.bus),
        fail_after: 12_000,
    });
    let (tx, rx) = tokio::sync::oneshot::channel::<()>();
    let running = flexid::daemon::start(cfg, backend, async move {
        let _ = rx.await;
    })
    .await
    .unwrap();
    let base = format!("http://{}", running.addr);
    let id = start_sweep_at(&base, "b1", LONG).await;
    let evs = read_events_at(&base, &id, |_| false).await;
    check_ended(
        &evs,
        &tmp.path().join("data"),
        ("b1", &id),
        "failed",
        "bus error:",
        2000,
    );
    let why = evs.last().unwrap().data["reason"].as_str().unwrap();
    assert!(why.contains("send"), "{why}");
    let _ = tx.send(());
    tokio::time::timeout(Duration::from_secs(20), running.wait())
        .await
        .expect("daemon stops")
        .unwrap();
}
