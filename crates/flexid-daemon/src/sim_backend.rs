//! A simulated [`AxisBackend`]: the plan's torque drives a chain (exact ZOH state space,
//! torque noise, encoder quantisation; or, for a plant file with an `[effects]` section,
//! [`flexid_core::plant::PlantSim`] with every effect) behind the sweep library's CAN-free
//! [`SimulatedDrive`], run by the same sweep loop as the CANopen backend
//! ([`DriveJob::run_on`]) on a thread of its own, in real time (`clock = "monotonic"`)
//! or as fast as possible (`clock = "simulated"`): the same events, limits, abort
//! behaviour and recording.

use super::backend::{AxisBackend, BackendError, SweepHandle, SweepPlan};
use super::config::AxisConfig;
use super::drive_sweep::DriveJob;
use flexid_core::model::Chain;
use flexid_sweep::SimulatedPlant;

/// The seed of the simulated plant's noise (the same on every sweep).
const NOISE_SEED: u64 = 0x5eed;

/// The simulated backend: every axis is the same plant.
#[derive(Debug, Clone)]
pub struct SimBackend {
    /// The plant behind every axis (chain, disturbance torque, encoder, effects).
    pub plant: SimulatedPlant,
    /// Name of the plant, for the sidecar's `source`.
    pub name: String,
}

impl SimBackend {
    /// A backend simulating `chain` (validated) with an ideal encoder and no noise.
    pub fn new(chain: Chain, name: &str) -> Result<Self, BackendError> {
        chain.validate().map_err(|e| BackendError::Unavailable {
            axis: "*".into(),
            reason: format!("simulated plant: {e}"),
        })?;
        Ok(SimBackend {
            plant: SimulatedPlant::linear(chain),
            name: name.into(),
        })
    }

    /// A backend for a plant file (the embedded SCARA shoulder when `None`), with its
    /// torque noise, encoder and effects.
    pub fn from_plant_file(
        path: Option<&std::path::Path>,
    ) -> Result<Self, flexid_files::plant::LoadPlantError> {
        let p = flexid_files::plant::load_plant_file(path)?;
        Ok(SimBackend {
            plant: SimulatedPlant::of_file(&p),
            name: p.name.clone().unwrap_or_else(|| "plant file".into()),
        })
    }
}

impl AxisBackend for SimBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        if (plan.sample_rate_hz - axis.cycle_hz).abs() > 1e-9 * axis.cycle_hz {
            return Err(BackendError::Plan {
                axis: axis.name.clone(),
                reason: format!(
                    "planned at {} Hz, the axis cycles at {} Hz",
                    plan.sample_rate_hz, axis.cycle_hz
                ),
            });
        }
        let drive = self
            .plant
            .drive(plan.sample_rate_hz, NOISE_SEED)
            .map_err(|e| BackendError::Plan {
                axis: axis.name.clone(),
                reason: format!("simulated plant: {e}"),
            })?;
        let (mut job, handle) = DriveJob::plan(axis, plan)?;
        let source = format!("simulated: {} (daemon sim backend)", self.name);
        DriveJob::spawn(format!("sim-{}", axis.name), &axis.name, move || {
            job.run_on(drive, source, |_| {})
        })?;
        Ok(handle)
    }
}
