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
use flexid_core::plant::physics::{LinearChain, TorqueNoise};
use flexid_core::plant::PlantSim;
use flexid_sweep::SimulatedDrive;

/// The simulated backend: every axis is the same chain.
#[derive(Debug, Clone)]
pub struct SimBackend {
    chain: Chain,
    /// RMS of a white disturbance torque [N m].
    pub torque_noise_nm: f64,
    /// Encoder resolution [counts/rev]; `None` for an ideal encoder.
    pub encoder_counts_per_rev: Option<u64>,
    /// Name of the plant, for the sidecar's `source`.
    pub name: String,
    /// The plant with its unmodelled effects (noise and encoder folded in) and the RK4
    /// sub-steps per cycle: simulated by [`flexid_core::plant::PlantSim`] instead of the exact
    /// linear chain. `None`: the linear chain.
    pub effects: Option<(flexid_core::plant::PlantSpec, u32)>,
}

impl SimBackend {
    /// A backend simulating `chain` (validated) with an ideal encoder and no noise.
    pub fn new(chain: Chain, name: &str) -> Result<Self, BackendError> {
        chain.validate().map_err(|e| BackendError::Unavailable {
            axis: "*".into(),
            reason: format!("simulated plant: {e}"),
        })?;
        Ok(SimBackend {
            chain,
            torque_noise_nm: 0.0,
            encoder_counts_per_rev: None,
            name: name.into(),
            effects: None,
        })
    }

    /// A backend for a plant file (the embedded SCARA shoulder when `None`), with its
    /// torque noise and encoder.
    pub fn from_plant_file(
        path: Option<&std::path::Path>,
    ) -> Result<Self, flexid_files::plant::LoadPlantError> {
        let p = flexid_files::plant::load_plant_file(path)?;
        // the chain was validated with the file: `new` cannot refuse it
        let mut b = SimBackend {
            chain: p.chain.clone(),
            torque_noise_nm: 0.0,
            encoder_counts_per_rev: None,
            name: p.name.clone().unwrap_or_else(|| "plant file".into()),
            effects: None,
        };
        b.torque_noise_nm = p.measurement.torque_noise_nm;
        b.encoder_counts_per_rev = p.measurement.encoder_counts_per_rev;
        if p.has_effects() {
            b.effects = Some((p.spec(), p.substeps()));
        }
        Ok(b)
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
            .drive(plan.sample_rate_hz)
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

impl SimBackend {
    /// The CAN-free simulated drive of this plant at `cycle_hz`: the plant with its effects
    /// ([`PlantSim`], noise and encoder folded in), or the exact linear chain with the
    /// disturbance torque and the encoder. Noise seed `0x5eed`.
    fn drive(&self, cycle_hz: f64) -> Result<SimulatedDrive, String> {
        const SEED: u64 = 0x5eed;
        if let Some((spec, substeps)) = &self.effects {
            let sim = PlantSim::new(spec, cycle_hz, *substeps, SEED).map_err(|e| e.to_string())?;
            return Ok(SimulatedDrive::on(Box::new(sim), cycle_hz));
        }
        let chain = LinearChain::new(&self.chain, cycle_hz).map_err(|e| e.to_string())?;
        let noisy = TorqueNoise::new(chain, self.torque_noise_nm, SEED);
        let drive = SimulatedDrive::on(Box::new(noisy), cycle_hz);
        Ok(match self.encoder_counts_per_rev {
            Some(c) => drive.with_encoder(c as f64),
            None => drive,
        })
    }
}
