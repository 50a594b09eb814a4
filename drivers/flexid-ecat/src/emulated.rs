//! An emulated line of CiA 402 servos in front of a plant file: what a daemon or a command
//! without an EtherCAT interface runs the sweep against, in process (the servos carry the
//! `flexid-vdrive` firmware profile's EtherCAT identity).

use crate::esc::sii::{Identity, SiiError};
use crate::inprocess::SharedSegment;
use crate::segment::Segment;
use crate::servo::ServoConfig;
use flexid_core::plant::physics::LinearChain;
use flexid_core::plant::PlantFile;
use std::sync::{Arc, Mutex};
use thiserror::Error;

/// SII vendor id of the emulated servo (a placeholder, as `firmware-profiles/flexid-vdrive.toml`
/// says).
pub const VENDOR_ID: u32 = 0x0000_0A1D;
/// SII product code of the emulated servo.
pub const PRODUCT_CODE: u32 = 0x0402_0000;
/// The emulated line's process-data watchdog, in 100 us units: 2 s. The servos run in
/// lock-step (one cycle per frame) while the watchdog counts wall time, so a loaded host
/// that deschedules the master for longer than a real ESC's 100 ms would trip it without
/// any fault of the sweep; 2 s still catches a master that stopped.
pub const LOCKSTEP_WATCHDOG_UNITS: u16 = 20_000;

/// Why the emulated line could not be built.
#[derive(Debug, Error)]
pub enum EmulatedError {
    #[error("plant {plant}: the chain cannot be stepped at {cycle_hz} Hz: {reason}")]
    Chain {
        plant: String,
        cycle_hz: f64,
        reason: String,
    },
    #[error("emulated SubDevice {position}: {source}")]
    Sii {
        position: usize,
        #[source]
        source: SiiError,
    },
}

/// The identity of emulated servo `serial`.
pub fn identity(serial: u32) -> Identity {
    Identity {
        vendor_id: VENDOR_ID,
        product_code: PRODUCT_CODE,
        revision: 1,
        serial,
    }
}

/// `n` servos in a line, each with the plant file's drive constants in front of its chain
/// (the exact ZOH chain stepped at `cycle_hz`, Hz; the plant's noise and effects are not
/// emulated).
pub fn servo_line(
    plant: &PlantFile,
    n: usize,
    cycle_hz: f64,
) -> Result<SharedSegment, EmulatedError> {
    let config = ServoConfig::from_plant(plant);
    let name = plant.name.clone().unwrap_or_else(|| "plant file".into());
    let mut segment = Segment::new();
    for position in 0..n {
        let physics =
            LinearChain::new(&plant.chain, cycle_hz).map_err(|e| EmulatedError::Chain {
                plant: name.clone(),
                cycle_hz,
                reason: e.to_string(),
            })?;
        let (device, servo) = config
            .build(
                identity(position as u32),
                &format!("FLEXID-SERVO{position}"),
                physics,
            )
            .map_err(|source| EmulatedError::Sii { position, source })?;
        let mut device = device;
        device.set_sm_watchdog_time(LOCKSTEP_WATCHDOG_UNITS);
        segment.push_with(device, servo);
    }
    Ok(Arc::new(Mutex::new(segment)))
}
