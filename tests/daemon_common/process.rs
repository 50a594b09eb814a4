//! The real `flexid daemon` binary as a child process, with the CANopen backend over the
//! user-space (UDP multicast) bus: one `[[bus]]` per axis (each sweep runs its own SYNC
//! producer, so two independent sweeps need two buses).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

/// The multicast group of the daemon tests' buses.
pub const GROUP: &str = "239.74.163.2";

/// One axis of a CANopen configuration: its name, the UDP port of its own bus, the
/// position window [rad].
pub struct CanAxis<'a> {
    pub name: &'a str,
    pub port: u16,
    pub position_window_rad: f64,
    /// `"simulated"` (lock-step, the default) or `"monotonic"` (real time).
    pub clock: &'a str,
    /// Cycle rate [Hz] (1000 by default).
    pub cycle_hz: f64,
    /// The bus's `bitrate` [bit/s] (1 Mbit/s by default; above that a udp bus stands for
    /// a faster transport).
    pub bitrate: u32,
    /// `limits.max_lost_tpdos` (`None`: not written, the daemon's default budget).
    pub max_lost_tpdos: Option<u64>,
}

impl<'a> CanAxis<'a> {
    /// An axis at node 5 on its own bus, with a wide position window.
    pub fn new(name: &'a str, port: u16) -> Self {
        CanAxis {
            name,
            port,
            position_window_rad: 1000.0,
            clock: "simulated",
            cycle_hz: 1000.0,
            bitrate: 1_000_000,
            max_lost_tpdos: None,
        }
    }
}

/// Write `flexid.toml` for the CANopen backend (1 N m peak) with
/// `extra` appended; returns its path. The data directory is `dir/data`.
pub fn canopen_config(dir: &Path, token: &Path, axes: &[CanAxis], extra: &str) -> PathBuf {
    let mut text = format!(
        "data_dir = \"{}\"\n[api]\nlisten = \"127.0.0.1:0\"\ntoken_file = \"{}\"\n\
         [backend]\nkind = \"canopen\"\n",
        dir.join("data").display(),
        token.display()
    );
    for a in axes {
        text.push_str(&format!(
            "[[bus]]\nname = \"bus-{name}\"\nkind = \"udp\"\ngroup = \"{GROUP}\"\nport = {port}\n\
             bitrate = {bitrate}\n",
            name = a.name,
            port = a.port,
            bitrate = a.bitrate
        ));
    }
    for a in axes {
        text.push_str(&format!(
            "[[axis]]\nname = \"{name}\"\nbus = \"bus-{name}\"\nnode = 5\ncycle_hz = {hz}\n\
             clock = \"{clock}\"\nlimits = {{ peak_torque_nm = 1.0, max_speed_rad_s = 300.0, \
             position_window_rad = {w}, max_sweep_s = 120{lost} }}\n",
            lost = a
                .max_lost_tpdos
                .map_or(String::new(), |n| format!(", max_lost_tpdos = {n}")),
            name = a.name,
            w = a.position_window_rad,
            clock = a.clock,
            hz = a.cycle_hz
        ));
    }
    text.push_str(extra);
    let p = dir.join("flexid.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// A `flexid daemon` child process, killed (SIGKILL) on drop.
pub struct DaemonProc {
    pub child: Child,
    /// `http://ADDR`
    pub base: String,
}

impl DaemonProc {
    /// Start `flexid` (`bin`) `daemon --config cfg` and wait for its listening line.
    pub fn start(bin: &str, cfg: &Path) -> DaemonProc {
        let mut cmd = Command::new(bin);
        cmd.args(["daemon", "--config"]).arg(cfg);
        Self::spawn(cmd)
    }

    /// Spawn `cmd` (a `flexid daemon` command line, stderr inherited unless set) and
    /// wait for its first stdout line, `flexid daemon: listening on ADDR`.
    pub fn spawn(mut cmd: Command) -> DaemonProc {
        let mut child = cmd
            .stdout(Stdio::piped())
            .spawn()
            .expect("start flexid daemon");
        let mut out = BufReader::new(child.stdout.take().unwrap());
        let mut line = String::new();
        out.read_line(&mut line).unwrap();
        assert!(!line.is_empty(), "the daemon exited before listening");
        // keep reading so the daemon never blocks on a full pipe
        std::thread::spawn(move || for _ in out.lines() {});
        let addr = line
            .trim()
            .strip_prefix("flexid daemon: listening on ")
            .unwrap_or_else(|| panic!("first line: {line:?}"));
        let base = format!("http://{addr}");
        DaemonProc { child, base }
    }

    /// The bound address (`ADDR` of `base`).
    pub fn addr(&self) -> &str {
        self.base.trim_start_matches("http://")
    }

    /// `base` + `path`.
    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// SIGKILL, at once.
    pub fn kill(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

impl Drop for DaemonProc {
    fn drop(&mut self) {
        self.kill();
    }
}
