//! The drive's configuration and the plant file: the main crate's plant TOML (`[chain]`,
//! `[measurement]`, ...) plus a `[drive]` section:
//!
//! ```toml
//! [drive]
//! node_id = 5                        # default node id (the CLI's --node overrides it)
//! rated_torque_nm = 1.0              # 0x6076 (the per-mille unit of 0x6071/0x6077)
//! peak_torque_nm = 3.0               # set-points are clamped to it (and to 0x6072)
//! max_speed_rad_s = 314.0            # above it: fault, EMCY 0x8400
//! encoder_increments_per_rev = 1048576
//! heartbeat_producer_ms = 0          # 0x1017 after reset (0 = off)
//! heartbeat_consumer_ms = 0          # 0x1016:1 time after reset (0 = off) ...
//! master_node_id = 1                 # ... of this node
//! quick_stop_slope_nm_per_s = 100.0  # quick stop torque ramp
//! continuous_torque_nm = 2.0         # optional i2t monitor: EMCY 0x2310 when exceeded
//! i2t_time_constant_s = 1.0
//! velocity_loop_hz = 30.0            # CSV/CSP: velocity PI bandwidth (gains from the total inertia)
//! position_loop_hz = 5.0             # CSP: position P bandwidth
//! sync_loss_cycles = 3               # no SYNC for this many 0x1006 periods in Operation
//!                                    # enabled: fault, torque off, EMCY 0x8700 (0 = off)
//! ```

use std::path::Path;

use flexid_core::plant::{PlantFile, DEFAULT_PLANT};
use serde::Deserialize;

use crate::limits::LimitConfig;

/// How the plant advances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ClockMode {
    /// Each SYNC advances the plant by exactly one cycle (deterministic).
    #[default]
    LockStep,
    /// On each SYNC the plant advances by the whole cycles of wall time since the last.
    RealTime,
}

/// The `[drive]` section (all fields optional).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DriveSection {
    pub node_id: u8,
    pub rated_torque_nm: f64,
    pub peak_torque_nm: f64,
    pub max_speed_rad_s: f64,
    pub encoder_increments_per_rev: u32,
    pub heartbeat_producer_ms: u16,
    pub heartbeat_consumer_ms: u16,
    pub master_node_id: u8,
    pub quick_stop_slope_nm_per_s: f64,
    pub continuous_torque_nm: Option<f64>,
    pub i2t_time_constant_s: f64,
    pub velocity_loop_hz: f64,
    pub position_loop_hz: f64,
    pub sync_loss_cycles: u16,
}

impl Default for DriveSection {
    fn default() -> Self {
        Self {
            node_id: 5,
            rated_torque_nm: 1.0,
            peak_torque_nm: 3.0,
            max_speed_rad_s: 314.0,
            encoder_increments_per_rev: 1 << 20,
            heartbeat_producer_ms: 0,
            heartbeat_consumer_ms: 0,
            master_node_id: 1,
            quick_stop_slope_nm_per_s: 100.0,
            continuous_torque_nm: None,
            i2t_time_constant_s: 1.0,
            velocity_loop_hz: 30.0,
            position_loop_hz: 5.0,
            sync_loss_cycles: 3,
        }
    }
}

/// Everything the drive core needs besides the physics.
#[derive(Debug, Clone, PartialEq)]
pub struct DriveConfig {
    /// Node id 1..=127.
    pub node_id: u8,
    /// Cycle (SYNC) rate of the plant [Hz].
    pub cycle_hz: f64,
    /// Rated torque [N m] (0x6076 default, in mN m).
    pub rated_torque_nm: f64,
    /// Encoder increments per motor revolution (0x6064 / 0x606C scaling).
    pub encoder_increments_per_rev: u32,
    /// 0x1017 default [ms].
    pub heartbeat_producer_ms: u16,
    /// 0x1016:1 default, `(master << 16) | ms`.
    pub heartbeat_consumer: u32,
    /// Quick stop torque ramp [N m/s].
    pub quick_stop_slope_nm_per_s: f64,
    /// Torque and speed limits.
    pub limits: LimitConfig,
    /// CSV/CSP velocity PI: proportional gain [N m s/rad].
    pub velocity_kp: f64,
    /// CSV/CSP velocity PI: integral gain [N m/rad].
    pub velocity_ki: f64,
    /// CSP position loop gain [1/s].
    pub position_kp: f64,
    /// Lock-step or real time.
    pub clock: ClockMode,
    /// SYNC-loss supervision: communication cycle periods (0x1006) without SYNC in
    /// Operation enabled that fault the drive (0: off).
    pub sync_loss_cycles: u16,
}

impl DriveConfig {
    /// From a `[drive]` section, the cycle rate and the axis' total inertia [kg m^2].
    pub fn from_section(d: &DriveSection, cycle_hz: f64, total_inertia_kgm2: f64) -> Self {
        let wv = 2.0 * std::f64::consts::PI * d.velocity_loop_hz;
        Self {
            node_id: d.node_id,
            cycle_hz,
            rated_torque_nm: d.rated_torque_nm,
            encoder_increments_per_rev: d.encoder_increments_per_rev,
            heartbeat_producer_ms: d.heartbeat_producer_ms,
            heartbeat_consumer: if d.heartbeat_consumer_ms == 0 {
                0
            } else {
                (u32::from(d.master_node_id) << 16) | u32::from(d.heartbeat_consumer_ms)
            },
            quick_stop_slope_nm_per_s: d.quick_stop_slope_nm_per_s,
            limits: LimitConfig {
                peak_torque_nm: d.peak_torque_nm,
                max_speed_rad_s: d.max_speed_rad_s,
                continuous_torque_nm: d.continuous_torque_nm,
                i2t_time_constant_s: d.i2t_time_constant_s,
            },
            velocity_kp: total_inertia_kgm2 * wv,
            velocity_ki: total_inertia_kgm2 * wv * wv / 4.0,
            position_kp: 2.0 * std::f64::consts::PI * d.position_loop_hz,
            clock: ClockMode::LockStep,
            sync_loss_cycles: d.sync_loss_cycles,
        }
    }
}

/// Errors of the configuration layer (each names the file).
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{origin}: {source}")]
    Read {
        origin: String,
        #[source]
        source: std::io::Error,
    },
    /// Not TOML, or a field of `[drive]` is wrong.
    #[error("{origin}: {message}")]
    Parse { origin: String, message: String },
    /// The plant part (`[chain]`, `[measurement]`, ...) is wrong (flexid's message).
    #[error("{0}")]
    Plant(#[from] flexid_core::plant::PlantFileError),
    /// The plant's cycle rate is outside what a drive can run.
    #[error("{origin}: [measurement] sample_rate_hz = {fs_hz} must be in (0, 1e6]")]
    SampleRate { origin: String, fs_hz: f64 },
    /// A `[drive]` value is out of range.
    #[error("{origin}: [drive] {message}")]
    Drive { origin: String, message: String },
}

/// A plant file with its `[drive]` section.
#[derive(Debug, Clone)]
pub struct DrivePlant {
    /// The main crate's plant file.
    pub plant: PlantFile,
    /// The `[drive]` section (defaults when absent).
    pub drive: DriveSection,
}

impl DrivePlant {
    /// Parses a plant file's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let perr = |message: String| ConfigError::Parse {
            origin: origin.to_string(),
            message,
        };
        let mut table: toml::Table = toml::from_str(text).map_err(|e| perr(e.to_string()))?;
        let drive = match table.remove("drive") {
            None => DriveSection::default(),
            Some(v) => v
                .try_into::<DriveSection>()
                .map_err(|e| perr(format!("[drive] {e}")))?,
        };
        let rest = toml::to_string(&table).map_err(|e| perr(e.to_string()))?;
        let plant = PlantFile::parse(&rest, origin).map_err(ConfigError::Plant)?;
        let bad = |message: &str| {
            Err(ConfigError::Drive {
                origin: origin.to_string(),
                message: message.to_string(),
            })
        };
        let pos = |x: f64| x.is_finite() && x > 0.0;
        if !(1..=127).contains(&drive.node_id) {
            return bad("node_id must be 1..=127");
        }
        if !(1..=127).contains(&drive.master_node_id) {
            return bad("master_node_id must be 1..=127");
        }
        if !pos(drive.rated_torque_nm) || drive.rated_torque_nm * 1000.0 > u32::MAX as f64 {
            return bad("rated_torque_nm must be positive");
        }
        if !pos(drive.peak_torque_nm) {
            return bad("peak_torque_nm must be positive");
        }
        if !pos(drive.max_speed_rad_s) {
            return bad("max_speed_rad_s must be positive");
        }
        if drive.encoder_increments_per_rev == 0 {
            return bad("encoder_increments_per_rev must be positive");
        }
        if !pos(drive.quick_stop_slope_nm_per_s)
            || !pos(drive.i2t_time_constant_s)
            || !pos(drive.velocity_loop_hz)
            || !pos(drive.position_loop_hz)
            || drive.continuous_torque_nm.is_some_and(|t| !pos(t))
        {
            return bad(
                "slopes, time constants, loop bandwidths and continuous torque must be positive",
            );
        }
        let fs = plant.measurement.sample_rate_hz;
        if !pos(fs) || fs > 1e6 {
            return Err(ConfigError::SampleRate {
                origin: origin.to_string(),
                fs_hz: fs,
            });
        }
        Ok(Self { plant, drive })
    }

    /// Reads a plant file, or the embedded default (`plants/scara_shoulder.toml`).
    pub fn load(path: Option<&Path>) -> Result<Self, ConfigError> {
        match path {
            None => Self::parse(DEFAULT_PLANT, "embedded default plant"),
            Some(p) => {
                let origin = p.display().to_string();
                let text = std::fs::read_to_string(p).map_err(|source| ConfigError::Read {
                    origin: origin.clone(),
                    source,
                })?;
                Self::parse(&text, &origin)
            }
        }
    }

    /// The drive configuration (cycle rate from `[measurement] sample_rate_hz`).
    pub fn drive_config(&self) -> DriveConfig {
        DriveConfig::from_section(
            &self.drive,
            self.plant.measurement.sample_rate_hz,
            self.plant.chain.total_inertia(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_plant_has_default_drive() {
        let p = DrivePlant::load(None).unwrap();
        assert_eq!(p.drive, DriveSection::default());
        assert_eq!(p.plant.chain.masses(), 3);
        assert_eq!(p.drive_config().cycle_hz, 2000.0);
    }

    #[test]
    fn drive_section_is_read_and_checked() {
        let text = format!("{DEFAULT_PLANT}\n[drive]\nnode_id = 9\npeak_torque_nm = 2.5\n");
        let p = DrivePlant::parse(&text, "x.toml").unwrap();
        assert_eq!((p.drive.node_id, p.drive.peak_torque_nm), (9, 2.5));
        let bad = format!("{DEFAULT_PLANT}\n[drive]\nnode_id = 0\n");
        let e = DrivePlant::parse(&bad, "x.toml").unwrap_err().to_string();
        assert!(e.contains("x.toml") && e.contains("node_id"), "{e}");
        let unknown = format!("{DEFAULT_PLANT}\n[drive]\nnode = 3\n");
        assert!(DrivePlant::parse(&unknown, "x.toml").is_err());
        let chain =
            "[chain]\ninertia_kgm2 = [-1.0]\nstiffness_nm_per_rad = []\ndamping_nms_per_rad = []\n";
        assert!(matches!(
            DrivePlant::parse(chain, "c.toml"),
            Err(ConfigError::Plant(_))
        ));
    }
}
