//! The daemon under a flood of idle connections (issue 16 item 4): about 1000 idle local
//! connections locked the API (its descriptors ran out: `accept` failed with EMFILE) and a
//! sweep that ended meanwhile lost its result.
//!
//! The real `flexid daemon` runs as a child with `RLIMIT_NOFILE` 1024 (soft and hard, as
//! a shell or a unit without `LimitNOFILE` gives it), the simulated backend and a real-time
//! sweep of 5 s. While it runs, 2000 idle connections are opened (nothing sent) and the
//! API is asked every 100 ms on a fresh connection. Done when: every answer comes within
//! 1 s, the sweep completes, its `result.json` is on disk and served with the model.

mod daemon_common;
use daemon_common::process::DaemonProc;
use daemon_common::{auth, body, config_text, get_json, start_sweep_at, token_file, TOKEN};

use std::os::unix::process::CommandExt;
use std::process::Command;
use std::time::{Duration, Instant};

const IDLE_CONNECTIONS: usize = 2000;
const ANSWER_WITHIN: Duration = Duration::from_secs(1);

/// Raise this process's soft `RLIMIT_NOFILE` to its hard limit; returns the soft limit.
fn raise_own_nofile() -> u64 {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: valid pointers to a local rlimit.
    unsafe {
        assert_eq!(libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim), 0);
        lim.rlim_cur = lim.rlim_max;
        libc::setrlimit(libc::RLIMIT_NOFILE, &lim);
        libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim);
    }
    lim.rlim_cur as u64
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn idle_connections_neither_lock_the_api_nor_lose_a_result() {
    let nofile = raise_own_nofile();
    if nofile < (IDLE_CONNECTIONS + 200) as u64 {
        let msg = format!(
            "RLIMIT_NOFILE hard limit {nofile} < {} needed",
            IDLE_CONNECTIONS + 200
        );
        assert!(std::env::var("CI").as_deref() != Ok("true"), "{msg}");
        eprintln!("skipped: {msg}");
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let token = token_file(tmp.path(), 0o600);
    let cfg = tmp.path().join("flexid.toml");
    std::fs::write(&cfg, config_text(tmp.path(), &token, "")).unwrap();
    // FLEXID_BIN_UNDER_TEST: run against another build (e.g. the one before the fix)
    let bin = std::env::var("FLEXID_BIN_UNDER_TEST")
        .unwrap_or_else(|_| env!("CARGO_BIN_EXE_flexid").to_string());
    let mut cmd = Command::new(bin);
    cmd.args(["daemon", "--config"]).arg(&cfg);
    // SAFETY: setrlimit is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            let lim = libc::rlimit {
                rlim_cur: 1024,
                rlim_max: 1024,
            };
            if libc::setrlimit(libc::RLIMIT_NOFILE, &lim) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let daemon = DaemonProc::spawn(cmd);
    let base = daemon.base.clone();
    let addr = daemon.addr().to_string();

    // a real-time sweep of 5 s on the simulated drive
    let id = start_sweep_at(&base, "slow", &body("multisine", 4, 5.0)).await;
    let sweep_started = Instant::now();

    // 2000 idle connections, opened while the sweep runs (nothing is ever sent on them)
    let opener = tokio::spawn({
        let addr = addr.clone();
        async move {
            let mut held = Vec::with_capacity(IDLE_CONNECTIONS);
            let mut failed = 0usize;
            for chunk in 0..IDLE_CONNECTIONS / 100 {
                let mut tasks = Vec::new();
                for _ in 0..100 {
                    let addr = addr.clone();
                    tasks.push(tokio::spawn(async move {
                        tokio::time::timeout(
                            Duration::from_secs(3),
                            tokio::net::TcpStream::connect(addr),
                        )
                        .await
                    }));
                }
                for t in tasks {
                    match t.await.unwrap() {
                        Ok(Ok(s)) => held.push(s),
                        _ => failed += 1,
                    }
                }
                let _ = chunk;
            }
            (held, failed)
        }
    });

    // the API, on a fresh connection every 100 ms, until the sweep has ended
    let fresh = reqwest::Client::builder()
        .pool_max_idle_per_host(0)
        .timeout(Duration::from_secs(10))
        .build()
        .unwrap();
    let mut slowest = Duration::ZERO;
    let mut asked = 0usize;
    let state = loop {
        let t0 = Instant::now();
        let r = auth(fresh.get(format!("{base}/api/v1/sweeps/{id}")))
            .send()
            .await
            .unwrap_or_else(|e| panic!("the API did not answer after {asked} requests: {e}"));
        assert_eq!(r.status(), 200);
        let v: serde_json::Value = r.json().await.unwrap();
        let took = t0.elapsed();
        slowest = slowest.max(took);
        asked += 1;
        assert!(
            took <= ANSWER_WITHIN,
            "request {asked} took {took:?} (limit {ANSWER_WITHIN:?})"
        );
        let state = v["state"].as_str().unwrap_or("").to_string();
        if state != "running" {
            break state;
        }
        assert!(
            sweep_started.elapsed() < Duration::from_secs(60),
            "the sweep did not end within 60 s"
        );
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let (held, failed) = opener.await.unwrap();
    eprintln!(
        "{} idle connections opened ({failed} failed), {asked} API requests, slowest {slowest:?}",
        held.len()
    );
    assert_eq!(state, "completed");
    assert!(
        held.len() + failed == IDLE_CONNECTIONS && failed < IDLE_CONNECTIONS / 10,
        "{} of {IDLE_CONNECTIONS} idle connections opened",
        held.len()
    );

    // the result on disk and served
    let dir = tmp.path().join("data").join("slow").join(&id);
    let on_disk = std::fs::read_to_string(dir.join("result.json"))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
    let on_disk: serde_json::Value = serde_json::from_str(&on_disk).unwrap();
    assert!(on_disk["model"]["masses"].as_u64().is_some(), "{on_disk}");
    // the daemon's identification has a time cap too (issue 16 item 2; it had none)
    assert_eq!(
        on_disk["time_cap"]["max_seconds"].as_f64(),
        Some(120.0),
        "{}",
        on_disk["time_cap"]
    );
    let served = get_json(&format!("{base}/api/v1/sweeps/{id}")).await;
    assert_eq!(served["result"]["model"], on_disk["model"]);
    // still answering with every idle connection held
    let t0 = Instant::now();
    let r = fresh
        .get(format!("{base}/api/v1/axes"))
        .header("Authorization", format!("Bearer {TOKEN}"))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 200);
    assert!(t0.elapsed() <= ANSWER_WITHIN);
    drop(held);
    drop(daemon);
}
