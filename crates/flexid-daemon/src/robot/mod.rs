//! Multi-axis measurement of a robot (issue 17): a pose measured through a group of
//! drives with orthogonal multisines ([`measure`]), and a simulated robot on an
//! in-process bus to run it against ([`sim`]); the daemon's robot and its jobs
//! ([`service`]) and their files ([`files`]).

pub mod files;
pub mod measure;
pub mod service;
pub mod sim;

pub use measure::{measure_pose, plan_pose, MeasurePoseError};
pub use service::{RobotError, RobotJob, RobotService};
pub use sim::{SimRobotError, SimulatedRobot};
