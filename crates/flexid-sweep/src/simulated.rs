//! A CAN-free drive: a physics model (by default the exact ZOH simulation of a chain)
//! behind [`CyclicDrive`], for the daemon's simulated axes, the tests of the sweep logic
//! and the demo when no bus can be used.

use flexid_canopen::cia402::State;
use flexid_canopen::{Counters, CyclicDrive, Feedback};
use flexid_core::model::{Chain, ModelError};
use flexid_core::plant::physics::{LinearChain, Physics, PhysicsError, TorqueNoise};
use flexid_core::plant::{PlantFile, PlantSim, PlantSpec};
use std::time::{Duration, Instant};

/// A fault injected into a [`SimulatedDrive`] (an EMCY as a real drive would send).
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("simulated drive: EMCY {code:#06x} ({text}) at cycle {cycle}")]
pub struct SimulatedFault {
    /// The cycle at which it happened.
    pub cycle: u64,
    /// The emergency error code.
    pub code: u16,
    /// Its class.
    pub text: &'static str,
}

/// An enabled drive in CST in front of a [`Physics`] model: by default the exact ZOH
/// simulation of a chain (as `flexid_core::sim`), or any model ([`SimulatedDrive::on`]:
/// the nonlinear plant, a disturbance torque, ...). The feedback of cycle k is the state
/// before torque k acts; the torque actual is the one held during the previous cycle. No
/// allocation per cycle.
pub struct SimulatedDrive {
    physics: Box<dyn Physics>,
    period: Duration,
    rated_torque_nm: f64,
    increments_per_rev: Option<f64>,
    last_torque: f64,
    counters: Counters,
    fault_at: Option<u64>,
}

impl std::fmt::Debug for SimulatedDrive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulatedDrive")
            .field("period", &self.period)
            .field("increments_per_rev", &self.increments_per_rev)
            .field("counters", &self.counters)
            .finish_non_exhaustive()
    }
}

impl SimulatedDrive {
    /// A drive on `chain` cycling at `cycle_hz`, at rest, rated torque 1 N m, exact
    /// position (no encoder quantisation).
    pub fn new(chain: &Chain, cycle_hz: f64) -> Result<Self, ModelError> {
        if !(cycle_hz.is_finite() && cycle_hz > 0.0) {
            return Err(ModelError::SampleRate { fs_hz: cycle_hz });
        }
        let physics = LinearChain::new(chain, cycle_hz).map_err(|e| match e {
            PhysicsError::Chain(m) => m,
            _ => ModelError::SampleRate { fs_hz: cycle_hz },
        })?;
        Ok(Self::on(Box::new(physics), cycle_hz))
    }

    /// A drive in front of `physics`, stepped at `cycle_hz` [Hz] (the rate `physics` was
    /// built for), rated torque 1 N m, the position as `physics` samples it.
    pub fn on(physics: Box<dyn Physics>, cycle_hz: f64) -> Self {
        SimulatedDrive {
            physics,
            period: Duration::from_secs_f64(1.0 / cycle_hz),
            rated_torque_nm: 1.0,
            increments_per_rev: None,
            last_torque: 0.0,
            counters: Counters::default(),
            fault_at: None,
        }
    }

    /// Quantise the position as an encoder with this many increments per revolution.
    pub fn with_encoder(mut self, increments_per_rev: f64) -> Self {
        self.increments_per_rev = Some(increments_per_rev);
        self
    }

    /// Fail with an EMCY (0x8400, velocity) at cycle `cycle` (0-based): that cycle
    /// returns the error, as a CANopen drive's EMCY does.
    pub fn fault_at(mut self, cycle: u64) -> Self {
        self.fault_at = Some(cycle);
        self
    }
}

impl CyclicDrive for SimulatedDrive {
    type Error = SimulatedFault;

    fn cycle(&mut self, torque_nm: f64, _deadline: Instant) -> Result<Feedback, SimulatedFault> {
        let cycle = self.counters.cycles;
        if self.fault_at == Some(cycle) {
            return Err(SimulatedFault {
                cycle,
                code: 0x8400,
                text: "velocity speed controller (simulated)",
            });
        }
        let sync_time = Instant::now();
        let sample = self.physics.sample();
        let mut position = sample.position_rad;
        if let Some(inc) = self.increments_per_rev {
            let q = std::f64::consts::TAU / inc;
            position = (position / q).round() * q;
        }
        let velocity = sample.velocity_rad_s;
        self.physics.step(torque_nm);
        let actual = self.last_torque;
        self.last_torque = torque_nm;
        self.counters.cycles += 1;
        Ok(Feedback {
            cycle,
            sync_time,
            statusword: 0x0027,
            state: Some(State::OperationEnabled),
            position_rad: position,
            velocity_rad_s: velocity,
            torque_nm: actual,
            torque_setpoint_nm: torque_nm,
            saturated: false,
            fresh: true,
            drive_cycle: None,
            counters: self.counters,
        })
    }

    fn cycle_period(&self) -> Duration {
        self.period
    }

    fn rated_torque_nm(&self) -> f64 {
        self.rated_torque_nm
    }

    fn counters(&self) -> Counters {
        self.counters
    }
}

/// A plant to put behind a [`SimulatedDrive`]: the chain, the plant file's disturbance
/// torque, encoder and initial drift, and its unmodelled effects when it has any. The
/// daemon's simulated axes and the demo without a bus measure through it.
#[derive(Debug, Clone)]
pub struct SimulatedPlant {
    /// The chain (the linear part).
    pub chain: Chain,
    /// RMS of a white disturbance torque [N m] (the linear path; with effects, the spec
    /// carries it).
    pub torque_noise_nm: f64,
    /// Encoder resolution [counts/rev]; `None` for an ideal encoder (the linear path).
    pub encoder_counts_per_rev: Option<u64>,
    /// Velocity of every body at the start [rad/s].
    pub initial_velocity_rad_s: f64,
    /// The plant with its effects and the RK4 sub-steps per cycle, simulated by
    /// [`PlantSim`] instead of the exact linear chain. `None`: the linear chain.
    pub effects: Option<(PlantSpec, u32)>,
}

impl SimulatedPlant {
    /// The exact linear chain, ideal encoder, no noise.
    pub fn linear(chain: Chain) -> Self {
        SimulatedPlant {
            chain,
            torque_noise_nm: 0.0,
            encoder_counts_per_rev: None,
            initial_velocity_rad_s: 0.0,
            effects: None,
        }
    }

    /// The plant of a plant file: its chain, measurement noise torque, encoder, initial
    /// velocity and effects.
    pub fn of_file(p: &PlantFile) -> Self {
        SimulatedPlant {
            chain: p.chain.clone(),
            torque_noise_nm: p.measurement.torque_noise_nm,
            encoder_counts_per_rev: p.measurement.encoder_counts_per_rev,
            initial_velocity_rad_s: p.measurement.initial_velocity_rad_s,
            effects: p.has_effects().then(|| (p.spec(), p.substeps())),
        }
    }

    /// The drive in front of this plant at `cycle_hz` [Hz], noise seed `seed`.
    pub fn drive(&self, cycle_hz: f64, seed: u64) -> Result<SimulatedDrive, PhysicsError> {
        if let Some((spec, substeps)) = &self.effects {
            let mut sim = PlantSim::new(spec, cycle_hz, *substeps, seed)
                .map_err(|e| PhysicsError::Plant(e.to_string()))?;
            sim.set_initial_velocity(self.initial_velocity_rad_s);
            return Ok(SimulatedDrive::on(Box::new(sim), cycle_hz));
        }
        let mut chain = LinearChain::new(&self.chain, cycle_hz)?;
        chain.set_velocity(self.initial_velocity_rad_s);
        let noisy = TorqueNoise::new(chain, self.torque_noise_nm, seed);
        let drive = SimulatedDrive::on(Box::new(noisy), cycle_hz);
        Ok(match self.encoder_counts_per_rev {
            Some(c) => drive.with_encoder(c as f64),
            None => drive,
        })
    }
}
