//! Plant files (TOML): the chain, how it is measured, and optional effects, for
//! `flexid simulate` and the demo.

use super::{Effects, PlantError, PlantFileError, PlantSpec, TimeDelay};
use crate::model::Chain;
use crate::sim::SimOptions;
use serde::Deserialize;

/// The embedded default plant (`plants/scara_shoulder.toml`).
pub const DEFAULT_PLANT: &str = include_str!("../../../../plants/scara_shoulder.toml");

/// Integration sub-steps per sample used when a plant file has effects and does not say.
pub const DEFAULT_SUBSTEPS: u32 = 20;

/// A plant file: `name`, `[chain]`, `[measurement]`, and optionally `[effects]` (see
/// [`Effects`]; a file without it is the linear chain, simulated exactly under ZOH).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlantFile {
    /// A human-readable name.
    #[serde(default)]
    pub name: Option<String>,
    /// The chain (body 1 = motor).
    pub chain: Chain,
    /// How the plant is measured.
    #[serde(default)]
    pub measurement: Measurement,
    /// Unmodelled effects; all off when the section is absent.
    #[serde(default)]
    pub effects: Effects,
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
    /// Sample (drive cycle) rate [Hz].
    pub sample_rate_hz: f64,
    /// Whole samples between a set-point and its application (recorded in the sidecar).
    pub delay_samples: u32,
    /// Encoder resolution [counts/rev]; `None` = ideal.
    pub encoder_counts_per_rev: Option<u64>,
    /// White noise on the differenced velocity, relative to its RMS [-].
    pub velocity_noise_rel: f64,
    /// RMS of a white disturbance torque on the motor [N m], one draw per sample.
    pub torque_noise_nm: f64,
    /// Initial velocity of the whole chain [rad/s].
    pub initial_velocity_rad_s: f64,
    /// Integration sub-steps per sample when the file has `[effects]` (default
    /// [`DEFAULT_SUBSTEPS`]); unused for a purely linear plant (exact ZOH).
    pub substeps: Option<u32>,
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
            substeps: None,
        }
    }
}

impl PlantFile {
    /// Parse a plant file's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, PlantFileError> {
        let origin = || origin.to_string();
        let p: PlantFile = toml::from_str(text).map_err(|source| PlantFileError::Syntax {
            origin: origin(),
            source,
        })?;
        p.chain.validate().map_err(|source| PlantFileError::Chain {
            origin: origin(),
            source,
        })?;
        let m = &p.measurement;
        for (key, value, ok, requirement) in [
            (
                "sample_rate_hz",
                m.sample_rate_hz,
                m.sample_rate_hz.is_finite() && m.sample_rate_hz > 0.0,
                "must be positive and finite",
            ),
            (
                "velocity_noise_rel",
                m.velocity_noise_rel,
                m.velocity_noise_rel.is_finite() && m.velocity_noise_rel >= 0.0,
                "must be zero or positive",
            ),
            (
                "torque_noise_nm",
                m.torque_noise_nm,
                m.torque_noise_nm.is_finite() && m.torque_noise_nm >= 0.0,
                "must be zero or positive",
            ),
            (
                "initial_velocity_rad_s",
                m.initial_velocity_rad_s,
                m.initial_velocity_rad_s.is_finite(),
                "must be finite",
            ),
        ] {
            if !ok {
                return Err(PlantFileError::Measurement {
                    origin: origin(),
                    key,
                    value,
                    requirement,
                });
            }
        }
        p.spec()
            .validate()
            .map_err(|source| PlantFileError::Plant {
                origin: origin(),
                source,
            })?;
        if p.measurement.substeps == Some(0) {
            return Err(PlantFileError::Substeps { origin: origin() });
        }
        Ok(p)
    }

    /// Whether the file has any effect (then it is simulated by [`super::PlantSim`]).
    pub fn has_effects(&self) -> bool {
        self.effects.any()
    }

    /// Simulation options from the measurement section, with a noise seed (the exact
    /// linear path).
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

    /// The plant as simulated: chain and effects, with the measurement section folded in
    /// (its `delay_samples` added to the time delay, its torque noise combined with the
    /// effects' in quadrature, its encoder used when the effects name none).
    pub fn spec(&self) -> PlantSpec {
        let m = &self.measurement;
        let mut effects = self.effects.clone();
        if m.delay_samples > 0 {
            let extra = f64::from(m.delay_samples) / m.sample_rate_hz;
            let d = effects.time_delay.get_or_insert(TimeDelay { delay_s: 0.0 });
            d.delay_s += extra;
        }
        effects.torque_noise_nm = effects.torque_noise_nm.hypot(m.torque_noise_nm);
        effects.encoder_counts_per_rev =
            effects.encoder_counts_per_rev.or(m.encoder_counts_per_rev);
        PlantSpec {
            chain: self.chain.clone(),
            effects,
        }
    }

    /// Sub-steps per sample for [`super::PlantSim`].
    pub fn substeps(&self) -> u32 {
        self.measurement.substeps.unwrap_or(DEFAULT_SUBSTEPS)
    }
}

/// Simulated motor positions [rad] (one per sample of `torque_nm` [N m]) of a plant file
/// with effects: [`super::PlantSim`] at the file's sample rate and sub-steps, the initial
/// velocity, then the measurement's velocity noise and encoder quantisation, in that order
/// (as [`crate::sim::simulate_position`]).
pub fn simulate_file_positions(
    file: &PlantFile,
    torque_nm: &[f64],
    seed: u64,
) -> Result<Vec<f64>, PlantError> {
    let mut spec = file.spec();
    let counts = spec.effects.encoder_counts_per_rev.take();
    let mut sim = super::PlantSim::new(
        &spec,
        file.measurement.sample_rate_hz,
        file.substeps(),
        seed,
    )?;
    sim.set_initial_velocity(file.measurement.initial_velocity_rad_s);
    let mut pos: Vec<f64> = super::run(&mut sim, torque_nm)
        .map(|s| s.position_rad)
        .collect();
    let mut rng =
        <rand::rngs::StdRng as rand::SeedableRng>::seed_from_u64(seed ^ 0x9e37_79b9_7f4a_7c15);
    crate::sim::add_velocity_noise(
        &mut pos,
        file.measurement.velocity_noise_rel,
        file.measurement.sample_rate_hz,
        &mut rng,
    );
    if let Some(c) = counts {
        crate::sim::quantise(&mut pos, c);
    }
    Ok(pos)
}
