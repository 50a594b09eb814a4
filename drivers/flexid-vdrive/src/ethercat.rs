//! The simulated drive on EtherCAT (issue 18): emulated CiA 402 servos
//! (`flexid_ecat::Servo` behind an emulated ESC) in front of a plant file's chain, in a
//! line, served on a network interface (`flexid-vdrive --ethercat IFACE`).
//!
//! The servos are flexid-ecat's (the ESC, the CoE dictionary and the CST process data);
//! this module builds them from the same plant file and `[drive]` section as the CAN drive
//! (rated and peak torque, encoder) and serves them: frames and SYNC0 pulses on the calling
//! thread, in the order of their times ([`flexid_ecat::socket_link::SocketLink`]).
//! Only the plant's linear chain is simulated here (the `[effects]` of a plant file are
//! not, yet).

use crate::config::DrivePlant;
use flexid_core::plant::physics::{LinearChain, PhysicsError};
use flexid_ecat::esc::sii::SiiError;
use flexid_ecat::inprocess::SharedSegment;
use flexid_ecat::socket_link::{LinkStats, SocketError, SocketLink};
use flexid_ecat::sync0_clock::Sync0ClockStats;
use flexid_ecat::{CycleStats, Segment, ServoClock, ServoConfig};
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, Mutex};
use thiserror::Error;

/// Vendor id and product code of the emulated SubDevices: the `[ethercat]` identity of
/// `firmware-profiles/flexid-vdrive.toml` (placeholders, not ETG-assigned ids), so that the
/// MainDevice picks that profile.
pub use flexid_ecat::emulated::{PRODUCT_CODE, VENDOR_ID};

/// How to build the servos.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EthercatOptions {
    /// Servos in the line (each with its own copy of the plant).
    pub axes: usize,
    /// The cycle the plant is discretised at, Hz: the MainDevice's SYNC0 (and, in
    /// lock-step, frame) rate.
    pub cycle_hz: f64,
    /// What advances the plants.
    pub clock: ServoClock,
    /// SYNC0 clock: consecutive missed cycles that fault a servo (0: never).
    pub fault_after_missed_cycles: u32,
}

/// Why the EtherCAT drive could not be built or served.
#[derive(Debug, Error)]
pub enum EthercatError {
    #[error("--axes {axes}: must be 1..=16")]
    Axes { axes: usize },
    #[error("the plant's chain at {cycle_hz} Hz: {source}")]
    Physics {
        cycle_hz: f64,
        #[source]
        source: PhysicsError,
    },
    #[error("SubDevice {position}: SII image: {source}")]
    Sii {
        position: usize,
        #[source]
        source: SiiError,
    },
    #[error(transparent)]
    Socket(#[from] SocketError),
    #[error("the segment's lock is poisoned")]
    Poisoned,
}

/// What serving did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct EthercatStats {
    pub link: LinkStats,
    pub clock: Sync0ClockStats,
    /// The servos' counters, summed.
    pub servos: CycleStats,
}

/// The servo constants of `plant`'s `[drive]` section.
pub fn servo_config(plant: &DrivePlant, options: &EthercatOptions) -> ServoConfig {
    ServoConfig {
        rated_torque_nm: plant.drive.rated_torque_nm,
        peak_torque_nm: plant.drive.peak_torque_nm,
        increments_per_rev: plant.drive.encoder_increments_per_rev,
        clock: options.clock,
        fault_after_missed_cycles: options.fault_after_missed_cycles,
        // the torque is clamped to the peak, as on CAN; no overload fault
        overtorque_cycles: 0,
    }
}

/// `options.axes` emulated servos in a line, each in front of `plant`'s chain stepped at
/// `options.cycle_hz`; SubDevice `i` has serial number `i` and name `FLEXID-SERVO<i>`.
pub fn servo_segment(
    plant: &DrivePlant,
    options: &EthercatOptions,
) -> Result<SharedSegment, EthercatError> {
    if !(1..=16).contains(&options.axes) {
        return Err(EthercatError::Axes { axes: options.axes });
    }
    let config = servo_config(plant, options);
    let mut segment = Segment::new();
    for position in 0..options.axes {
        let identity = flexid_ecat::emulated::identity(position as u32);
        let physics = LinearChain::new(&plant.plant.chain, options.cycle_hz).map_err(|source| {
            EthercatError::Physics {
                cycle_hz: options.cycle_hz,
                source,
            }
        })?;
        let (device, servo) = config
            .build(identity, &format!("FLEXID-SERVO{position}"), physics)
            .map_err(|source| EthercatError::Sii { position, source })?;
        segment.push_with(device, servo);
    }
    Ok(Arc::new(Mutex::new(segment)))
}

/// The servos' counters, summed.
pub fn servo_stats(segment: &SharedSegment) -> Result<CycleStats, EthercatError> {
    let seg = segment.lock().map_err(|_| EthercatError::Poisoned)?;
    let mut sum = CycleStats::default();
    for position in 0..seg.len() {
        if let Some(app) = seg.application(position) {
            let s = app.stats();
            sum.latches += s.latches;
            sum.cycles += s.cycles;
            sum.pulses += s.pulses;
            sum.missed += s.missed;
            sum.overwritten += s.overwritten;
            sum.longest_missed_run = sum.longest_missed_run.max(s.longest_missed_run);
        }
    }
    Ok(sum)
}

/// Serves the link's segment until `stop` is set: frames and SYNC0 pulses on this thread
/// in time order ([`SocketLink::serve_with_sync0`]); the caller sets its scheduling.
pub fn serve(
    link: &mut SocketLink,
    segment: &SharedSegment,
    stop: &AtomicBool,
) -> Result<EthercatStats, EthercatError> {
    let (link, clock) = link.serve_with_sync0(stop)?;
    Ok(EthercatStats {
        link,
        clock,
        servos: servo_stats(segment)?,
    })
}
