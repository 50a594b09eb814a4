//! Bring-up: NMT reset, boot-up, identity, profile; then PDO mapping, cycle period,
//! heartbeats, cyclic synchronous torque mode and NMT start.

use std::marker::PhantomData;
use std::time::Duration;

use flexid_can::CanBus;

use super::exchange::Exchange;
use super::{Configured, Drive, Link, MasterConfig, MasterError, PreOperational};
use crate::cia402::{Controlword, ModeOfOperation, SupportedModes};
use crate::cob;
use crate::objects::comm;
use crate::pdo::{check_bus_load, default_mapping, ProcessDataMapping};
use crate::profile::{Identity, ProfileSet, Quirk, Setting};
use crate::scaling::PositionUnwrap;
use crate::sdo::{abort, Sdo, SdoError};

/// NMT command specifiers (CiA 301 §7.2.8.3.1).
const NMT_START: u8 = 0x01;
const NMT_ENTER_PRE_OPERATIONAL: u8 = 0x80;
const NMT_RESET_NODE: u8 = 0x81;

/// Boot and configure in one call: [`Drive::boot`] then [`Drive::configure`].
pub fn bring_up<B: CanBus>(
    bus: B,
    config: MasterConfig,
    profiles: &ProfileSet,
) -> Result<Drive<B, Configured>, MasterError> {
    Drive::boot(bus, config, profiles)?.configure()
}

fn missing(e: &SdoError) -> bool {
    matches!(
        e.abort_code(),
        Some(abort::OBJECT_DOES_NOT_EXIST | abort::SUBINDEX_DOES_NOT_EXIST)
    )
}

/// The value, or `default` when the object does not exist.
fn or_missing<T>(r: Result<T, SdoError>, default: T) -> Result<T, SdoError> {
    match r {
        Err(e) if missing(&e) => Ok(default),
        r => r,
    }
}

impl<B: CanBus> Drive<B, PreOperational> {
    /// Resets the drive (NMT reset node 0x81), waits for its boot-up (0x700 + id, data
    /// 0x00) up to `config.boot_timeout`, reads 0x1000 and 0x1018:1..4 (3 and 4 read as 0
    /// when absent) and selects the firmware profile. `bus` becomes the cycle's handle;
    /// the SDO client gets a [`CanBus::try_clone`] of it.
    pub fn boot(
        mut bus: B,
        config: MasterConfig,
        profiles: &ProfileSet,
    ) -> Result<Self, MasterError> {
        config.validate().map_err(MasterError::Config)?;
        let node = config.node;
        let sdo_bus = bus.try_clone().map_err(|source| MasterError::Bus {
            node,
            during: "opening the SDO handle",
            source,
        })?;
        let sdo = Sdo::new(sdo_bus, node, config.sdo_timeout, config.clock)?;
        // Anything queued before the reset is not this boot's.
        while let Ok(Some(_)) = bus.recv_timeout(Duration::ZERO) {}
        // Placeholder until the identity is read (any profile; the generic one if loaded).
        let fallback = profiles
            .get(crate::profile::GENERIC)
            .or(profiles.profiles().first())
            .ok_or(crate::profile::ProfileError::NoFallback)?
            .clone();
        let mut link = Link {
            bus,
            sdo,
            cfg: config,
            identity: Identity::default(),
            scaling: fallback.scaling(f64::NAN, f64::NAN),
            profile: fallback,
            mapping: ProcessDataMapping { pdos: Vec::new() },
            exchange: Exchange::new(node),
            unwrap: PositionUnwrap::default(),
            next_heartbeat: None,
            last_cw: Controlword(0),
            last_emcy: None,
            last_sync: None,
            drive_nmt: None,
            error_watch: super::error_frames::ErrorFrameWatch::new(config.error_frames),
            nmt_operational: false,
            armed: false,
        };
        link.nmt(NMT_RESET_NODE, "NMT reset node")?;
        link.wait_bootup()?;
        let s = &mut link.sdo;
        let device_type = s.read_u32(comm::DEVICE_TYPE, 0)?;
        if device_type & 0xFFFF != 402 {
            return Err(MasterError::NotCia402 { node, device_type });
        }
        let identity = Identity {
            device_type,
            vendor_id: s.read_u32(comm::IDENTITY, 1)?,
            product_code: s.read_u32(comm::IDENTITY, 2)?,
            revision: or_missing(s.read_u32(comm::IDENTITY, 3), 0)?,
            serial: or_missing(s.read_u32(comm::IDENTITY, 4), 0)?,
        };
        link.profile = profiles.select(&identity)?.clone();
        link.identity = identity;
        tracing::info!(
            node,
            vendor_id = format_args!("{:#010x}", identity.vendor_id),
            product_code = format_args!("{:#010x}", identity.product_code),
            revision = format_args!("{:#010x}", identity.revision),
            profile = %link.profile.name,
            "drive booted"
        );
        Ok(Self {
            link,
            _state: PhantomData,
        })
    }

    /// Configures the drive and starts it (NMT operational), in this order: NMT enter
    /// pre-operational; checks (cycle period against the profile's minimum, PDO entries,
    /// bus load, CST in the profile and in 0x6502 if present); reads what the profile
    /// says to read (0x608F:1/2, 0x6076); writes the default PDO mapping
    /// ([`crate::pdo::ProcessDataMapping::sdo_writes`]), 0x1006 cycle period (µs),
    /// 0x1016:1 = (master node-id << 16) | consumer time (ms), 0x1017 producer
    /// heartbeat (ms), 0x6060 = 10 (CST); checks 0x6061; NMT start.
    pub fn configure(self) -> Result<Drive<B, Configured>, MasterError> {
        let mut link = self.link;
        let node = link.node();
        let cfg = link.cfg;
        let profile = link.profile.clone();
        link.nmt(NMT_ENTER_PRE_OPERATIONAL, "NMT enter pre-operational")?;

        let min = Duration::from_micros(profile.min_cycle_us as u64);
        if cfg.cycle_period < min {
            return Err(MasterError::CycleTooShort {
                node,
                cycle: cfg.cycle_period,
                min,
                profile: profile.name.clone(),
            });
        }
        let mapping = default_mapping(&profile.objects);
        if mapping.max_entries() > profile.max_pdo_entries as usize {
            return Err(MasterError::MappingTooLong {
                node,
                entries: mapping.max_entries(),
                max: profile.max_pdo_entries,
                profile: profile.name.clone(),
            });
        }
        let heartbeats = [cfg.heartbeat_period, cfg.drive_heartbeat_period];
        let load = check_bus_load(
            &mapping,
            &heartbeats,
            1.0 / cfg.cycle_period.as_secs_f64(),
            cfg.bitrate,
            cfg.max_bus_load,
        )?;
        tracing::debug!(node, load, "bus load admitted");
        let cst = ModeOfOperation::CyclicSyncTorque;
        let unsupported = || MasterError::ModeUnsupported {
            node,
            mode: cst.name(),
            profile: profile.name.clone(),
        };
        if !profile.supports(cst) {
            return Err(unsupported());
        }
        let s = &mut link.sdo;
        let supported = or_missing(
            s.read_u32(profile.objects.supported_modes, 0).map(Some),
            None,
        )?;
        if supported.is_some_and(|m| !SupportedModes(m).supports(cst)) {
            return Err(unsupported());
        }

        let mut increments = f64::NAN;
        if let Setting::Read(index) = profile.increments_per_rev {
            let inc = s.read_u32(index, 1)?;
            let revs = s.read_u32(index, 2)?;
            if inc == 0 || revs == 0 {
                return Err(MasterError::Config(format!(
                    "node {node}: position encoder resolution {index:#06x} = {inc}/{revs}"
                )));
            }
            increments = inc as f64 / revs as f64;
        }
        let mut rated = f64::NAN;
        if let Setting::Read(index) = profile.rated_torque {
            let mnm = s.read_u32(index, 0)?;
            if mnm == 0 {
                return Err(MasterError::Config(format!(
                    "node {node}: rated torque {index:#06x} reads 0"
                )));
            }
            rated = mnm as f64 / 1000.0;
        }
        link.scaling = profile.scaling(increments, rated);

        for w in mapping.sdo_writes(node, !profile.has(Quirk::KeepUnusedPdos)) {
            match s.write(w.index, w.subindex, w.value) {
                Err(e) if w.missing_ok && missing(&e) => {}
                r => r?,
            }
        }
        if !profile.has(Quirk::NoCyclePeriod) {
            s.write_u32(comm::CYCLE_PERIOD, 0, cfg.cycle_period.as_micros() as u32)?;
        }
        if !profile.has(Quirk::NoHeartbeatConsumer) {
            let v =
                ((cfg.master_node as u32) << 16) | cfg.heartbeat_consumer_time.as_millis() as u32;
            s.write_u32(comm::CONSUMER_HEARTBEAT, 1, v)?;
        } else {
            tracing::warn!(
                node,
                "no heartbeat consumer: a dead master will not stop this drive"
            );
        }
        s.write_u16(
            comm::PRODUCER_HEARTBEAT,
            0,
            cfg.drive_heartbeat_period.as_millis() as u16,
        )?;
        s.write_i8(profile.objects.modes_of_operation, 0, cst.code())?;
        let display = profile.objects.modes_of_operation_display;
        let mut shown = s.read_i8(display, 0)?;
        if shown != cst.code() && profile.has(Quirk::ModeDisplayLags) {
            let t0 = (cfg.clock)();
            while shown != cst.code() && (cfg.clock)().duration_since(t0) < cfg.mode_timeout {
                std::thread::sleep(Duration::from_millis(5));
                shown = s.read_i8(display, 0)?;
            }
        }
        if shown != cst.code() {
            return Err(MasterError::ModeNotAccepted {
                node,
                requested: cst.code(),
                shown,
            });
        }
        link.mapping = mapping;
        link.nmt(NMT_START, "NMT start")?;
        link.nmt_operational = true;
        Ok(Drive::from_link(link))
    }
}

impl<B: CanBus> Link<B> {
    /// Waits for the boot-up message of the node on the cycle's handle.
    fn wait_bootup(&mut self) -> Result<(), MasterError> {
        let node = self.node();
        let after = self.cfg.boot_timeout;
        let deadline = self.now() + after;
        loop {
            let left = deadline.saturating_duration_since(self.now());
            if left.is_zero() {
                return Err(MasterError::BootUpMissing { node, after });
            }
            match self.bus.recv_timeout(left) {
                Ok(Some(r)) => {
                    let f = r.frame;
                    if cob::classify(&f) == cob::Cob::Heartbeat(node) && f.data() == [0x00] {
                        return Ok(());
                    }
                }
                Ok(None) => {}
                Err(e) if e.is_report() => {}
                Err(source) => {
                    return Err(MasterError::Bus {
                        node,
                        during: "waiting for the boot-up",
                        source,
                    })
                }
            }
        }
    }
}
