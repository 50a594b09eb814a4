//! ethercrab's MainDevice against emulated SubDevices, in process: PduTx/PduRx straight into
//! a [`Segment`] (no socket, no root). Discovery and SII identity, CoE SDO upload/download
//! and abort, DC delays and synchronised system times, AL refusal codes, and the way to OP
//! with a process-data exchange and its working counter.

use ethercrab::error::{Error, MailboxError};
use ethercrab::subdevice_group::DcConfiguration;
use ethercrab::{AlStatusCode, DcSync, MainDevice, MainDeviceConfig, PduStorage, Timeouts};
use flexid_ecat::esc::al::{AlState, AlStatusCode as EmulatedCode};
use flexid_ecat::esc::sii::Identity;
use flexid_ecat::inprocess::{LinkError, Recording, SegmentLink, SharedSegment};
use flexid_ecat::{Segment, SubDevice, SubDeviceConfig};
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::task::JoinHandle;

const MAX_FRAMES: usize = 16;
const MAX_PDU_DATA: usize = PduStorage::element_size(1100);
const MAX_SUBDEVICES: usize = 4;
const MAX_PDI: usize = 64;
/// The emulated SubDevices' vendor id.
const VENDOR: u32 = 0x0000_0A1D;

fn identity(position: usize) -> Identity {
    Identity {
        vendor_id: VENDOR,
        product_code: 0x0402_0000 + position as u32,
        revision: 0x0001_0002,
        serial: 1000 + position as u32,
    }
}

/// `n` servo axes in a line; their clocks started at different times.
fn segment_with(n: usize, configure: impl Fn(&mut SubDeviceConfig)) -> SharedSegment {
    let mut segment = Segment::new();
    for i in 0..n {
        let mut config = SubDeviceConfig::servo_axis(identity(i), &format!("FLEXID-AX{i}"));
        config.clock_origin_ns = 3_000_000 + 7_654_321 * i as u64;
        configure(&mut config);
        segment.push(SubDevice::new(config).expect("valid SII"));
    }
    Arc::new(Mutex::new(segment))
}

fn segment(n: usize) -> SharedSegment {
    segment_with(n, |_| {})
}

fn timeouts() -> Timeouts {
    Timeouts {
        state_transition: Duration::from_millis(500),
        ..Timeouts::default()
    }
}

/// A MainDevice (leaked: one per test) linked to `segment`, and the link's task.
fn start(
    segment: SharedSegment,
    clock: Option<fn() -> u64>,
    recording: Option<Recording>,
) -> (
    &'static MainDevice<'static>,
    JoinHandle<Result<(), LinkError>>,
) {
    let storage: &'static PduStorage<MAX_FRAMES, MAX_PDU_DATA> =
        Box::leak(Box::new(PduStorage::new()));
    let (tx, rx, pdu_loop) = storage.try_split().expect("storage split once");
    let config = MainDeviceConfig {
        dc_static_sync_iterations: 100,
        ..MainDeviceConfig::default()
    };
    let maindevice = Box::leak(Box::new(MainDevice::new(pdu_loop, timeouts(), config)));
    let mut link = SegmentLink::new(tx, rx, segment);
    if let Some(clock) = clock {
        link = link.with_clock(clock);
    }
    if let Some(recording) = recording {
        link = link.recording(recording);
    }
    (maindevice, tokio::spawn(link))
}

/// ethercrab's `now` for DC: a fixed epoch, so that runs are comparable.
fn dc_now() -> u64 {
    1_000_000_000
}

#[tokio::test]
async fn init_discovers_one_subdevice_with_its_sii_identity() {
    let seg = segment(1);
    let (md, link) = start(seg.clone(), None, None);
    let group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    assert_eq!(group.len(), 1);
    let sd = group.subdevice(md, 0).expect("SubDevice 0");
    assert_eq!(sd.name(), "FLEXID-AX0");
    let id = sd.identity();
    assert_eq!(
        (id.vendor_id, id.product_id, id.revision, id.serial),
        (VENDOR, 0x0402_0000, 0x0001_0002, 1000)
    );
    assert_eq!(sd.configured_address(), 0x1000);
    assert_eq!(
        sd.description().await.expect("description").as_deref(),
        Some("FLEXID-AX0 (flexid emulated CiA 402 axis)")
    );
    {
        let seg = seg.lock().expect("segment");
        let emulated = seg.subdevice(0).expect("emulated 0");
        assert_eq!(emulated.station_address(), 0x1000);
        assert_eq!(emulated.al_state(), AlState::PreOp);
    }
    assert!(!link.is_finished(), "the link stopped: {:?}", link.await);
}

#[tokio::test]
async fn init_discovers_two_subdevices_in_ring_order_with_dc_delays() {
    let seg = segment(2);
    let (md, link) = start(seg.clone(), None, None);
    let group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    assert_eq!(group.len(), 2);
    let names: Vec<String> = group.iter(md).map(|sd| sd.name().to_string()).collect();
    assert_eq!(names, ["FLEXID-AX0", "FLEXID-AX1"]);
    let products: Vec<u32> = group.iter(md).map(|sd| sd.identity().product_id).collect();
    assert_eq!(products, [0x0402_0000, 0x0402_0001]);
    let addresses: Vec<u16> = group.iter(md).map(|sd| sd.configured_address()).collect();
    assert_eq!(addresses, [0x1000, 0x1001]);

    // Propagation delay: half the loop time through the first SubDevice (two hops).
    let hop = seg.lock().expect("segment").hop_ns;
    let delays: Vec<u32> = group.iter(md).map(|sd| sd.propagation_delay()).collect();
    assert_eq!(delays, [0, hop as u32]);

    // After the static drift compensation both system times agree, whatever the clocks'
    // origins, and the last compensation measured no difference.
    let seg = seg.lock().expect("segment");
    let t = seg.time_ns() + 1_000_000;
    let (a, b) = (seg.subdevice(0).expect("0"), seg.subdevice(1).expect("1"));
    assert_eq!(a.system_time_at(t), b.system_time_at(t));
    let difference = u32::from_le_bytes(b.memory()[0x092C..0x0930].try_into().expect("4 bytes"));
    assert_eq!(difference & 0x7FFF_FFFF, 0);
    let delay = u32::from_le_bytes(b.memory()[0x0928..0x092C].try_into().expect("4 bytes"));
    assert_eq!(u64::from(delay), hop);
    assert!(!link.is_finished());
}

#[tokio::test]
async fn sdo_upload_download_and_abort_through_coe() {
    let seg = segment(1);
    let (md, _link) = start(seg.clone(), None, None);
    let group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    let sd = group.subdevice(md, 0).expect("SubDevice 0");

    // Expedited uploads of the identity object.
    assert_eq!(sd.sdo_read::<u8>(0x1018, 0).await.expect("0x1018:0"), 4);
    assert_eq!(
        sd.sdo_read::<u32>(0x1018, 1).await.expect("0x1018:1"),
        VENDOR
    );
    assert_eq!(
        sd.sdo_read::<u32>(0x1018, 2).await.expect("0x1018:2"),
        0x0402_0000
    );
    // A normal (not expedited) upload: the device name.
    let name = sd
        .sdo_read::<heapless::String<32>>(0x1008, 0)
        .await
        .expect("0x1008");
    assert_eq!(name.as_str(), "FLEXID-AX0");

    // Expedited download of modes of operation (cyclic synchronous torque), read back through
    // CoE and seen in the emulated dictionary.
    sd.sdo_write(0x6060, 0, 10i8).await.expect("write 0x6060");
    assert_eq!(sd.sdo_read::<i8>(0x6060, 0).await.expect("0x6060"), 10);
    {
        let seg = seg.lock().expect("segment");
        let od = seg.subdevice(0).expect("emulated 0").dictionary();
        assert_eq!(od.get(0x6060, 0), Some(&[10u8][..]));
    }

    // Refusals come back as SDO aborts with their codes.
    let read_only = sd.sdo_write(0x6041, 0, 1u16).await;
    assert!(
        matches!(
            read_only,
            Err(Error::Mailbox(MailboxError::Aborted {
                address: 0x6041,
                sub_index: 0,
                ..
            }))
        ),
        "{read_only:?}"
    );
    let absent = sd.sdo_read::<u32>(0x2000, 0).await;
    assert!(
        matches!(
            absent,
            Err(Error::Mailbox(MailboxError::Aborted {
                address: 0x2000,
                ..
            }))
        ),
        "{absent:?}"
    );
    // The mailbox still serves after the aborts.
    assert_eq!(sd.sdo_read::<u32>(0x1018, 4).await.expect("0x1018:4"), 1000);
}

#[tokio::test]
async fn pdo_mapping_written_entry_by_entry_then_op_with_process_data() {
    let seg = segment(2);
    let (md, link) = start(seg.clone(), None, None);
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");

    // Remap SubDevice 1's RxPDO to control word and target torque only (ethercrab's SDO
    // download is expedited: one 32-bit entry at a time, sub-index 0 last).
    {
        let sd = group.subdevice(md, 1).expect("SubDevice 1");
        sd.sdo_write(0x1600, 0, 0u8).await.expect("clear 0x1600");
        sd.sdo_write(0x1600, 1, 0x6040_0010u32)
            .await
            .expect("entry 1");
        sd.sdo_write(0x1600, 2, 0x6071_0010u32)
            .await
            .expect("entry 2");
        sd.sdo_write(0x1600, 0, 2u8).await.expect("count 0x1600");
        // An unmappable entry is refused when the count is written.
        sd.sdo_write(0x1A00, 0, 0u8).await.expect("clear 0x1A00");
        sd.sdo_write(0x1A00, 1, 0x6040_0010u32)
            .await
            .expect("entry");
        let refused = sd.sdo_write(0x1A00, 0, 1u8).await;
        assert!(matches!(
            refused,
            Err(Error::Mailbox(MailboxError::Aborted { .. }))
        ));
        sd.sdo_write(0x1A00, 1, 0x6041_0010u32)
            .await
            .expect("entry");
        sd.sdo_write(0x1A00, 0, 1u8).await.expect("count 0x1A00");
    }
    for mut sd in group.iter_mut(md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = group
        .into_pre_op_pdi(md)
        .await
        .expect("PDI")
        .configure_dc_sync(
            md,
            DcConfiguration {
                start_delay: Duration::from_millis(1),
                sync0_period: Duration::from_micros(250),
                sync0_shift: Duration::ZERO,
            },
        )
        .await
        .expect("DC sync");
    let group = group.into_safe_op(md).await.expect("SAFE-OP");
    let group = group.into_op(md).await.expect("OP");

    // Process image: SubDevice 0 outputs 5 bytes, inputs 13; SubDevice 1 outputs 4, inputs 2.
    let io: Vec<(usize, usize)> = group
        .iter(md)
        .map(|sd| (sd.outputs_raw().len(), sd.inputs_raw().len()))
        .collect();
    assert_eq!(io, [(5, 13), (4, 2)]);

    {
        let mut seg = seg.lock().expect("segment");
        for i in 0..2 {
            let d = seg.subdevice_mut(i).expect("emulated");
            assert_eq!(d.al_state(), AlState::Op);
            let sync0 = d.sync0().expect("SYNC0 active");
            assert_eq!(sync0.cycle, 250_000);
            assert_eq!(sync0.start % 250_000, 0);
            d.dictionary_mut()
                .set(0x6041, 0, &(0x0230u16 + i as u16).to_le_bytes())
                .expect("status word");
        }
        let d0 = seg.subdevice_mut(0).expect("emulated 0");
        d0.dictionary_mut()
            .set(0x6064, 0, &(-123_456i32).to_le_bytes())
            .expect("position");
    }
    for (i, sd) in group.iter(md).enumerate() {
        let mut out = sd.outputs_raw_mut();
        out[0..2].copy_from_slice(&(0x000F_u16 + i as u16).to_le_bytes());
        out[2..4].copy_from_slice(&(-300i16 * (i as i16 + 1)).to_le_bytes());
    }
    let response = group.tx_rx(md).await.expect("tx/rx");
    // Each SubDevice reads its inputs (1) and takes its outputs (2).
    assert_eq!(response.working_counter, 6);

    let inputs: Vec<Vec<u8>> = group.iter(md).map(|sd| sd.inputs_raw().to_vec()).collect();
    assert_eq!(inputs[0][0..2], 0x0230u16.to_le_bytes());
    assert_eq!(inputs[0][2..6], (-123_456i32).to_le_bytes());
    assert_eq!(inputs[1][0..2], 0x0231u16.to_le_bytes());
    let seg_now = seg.lock().expect("segment");
    for i in 0..2 {
        let od = seg_now.subdevice(i).expect("emulated").dictionary();
        assert_eq!(
            od.get(0x6040, 0),
            Some(&(0x000F_u16 + i as u16).to_le_bytes()[..])
        );
        assert_eq!(
            od.get(0x6071, 0),
            Some(&(-300i16 * (i as i16 + 1)).to_le_bytes()[..])
        );
    }
    drop(seg_now);
    assert!(!link.is_finished());
}

#[tokio::test]
async fn refused_safe_op_reports_the_al_status_code() {
    // The SubDevice accepts SYNC0 down to 500 us; the MainDevice asks for 250 us.
    let seg = segment_with(1, |c| c.min_sync0_cycle_ns = 500_000);
    let (md, _link) = start(seg.clone(), None, None);
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    for mut sd in group.iter_mut(md) {
        sd.set_dc_sync(DcSync::Sync0);
    }
    let group = group
        .into_pre_op_pdi(md)
        .await
        .expect("PDI")
        .configure_dc_sync(
            md,
            DcConfiguration {
                start_delay: Duration::from_millis(1),
                sync0_period: Duration::from_micros(250),
                sync0_shift: Duration::ZERO,
            },
        )
        .await
        .expect("DC sync");
    let sd_address = group
        .subdevice(md, 0)
        .expect("SubDevice 0")
        .configured_address();
    assert!(group.into_safe_op(md).await.is_err());
    {
        let seg = seg.lock().expect("segment");
        let d = seg.subdevice(0).expect("emulated");
        assert_eq!(d.al_state(), AlState::PreOp);
        assert_eq!(d.al_error(), Some(EmulatedCode::SyncCycleTimeTooSmall));
    }
    // ethercrab reads the flag and the code from the registers.
    let code: u16 = {
        use ethercrab::{Command, RegisterAddress};
        Command::fprd(sd_address, RegisterAddress::AlStatusCode.into())
            .receive::<u16>(md)
            .await
            .expect("AL status code")
    };
    assert_eq!(code, 0x0036);
    assert_eq!(AlStatusCode::from(code), AlStatusCode::DcSync0CycleTime);
}

/// A deterministic segment clock: 10 us per frame.
fn stepping_clock() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static T: AtomicU64 = AtomicU64::new(0);
    T.fetch_add(10_000, Ordering::Relaxed)
}

#[tokio::test]
async fn init_traffic_returns_every_frame_marked_and_answered() {
    let recording: Recording = Arc::new(Mutex::new(Vec::new()));
    let seg = segment(2);
    let (md, _link) = start(seg.clone(), Some(stepping_clock), Some(recording.clone()));
    md.init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    let exchanges = recording.lock().expect("recording").clone();
    assert!(exchanges.len() > 100, "{} frames", exchanges.len());
    // Every returned frame is the sent one with the source MAC marked and PDU data and
    // working counters filled in: same length, same EtherCAT header, same commands and
    // indices.
    for (n, e) in exchanges.iter().enumerate() {
        assert_eq!(e.sent.len(), e.returned.len(), "frame {n}");
        assert_eq!(e.returned[6], e.sent[6] | 0x02, "frame {n}");
        assert_eq!(e.sent[12..18], e.returned[12..18], "frame {n}");
    }
    // The first frame is the BRD of the ESC type: both SubDevices answer.
    let first = &exchanges[0].returned;
    assert_eq!(first[16], 0x07);
    let len = usize::from(u16::from_le_bytes([first[22], first[23]]) & 0x07FF);
    assert_eq!(first[26], 0x11);
    assert_eq!(u16::from_le_bytes([first[26 + len], first[27 + len]]), 2);
}

#[tokio::test]
async fn ethercrab_writes_the_station_alias_and_its_checksum_into_the_eeprom() {
    let seg = segment(1);
    let (md, _link) = start(seg.clone(), None, None);
    let mut group = md
        .init_single_group::<MAX_SUBDEVICES, MAX_PDI>(dc_now)
        .await
        .expect("init");
    for mut sd in group.iter_mut(md) {
        sd.set_alias_address(0x0042).await.expect("alias written");
    }
    let seg = seg.lock().expect("segment");
    let eeprom = seg.subdevice(0).expect("emulated").eeprom();
    assert_eq!(eeprom[8..10], [0x42, 0x00]);
    // ethercrab computed the checksum with its CRC; the emulator's SII CRC agrees.
    assert_eq!(eeprom[14], flexid_ecat::esc::sii::checksum(&eeprom[..14]));
    assert_eq!(eeprom[15], 0);
}
