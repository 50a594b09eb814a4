//! A simulated robot on an in-process CAN bus: `flexid-vdrive`'s drives of a flexible
//! robot at one pose (one node per axis, one coupled plant), served on a thread of their
//! own, and the CANopen master's group of those drives brought up and enabled over the
//! bus: the whole multi-axis path (CiA 301/402 frames, one SYNC per cycle) without
//! hardware.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;

use flexid_can::InprocBus;
use flexid_canopen::{bring_up, DriveGroup, MasterConfig, MasterError, ProfileSet};
use flexid_core::manipulator::{Flexibilities, FlexibleRobot};
use flexid_vdrive::robot::{robot_drives, RobotBuildError, RobotDriveOptions};
use flexid_vdrive::{RunError, Runner};

/// Errors starting a simulated robot or its master.
#[derive(Debug, thiserror::Error)]
pub enum SimRobotError {
    /// The robot's drives could not be built (pose, springs, node ids).
    #[error("simulated robot: {0}")]
    Build(#[from] RobotBuildError),
    /// The master could not bring a drive up or enable it.
    #[error("simulated robot: {0}")]
    Master(#[from] MasterError),
    /// The drives' thread could not be started.
    #[error("simulated robot: thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// The drives of a simulated robot, served on their own thread until dropped.
pub struct SimulatedRobot {
    bus: InprocBus,
    nodes: Vec<u8>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<Result<(), RunError>>>,
}

impl SimulatedRobot {
    /// `robot`'s drives at joint angles `q_rad` [rad] with springs `theta`, on a fresh
    /// in-process bus named `name`.
    pub fn start(
        name: &str,
        robot: &FlexibleRobot,
        q_rad: &[f64],
        theta: &Flexibilities,
        opts: &RobotDriveOptions,
    ) -> Result<Self, SimRobotError> {
        let (set, _plant) = robot_drives(robot, q_rad, theta, opts)?;
        let nodes = set.node_ids();
        let bus = InprocBus::new(name);
        let h = bus.handle();
        let stop = Arc::new(AtomicBool::new(false));
        let s2 = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name(format!("vdrive-{name}"))
            .spawn(move || Runner::new(h, set).run(&s2))?;
        Ok(Self {
            bus,
            nodes,
            stop,
            thread: Some(thread),
        })
    }

    /// The drives' node ids, axis by axis.
    pub fn nodes(&self) -> &[u8] {
        &self.nodes
    }

    /// The master's group over the bus: every drive booted, configured as `cfg` says
    /// (its node id replaced) and enabled in cyclic synchronous torque.
    pub fn enable_group(&self, cfg: &MasterConfig) -> Result<DriveGroup<InprocBus>, SimRobotError> {
        let profiles = ProfileSet::builtin();
        let drives = self
            .nodes
            .iter()
            .map(|&node| {
                let c = MasterConfig {
                    node,
                    ..cfg.clone()
                };
                bring_up(self.bus.handle(), c, &profiles)
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(DriveGroup::enable(drives)?)
    }
}

impl Drop for SimulatedRobot {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            match t.join() {
                Ok(Ok(())) => {}
                Ok(Err(e)) => tracing::warn!("simulated robot: {e}"),
                Err(_) => tracing::warn!("simulated robot: the drives' thread panicked"),
            }
        }
    }
}
