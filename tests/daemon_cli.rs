//! `flexid daemon` as a process: configuration errors (exit code 2, the key named), the
//! bound address on stdout, and a crash (SIGKILL) during a sweep reported as `interrupted`
//! after the restart, with the data saved up to the last period.

mod daemon_common;

use daemon_common::process::DaemonProc;
use daemon_common::*;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::Duration;

const BIN: &str = env!("CARGO_BIN_EXE_flexid");

fn write_config(dir: &Path, extra: &str) -> std::path::PathBuf {
    let token = token_file(dir, 0o600);
    std::fs::write(dir.join("plant.toml"), PLANT_TOML).unwrap();
    let extra = format!(
        "[backend]\nkind = \"simulated\"\nplant = \"{}\"\n{extra}",
        dir.join("plant.toml").display()
    );
    let p = dir.join("flexid.toml");
    std::fs::write(&p, config_text(dir, &token, &extra)).unwrap();
    p
}

/// Runs `flexid daemon --config config`, which must refuse to start (exit code 2);
/// returns its stderr.
fn refused(config: &Path) -> String {
    let out = Command::new(BIN)
        .args(["daemon", "--config"])
        .arg(config)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{err}");
    err
}

/// Start the daemon (stderr discarded).
fn spawn(config: &Path) -> DaemonProc {
    let mut cmd = Command::new(BIN);
    cmd.args(["daemon", "--config"])
        .arg(config)
        .stderr(Stdio::null());
    DaemonProc::spawn(cmd)
}

#[test]
fn invalid_configuration_is_refused_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let p = write_config(tmp.path(), "");
    let text = std::fs::read_to_string(&p).unwrap();
    let cases = [
        (
            {
                // the second axis's peak torque
                let i = text.rfind("peak_torque_nm = 1.0").unwrap();
                format!("{}peak_torque_nm = 0{}", &text[..i], &text[i + 20..])
            },
            "flexid.toml: axis[1].limits.peak_torque_nm: must be > 0",
        ),
        (
            text.replace("[api]", "[api]\nlisten_all = true"),
            "flexid.toml: api.listen_all: unknown field",
        ),
        (
            text.replace("node = 2", "node = 200"),
            "flexid.toml: axis[1].node: must be 1..=127",
        ),
    ];
    for (bad, want) in cases {
        std::fs::write(&p, bad).unwrap();
        let err = refused(&p);
        assert!(err.contains(want), "want {want:?} in: {err}");
    }
    // a token file readable by others: refused, naming the file and the mode
    std::fs::write(&p, &text).unwrap();
    use std::os::unix::fs::PermissionsExt;
    let tok = tmp.path().join("token");
    std::fs::set_permissions(&tok, std::fs::Permissions::from_mode(0o644)).unwrap();
    let err = refused(&p);
    assert!(
        err.contains(&tok.display().to_string()) && err.contains("0644"),
        "{err}"
    );
}

#[tokio::test]
async fn crash_during_a_sweep_is_reported_interrupted_after_restart() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let mut d = spawn(&cfg);
    let base = d.base.clone();
    let id = start_sweep_at(&base, "slow", &body("multisine", 9, 20.0)).await;
    // let two or three periods (2 s each) reach the disk, then kill -9
    tokio::time::sleep(Duration::from_millis(5000)).await;
    d.kill();
    let dir = tmp.path().join("data/slow").join(&id);
    assert!(dir.join("running").exists(), "marker left behind");

    let mut d = spawn(&cfg);
    let base = d.base.clone();
    let st: serde_json::Value = get_json(&format!("{base}/api/v1/sweeps/{id}")).await;
    assert_eq!(st["state"], "interrupted", "{st}");
    let samples = st["samples"].as_u64().unwrap();
    assert!(
        samples >= 2000 && samples % 2000 == 0,
        "whole periods saved: {samples}"
    );
    let rec = get_recording(&base, &id).await;
    assert_eq!(rec.len() as u64, samples);
    assert!(rec
        .sidecar
        .ended_because
        .unwrap()
        .starts_with("interrupted"));
    assert!(!dir.join("running").exists());
    // the axis is free again
    let axes: serde_json::Value = get_json(&format!("{base}/api/v1/axes")).await;
    assert_eq!(axes["axes"][1]["state"], "idle");
    assert_eq!(axes["axes"][1]["last_sweep_id"], id.as_str());
    // SIGTERM: clean stop
    let pid = d.child.id().to_string();
    Command::new("kill").args(["-TERM", &pid]).status().unwrap();
    let t0 = std::time::Instant::now();
    loop {
        if let Some(status) = d.child.try_wait().unwrap() {
            assert!(status.success(), "{status}");
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(15),
            "no stop after SIGTERM"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
}

#[test]
fn notifies_systemd_ready_watchdog_and_stopping() {
    use std::os::unix::net::UnixDatagram;
    let tmp = tempfile::tempdir().unwrap();
    let cfg = write_config(tmp.path(), "");
    let sock_path = tmp.path().join("notify.sock");
    let sock = UnixDatagram::bind(&sock_path).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(10)))
        .unwrap();
    let mut cmd = Command::new(BIN);
    cmd.args(["daemon", "--config"])
        .arg(&cfg)
        .env("NOTIFY_SOCKET", &sock_path)
        .env("WATCHDOG_USEC", "200000")
        .env_remove("WATCHDOG_PID")
        .stderr(Stdio::null());
    let mut d = DaemonProc::spawn(cmd);
    let mut buf = [0u8; 512];
    let mut got = Vec::new();
    let t0 = std::time::Instant::now();
    while got
        .iter()
        .filter(|m: &&String| m.contains("WATCHDOG=1"))
        .count()
        < 3
    {
        let n = sock.recv(&mut buf).expect("a notification");
        got.push(String::from_utf8_lossy(&buf[..n]).into_owned());
        assert!(t0.elapsed() < Duration::from_secs(5), "{got:?}");
    }
    assert!(got[0].contains("READY=1"), "{got:?}");
    assert!(
        got[0].contains(&format!("STATUS=API on {}", d.addr())),
        "{got:?}"
    );
    // three pings at 100 ms (half of WATCHDOG_USEC) take about 0.2 s
    assert!(t0.elapsed() < Duration::from_secs(2));
    let pid = d.child.id().to_string();
    Command::new("kill").args(["-TERM", &pid]).status().unwrap();
    loop {
        let n = sock.recv(&mut buf).expect("STOPPING=1");
        if String::from_utf8_lossy(&buf[..n]).contains("STOPPING=1") {
            break;
        }
    }
    assert!(d.child.wait().unwrap().success());
}
