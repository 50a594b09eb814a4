//! `flexid sweep --daemon URL`: the command line as a client of the real daemon (port 0,
//! token, simulated backend): progress per period, the results downloaded into `--out`, the
//! parameter table in the terminal; refused requests exit 2 naming the flag and never reach
//! the backend.

mod daemon_common;

use daemon_common::*;
use std::path::Path;
use std::process::{Command, Output};

const BIN: &str = env!("CARGO_BIN_EXE_flexid");

async fn flexid_sweep(d: &TestDaemon, extra: &[&str]) -> Output {
    let mut cmd = Command::new(BIN);
    cmd.args(["sweep", "--daemon", &d.url("")])
        .arg("--token-file")
        .arg(d.dir.join("token"))
        .args(extra);
    tokio::task::spawn_blocking(move || cmd.output().expect("flexid runs"))
        .await
        .unwrap()
}

/// The value column of the table row `name` (e.g. `J1`).
fn table_value(stdout: &str, name: &str) -> f64 {
    stdout
        .lines()
        .find(|l| l.split_whitespace().next() == Some(name))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no {name} row in:\n{stdout}"))
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sweep_through_the_daemon_prints_the_table_and_saves_the_results() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let out = tmp.path().join("out");
    let o = flexid_sweep(
        &d,
        &[
            "--node",
            "1",
            "--band",
            "2",
            "200",
            "--peak-nm",
            "0.5",
            "--periods",
            "4",
            "--resolution-hz",
            "1",
            "--out",
            out.to_str().unwrap(),
        ],
    )
    .await;
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    println!("{stdout}\n{stderr}");
    assert!(o.status.success(), "{stderr}");
    // progress: one line per period (no terminal here, so no bar), 1 transient + 4
    for p in 1..=5 {
        assert!(
            stderr.contains(&format!("period {p}/5")),
            "period {p}: {stderr}"
        );
    }
    assert!(stderr.contains("completed"), "{stderr}");
    // the table holds the simulated chain
    let ch = chain();
    for (name, want) in [
        ("J1", ch.inertia_kgm2[0]),
        ("J2", ch.inertia_kgm2[1]),
        ("c1", ch.stiffness_nm_per_rad[0]),
    ] {
        let got = table_value(&stdout, name);
        assert!((got - want).abs() < 0.05 * want, "{name}: {got} vs {want}");
    }
    // the files, as the in-process sweep writes them; the recording is the daemon's
    for f in [
        "recording.csv",
        "recording.json",
        "frf.csv",
        "bode.svg",
        "result.json",
    ] {
        assert!(Path::new(&out.join(f)).is_file(), "{f} missing");
    }
    let rec = flexid::recording::read_recording(out.join("recording.csv")).unwrap();
    assert_eq!(rec.len(), 5000, "1 + 4 periods of 1 s at 1 kHz");
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    assert_eq!(result["model"]["masses"], 2);
    assert_eq!(d.backend.calls(), 1);
    d.stop().await;
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn refused_sweeps_exit_2_and_name_the_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let d = TestDaemon::start(tmp.path(), "").await;
    let out = tmp.path().join("out");
    let out = out.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        // above the axis's peak torque limit (1 N m)
        (
            &["--node", "1", "--peak-nm", "1.5", "--out", out],
            "--peak-nm",
        ),
        // a band above the axis's Nyquist frequency
        (
            &["--node", "1", "--band", "2", "600", "--out", out],
            "--band",
        ),
        // no axis with that node
        (&["--node", "9", "--out", out], "no axis with --node 9"),
        // a flag only the in-process sweep has
        (
            &["--node", "1", "--rms-nm", "0.2", "--out", out],
            "--rms-nm",
        ),
    ];
    for (args, says) in cases {
        let o = flexid_sweep(&d, args).await;
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    // a wrong token file
    let bad = tmp.path().join("bad-token");
    std::fs::write(&bad, "wrong-token-0123456789").unwrap();
    let o = Command::new(BIN)
        .args(["sweep", "--daemon", &d.url(""), "--node", "1"])
        .arg("--token-file")
        .arg(&bad)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("token"), "{stderr}");
    assert_eq!(d.backend.calls(), 0, "a refused sweep reached the backend");
    d.stop().await;
}
