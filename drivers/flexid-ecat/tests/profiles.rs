//! The EtherCAT drive's firmware profile from the SubDevice's SII identity (issue 18): the
//! emulated servo's identity selects the `flexid-vdrive` profile and its `[ethercat]`
//! limits; a drive no profile knows is refused at bring-up with its identity in the
//! message, and comes up only with the generic CiA 402 profile chosen on purpose (units
//! read from the drive).

mod common;

use common::{bring_up, servo_segment, servo_segment_identified, try_bring_up, CYCLE_HZ};
use flexid_ecat::esc::sii::Identity;
use flexid_ecat::{EcatConfig, EcatError, ProfileChoice};

#[test]
fn the_emulated_servo_is_known_by_its_sii_identity() {
    let rig = bring_up(servo_segment(1));
    assert_eq!(rig.drive.profile().name, "flexid-vdrive");
    assert_eq!(rig.drive.scaling().increments_per_rev, 1_048_576.0);
    // 8 kHz is within the profile's EtherCAT minimum of 125 us; 10 kHz is not.
    let mut config = EcatConfig::at_hz(10_000.0);
    config.profile = ProfileChoice::ByIdentity;
    let Err(e) = try_bring_up(servo_segment(1), config) else {
        panic!("a 100 us cycle brought up");
    };
    assert!(
        e.to_string()
            .contains("the cycle of 100 us is shorter than the firmware's 125 us"),
        "{e}"
    );
}

#[test]
fn an_unknown_drive_is_refused_unless_the_generic_profile_is_chosen() {
    let other = Identity {
        vendor_id: 0x0000_0539,
        product_code: 0x0000_1234,
        revision: 0x0002_0001,
        serial: 9,
    };
    let Err(e) = try_bring_up(servo_segment_identified(other), EcatConfig::at_hz(CYCLE_HZ)) else {
        panic!("an unknown drive brought up");
    };
    eprintln!("{e}");
    assert!(matches!(e, EcatError::Profile { position: 0, .. }), "{e:?}");
    let text = e.to_string();
    assert!(text.contains("SubDevice 0 (0x1000, OTHER-SERVO)"), "{text}");
    assert!(
        text.contains(
            "unknown EtherCAT drive: SII vendor id 0x00000539, product code 0x00001234, \
             revision 0x00020001"
        ),
        "{text}"
    );
    assert!(
        text.contains("choose the generic CiA 402 profile"),
        "{text}"
    );
    let config = EcatConfig {
        profile: ProfileChoice::Generic,
        ..EcatConfig::at_hz(CYCLE_HZ)
    };
    let rig = try_bring_up(servo_segment_identified(other), config).expect("generic");
    assert_eq!(rig.drive.profile().name, "generic-cia402");
    // Units read from the drive: 0x608F and 0x6076 of the plant file's drive.
    assert_eq!(rig.drive.scaling().increments_per_rev, 1_048_576.0);
    assert_eq!(rig.drive.scaling().rated_torque_nm, 1.0);
}
