//! What the in-process EtherCAT tests share: emulated CiA 402 servos in front of
//! `plants/e2e_3mass.toml` at 4 kHz, a MainDevice linked to them on its own thread, the
//! drive brought up, and the multisine plan.

#![allow(dead_code)] // each test file uses a part

use ethercrab::{MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use flexid_core::excitation::MultisineDesign;
use flexid_core::plant::physics::LinearChain;
use flexid_core::plant::PlantFile;
use flexid_ecat::emulated::identity;
use flexid_ecat::esc::sii::Identity;
use flexid_ecat::inprocess::{LinkError, SegmentLink, SharedSegment};
use flexid_ecat::{Application, EcatConfig, EcatDrive, EcatError, Segment, ServoConfig, SubDevice};
use flexid_sweep::{Pacing, SweepPlan};
use futures_lite::future::block_on;
use std::sync::{Arc, Mutex};
use std::time::Duration;

pub const MAX_FRAMES: usize = 16;
pub const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
pub const MAX_SUBDEVICES: usize = 4;
pub const MAX_PDI: usize = 64;
/// The cycle rate of every test here: 4 kHz, out of CAN's reach.
pub const CYCLE_HZ: f64 = 4000.0;
const PLANT: &str = include_str!("../../../../plants/e2e_3mass.toml");

pub type Drive = EcatDrive<'static, MAX_SUBDEVICES, MAX_PDI>;

pub fn plant() -> PlantFile {
    PlantFile::parse(PLANT, "plants/e2e_3mass.toml").expect("plant file")
}

/// Servo `i` of `config` in front of the plant file's chain stepped at `CYCLE_HZ`.
pub fn servo(config: &ServoConfig, i: usize) -> (SubDevice, Box<dyn Application>) {
    let physics = LinearChain::new(&plant().chain, CYCLE_HZ).expect("chain");
    config
        .build(identity(i as u32), &format!("FLEXID-SERVO{i}"), physics)
        .expect("SII")
}

/// `n` servos in a line with the plant file's drive constants.
pub fn servo_segment(n: usize) -> SharedSegment {
    servo_segment_with(n, &ServoConfig::from_plant(&plant()))
}

/// `n` servos of `config` in a line, with the emulated line's long lock-step watchdog (a
/// loaded host's stalls do not trip it; the watchdog's own test sets it back).
pub fn servo_segment_with(n: usize, config: &ServoConfig) -> SharedSegment {
    let mut segment = Segment::new();
    for i in 0..n {
        let (mut device, servo) = servo(config, i);
        device.set_sm_watchdog_time(flexid_ecat::emulated::LOCKSTEP_WATCHDOG_UNITS);
        segment.push_with(device, servo);
    }
    Arc::new(Mutex::new(segment))
}

/// One servo of the plant file's constants with SII identity `identity`.
pub fn servo_segment_identified(identity: Identity) -> SharedSegment {
    let physics = LinearChain::new(&plant().chain, CYCLE_HZ).expect("chain");
    let (device, servo) = ServoConfig::from_plant(&plant())
        .build(identity, "OTHER-SERVO", physics)
        .expect("SII");
    let mut segment = Segment::new();
    segment.push_with(device, servo);
    Arc::new(Mutex::new(segment))
}

/// A MainDevice (leaked: one per test), its link to a segment running on its own thread,
/// and the enabled drive.
pub struct Rig {
    pub md: &'static MainDevice<'static>,
    pub drive: Drive,
    pub link: std::thread::JoinHandle<Result<(), LinkError>>,
}

/// `segment` linked, discovered and brought up to an enabled CST axis 0.
pub fn bring_up(segment: SharedSegment) -> Rig {
    try_bring_up(segment, EcatConfig::at_hz(CYCLE_HZ)).expect("bring-up")
}

/// `segment` linked, discovered and brought up with `config` (the link is left running
/// when the bring-up fails).
pub fn try_bring_up(segment: SharedSegment, config: EcatConfig) -> Result<Rig, EcatError> {
    let storage: &'static PduStorage<MAX_FRAMES, MAX_PDU_DATA> =
        Box::leak(Box::new(PduStorage::new()));
    let (tx, rx, pdu_loop) = storage.try_split().expect("storage split once");
    // a loaded host may deschedule the link thread: late frames, never lost ones
    let timeouts = Timeouts {
        state_transition: Duration::from_millis(500),
        pdu: Duration::from_secs(1),
        ..Timeouts::default()
    };
    let md_config = MainDeviceConfig {
        dc_static_sync_iterations: 100,
        ..MainDeviceConfig::default()
    };
    let md: &'static MainDevice<'static> =
        Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts, md_config)));
    let link = SegmentLink::new(tx, rx, segment);
    let link = std::thread::spawn(move || block_on(link));
    let group = block_on(md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(|| 0)).expect("init");
    let drive = EcatDrive::bring_up(md, group, config)?;
    Ok(Rig { md, drive, link })
}

/// A multisine at 4 kHz on the per-mille grid of 1 N m: `period` samples, `periods` + 1
/// transient period, 1-500 Hz.
pub fn plan(period: usize, periods: usize) -> SweepPlan {
    let mut design = MultisineDesign::new(CYCLE_HZ, period, [1.0, 500.0], 0.8, 0.4);
    design.crest_iterations = 10;
    let ms = design.generate().expect("multisine");
    SweepPlan::from_multisine(CYCLE_HZ, &ms, periods, 1, 1000.0, Pacing::Lockstep)
}
