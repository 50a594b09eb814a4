//! Plant files (TOML): the chain and how it is measured, for `flexid simulate` and the demo.

use crate::model::Chain;
use crate::sim::SimOptions;
use serde::Deserialize;
use std::path::Path;

/// The embedded default plant (`plants/scara_shoulder.toml`).
pub const DEFAULT_PLANT: &str = include_str!("../../plants/scara_shoulder.toml");

/// A plant file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantFile {
    #[serde(default)]
    pub name: Option<String>,
    pub chain: Chain,
    #[serde(default)]
    pub measurement: Measurement,
    /// The `[drive]` section of `flexid-vdrive` (the simulated CiA 402 drive in front of
    /// the plant: node, rated torque, limits, encoder); read and checked by flexid-vdrive,
    /// carried along here.
    #[serde(default)]
    pub drive: Option<toml::Table>,
}

/// How the plant is measured.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Measurement {
    pub sample_rate_hz: f64,
    pub delay_samples: u32,
    pub encoder_counts_per_rev: Option<u64>,
    pub velocity_noise_rel: f64,
    pub torque_noise_nm: f64,
    pub initial_velocity_rad_s: f64,
}

impl Default for Measurement {
    fn default() -> Self {
        Measurement {
            sample_rate_hz: 2000.0,
            delay_samples: 0,
            encoder_counts_per_rev: None,
            velocity_noise_rel: 0.0,
            torque_noise_nm: 0.0,
            initial_velocity_rad_s: 0.0,
        }
    }
}

impl PlantFile {
    /// Parse a plant file's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, String> {
        let p: PlantFile = toml::from_str(text).map_err(|e| format!("{origin}: {e}"))?;
        p.chain
            .validate()
            .map_err(|e| format!("{origin}: [chain] {e}"))?;
        Ok(p)
    }

    /// Read a plant file, or the embedded default when `path` is `None`.
    pub fn load(path: Option<&Path>) -> Result<Self, String> {
        match path {
            None => Self::parse(DEFAULT_PLANT, "embedded default plant"),
            Some(p) => {
                let text =
                    std::fs::read_to_string(p).map_err(|e| format!("{}: {e}", p.display()))?;
                Self::parse(&text, &p.display().to_string())
            }
        }
    }

    /// Simulation options from the measurement section, with a noise seed.
    pub fn sim_options(&self, seed: u64) -> SimOptions {
        let m = &self.measurement;
        SimOptions {
            sample_rate_hz: m.sample_rate_hz,
            delay_samples: m.delay_samples,
            velocity_noise_rel: m.velocity_noise_rel,
            torque_noise_nm: m.torque_noise_nm,
            encoder_counts_per_rev: m.encoder_counts_per_rev,
            initial_velocity_rad_s: m.initial_velocity_rad_s,
            seed,
        }
    }
}
