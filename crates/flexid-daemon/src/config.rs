//! The daemon's TOML configuration (`/etc/flexid/flexid.toml`): parsed strictly (unknown
//! keys are errors) and validated before anything starts; every error names the file and
//! the key, e.g. `flexid.toml: axis[1].limits.peak_torque_nm: must be > 0`.

use serde::Deserialize;
use std::collections::HashSet;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// Errors of loading the configuration. The message names the file and the key.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{file}: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    /// TOML syntax error, wrong type or unknown key.
    #[error("{file}: {key}{message}")]
    Parse {
        file: String,
        /// The key path (`axis[1].limits.peak_torque_nm`), or empty for syntax errors.
        key: String,
        message: String,
    },
    /// A value out of range or inconsistent with another one.
    #[error("{file}: {key}: {reason}")]
    Invalid {
        file: String,
        key: String,
        reason: String,
    },
}

/// The whole configuration file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    /// Where results are stored: `data_dir/<axis>/<sweep-id>/`.
    pub data_dir: PathBuf,
    /// The HTTP API.
    pub api: ApiConfig,
    /// MQTT publishing of models and axis states (optional).
    #[serde(default)]
    pub mqtt: Option<MqttConfig>,
    /// Which backend drives the axes (default: the simulated one until the CANopen sweep is
    /// wired).
    #[serde(default)]
    pub backend: BackendConfig,
    /// The CAN buses.
    #[serde(default)]
    pub bus: Vec<BusConfig>,
    /// The axes (at least one).
    #[serde(default)]
    pub axis: Vec<AxisConfig>,
    /// A multi-axis robot measured with orthogonal multisines (optional).
    #[serde(default)]
    pub robot: Option<RobotConfig>,
}

/// `[robot]`: a robot whose axes are measured together (orthogonal random-phase
/// multisines, the N x N FRF matrix) and whose flexibilities are identified from it.
/// Simulated so far: `flexid-vdrive`'s drives of the robot, one per axis, in the daemon's
/// process on an in-process CAN bus (the same master, frames and sweep loop as a bus).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotConfig {
    /// Name in the API (`[A-Za-z0-9_-]`, 1..=32 characters).
    pub name: String,
    /// The robot's flexibility file (TOML naming its URDF); the reference arm
    /// `robots/flexid-arm6.flex.toml`, embedded, when absent.
    #[serde(default)]
    pub flex_file: Option<PathBuf>,
    /// Cycle rate [Hz], 100 ..= 8000.
    #[serde(default = "default_robot_cycle_hz")]
    pub cycle_hz: f64,
    /// Node id of axis 1 (axis i is `first_node + i - 1`).
    #[serde(default = "default_first_node")]
    pub first_node: u8,
    /// Periods per experiment averaged (>= 1) and left to settle before them.
    #[serde(default = "default_robot_periods")]
    pub periods: usize,
    #[serde(default = "default_robot_transient")]
    pub transient_periods: usize,
    /// How the cycle is timed (the simulated robot: `simulated`, as fast as it goes).
    #[serde(default = "default_robot_clock")]
    pub clock: ClockKind,
    /// The simulated robot's springs deviate from the file's by up to this fraction
    /// (each by its own seeded factor), as a real arm deviates from its data sheet; the
    /// identification starts from the file's values. 0 ..= 0.9.
    #[serde(default = "default_deviation")]
    pub simulated_deviation: f64,
    /// Seed of those factors.
    #[serde(default)]
    pub simulated_seed: u64,
}

fn default_robot_cycle_hz() -> f64 {
    1000.0
}
fn default_first_node() -> u8 {
    2
}
fn default_robot_periods() -> usize {
    4
}
fn default_robot_transient() -> usize {
    1
}
fn default_robot_clock() -> ClockKind {
    ClockKind::Simulated
}
fn default_deviation() -> f64 {
    0.3
}

/// `[api]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ApiConfig {
    /// Listen address, loopback by default (`127.0.0.1:8642`); port 0 picks a free port.
    #[serde(default = "default_listen")]
    pub listen: SocketAddr,
    /// File holding the bearer token (mode 0600 or 0400, owned by the service user).
    pub token_file: PathBuf,
}

fn default_listen() -> SocketAddr {
    SocketAddr::from(([127, 0, 0, 1], 8642))
}

/// `[mqtt]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MqttConfig {
    /// Broker host name or address.
    pub host: String,
    /// Broker TCP port (1883 by default).
    #[serde(default = "default_mqtt_port")]
    pub port: u16,
    /// Topic prefix: models go to `<prefix>/<axis>/model`, states to `<prefix>/<axis>/state`.
    #[serde(default = "default_prefix")]
    pub topic_prefix: String,
    /// MQTT client id (`flexid-<pid>` by default).
    #[serde(default)]
    pub client_id: Option<String>,
}

fn default_mqtt_port() -> u16 {
    1883
}
fn default_prefix() -> String {
    "flexid".into()
}

/// `[backend]`: what runs the sweeps.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BackendConfig {
    /// `"simulated"`: a simulated chain (no hardware); `"canopen"` (also `"drives"`): the
    /// drives on the configured buses, CAN or EtherCAT.
    #[serde(default = "default_backend_kind")]
    pub kind: BackendKind,
    /// Plant file (TOML) of the simulated backend; the embedded SCARA shoulder when absent.
    #[serde(default)]
    pub plant: Option<PathBuf>,
}

impl Default for BackendConfig {
    fn default() -> Self {
        BackendConfig {
            kind: BackendKind::Simulated,
            plant: None,
        }
    }
}

fn default_backend_kind() -> BackendKind {
    BackendKind::Simulated
}

/// Backend kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BackendKind {
    Simulated,
    #[serde(alias = "drives")]
    Canopen,
}

/// `[[bus]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BusConfig {
    /// Name referenced by `axis.bus`.
    pub name: String,
    /// `"socketcan"` (needs `interface`), `"udp"` (python-can compatible multicast; needs
    /// `group` and `port`) or `"ethercat"` (needs `interface`, or `emulated = true`).
    pub kind: BusKind,
    /// SocketCAN interface (e.g. `can0`) or the EtherCAT network interface (e.g. `eth1`).
    #[serde(default)]
    pub interface: Option<String>,
    /// `ethercat` only: the line is emulated in the daemon's process (CiA 402 servos behind
    /// emulated ESCs, one per node up to the highest configured on the bus, in front of
    /// `plant`): no interface, no privilege.
    #[serde(default)]
    pub emulated: bool,
    /// `ethercat` with `emulated = true`: the servos' plant file (the embedded SCARA
    /// shoulder when absent).
    #[serde(default)]
    pub plant: Option<PathBuf>,
    /// UDP multicast group, e.g. `239.74.163.2`.
    #[serde(default)]
    pub group: Option<std::net::IpAddr>,
    /// UDP port, e.g. 43113.
    #[serde(default)]
    pub port: Option<u16>,
    /// Bit rate [bit/s] (for the bus-load check), 10 000 ..= 1 000 000 (classic CAN). A
    /// `udp` bus has no wire time of its own, so it may also stand for a faster transport
    /// (an EtherCAT-class link, up to [`MAX_VIRTUAL_BITRATE`]): the admission then counts
    /// the same frames at that rate. Not given for an `ethercat` bus (100 Mbit/s; its
    /// cycle is limited by the drive's firmware profile, checked at bring-up).
    #[serde(default)]
    pub bitrate: u32,
}

/// Highest `bitrate` of a `udp` bus [bit/s]: 100 Mbit/s, an EtherCAT-class transport
/// (classic CAN, and so every `socketcan` bus, stops at 1 Mbit/s).
pub const MAX_VIRTUAL_BITRATE: u32 = 100_000_000;

/// Bus kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum BusKind {
    Udp,
    Socketcan,
    /// EtherCAT, CoE CiA 402 drives (`flexid-ecat`).
    Ethercat,
}

/// How an axis's cycle is timed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ClockKind {
    /// Real time: absolute deadlines on CLOCK_MONOTONIC (the default).
    Monotonic,
    /// Simulated time: cycles run as fast as possible (simulated backend and test benches).
    Simulated,
}

/// `[[axis]]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// Name in the API and the topics (`[A-Za-z0-9_-]`, 1..=32 characters).
    pub name: String,
    /// The bus (a `[[bus]]` name).
    pub bus: String,
    /// CANopen node-id, 1..=127; on an `ethercat` bus the SubDevice's position on the
    /// line, 1 = the first.
    pub node: u8,
    /// Firmware profile name (selected from the drive's identity when absent).
    #[serde(default)]
    pub profile: Option<String>,
    /// Cycle rate [Hz] = sample rate of the recording, 100 ..= 8000.
    pub cycle_hz: f64,
    /// How the cycle is timed.
    #[serde(default = "default_clock")]
    pub clock: ClockKind,
    /// Safety limits of this axis.
    pub limits: Limits,
}

fn default_clock() -> ClockKind {
    ClockKind::Monotonic
}

/// `axis.limits`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Largest torque command [N m] (> 0).
    pub peak_torque_nm: f64,
    /// Speed at which a sweep is stopped [rad/s] (> 0).
    pub max_speed_rad_s: f64,
    /// Largest excursion from the start position before a sweep is stopped [rad] (> 0).
    pub position_window_rad: f64,
    /// Longest sweep [s] (> 0).
    pub max_sweep_s: f64,
    /// Feedback messages (TPDOs) that may be lost in one sweep before it is stopped
    /// (default: 0.5 % of the sweep's cycles, at least 20). Raise it on a host without
    /// a real-time kernel, whose scheduling stalls lose feedback.
    #[serde(default)]
    pub max_lost_tpdos: Option<u64>,
}

impl AxisConfig {
    /// Nyquist frequency of the cycle [Hz].
    pub fn nyquist_hz(&self) -> f64 {
        self.cycle_hz / 2.0
    }
}

impl Config {
    /// Read and validate the file at `path`.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let file = display_name(path);
        let text = flexid_files::bounded_read::read_text_bounded(
            path,
            flexid_files::bounded_read::MAX_TEXT_FILE_BYTES,
        )
        .map_err(|source| ConfigError::Io {
            file: file.clone(),
            source,
        })?;
        Self::parse(&text, &file)
    }

    /// Parse and validate configuration text; `file` names it in errors.
    pub fn parse(text: &str, file: &str) -> Result<Config, ConfigError> {
        let de = toml::Deserializer::parse(text).map_err(|e| ConfigError::Parse {
            file: file.into(),
            key: String::new(),
            message: describe(&e, text),
        })?;
        let cfg: Config = serde_path_to_error::deserialize(de).map_err(|e| {
            let key = e.path().to_string();
            let message = describe(e.inner(), text);
            let top = key == "." || key.is_empty();
            ConfigError::Parse {
                file: file.into(),
                key: if top { String::new() } else { key },
                message: if top { message } else { format!(": {message}") },
            }
        })?;
        cfg.validate(file)?;
        Ok(cfg)
    }

    /// The axis named `name`.
    pub fn axis(&self, name: &str) -> Option<&AxisConfig> {
        self.axis.iter().find(|a| a.name == name)
    }

    fn validate(&self, file: &str) -> Result<(), ConfigError> {
        let bad = |key: String, reason: &str| ConfigError::Invalid {
            file: file.into(),
            key,
            reason: reason.into(),
        };
        if self.data_dir.as_os_str().is_empty() {
            return Err(bad("data_dir".into(), "must not be empty"));
        }
        if let Some(m) = &self.mqtt {
            if m.host.trim().is_empty() {
                return Err(bad("mqtt.host".into(), "must not be empty"));
            }
            if m.port == 0 {
                return Err(bad("mqtt.port".into(), "must be 1..=65535"));
            }
            if m.topic_prefix.is_empty()
                || m.topic_prefix.contains(['#', '+'])
                || m.topic_prefix.ends_with('/')
            {
                return Err(bad(
                    "mqtt.topic_prefix".into(),
                    "must be non-empty, without '#', '+' or a trailing '/'",
                ));
            }
        }
        let mut buses = HashSet::new();
        for (i, b) in self.bus.iter().enumerate() {
            let key = |k: &str| format!("bus[{i}].{k}");
            if !valid_name(&b.name) {
                return Err(bad(
                    key("name"),
                    "must be 1..=32 characters of [A-Za-z0-9_-]",
                ));
            }
            if !buses.insert(b.name.as_str()) {
                return Err(bad(key("name"), "duplicate bus name"));
            }
            if b.kind != BusKind::Ethercat && (b.emulated || b.plant.is_some()) {
                return Err(bad(
                    key("emulated"),
                    "`emulated` and `plant` are for an ethercat bus only",
                ));
            }
            match b.kind {
                BusKind::Ethercat => {
                    if b.emulated == b.interface.is_some() {
                        return Err(bad(
                            key("interface"),
                            "an ethercat bus needs an interface name, or emulated = true \
                             (not both)",
                        ));
                    }
                    if b.plant.is_some() && !b.emulated {
                        return Err(bad(
                            key("plant"),
                            "only an emulated ethercat bus has a plant",
                        ));
                    }
                    if b.bitrate != 0 {
                        return Err(bad(
                            key("bitrate"),
                            "not given for an ethercat bus (100 Mbit/s)",
                        ));
                    }
                }
                BusKind::Socketcan => {
                    if b.interface
                        .as_deref()
                        .is_none_or(|s| s.is_empty() || s.len() > 15)
                    {
                        return Err(bad(
                            key("interface"),
                            "a socketcan bus needs an interface name (1..=15 characters)",
                        ));
                    }
                }
                BusKind::Udp => {
                    if !b.group.is_some_and(|g| g.is_multicast()) {
                        return Err(bad(key("group"), "a udp bus needs a multicast group"));
                    }
                    if b.port.is_none_or(|p| p == 0) {
                        return Err(bad(key("port"), "a udp bus needs a port 1..=65535"));
                    }
                }
            }
            match b.kind {
                BusKind::Socketcan if !(10_000..=1_000_000).contains(&b.bitrate) => {
                    return Err(bad(key("bitrate"), "must be 10000..=1000000 bit/s"));
                }
                BusKind::Udp if !(10_000..=MAX_VIRTUAL_BITRATE).contains(&b.bitrate) => {
                    return Err(bad(
                        key("bitrate"),
                        "must be 10000..=100000000 bit/s (above 1000000 only on a udp bus, \
                         standing for a faster transport)",
                    ));
                }
                _ => {}
            }
        }
        if self.axis.is_empty() {
            return Err(bad("axis".into(), "at least one [[axis]] is needed"));
        }
        let mut names = HashSet::new();
        let mut nodes = HashSet::new();
        for (i, a) in self.axis.iter().enumerate() {
            let key = |k: &str| format!("axis[{i}].{k}");
            if !valid_name(&a.name) {
                return Err(bad(
                    key("name"),
                    "must be 1..=32 characters of [A-Za-z0-9_-]",
                ));
            }
            if !names.insert(a.name.as_str()) {
                return Err(bad(key("name"), "duplicate axis name"));
            }
            if !buses.contains(a.bus.as_str()) {
                return Err(bad(key("bus"), "no [[bus]] has this name"));
            }
            if !(1..=127).contains(&a.node) {
                return Err(bad(key("node"), "must be 1..=127"));
            }
            if !nodes.insert((a.bus.as_str(), a.node)) {
                return Err(bad(
                    key("node"),
                    "another axis uses this node on the same bus",
                ));
            }
            if !(a.cycle_hz.is_finite() && (100.0..=8000.0).contains(&a.cycle_hz)) {
                return Err(bad(key("cycle_hz"), "must be 100..=8000 Hz"));
            }
            let l = &a.limits;
            for (k, v) in [
                ("peak_torque_nm", l.peak_torque_nm),
                ("max_speed_rad_s", l.max_speed_rad_s),
                ("position_window_rad", l.position_window_rad),
                ("max_sweep_s", l.max_sweep_s),
            ] {
                if !(v.is_finite() && v > 0.0) {
                    return Err(bad(format!("axis[{i}].limits.{k}"), "must be > 0"));
                }
            }
            if l.max_sweep_s > 3600.0 {
                return Err(bad(key("limits.max_sweep_s"), "must be at most 3600 s"));
            }
        }
        if let Some(r) = &self.robot {
            let key = |k: &str| format!("robot.{k}");
            if !valid_name(&r.name) {
                return Err(bad(
                    key("name"),
                    "must be 1..=32 characters of [A-Za-z0-9_-]",
                ));
            }
            if !(r.cycle_hz.is_finite() && (100.0..=8000.0).contains(&r.cycle_hz)) {
                return Err(bad(key("cycle_hz"), "must be 100..=8000 Hz"));
            }
            if !(1..=127).contains(&r.first_node) {
                return Err(bad(key("first_node"), "must be 1..=127"));
            }
            if !(1..=64).contains(&r.periods) || r.transient_periods > 16 {
                return Err(bad(
                    key("periods"),
                    "periods must be 1..=64 and transient_periods 0..=16",
                ));
            }
            if !(r.simulated_deviation.is_finite() && (0.0..=0.9).contains(&r.simulated_deviation))
            {
                return Err(bad(key("simulated_deviation"), "must be 0..=0.9"));
            }
        }
        Ok(())
    }
}

/// Axis and bus names: 1..=32 characters of `[A-Za-z0-9_-]` (safe in paths, URLs, topics).
pub fn valid_name(s: &str) -> bool {
    !s.is_empty()
        && s.len() <= 32
        && s.bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-')
}

fn display_name(path: &Path) -> String {
    path.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| path.display().to_string())
}

/// The error's message on one line, with the line and column of its span.
fn describe(e: &toml::de::Error, text: &str) -> String {
    let msg = e.message().split_whitespace().collect::<Vec<_>>().join(" ");
    match e.span() {
        Some(span) => {
            let before = &text.as_bytes()[..span.start.min(text.len())];
            let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
            let col = before.iter().rev().take_while(|&&b| b != b'\n').count() + 1;
            format!("{msg} (line {line}, column {col})")
        }
        None => msg,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
data_dir = "/tmp/x"
[api]
listen = "127.0.0.1:0"
token_file = "/tmp/token"
[[bus]]
name = "can0"
kind = "socketcan"
interface = "can0"
bitrate = 1000000
[[axis]]
name = "j1"
bus = "can0"
node = 1
cycle_hz = 2000
limits = { peak_torque_nm = 2.0, max_speed_rad_s = 10.0, position_window_rad = 1.0, max_sweep_s = 60 }
[[axis]]
name = "j2"
bus = "can0"
node = 2
cycle_hz = 2000
limits = { peak_torque_nm = 2.0, max_speed_rad_s = 10.0, position_window_rad = 1.0, max_sweep_s = 60 }
"#;

    #[test]
    fn good_config_parses() {
        let c = Config::parse(GOOD, "flexid.toml").unwrap();
        assert_eq!(c.axis.len(), 2);
        assert_eq!(c.axis[0].clock, ClockKind::Monotonic);
        assert_eq!(c.backend.kind, BackendKind::Simulated);
        assert_eq!(c.axis[0].limits.max_lost_tpdos, None);
        let text = GOOD.replacen(
            "max_sweep_s = 60 }",
            "max_sweep_s = 60, max_lost_tpdos = 200 }",
            1,
        );
        let c = Config::parse(&text, "flexid.toml").unwrap();
        assert_eq!(c.axis[0].limits.max_lost_tpdos, Some(200));
        assert_eq!(c.axis[1].limits.max_lost_tpdos, None);
    }

    #[test]
    fn bad_limit_names_the_key() {
        let text = replace_nth(GOOD, "peak_torque_nm = 2.0", "peak_torque_nm = -1", 1);
        let e = Config::parse(&text, "flexid.toml").unwrap_err().to_string();
        assert_eq!(e, "flexid.toml: axis[1].limits.peak_torque_nm: must be > 0");
    }

    #[test]
    fn unknown_key_is_an_error_naming_it() {
        let text = GOOD.replace("node = 2", "node = 2\nspeed = 3");
        let e = Config::parse(&text, "flexid.toml").unwrap_err().to_string();
        assert!(e.contains("axis[1]") && e.contains("speed"), "{e}");
        let e = Config::parse(&GOOD.replace("[api]", "[api]\nfoo = 1"), "flexid.toml")
            .unwrap_err()
            .to_string();
        assert!(e.contains("api") && e.contains("foo"), "{e}");
    }

    #[test]
    fn wrong_type_names_the_key() {
        let text = GOOD.replacen("cycle_hz = 2000", "cycle_hz = \"fast\"", 1);
        let e = Config::parse(&text, "flexid.toml").unwrap_err().to_string();
        assert!(e.starts_with("flexid.toml: axis[0].cycle_hz"), "{e}");
    }

    #[test]
    fn unknown_bus_and_duplicate_names() {
        let e = Config::parse(
            &GOOD.replace("bus = \"can0\"\nnode = 2", "bus = \"can9\"\nnode = 2"),
            "f",
        )
        .unwrap_err()
        .to_string();
        assert_eq!(e, "f: axis[1].bus: no [[bus]] has this name");
        let e = Config::parse(&GOOD.replace("\"j2\"", "\"j1\""), "f")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "f: axis[1].name: duplicate axis name");
    }

    #[test]
    fn bitrate_above_classic_can_only_on_a_udp_bus() {
        let fast = GOOD.replace("bitrate = 1000000", "bitrate = 100000000");
        let e = Config::parse(&fast, "f").unwrap_err().to_string();
        assert_eq!(e, "f: bus[0].bitrate: must be 10000..=1000000 bit/s");
        let udp = fast.replace(
            "kind = \"socketcan\"\ninterface = \"can0\"",
            "kind = \"udp\"\ngroup = \"239.74.163.2\"\nport = 43113",
        );
        let c = Config::parse(&udp, "f").unwrap();
        assert_eq!(c.bus[0].bitrate, MAX_VIRTUAL_BITRATE);
        let e = Config::parse(&udp.replace("100000000", "100000001"), "f")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("f: bus[0].bitrate: must be 10000..=100000000"),
            "{e}"
        );
    }

    #[test]
    fn an_ethercat_bus_has_an_interface_or_is_emulated() {
        let ecat = GOOD.replace(
            "kind = \"socketcan\"\ninterface = \"can0\"\nbitrate = 1000000",
            "kind = \"ethercat\"\ninterface = \"eth1\"",
        );
        let c = Config::parse(&ecat, "f").unwrap();
        assert_eq!(c.bus[0].kind, BusKind::Ethercat);
        assert_eq!(c.bus[0].interface.as_deref(), Some("eth1"));
        let emulated = ecat.replace("interface = \"eth1\"", "emulated = true");
        let c = Config::parse(&emulated, "f").unwrap();
        assert!(c.bus[0].emulated);
        for (text, want) in [
            (
                ecat.replace("interface = \"eth1\"", ""),
                "f: bus[0].interface: an ethercat bus needs an interface name, or emulated = \
                 true (not both)",
            ),
            (
                ecat.replace(
                    "interface = \"eth1\"",
                    "interface = \"eth1\"\nemulated = true",
                ),
                "f: bus[0].interface: an ethercat bus needs an interface name, or emulated = \
                 true (not both)",
            ),
            (
                ecat.replace(
                    "interface = \"eth1\"",
                    "interface = \"eth1\"\nbitrate = 1000000",
                ),
                "f: bus[0].bitrate: not given for an ethercat bus (100 Mbit/s)",
            ),
            (
                GOOD.replace(
                    "interface = \"can0\"",
                    "interface = \"can0\"\nemulated = true",
                ),
                "f: bus[0].emulated: `emulated` and `plant` are for an ethercat bus only",
            ),
        ] {
            let e = Config::parse(&text, "f").unwrap_err().to_string();
            assert_eq!(e, want);
        }
        let drives = emulated.replace("data_dir", "[backend]\nkind = \"drives\"\ndata_dir");
        let drives = drives.replacen(
            "[backend]\nkind = \"drives\"\ndata_dir = \"/tmp/x\"",
            "data_dir = \"/tmp/x\"\n[backend]\nkind = \"drives\"",
            1,
        );
        assert_eq!(
            Config::parse(&drives, "f").unwrap().backend.kind,
            BackendKind::Canopen
        );
    }

    fn replace_nth(s: &str, from: &str, to: &str, n: usize) -> String {
        let mut out = String::new();
        let mut rest = s;
        let mut i = 0;
        while let Some(p) = rest.find(from) {
            out.push_str(&rest[..p]);
            out.push_str(if i == n { to } else { from });
            rest = &rest[p + from.len()..];
            i += 1;
        }
        out.push_str(rest);
        out
    }
}
