//! Helpers of the end-to-end tests: the real `flexid-vdrive` and `flexid` binaries on a bus.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// The `flexid` binary under test.
pub const FLEXID: &str = env!("CARGO_BIN_EXE_flexid");

/// The 3-mass plant of the end-to-end tests.
pub fn plant_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/e2e_3mass.toml")
}

/// `flexid-vdrive` from the target directory of this test executable
/// (`target/release/deps/e2e_sweep-*` -> `target/release/flexid-vdrive`).
pub fn vdrive_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("current_exe");
    let dir = exe
        .parent()
        .and_then(|d| {
            if d.ends_with("deps") {
                d.parent()
            } else {
                Some(d)
            }
        })
        .expect("target directory");
    let bin = dir.join(format!("flexid-vdrive{}", std::env::consts::EXE_SUFFIX));
    assert!(
        bin.is_file(),
        "{} is not built: run `cargo build --release --workspace` (the end-to-end tests start \
         the simulated drive binary from the test's own target directory)",
        bin.display()
    );
    bin
}

/// Keeps 239.0.0.0/8 on `lo` ([`flexid_can::keep_multicast_on_loopback`]). False: skip
/// (with a message); under `CI=true` a panic instead.
pub fn loopback_multicast() -> bool {
    match flexid_can::keep_multicast_on_loopback(std::net::Ipv4Addr::new(239, 74, 163, 2)) {
        Ok(()) => true,
        Err(msg) if std::env::var("CI").is_ok_and(|v| v == "true") => {
            panic!("loopback multicast required under CI=true: {msg}")
        }
        Err(msg) => {
            eprintln!("skipped: {msg}");
            false
        }
    }
}

/// A running `flexid-vdrive`, killed on drop.
pub struct VDrive {
    pub child: Child,
}

impl VDrive {
    /// Starts it on `bus` with `plant` in lock-step and waits for its ready line.
    pub fn start(bus: &str, plant: &Path) -> VDrive {
        Self::start_clocked(bus, plant, "lockstep")
    }

    /// [`VDrive::start`] with `--clock CLOCK` (`lockstep` or `realtime`).
    pub fn start_clocked(bus: &str, plant: &Path, clock: &str) -> VDrive {
        Self::start_with(bus, plant, clock, &[])
    }

    /// [`VDrive::start`] serving at `SCHED_FIFO` 70 when permitted (`--fifo-priority`):
    /// the drive for a real-time (`SCHED_FIFO`) master on this host, which holds its
    /// deadlines while a normal-priority drive would answer late whenever the host is busy.
    pub fn start_rt(bus: &str, plant: &Path) -> VDrive {
        Self::start_with(bus, plant, "lockstep", &["--fifo-priority", "70"])
    }

    /// [`VDrive::start_clocked`] with more arguments.
    pub fn start_with(bus: &str, plant: &Path, clock: &str, more: &[&str]) -> VDrive {
        let mut child = Command::new(vdrive_bin())
            .args(["--bus", bus, "--node", "5", "--clock", clock, "--plant"])
            .arg(plant)
            .args(more)
            .stdout(Stdio::piped())
            .stderr(Stdio::inherit())
            .spawn()
            .expect("start flexid-vdrive");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = mpsc::channel();
        std::thread::spawn(move || {
            let mut lines = BufReader::new(stdout).lines();
            if let Some(Ok(l)) = lines.next() {
                let _ = tx.send(l);
            }
            for _ in lines {}
        });
        let mut vd = VDrive { child };
        match rx.recv_timeout(Duration::from_secs(20)) {
            Ok(l) => assert!(l.contains("node 5 ready on"), "unexpected line: {l}"),
            Err(_) => {
                let st = vd.child.try_wait();
                panic!("flexid-vdrive not ready within 20 s (status {st:?})");
            }
        }
        vd
    }

    /// Kills it at once (SIGKILL).
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for VDrive {
    fn drop(&mut self) {
        self.kill();
    }
}

/// Runs `flexid sweep ARGS` to its end (at most `limit`), returning its output.
pub fn flexid(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(FLEXID)
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start flexid");
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let to = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = out.read_to_end(&mut s);
        s
    });
    let te = std::thread::spawn(move || {
        let mut s = Vec::new();
        let _ = err.read_to_end(&mut s);
        s
    });
    let end = Instant::now() + limit;
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if Instant::now() > end {
            let _ = child.kill();
            let s = child.wait().unwrap();
            let e = te.join().unwrap();
            panic!(
                "flexid {args:?} did not finish within {limit:?} ({s:?}); stderr:\n{}",
                String::from_utf8_lossy(&e)
            );
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    Output {
        status,
        stdout: to.join().unwrap(),
        stderr: te.join().unwrap(),
    }
}

/// `flexid sweep --bus BUS --node 5 FLAGS... --out OUT`, as [`flexid`] runs it.
pub fn sweep_node5(bus: &str, out: &Path, flags: &[&str], limit: Duration) -> Output {
    let mut args = vec!["sweep", "--bus", bus, "--node", "5"];
    args.extend_from_slice(flags);
    args.extend(["--out", out.to_str().unwrap()]);
    flexid(&args, limit)
}

/// Watches `watch` for up to `within` after `since` for the first EMCY (8 bytes) of
/// node 5: how long after `since` it came, and its error code.
pub fn first_emcy(
    watch: &mut impl flexid_can::CanBus,
    since: Instant,
    within: Duration,
) -> Option<(Duration, u16)> {
    while since.elapsed() < within {
        let Ok(Some(r)) = watch.recv_timeout(Duration::from_millis(50)) else {
            continue;
        };
        let f = r.frame;
        if f.id() == flexid_can::CanId::Standard(0x085) && f.data().len() == 8 {
            return Some((
                since.elapsed(),
                u16::from_le_bytes([f.data()[0], f.data()[1]]),
            ));
        }
    }
    None
}

/// The plant file's chain: (inertias, stiffnesses).
pub fn plant_truth(plant: &Path) -> (Vec<f64>, Vec<f64>) {
    let p = flexid::cli::plant::PlantFile::parse(
        &std::fs::read_to_string(plant).unwrap(),
        &plant.display().to_string(),
    )
    .expect("plant file");
    (p.chain.inertia_kgm2, p.chain.stiffness_nm_per_rad)
}

/// Asserts `result.json` in `out` holds the plant's inertias and stiffnesses within `tol`.
pub fn assert_identified(out: &Path, plant: &Path, tol: f64) {
    let text = std::fs::read_to_string(out.join("result.json")).expect("result.json");
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let m = &v["model"];
    let get = |k: &str| -> Vec<f64> {
        m[k].as_array()
            .unwrap_or_else(|| panic!("model.{k} missing: {m}"))
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect()
    };
    let (j, c) = plant_truth(plant);
    flexid::model::truth::assert_within(
        (&get("inertia_kgm2"), &get("stiffness_nm_per_rad")),
        (&j, &c),
        tol,
    );
}

/// The sidecar written beside the recording.
pub fn sidecar(out: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(out.join("recording.json")).expect("recording.json");
    serde_json::from_str(&text).unwrap()
}

/// Data rows of `recording.csv`.
pub fn rows(out: &Path) -> usize {
    let text = std::fs::read_to_string(out.join("recording.csv")).expect("recording.csv");
    text.lines()
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .count()
        - 1
}

/// The "N cycles/s" figure of the sweep's summary line on stderr.
pub fn cycles_per_s(stderr: &str) -> Option<f64> {
    let line = stderr.lines().rev().find(|l| l.contains(" rows in "))?;
    let i = line.find(" cycles/s")?;
    let head = &line[..i];
    head[head.rfind('(')? + 1..].parse().ok()
}
