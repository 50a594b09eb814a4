//! The EtherCAT [`AxisBackend`]: the same sweep ([`DriveJob::run_on`], the one sweep loop
//! through the daemon's tap) over a CiA 402 drive on an EtherCAT line (`[[bus]] kind =
//! "ethercat"`), one MainDevice session per sweep on the cycle thread
//! ([`flexid_ecat::with_drive`]): discovery, the drive's firmware profile from its SII
//! identity, CST mapping, SYNC0 at the axis's cycle, OP, enable; after the sweep the drive
//! disabled and the link stopped.
//!
//! The line is a network interface (ethercrab's `tx_rx_task`: root or `CAP_NET_RAW`), or
//! with `emulated = true` the emulated servos in the daemon's process in front of the bus's
//! plant file (one servo per position up to the highest node configured on the bus), so
//! the daemon's tests and web page run an EtherCAT sweep without privileges.

use super::backend::{AxisBackend, BackendError, SweepHandle, SweepPlan};
use super::config::{AxisConfig, BusConfig, Config};
use super::drive_sweep::DriveJob;
use flexid_canopen::profile::GENERIC;
use flexid_canopen::{CyclicDrive, ProfileSet};
use flexid_core::plant::PlantFile;
use flexid_ecat::{with_drive, EcatConfig, Link, ProfileChoice};
use std::collections::HashMap;

/// One configured EtherCAT line.
#[derive(Debug, Clone)]
struct Line {
    bus: BusConfig,
    /// The emulated line's plant and its number of servos (`None`: an interface).
    emulated: Option<(PlantFile, usize)>,
}

/// Runs sweeps on EtherCAT drives.
pub struct EcatBackend {
    lines: HashMap<String, Line>,
    profiles: ProfileSet,
}

impl EcatBackend {
    /// A backend for the configuration's `ethercat` buses with the built-in firmware
    /// profiles; an emulated bus's plant file is loaded here (its error names the bus).
    pub fn new(cfg: &Config) -> Result<Self, String> {
        let mut lines = HashMap::new();
        for bus in cfg
            .bus
            .iter()
            .filter(|b| b.kind == super::config::BusKind::Ethercat)
        {
            let emulated = if bus.emulated {
                let plant = flexid_files::plant::load_plant_file(bus.plant.as_deref())
                    .map_err(|e| format!("bus {}: plant: {e}", bus.name))?;
                let servos = cfg
                    .axis
                    .iter()
                    .filter(|a| a.bus == bus.name)
                    .map(|a| usize::from(a.node))
                    .max()
                    .unwrap_or(1);
                Some((plant, servos))
            } else {
                None
            };
            lines.insert(
                bus.name.clone(),
                Line {
                    bus: bus.clone(),
                    emulated,
                },
            );
        }
        Ok(EcatBackend {
            lines,
            profiles: ProfileSet::builtin(),
        })
    }
}

impl AxisBackend for EcatBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        let line = self
            .lines
            .get(&axis.bus)
            .cloned()
            .ok_or_else(|| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("no ethercat bus {:?}", axis.bus),
            })?;
        let config = EcatConfig {
            axis: usize::from(axis.node).saturating_sub(1),
            profile: if axis.profile.as_deref() == Some(GENERIC) {
                ProfileChoice::Generic
            } else {
                ProfileChoice::ByIdentity
            },
            ..EcatConfig::at_hz(axis.cycle_hz)
        };
        let (mut job, handle) = DriveJob::plan(axis, plan)?;
        let profiles = self.profiles.clone();
        DriveJob::spawn(format!("cycle-{}", axis.name), &axis.name, move || {
            let link = match &line.emulated {
                Some((plant, servos)) => {
                    match flexid_ecat::emulated::servo_line(plant, *servos, job.plan.cycle_hz) {
                        Ok(segment) => Link::Emulated(segment),
                        Err(e) => return job.failed(format!("bus {}: {e}", line.bus.name)),
                    }
                }
                None => Link::Interface(line.bus.interface.clone().unwrap_or_default()),
            };
            let source = format!(
                "flexid daemon: axis {} (SubDevice {} on bus {}, {})",
                job.axis.name,
                job.axis.node,
                line.bus.name,
                link.describe()
            );
            let axis = job.axis.name.clone();
            let ran = with_drive(link, config, &profiles, |drive| {
                let profile = drive.profile().name.clone();
                let rate = 1.0 / drive.cycle_period().as_secs_f64();
                tracing::info!("axis {axis}: EtherCAT drive enabled ({profile}, {rate:.0} Hz)");
                job.run_on(drive, format!("{source}, profile {profile}"), |mut d| {
                    if let Err(e) = d.disable() {
                        tracing::warn!("axis {axis}: disabling the drive: {e}");
                    }
                })
            });
            if let Err(e) = ran {
                job.failed(e.to_string());
            }
        })?;
        Ok(handle)
    }
}
