//! The CANopen [`AxisBackend`]: the sweep library ([`flexid_sweep::run_sweep`]) over a
//! CiA 402 drive on the axis's bus (`[[bus]]` udp or socketcan), brought up, enabled, run,
//! ramped to zero and disabled on a plain OS thread of its own (never on the async
//! runtime; `SCHED_FIFO` and locked memory when the service has the rights and the axis
//! runs in real time).
//!
//! While the sweep runs, the drive is wrapped in a [`Tap`] that stores every row into a
//! pre-allocated [`PeriodRows`] and enforces the position window; after every period the
//! sweep's progress hook publishes the rows and a relay thread ([`spawn_relay`]) sends
//! them with the FRF estimate so far, so the daemon streams them to disk and the clients
//! see a Bode update per period, exactly as with the simulated backend. The final
//! recording's sidecar carries the cycle timing (`cycle_timing`: wake-up lateness, late
//! wake-ups, overruns) beside the exchange counters (late and lost TPDOs).
use super::backend::{AxisBackend, BackendError, SweepHandle, SweepPlan};
use super::config::{AxisConfig, BusConfig, BusKind};
use super::drive_sweep::DriveJob;
use flexid_can::{CanBus, UdpConfig, UdpMulticastBus};
use flexid_canopen::{bring_up, MasterConfig, ProfileSet};
use flexid_sweep::admission_check;
use std::collections::HashMap;

pub use super::drive_sweep::CYCLE_FIFO_PRIORITY;

/// Runs sweeps on CiA 402 drives.
pub struct CanopenBackend {
    buses: HashMap<String, BusConfig>,
    profiles: ProfileSet,
}

impl CanopenBackend {
    /// A backend for the configured buses with the built-in firmware profiles.
    pub fn new(buses: &[BusConfig]) -> Self {
        CanopenBackend {
            buses: buses.iter().map(|b| (b.name.clone(), b.clone())).collect(),
            profiles: ProfileSet::builtin(),
        }
    }
}

impl CanopenBackend {
    /// Starts `plan` on `axis` over the bus `open` returns (called on the cycle thread with
    /// the axis's `[[bus]]`): the seam for buses that are not in the configuration, e.g. a
    /// test's bus that fails on purpose. An error of `open` ends the sweep as failed before
    /// the motor moves.
    pub fn start_on<B, F>(
        &self,
        axis: &AxisConfig,
        plan: SweepPlan,
        open: F,
    ) -> Result<SweepHandle, BackendError>
    where
        B: CanBus + 'static,
        F: FnOnce(&BusConfig) -> Result<B, BusOpenError> + Send + 'static,
    {
        let bus = self
            .buses
            .get(&axis.bus)
            .cloned()
            .ok_or_else(|| BackendError::Unavailable {
                axis: axis.name.clone(),
                reason: format!("no bus {:?}", axis.bus),
            })?;
        admission_check(axis.cycle_hz, bus.bitrate).map_err(|e| BackendError::Plan {
            axis: axis.name.clone(),
            reason: e.to_string(),
        })?;
        let (mut job, handle) = DriveJob::plan(axis, plan)?;
        let profiles = self.profiles.clone();
        DriveJob::spawn(format!("cycle-{}", axis.name), &axis.name, move || {
            let source = format!(
                "flexid daemon: axis {} (node {} on bus {})",
                job.axis.name, job.axis.node, bus.name
            );
            let r = open(&bus).map_err(|e| e.to_string()).and_then(|b| {
                let cfg = MasterConfig {
                    node: job.axis.node,
                    cycle_period: job.plan.period(),
                    bitrate: bus.bitrate,
                    ..MasterConfig::for_node(job.axis.node)
                };
                let drive = bring_up(b, cfg, &profiles).map_err(|e| format!("bring-up: {e}"))?;
                drive.enable().map_err(|e| format!("enable: {e}"))
            });
            match r {
                Err(reason) => job.failed(reason),
                Ok(drive) => {
                    let axis = job.axis.name.clone();
                    job.run_on(drive, source, |d| {
                        if let Err(e) = d.disable() {
                            tracing::warn!("axis {axis}: disabling the drive: {e}");
                        }
                    })
                }
            }
        })?;
        Ok(handle)
    }
}

impl AxisBackend for CanopenBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        match self.buses.get(&axis.bus).map(|b| b.kind) {
            Some(BusKind::Socketcan) => self.start_on(axis, plan, |bus: &BusConfig| {
                let iface = bus.interface.clone().unwrap_or_default();
                flexid_can::SocketCanBus::open(&iface).map_err(|source| BusOpenError {
                    bus: format!("{} ({iface})", bus.name),
                    source,
                })
            }),
            _ => self.start_on(axis, plan, open_udp),
        }
    }
}

/// A configured bus that could not be opened.
#[derive(Debug, thiserror::Error)]
#[error("bus {bus}: {source}")]
pub struct BusOpenError {
    /// The bus's name in the configuration (and its interface, for SocketCAN).
    pub bus: String,
    /// What the bus driver said.
    #[source]
    pub source: flexid_can::BusError,
}

/// Opens a `kind = "udp"` bus of the configuration.
pub fn open_udp(bus: &BusConfig) -> Result<UdpMulticastBus, BusOpenError> {
    let mut cfg = UdpConfig::default();
    if let Some(g) = bus.group {
        cfg.group = g;
    }
    if let Some(p) = bus.port {
        cfg.port = p;
    }
    UdpMulticastBus::open(cfg).map_err(|source| BusOpenError {
        bus: bus.name.clone(),
        source,
    })
}
