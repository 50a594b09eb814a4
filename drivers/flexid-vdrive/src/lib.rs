//! flexid-vdrive: a simulated CiA 402 servo drive — a CANopen slave (CiA 301 through
//! canopen-rs, CiA 402 by hand) in front of a physics model of a compliant axis.
//!
//! * [`physics`]: the [`Physics`] trait (sample / step one cycle under ZOH) and
//!   [`LinearChain`], the exact discretisation of `flexid_core::model::StateSpace`.
//! * [`od`]: the object dictionary (CiA 301 communication objects, CiA 402 objects).
//! * [`slave`]: the CiA 301 slave on canopen-rs's `Node`, plus what it lacks.
//! * [`cia402`]: the CiA 402 device state machine and statusword.
//! * [`limits`]: torque clamp, overspeed and i²t faults, EMCY codes.
//! * [`heartbeat`]: heartbeat producer and consumer timers.
//! * [`sync_watch`]: SYNC-loss supervision.
//! * [`drive`]: the sans-I/O core [`VirtualDrive`] (`on_frame`, `on_sync`, `tick`, time
//!   injected).
//! * [`node`]: [`BusNode`], what a runner serves: one drive, or a [`DriveSet`] of drives
//!   on one bus.
//! * [`robot`]: a whole robot, one drive per axis, sharing one coupled multi-axis plant
//!   (the linearised flexible manipulator of `flexid_core::manipulator`).
//! * [`runner`]: the blocking [`Runner`] over any `flexid_can::CanBus`.
//! * [`config`]: the plant file's `[drive]` section and [`DriveConfig`].
//! * `ethercat` (Linux): the same plant behind emulated EtherCAT SubDevices (flexid-ecat's
//!   ESC and CiA 402 servo), served on a network interface (`--ethercat IFACE`).

pub mod cia402;
pub mod config;
pub mod drive;
#[cfg(target_os = "linux")]
pub mod ethercat;
pub mod heartbeat;
pub mod limits;
pub mod node;
pub mod od;
pub mod physics;
pub mod robot;
pub mod runner;
pub mod slave;
pub mod sync_watch;

pub use cia402::State;
pub use config::{ClockMode, ConfigError, DriveConfig, DrivePlant, DriveSection};
pub use drive::{DriveError, DriveStats, Outputs, VirtualDrive};
pub use limits::FaultKind;
pub use node::{BusNode, DriveSet};
pub use physics::{AxisSample, LinearChain, Physics, PhysicsError};
pub use runner::{RunError, Runner};

/// A drive in front of the linear chain of a plant file, with `clock`.
pub fn linear_drive(
    plant: &DrivePlant,
    clock: ClockMode,
) -> Result<VirtualDrive<LinearChain>, BuildError> {
    let mut cfg = plant.drive_config();
    cfg.clock = clock;
    let mut chain = LinearChain::new(&plant.plant.chain, cfg.cycle_hz)?;
    chain.set_velocity(plant.plant.measurement.initial_velocity_rad_s);
    Ok(VirtualDrive::new(cfg, chain)?)
}

/// A drive in front of the plant file's physics, boxed: with an `[effects]` section, the main crate's nonlinear `flexid_core::plant::PlantSim` (noise seeded
/// by `seed`); otherwise the exact [`LinearChain`].
pub fn plant_drive(
    plant: &DrivePlant,
    clock: ClockMode,
    seed: u64,
) -> Result<VirtualDrive<Box<dyn Physics>>, BuildError> {
    let mut cfg = plant.drive_config();
    cfg.clock = clock;
    if plant.plant.has_effects() {
        let sim = physics::PlantSimPhysics::new(
            plant.plant.spec(),
            cfg.cycle_hz,
            plant.plant.substeps(),
            seed,
            plant.plant.measurement.initial_velocity_rad_s,
        )?;
        return Ok(VirtualDrive::new(cfg, Box::new(sim) as Box<dyn Physics>)?);
    }
    let _ = seed; // the linear chain is noise-free
    let mut chain = LinearChain::new(&plant.plant.chain, cfg.cycle_hz)?;
    chain.set_velocity(plant.plant.measurement.initial_velocity_rad_s);
    Ok(VirtualDrive::new(cfg, Box::new(chain) as Box<dyn Physics>)?)
}

/// Errors building a drive from a plant file.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The physics could not be built.
    #[error("physics: {0}")]
    Physics(#[from] PhysicsError),
    /// The drive could not be built.
    #[error("drive: {0}")]
    Drive(#[from] DriveError),
}
