//! The CANopen master for one CiA 402 drive: bring-up, enable, the cycle, disable.
//!
//! Blocking over any [`CanBus`]; the drive's lifecycle is in its type:
//!
//! ```text
//! Drive::boot(bus, config, profiles)   NMT reset, boot-up, identity, profile
//!   -> Drive<B, PreOperational>
//!      .configure()                    PDO mapping, 0x1006, heartbeats, CST, NMT start
//!   -> Drive<B, Configured>            (bring_up() = boot + configure)
//!      .enable()                       CiA 402 walk to Operation enabled, cycle by cycle
//!   -> Drive<B, Enabled>               .cycle(torque_nm, deadline) -> Feedback
//!      .disable() / .quick_stop()      back to Switch on disabled, NMT pre-operational
//!   -> Drive<B, Configured>
//! ```
//!
//! The cycle's protocol logic is sans-I/O in [`exchange`]; this module moves frames and
//! reads the clock given in [`MasterConfig::clock`]. SDO transfers use their own bus
//! handle (a [`CanBus::try_clone`]), so no PDO is lost while an SDO waits.

mod bringup;
pub mod config;
mod cyclic;
pub mod error;
pub mod error_frames;
pub mod exchange;
mod group;

use std::marker::PhantomData;
use std::time::Instant;

use canopen_rs::EmergencyMessage;
use flexid_can::{CanBus, CanFrame};

pub use bringup::bring_up;
pub use config::MasterConfig;
pub use error::{emcy_text, MasterError};
pub use error_frames::ErrorFramePolicy;
pub use group::DriveGroup;

use crate::cia402::Controlword;
use crate::cob;
use crate::drive::Counters;
use crate::pdo::ProcessDataMapping;
use crate::profile::{Identity, Profile};
use crate::scaling::{PositionUnwrap, Scaling};
use crate::sdo::Sdo;
use exchange::Exchange;

/// Lifecycle state of a [`Drive`] (sealed).
pub trait DriveState: private::Sealed {}
mod private {
    pub trait Sealed {}
}

/// Booted and identified, NMT pre-operational, nothing configured.
#[derive(Debug)]
pub struct PreOperational;
/// Process data, heartbeats and CST configured; NMT operational (or pre-operational
/// after a disable); CiA 402 not enabled.
#[derive(Debug)]
pub struct Configured;
/// Operation enabled in cyclic synchronous torque: only here is there [`Drive::cycle`].
#[derive(Debug)]
pub struct Enabled;

impl private::Sealed for PreOperational {}
impl private::Sealed for Configured {}
impl private::Sealed for Enabled {}
impl DriveState for PreOperational {}
impl DriveState for Configured {}
impl DriveState for Enabled {}

/// One CiA 402 drive on a CAN bus, in lifecycle state `S`.
#[derive(Debug)]
pub struct Drive<B: CanBus, S: DriveState> {
    link: Link<B>,
    _state: PhantomData<S>,
}

/// What all states share. Dropping it while the drive is enabled sends Disable voltage
/// and NMT pre-operational (best effort).
#[derive(Debug)]
struct Link<B: CanBus> {
    bus: B,
    sdo: Sdo<B>,
    cfg: MasterConfig,
    identity: Identity,
    profile: Profile,
    scaling: Scaling,
    mapping: ProcessDataMapping,
    exchange: Exchange,
    unwrap: PositionUnwrap,
    next_heartbeat: Option<Instant>,
    last_cw: Controlword,
    last_emcy: Option<EmergencyMessage>,
    /// The NMT state the drive's heartbeat last reported when it was not operational
    /// (0x04 stopped, 0x7F pre-operational); cleared by the master's NMT start.
    drive_nmt: Option<u8>,
    /// The error frames of the recent window (the error-frame policy).
    error_watch: error_frames::ErrorFrameWatch,
    /// When the last SYNC went out: the CiA 402 walks keep one SYNC per cycle period
    /// from it.
    last_sync: Option<Instant>,
    nmt_operational: bool,
    armed: bool,
}

impl<B: CanBus, S: DriveState> Drive<B, S> {
    fn from_link(link: Link<B>) -> Self {
        Self {
            link,
            _state: PhantomData,
        }
    }

    fn into_state<T: DriveState>(self) -> Drive<B, T> {
        Drive::from_link(self.link)
    }

    /// The drive's node-id.
    pub fn node(&self) -> u8 {
        self.link.cfg.node
    }

    /// The master configuration.
    pub fn config(&self) -> &MasterConfig {
        &self.link.cfg
    }

    /// Identity (0x1000, 0x1018) read at boot.
    pub fn identity(&self) -> &Identity {
        &self.link.identity
    }

    /// The firmware profile selected from the identity.
    pub fn profile(&self) -> &Profile {
        &self.link.profile
    }

    /// The SDO client (own bus handle) for further object access.
    pub fn sdo(&mut self) -> &mut Sdo<B> {
        &mut self.link.sdo
    }

    /// The bus statistics of the cycle's handle.
    pub fn bus_stats(&self) -> flexid_can::BusStats {
        self.link.bus.stats()
    }
}

impl<B: CanBus> Link<B> {
    fn node(&self) -> u8 {
        self.cfg.node
    }

    fn now(&self) -> Instant {
        (self.cfg.clock)()
    }

    fn send(&mut self, frame: &CanFrame, during: &'static str) -> Result<(), MasterError> {
        let node = self.node();
        self.bus.send(frame).map_err(|source| MasterError::Bus {
            node,
            during,
            source,
        })
    }

    /// NMT node control `[command, node]` on 0x000.
    fn nmt(&mut self, command: u8, during: &'static str) -> Result<(), MasterError> {
        let f = CanFrame::standard(cob::NMT, &[command, self.node()]).expect("2 bytes");
        self.send(&f, during)
    }

    /// Discards everything queued on the cycle's handle (SDO traffic of the bring-up,
    /// old heartbeats); overrun reports included.
    fn drain(&mut self) {
        for _ in 0..100_000 {
            match self.bus.recv_timeout(std::time::Duration::ZERO) {
                Ok(Some(_)) | Err(_) => continue,
                Ok(None) => break,
            }
        }
    }
}

impl<B: CanBus> Drop for Link<B> {
    fn drop(&mut self) {
        if self.armed {
            tracing::warn!(
                node = self.node(),
                "enabled drive dropped: disabling voltage"
            );
            let node = self.node();
            if let Ok(f) = CanFrame::standard(cob::rpdo(1, node), &crate::pdo::pack_rpdo1(0, 0)) {
                let _ = self.bus.send(&f);
            }
            if let Ok(f) = CanFrame::standard(cob::SYNC, &[]) {
                let _ = self.bus.send(&f);
            }
            if let Ok(f) = CanFrame::standard(cob::NMT, &[0x80, node]) {
                let _ = self.bus.send(&f);
            }
        }
    }
}

impl<B: CanBus> Drive<B, Configured> {
    /// The unit conversions (resolved at configure).
    pub fn scaling(&self) -> &Scaling {
        &self.link.scaling
    }

    /// The process-data mapping in use.
    pub fn mapping(&self) -> &ProcessDataMapping {
        &self.link.mapping
    }
}

impl<B: CanBus> Drive<B, Enabled> {
    /// The unit conversions (resolved at configure).
    pub fn scaling(&self) -> &Scaling {
        &self.link.scaling
    }

    /// The process-data mapping in use.
    pub fn mapping(&self) -> &ProcessDataMapping {
        &self.link.mapping
    }

    /// Counters since enable.
    pub fn counters(&self) -> Counters {
        self.link.exchange.counters
    }
}
