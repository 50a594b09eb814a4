//! The veth tier of the EtherCAT tests and benchmark (issue 18): a network namespace and a
//! veth pair made for one test (unique names, removed on drop, also after a failure),
//! `flexid-vdrive --ethercat` serving emulated servos on the namespace's end, and
//! ethercrab's `MainDevice` with its stock `std::tx_rx_task` on the host's end.
//!
//! Runs as root with `ip` (iproute2); otherwise the test skips with the reason, and fails
//! instead when `FLEXID_VETH_REQUIRED=1` or `CI=true` (as the vcan tests fail with
//! `FLEXID_VCAN_REQUIRED=1`).

#![allow(dead_code)]

use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use std::io::{BufRead, BufReader, Read};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

pub const MAX_FRAMES: usize = 16;
pub const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
pub const MAX_SUBDEVICES: usize = 4;
pub const MAX_PDI: usize = 64;

/// Whether a veth tier that cannot run is a failure (`FLEXID_VETH_REQUIRED=1`, `CI=true`).
pub fn required() -> bool {
    std::env::var("FLEXID_VETH_REQUIRED").is_ok_and(|v| v == "1")
        || std::env::var("CI").is_ok_and(|v| v == "true")
}

/// Runs `ip` with `args`; its stderr on failure.
fn ip(args: &[&str]) -> Result<(), String> {
    let out = Command::new("ip")
        .args(args)
        .output()
        .map_err(|e| format!("ip {}: {e} (is iproute2 installed?)", args.join(" ")))?;
    if out.status.success() {
        Ok(())
    } else {
        Err(format!(
            "ip {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr).trim()
        ))
    }
}

/// A network namespace holding one end of a veth pair; the other end is in this
/// process's namespace. Both are removed on drop.
#[derive(Debug)]
pub struct Veth {
    /// The namespace (`ip netns`).
    pub ns: String,
    /// The MainDevice's end, in this namespace.
    pub host: String,
    /// The SubDevices' end, in `ns`.
    pub inner: String,
}

impl Veth {
    /// Creates the namespace and the pair, both ends up; names unique to this process and
    /// call.
    pub fn create() -> Result<Self, String> {
        static SEQ: AtomicU32 = AtomicU32::new(0);
        // SAFETY: geteuid has no preconditions.
        if unsafe { libc::geteuid() } != 0 {
            return Err("not root (creating a network namespace and a veth pair needs it)".into());
        }
        let tag = format!(
            "{}{}",
            std::process::id() % 1_000_000,
            SEQ.fetch_add(1, Ordering::Relaxed)
        );
        let v = Veth {
            ns: format!("flexid-ecat-{tag}"),
            host: format!("fxm{tag}"),
            inner: format!("fxs{tag}"),
        };
        ip(&["netns", "add", &v.ns])?;
        // From here on, drop removes what was made.
        ip(&[
            "link", "add", &v.host, "type", "veth", "peer", "name", &v.inner, "netns", &v.ns,
        ])?;
        // No IPv6 chatter (router solicitations, MLD) on the MainDevice's end.
        let _ = std::fs::write(
            format!("/proc/sys/net/ipv6/conf/{}/disable_ipv6", v.host),
            "1",
        );
        ip(&["link", "set", &v.host, "up"])?;
        ip(&["-n", &v.ns, "link", "set", &v.inner, "up"])?;
        Ok(v)
    }

    /// The pair, or `None` with the reason on stderr (a panic when required).
    pub fn create_or_skip(test: &str) -> Option<Self> {
        match Self::create() {
            Ok(v) => Some(v),
            Err(why) => {
                assert!(
                    !required(),
                    "{test}: the veth tier is required (FLEXID_VETH_REQUIRED=1 or CI=true) \
                     but cannot run: {why}"
                );
                eprintln!("skipped: {test}: {why}");
                None
            }
        }
    }
}

impl Drop for Veth {
    fn drop(&mut self) {
        let _ = ip(&["link", "del", &self.host]);
        let _ = ip(&["netns", "del", &self.ns]);
    }
}

/// The plant file of the EtherCAT tests.
pub fn plant_path() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../plants/e2e_3mass.toml")
}

/// `flexid-vdrive --ethercat` in the namespace; SIGTERM on stop or drop.
pub struct Emulator {
    child: Option<Child>,
}

impl Emulator {
    /// Starts the binary on `veth.inner` with `args` and waits for its ready line.
    pub fn start(veth: &Veth, args: &[&str]) -> Self {
        let plant = plant_path();
        let mut child = Command::new("ip")
            .args(["netns", "exec", &veth.ns])
            .arg(env!("CARGO_BIN_EXE_flexid-vdrive"))
            .args(["--ethercat", &veth.inner, "--plant"])
            .arg(&plant)
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("ip netns exec flexid-vdrive");
        let stdout = child.stdout.take().expect("stdout");
        let mut line = String::new();
        let ready = BufReader::new(stdout).read_line(&mut line);
        let mut emulator = Emulator { child: Some(child) };
        if !matches!(ready, Ok(n) if n > 0) || !line.contains("ready on") {
            let stderr = emulator.stop();
            panic!("flexid-vdrive --ethercat did not get ready: {line:?}\n{stderr}");
        }
        eprintln!("{}", line.trim());
        emulator
    }

    /// SIGTERM, wait, and its stderr (the counters line).
    pub fn stop(&mut self) -> String {
        let Some(mut child) = self.child.take() else {
            return String::new();
        };
        // SAFETY: signalling our own child.
        unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
        let deadline = Instant::now() + Duration::from_secs(5);
        while Instant::now() < deadline {
            if let Ok(Some(_)) = child.try_wait() {
                break;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        let _ = child.kill();
        let _ = child.wait();
        let mut stderr = String::new();
        if let Some(mut e) = child.stderr.take() {
            let _ = e.read_to_string(&mut stderr);
        }
        stderr
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        let _ = self.stop();
    }
}

/// A number after `label` in the emulator's counters line.
pub fn counter(stderr: &str, label: &str) -> Option<u64> {
    let at = stderr.find(label)? + label.len();
    stderr[at..]
        .trim_start()
        .split(|c: char| !c.is_ascii_digit())
        .next()?
        .parse()
        .ok()
}

/// A MainDevice (leaked: one per test) with ethercrab's stock `tx_rx_task` on `iface`,
/// on a thread of its own at `SCHED_FIFO` `priority` when granted.
pub fn main_device(iface: &str, priority: u8) -> &'static MainDevice<'static> {
    let storage: &'static PduStorage<MAX_FRAMES, MAX_PDU_DATA> =
        Box::leak(Box::new(PduStorage::new()));
    let (tx, rx, pdu_loop) = storage.try_split().expect("storage split once");
    let task = ethercrab::std::tx_rx_task(iface, tx, rx).expect("tx_rx_task on the host end");
    std::thread::Builder::new()
        .name("ethercrab-tx-rx".into())
        .spawn(move || {
            let _ = flexid_rt::RtSetup {
                lock_memory: false,
                ..flexid_rt::RtSetup::realtime(priority)
            }
            .apply();
            async_io::block_on(task)
        })
        .expect("tx/rx thread");
    let timeouts = Timeouts {
        state_transition: Duration::from_secs(2),
        pdu: Duration::from_millis(50),
        ..Timeouts::default()
    };
    let config = MainDeviceConfig {
        dc_static_sync_iterations: 100,
        ..MainDeviceConfig::default()
    };
    Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts, config)))
}

/// The emulated servos served in this process, on a thread that entered the namespace
/// (`setns`), so their counters can be read at any time; stopped on drop.
pub struct InProcessEmulator {
    pub segment: flexid_ecat::inprocess::SharedSegment,
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    thread: Option<std::thread::JoinHandle<Result<flexid_vdrive::ethercat::EthercatStats, String>>>,
}

impl InProcessEmulator {
    /// `options`' servos in front of the test plant on `veth.inner`, the frames served at
    /// `SCHED_FIFO` `priority` (with the SYNC0 pulses, on one thread) when granted.
    pub fn start(
        veth: &Veth,
        options: flexid_vdrive::ethercat::EthercatOptions,
        priority: u8,
    ) -> Self {
        use std::sync::atomic::AtomicBool;
        use std::sync::Arc;
        let plant = flexid_vdrive::DrivePlant::load(Some(&plant_path())).expect("plant file");
        let segment = flexid_vdrive::ethercat::servo_segment(&plant, &options).expect("servos");
        let stop = Arc::new(AtomicBool::new(false));
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let (seg, halt, ns, inner) = (
            segment.clone(),
            stop.clone(),
            veth.ns.clone(),
            veth.inner.clone(),
        );
        let thread = std::thread::Builder::new()
            .name("ecat-emulator".into())
            .spawn(move || {
                let entered = enter_namespace(&ns);
                let link = entered.and_then(|()| {
                    let clock = flexid_ecat::sync0_clock::SegmentClock::start();
                    flexid_ecat::socket_link::SocketLink::open(&inner, seg.clone(), clock)
                        .map_err(|e| e.to_string())
                });
                let mut link = match link {
                    Ok(l) => {
                        let _ = ready_tx.send(Ok(()));
                        l
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e.clone()));
                        return Err(e);
                    }
                };
                let setup = flexid_rt::RtSetup {
                    lock_memory: false,
                    ..flexid_rt::RtSetup::realtime(priority)
                };
                let _ = setup.apply();
                flexid_vdrive::ethercat::serve(&mut link, &seg, &halt).map_err(|e| e.to_string())
            })
            .expect("emulator thread");
        ready_rx
            .recv()
            .expect("emulator thread answers")
            .expect("emulator on the namespace's end");
        InProcessEmulator {
            segment,
            stop,
            thread: Some(thread),
        }
    }

    /// The servos' counters now.
    pub fn servo_stats(&self) -> flexid_ecat::CycleStats {
        flexid_vdrive::ethercat::servo_stats(&self.segment).expect("servo counters")
    }

    /// Stops serving; the link's, the clock's and the servos' counters.
    pub fn stop(&mut self) -> Option<flexid_vdrive::ethercat::EthercatStats> {
        self.stop.store(true, Ordering::Relaxed);
        self.thread.take()?.join().ok()?.ok()
    }
}

impl Drop for InProcessEmulator {
    fn drop(&mut self) {
        let _ = self.stop();
    }
}

/// Moves the calling thread into network namespace `ns` (`ip netns`' bind mount).
fn enter_namespace(ns: &str) -> Result<(), String> {
    use std::os::fd::AsRawFd;
    let path = format!("/run/netns/{ns}");
    let f = std::fs::File::open(&path).map_err(|e| format!("{path}: {e}"))?;
    // SAFETY: a valid namespace descriptor; only this thread changes namespace.
    let rc = unsafe { libc::setns(f.as_raw_fd(), libc::CLONE_NEWNET) };
    if rc != 0 {
        return Err(format!("setns {path}: {}", std::io::Error::last_os_error()));
    }
    Ok(())
}
