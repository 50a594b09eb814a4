//! The drives on the configured buses (`backend.kind = "canopen"`, also `"drives"`): each
//! axis's sweep goes to the backend of its bus's kind, the CANopen master on a CAN bus
//! ([`CanopenBackend`]) or the EtherCAT MainDevice on an EtherCAT line ([`EcatBackend`]);
//! the sweep loop, limits, events and results files are the same.

use super::backend::{AxisBackend, BackendError, SweepHandle, SweepPlan};
use super::canopen_backend::CanopenBackend;
use super::config::{AxisConfig, BusKind, Config};
use super::ecat_backend::EcatBackend;
use std::collections::HashMap;

/// Dispatches by bus kind.
pub struct FieldbusBackend {
    kinds: HashMap<String, BusKind>,
    can: CanopenBackend,
    ecat: EcatBackend,
}

impl FieldbusBackend {
    /// The backends of the configuration's buses.
    pub fn new(cfg: &Config) -> Result<Self, String> {
        Ok(FieldbusBackend {
            kinds: cfg.bus.iter().map(|b| (b.name.clone(), b.kind)).collect(),
            can: CanopenBackend::new(&cfg.bus),
            ecat: EcatBackend::new(cfg)?,
        })
    }
}

impl AxisBackend for FieldbusBackend {
    fn start(&self, axis: &AxisConfig, plan: SweepPlan) -> Result<SweepHandle, BackendError> {
        match self.kinds.get(&axis.bus) {
            Some(BusKind::Ethercat) => self.ecat.start(axis, plan),
            _ => self.can.start(axis, plan),
        }
    }
}
