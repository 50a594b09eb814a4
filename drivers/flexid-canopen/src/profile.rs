//! Firmware profiles: per-firmware object indices, units and scaling, supported modes,
//! timing limits and quirks, in TOML files (`firmware-profiles/*.toml`), selected from
//! the drive's identity object (0x1018) with `generic-cia402` as the fallback.
//!
//! The built-in profiles are the files of the repository's `firmware-profiles/`
//! directory, embedded at compile time; [`ProfileSet::load_dir`] adds (or replaces, by
//! name) profiles from a directory at run time. The file format is described in
//! `firmware-profiles/README.md`.

use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use crate::cia402::ModeOfOperation;
use crate::objects::cia402 as obj;
use crate::scaling::Scaling;

/// Name of the fallback profile.
pub const GENERIC: &str = "generic-cia402";

/// The built-in profiles: `(file name, contents)`.
pub const BUILTIN: [(&str, &str); 2] = [
    (
        "generic-cia402.toml",
        include_str!("../../../firmware-profiles/generic-cia402.toml"),
    ),
    (
        "flexid-vdrive.toml",
        include_str!("../../../firmware-profiles/flexid-vdrive.toml"),
    ),
];

/// Errors of the profile layer; each names the file (and the key where there is one).
#[derive(Debug, thiserror::Error)]
pub enum ProfileError {
    /// Reading a profile file or directory failed.
    #[error("cannot read firmware profile {path}: {source}")]
    Io {
        /// The file or directory.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML or does not fit the profile schema (unknown or missing
    /// key, wrong type, unknown quirk); the message names the key, line and column.
    #[error("firmware profile {file}: {message}")]
    Parse {
        /// The file.
        file: String,
        /// The parser's message.
        message: String,
    },
    /// A value is out of range.
    #[error("firmware profile {file}: key `{key}`: {reason}")]
    Invalid {
        /// The file.
        file: String,
        /// The key, dotted (`units.increments_per_rev`).
        key: &'static str,
        /// What is wrong.
        reason: String,
    },
    /// No profile without `[identity]` named `generic-cia402` is loaded.
    #[error("no `{GENERIC}` fallback profile loaded")]
    NoFallback,
}

/// The identity object (0x1018) of a drive, and its device type (0x1000).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Identity {
    /// 0x1000 device type (low 16 bits: device profile, 402 for drives).
    pub device_type: u32,
    /// 0x1018:1 vendor-id (assigned by CiA).
    pub vendor_id: u32,
    /// 0x1018:2 product code.
    pub product_code: u32,
    /// 0x1018:3 revision number (major << 16 | minor).
    pub revision: u32,
    /// 0x1018:4 serial number.
    pub serial: u32,
}

/// Which drives a profile is for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentityMatch {
    /// 0x1018:1 vendor-id.
    pub vendor_id: u32,
    /// 0x1018:2 product code.
    pub product_code: u32,
    /// Lowest matching 0x1018:3 revision (inclusive), none: any.
    pub revision_min: Option<u32>,
    /// Highest matching 0x1018:3 revision (inclusive), none: any.
    pub revision_max: Option<u32>,
}

impl IdentityMatch {
    /// Whether `id` matches.
    pub fn matches(&self, id: &Identity) -> bool {
        self.vendor_id == id.vendor_id
            && self.product_code == id.product_code
            && self.revision_min.is_none_or(|r| id.revision >= r)
            && self.revision_max.is_none_or(|r| id.revision <= r)
    }

    fn width(&self) -> u64 {
        self.revision_max.unwrap_or(u32::MAX) as u64 - self.revision_min.unwrap_or(0) as u64
    }
}

/// The EtherCAT identity of a drive's firmware (`[ethercat]`): what the SubDevice's SII
/// EEPROM holds (vendor id as assigned by the ETG, product code, revision; a CoE drive
/// shows the same in 0x1018), and its shortest SYNC0 cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EthercatIdentity {
    /// SII vendor id (ETG-assigned).
    pub vendor_id: u32,
    /// SII product code.
    pub product_code: u32,
    /// Lowest matching SII revision (inclusive), none: any.
    pub revision_min: Option<u32>,
    /// Highest matching SII revision (inclusive), none: any.
    pub revision_max: Option<u32>,
    /// Shortest SYNC0 cycle over EtherCAT, µs; none: the profile's `min_cycle_us`.
    pub min_cycle_us: Option<u32>,
}

impl EthercatIdentity {
    /// As an identity match (the same rules as 0x1018 on CAN).
    pub fn as_match(&self) -> IdentityMatch {
        IdentityMatch {
            vendor_id: self.vendor_id,
            product_code: self.product_code,
            revision_min: self.revision_min,
            revision_max: self.revision_max,
        }
    }
}

/// The CiA 402 object indices a firmware uses (standard ones unless overridden in the
/// profile's `[objects]` table). Subindex 0 throughout.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ObjectMap {
    /// Controlword, u16 (0x6040).
    pub controlword: u16,
    /// Statusword, u16 (0x6041).
    pub statusword: u16,
    /// Modes of operation, i8 (0x6060).
    pub modes_of_operation: u16,
    /// Modes of operation display, i8 (0x6061).
    pub modes_of_operation_display: u16,
    /// Position actual value, i32, increments (0x6064).
    pub position_actual: u16,
    /// Velocity actual value, i32, velocity unit (0x606C).
    pub velocity_actual: u16,
    /// Target torque, i16, per-mille of rated torque (0x6071).
    pub target_torque: u16,
    /// Motor rated torque, u32, mN m (0x6076).
    pub rated_torque: u16,
    /// Torque actual value, i16, per-mille of rated torque (0x6077).
    pub torque_actual: u16,
    /// Supported drive modes, u32 (0x6502).
    pub supported_modes: u16,
    /// Error code, u16 (0x603F).
    pub error_code: u16,
}

impl Default for ObjectMap {
    fn default() -> Self {
        Self {
            controlword: obj::CONTROLWORD,
            statusword: obj::STATUSWORD,
            modes_of_operation: obj::MODES_OF_OPERATION,
            modes_of_operation_display: obj::MODES_OF_OPERATION_DISPLAY,
            position_actual: obj::POSITION_ACTUAL,
            velocity_actual: obj::VELOCITY_ACTUAL,
            target_torque: obj::TARGET_TORQUE,
            rated_torque: obj::RATED_TORQUE,
            torque_actual: obj::TORQUE_ACTUAL,
            supported_modes: obj::SUPPORTED_MODES,
            error_code: obj::ERROR_CODE,
        }
    }
}

/// A quantity given in the profile or read from the drive at bring-up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setting {
    /// The value, in the key's unit.
    Value(f64),
    /// Read from this object at bring-up (`"read 0x6076"`).
    Read(u16),
}

/// The unit of velocity actual value (0x606C).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum VelocityUnit {
    /// Encoder increments per second (the CiA 402 default).
    IncrementsPerSecond,
    /// `factor` rad/s per unit: `rpm` (2π/60), `0.1rpm` (2π/600), `0.01rpm`,
    /// `rad/s` (1), `mrad/s` (0.001), or `velocity_unit_rad_s` given as a number.
    RadPerSecond(f64),
}

impl VelocityUnit {
    /// rad/s per unit, given the encoder resolution.
    pub fn rad_s_per_unit(self, increments_per_rev: f64) -> f64 {
        match self {
            Self::IncrementsPerSecond => TAU / increments_per_rev,
            Self::RadPerSecond(f) => f,
        }
    }
}

/// A named deviation of a firmware from CiA 301/402 that the master works around.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Quirk {
    /// `keep-unused-pdos`: do not write the COB-IDs of the PDOs outside the default
    /// mapping (RPDO2-4, TPDO3-4) to disable them (the firmware aborts such writes, or
    /// needs them for something else).
    KeepUnusedPdos,
    /// `no-heartbeat-consumer`: the drive has no 0x1016; the master's heartbeat is not
    /// monitored, so a dead master does NOT stop the motor (use only with an external
    /// safe torque off).
    NoHeartbeatConsumer,
    /// `mode-display-lags`: 0x6061 shows the new mode only some time after 0x6060 was
    /// written: poll it (up to the configured mode timeout) instead of reading once.
    ModeDisplayLags,
    /// `no-cycle-period`: the drive has no 0x1006 communication cycle period; it is
    /// not written (the drive infers the period from the SYNCs).
    NoCyclePeriod,
}

impl Quirk {
    /// The name used in profile files.
    pub const fn name(self) -> &'static str {
        match self {
            Self::KeepUnusedPdos => "keep-unused-pdos",
            Self::NoHeartbeatConsumer => "no-heartbeat-consumer",
            Self::ModeDisplayLags => "mode-display-lags",
            Self::NoCyclePeriod => "no-cycle-period",
        }
    }
}

/// One firmware profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Profile {
    /// Profile name (`name` key).
    pub name: String,
    /// The file it came from (`<builtin>/flexid-vdrive.toml` for built-ins).
    pub source: String,
    /// Free text.
    pub description: String,
    /// Which drives it is for; `None` for the generic fallback.
    pub identity: Option<IdentityMatch>,
    /// Which EtherCAT SubDevices it is for (`[ethercat]`); `None`: not an EtherCAT drive.
    pub ethercat: Option<EthercatIdentity>,
    /// Object indices.
    pub objects: ObjectMap,
    /// Encoder increments per revolution, or read 0x608F (sub 1 increments / sub 2
    /// revolutions).
    pub increments_per_rev: Setting,
    /// Rated torque, N m, or read 0x6076 (u32, mN m).
    pub rated_torque: Setting,
    /// Velocity unit.
    pub velocity_unit: VelocityUnit,
    /// Modes of operation the firmware supports.
    pub modes: Vec<ModeOfOperation>,
    /// Shortest SYNC cycle the firmware keeps up with, µs.
    pub min_cycle_us: u32,
    /// Most entries in one PDO mapping (1..=8).
    pub max_pdo_entries: u8,
    /// Quirks.
    pub quirks: Vec<Quirk>,
}

impl Profile {
    /// Whether the profile lists `q`.
    pub fn has(&self, q: Quirk) -> bool {
        self.quirks.contains(&q)
    }

    /// Whether the profile lists `mode`.
    pub fn supports(&self, mode: ModeOfOperation) -> bool {
        self.modes.contains(&mode)
    }

    /// The scaling, once the values to be read from the drive are known
    /// (`increments_per_rev`, `rated_torque_nm`: used only where the profile says
    /// "read").
    pub fn scaling(&self, read_increments_per_rev: f64, read_rated_torque_nm: f64) -> Scaling {
        let inc = match self.increments_per_rev {
            Setting::Value(v) => v,
            Setting::Read(_) => read_increments_per_rev,
        };
        let torque = match self.rated_torque {
            Setting::Value(v) => v,
            Setting::Read(_) => read_rated_torque_nm,
        };
        Scaling {
            increments_per_rev: inc,
            rated_torque_nm: torque,
            velocity_unit_rad_s: self.velocity_unit.rad_s_per_unit(inc),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FileRepr {
    name: String,
    #[serde(default)]
    description: String,
    identity: Option<IdentityMatch>,
    ethercat: Option<EthercatIdentity>,
    #[serde(default)]
    objects: ObjectMap,
    units: UnitsRepr,
    modes: Vec<ModeOfOperation>,
    min_cycle_us: u32,
    #[serde(default = "eight")]
    max_pdo_entries: u8,
    #[serde(default)]
    quirks: Vec<Quirk>,
}

fn eight() -> u8 {
    8
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct UnitsRepr {
    increments_per_rev: SettingRepr,
    rated_torque: SettingRepr,
    velocity_unit: Option<String>,
    velocity_unit_rad_s: Option<f64>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum SettingRepr {
    Number(f64),
    Text(String),
}

/// Parses one profile; `file` names it in errors.
pub fn parse(file: &str, text: &str) -> Result<Profile, ProfileError> {
    let r: FileRepr = toml::from_str(text).map_err(|e| ProfileError::Parse {
        file: file.to_string(),
        message: e.to_string().trim_end().to_string(),
    })?;
    let invalid = |key: &'static str, reason: String| ProfileError::Invalid {
        file: file.to_string(),
        key,
        reason,
    };
    let setting = |key: &'static str, s: SettingRepr| -> Result<Setting, ProfileError> {
        match s {
            SettingRepr::Number(v) if v.is_finite() && v > 0.0 => Ok(Setting::Value(v)),
            SettingRepr::Number(v) => Err(invalid(key, format!("{v} is not a positive number"))),
            SettingRepr::Text(t) => {
                let index = t
                    .strip_prefix("read 0x")
                    .and_then(|h| u16::from_str_radix(h, 16).ok())
                    .ok_or_else(|| {
                        invalid(
                            key,
                            format!("\"{t}\": expected a number or \"read 0xIIII\""),
                        )
                    })?;
                Ok(Setting::Read(index))
            }
        }
    };
    let increments_per_rev = setting("units.increments_per_rev", r.units.increments_per_rev)?;
    if let Setting::Read(i) = increments_per_rev {
        if i != obj::POSITION_ENCODER_RESOLUTION {
            return Err(invalid(
                "units.increments_per_rev",
                format!("can only be read from 0x608F, not {i:#06x}"),
            ));
        }
    }
    let rated_torque = setting("units.rated_torque", r.units.rated_torque)?;
    let velocity_unit = match (
        r.units.velocity_unit.as_deref(),
        r.units.velocity_unit_rad_s,
    ) {
        (Some(_), Some(_)) => {
            return Err(invalid(
                "units.velocity_unit",
                "give either velocity_unit or velocity_unit_rad_s, not both".into(),
            ))
        }
        (None, Some(f)) if f.is_finite() && f > 0.0 => VelocityUnit::RadPerSecond(f),
        (None, Some(f)) => {
            return Err(invalid(
                "units.velocity_unit_rad_s",
                format!("{f} is not positive"),
            ))
        }
        (None, None) => VelocityUnit::IncrementsPerSecond,
        (Some(u), None) => match u {
            "increments/s" | "inc/s" => VelocityUnit::IncrementsPerSecond,
            "rpm" => VelocityUnit::RadPerSecond(TAU / 60.0),
            "0.1rpm" => VelocityUnit::RadPerSecond(TAU / 600.0),
            "0.01rpm" => VelocityUnit::RadPerSecond(TAU / 6000.0),
            "rad/s" => VelocityUnit::RadPerSecond(1.0),
            "mrad/s" => VelocityUnit::RadPerSecond(0.001),
            other => {
                return Err(invalid(
                    "units.velocity_unit",
                    format!(
                        "\"{other}\": expected increments/s, rpm, 0.1rpm, 0.01rpm, rad/s or mrad/s"
                    ),
                ))
            }
        },
    };
    if r.modes.is_empty() {
        return Err(invalid("modes", "lists no mode".into()));
    }
    if r.min_cycle_us == 0 {
        return Err(invalid("min_cycle_us", "must be positive".into()));
    }
    if !(1..=8).contains(&r.max_pdo_entries) {
        return Err(invalid(
            "max_pdo_entries",
            format!("{} is outside 1..=8", r.max_pdo_entries),
        ));
    }
    for (key, id) in [
        ("identity.revision_min", r.identity),
        ("ethercat.revision_min", r.ethercat.map(|e| e.as_match())),
    ] {
        if let Some((lo, hi)) = id.and_then(|id| id.revision_min.zip(id.revision_max)) {
            if lo > hi {
                return Err(invalid(
                    key,
                    format!("{lo:#x} is above revision_max {hi:#x}"),
                ));
            }
        }
    }
    if r.ethercat.and_then(|e| e.min_cycle_us) == Some(0) {
        return Err(invalid("ethercat.min_cycle_us", "must be positive".into()));
    }
    if r.identity.is_none() && r.name != GENERIC {
        return Err(invalid(
            "identity",
            format!("missing: only `{GENERIC}` may go without an [identity]"),
        ));
    }
    Ok(Profile {
        name: r.name,
        source: file.to_string(),
        description: r.description,
        identity: r.identity,
        ethercat: r.ethercat,
        objects: r.objects,
        increments_per_rev,
        rated_torque,
        velocity_unit,
        modes: r.modes,
        min_cycle_us: r.min_cycle_us,
        max_pdo_entries: r.max_pdo_entries,
        quirks: r.quirks,
    })
}

/// The profiles to choose from.
#[derive(Debug, Clone, Default)]
pub struct ProfileSet {
    profiles: Vec<Profile>,
}

impl ProfileSet {
    /// An empty set.
    pub fn new() -> Self {
        Self::default()
    }

    /// The built-in profiles ([`BUILTIN`]).
    pub fn builtin() -> Self {
        let mut s = Self::new();
        for (file, text) in BUILTIN {
            let p = parse(&format!("<builtin>/{file}"), text)
                .expect("built-in profiles are checked by the tests");
            s.insert(p);
        }
        s
    }

    /// Built-ins plus the `*.toml` files of `dir` (which replace built-ins of the same
    /// name).
    pub fn builtin_and_dir(dir: &Path) -> Result<Self, ProfileError> {
        let mut s = Self::builtin();
        s.load_dir(dir)?;
        Ok(s)
    }

    /// Adds a profile, replacing one of the same name.
    pub fn insert(&mut self, p: Profile) {
        self.profiles.retain(|q| q.name != p.name);
        self.profiles.push(p);
    }

    /// Adds the `*.toml` files of `dir` (sorted by file name); returns how many.
    pub fn load_dir(&mut self, dir: &Path) -> Result<usize, ProfileError> {
        let io = |source| ProfileError::Io {
            path: dir.to_path_buf(),
            source,
        };
        let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
            .map_err(io)?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "toml"))
            .collect();
        files.sort();
        for path in &files {
            let text = std::fs::read_to_string(path).map_err(|source| ProfileError::Io {
                path: path.clone(),
                source,
            })?;
            self.insert(parse(&path.display().to_string(), &text)?);
        }
        Ok(files.len())
    }

    /// All profiles.
    pub fn profiles(&self) -> &[Profile] {
        &self.profiles
    }

    /// The profile called `name`.
    pub fn get(&self, name: &str) -> Option<&Profile> {
        self.profiles.iter().find(|p| p.name == name)
    }

    /// The profile for a drive: the matching one with the narrowest revision range
    /// (the later-added on a tie), else `generic-cia402`.
    pub fn select(&self, id: &Identity) -> Result<&Profile, ProfileError> {
        let mut best: Option<(&Profile, u64)> = None;
        for p in &self.profiles {
            if let Some(m) = p.identity.filter(|m| m.matches(id)) {
                if best.is_none_or(|(_, w)| m.width() <= w) {
                    best = Some((p, m.width()));
                }
            }
        }
        match best {
            Some((p, _)) => Ok(p),
            None => self.get(GENERIC).ok_or(ProfileError::NoFallback),
        }
    }

    /// The profile for an EtherCAT SubDevice from its SII identity (`vendor_id`,
    /// `product_code`, `revision`): the one whose `[ethercat]` matches, narrowest revision
    /// range first; `None` when no profile knows the drive (the caller refuses it, or
    /// chooses `generic-cia402` on purpose).
    pub fn select_ethercat(&self, id: &Identity) -> Option<&Profile> {
        let mut best: Option<(&Profile, u64)> = None;
        for p in &self.profiles {
            if let Some(m) = p.ethercat.map(|e| e.as_match()).filter(|m| m.matches(id)) {
                if best.is_none_or(|(_, w)| m.width() <= w) {
                    best = Some((p, m.width()));
                }
            }
        }
        best.map(|(p, _)| p)
    }
}
