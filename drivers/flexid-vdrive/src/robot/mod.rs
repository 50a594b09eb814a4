//! A whole robot on one bus: one simulated CiA 402 drive per axis (node ids
//! `first_node ..`), all in front of one coupled plant, the flexible manipulator of
//! `flexid_core::manipulator` linearised at a pose ([`RobotPlant`]). Each SYNC advances
//! the plant once with every axis's torque, so the master sees the coupling between axes
//! exactly as on a real arm: a torque on axis 1 moves motor 2.
//!
//! The plant is the linearisation about the pose with everything at rest: the static
//! holding torque is not part of it (the drives report deviations from the pose, from
//! position 0), and gravity enters as the pose's gravity stiffness, which makes most
//! poses unstable without a position loop (`../shared/design/multiaxis.md`, fact 1). The
//! master must hold the arm: the multi-axis sweep runs a low-bandwidth position loop
//! around the excitation.

mod plant;

pub use plant::{CoupledAxis, RobotPlant, SharedPlant, QUEUE};

use std::path::Path;

use flexid_core::manipulator::{FlexFile, Flexibilities, FlexibleRobot, ManipulatorError};

use crate::config::{ClockMode, DriveConfig, DriveSection};
use crate::drive::{DriveError, VirtualDrive};
use crate::node::DriveSet;

/// How the robot's drives are set up.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotDriveOptions {
    /// Node id of axis 1; axis `i` (from 0) is `first_node + i`.
    pub first_node: u8,
    /// Cycle (SYNC) rate [Hz] until the master writes 0x1006.
    pub cycle_hz: f64,
    /// Lock-step or real time.
    pub clock: ClockMode,
    /// The drives' settings (node id ignored): rated and peak torque, encoder, speed
    /// limit, heartbeats, SYNC-loss supervision.
    pub drive: DriveSection,
}

impl Default for RobotDriveOptions {
    /// Nodes 2.., 1 kHz, lock-step, a 1 N m rated torque (the set-point's 1 mN m step)
    /// with a 10 N m peak (a multisine of 0.6 N m RMS with the holding loop's torque
    /// stays far below it), a 20-bit encoder.
    fn default() -> Self {
        Self {
            first_node: 2,
            cycle_hz: 1000.0,
            clock: ClockMode::LockStep,
            drive: DriveSection {
                rated_torque_nm: 1.0,
                peak_torque_nm: 10.0,
                ..DriveSection::default()
            },
        }
    }
}

/// Errors building a robot's drives.
#[derive(Debug, thiserror::Error)]
pub enum RobotBuildError {
    /// The pose or the springs do not make a plant.
    #[error("robot {robot}: {source}")]
    Model {
        robot: String,
        #[source]
        source: ManipulatorError,
    },
    /// The node ids do not fit 1..=127.
    #[error("robot {robot}: {axes} axes from node {first_node} leave the node-id range 1..=127")]
    NodeIds {
        robot: String,
        axes: usize,
        first_node: u8,
    },
    /// A drive could not be built.
    #[error("robot {robot}: {source}")]
    Drive {
        robot: String,
        #[source]
        source: DriveError,
    },
}

/// The drives of `robot` at joint angles `q_rad` [rad] with the springs `theta`, and
/// their shared plant.
pub fn robot_drives(
    robot: &FlexibleRobot,
    q_rad: &[f64],
    theta: &Flexibilities,
    opts: &RobotDriveOptions,
) -> Result<(DriveSet<CoupledAxis>, SharedPlant), RobotBuildError> {
    let model = |source| RobotBuildError::Model {
        robot: robot.name.clone(),
        source,
    };
    let axes = robot.axes();
    if opts.first_node == 0 || usize::from(opts.first_node) + axes - 1 > 127 {
        return Err(RobotBuildError::NodeIds {
            robot: robot.name.clone(),
            axes,
            first_node: opts.first_node,
        });
    }
    let pose = robot.pose(q_rad).map_err(model)?;
    let plant = RobotPlant::new(pose.clone(), theta.clone(), opts.cycle_hz).map_err(model)?;
    let mut drives = Vec::with_capacity(axes);
    for (i, motor) in pose.motors.iter().enumerate() {
        // the axis's rigid inertia at the motor (only CSV/CSP gains use it)
        let j = robot.joint_coord[i];
        let r2 = motor.gear_ratio * motor.gear_ratio;
        let inertia = (pose.arm_mass[(j, j)] + motor.arm_side_inertia_kgm2()) / r2;
        let section = DriveSection {
            node_id: opts.first_node + i as u8,
            ..opts.drive.clone()
        };
        let mut cfg = DriveConfig::from_section(&section, opts.cycle_hz, inertia);
        cfg.clock = opts.clock;
        let drive = VirtualDrive::new(cfg, RobotPlant::axis(&plant, i)).map_err(|source| {
            RobotBuildError::Drive {
                robot: robot.name.clone(),
                source,
            }
        })?;
        drives.push(drive);
    }
    Ok((DriveSet::new(drives), plant))
}

/// The robot of a flexibility file and the URDF it names (relative to the file), or the
/// embedded reference arm (`robots/flexid-arm6.flex.toml`) without a path. The error says
/// which file and what is wrong.
pub fn load_robot(path: Option<&Path>) -> Result<FlexibleRobot, String> {
    let Some(path) = path else {
        return Ok(flexid_core::manipulator::reference::robot());
    };
    let origin = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|e| format!("{origin}: {e}"))?;
    let file = FlexFile::parse(&text, &origin).map_err(|e| e.to_string())?;
    let urdf_path = path.parent().unwrap_or(Path::new(".")).join(&file.urdf);
    let urdf =
        std::fs::read_to_string(&urdf_path).map_err(|e| format!("{}: {e}", urdf_path.display()))?;
    let rigid = flexid_core::robot::SerialRobot::from_urdf_str(&urdf)
        .map_err(|e| format!("{}: {e}", urdf_path.display()))?;
    FlexibleRobot::new(rigid, &file).map_err(|e| format!("{origin}: {e}"))
}
