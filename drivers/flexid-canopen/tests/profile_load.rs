//! Firmware profile selection and errors; bus load of the default mapping vs a hand
//! computation.

use std::f64::consts::TAU;
use std::time::Duration;

use flexid_canopen::cia402::ModeOfOperation;
use flexid_canopen::pdo::{bus_load, check_bus_load, default_mapping, max_cycle_rate_hz};
use flexid_canopen::profile::{parse, ObjectMap, ProfileError, Quirk, Setting};
use flexid_canopen::{Identity, ProfileSet};

fn id(vendor: u32, product: u32, revision: u32) -> Identity {
    Identity {
        device_type: 0x0002_0192,
        vendor_id: vendor,
        product_code: product,
        revision,
        serial: 1,
    }
}

#[test]
fn builtins_parse_and_vdrive_is_selected_by_identity() {
    let set = ProfileSet::builtin();
    let p = set.select(&id(0x0000_0F1D, 0x0000_0402, 7)).unwrap();
    assert_eq!(p.name, "flexid-vdrive");
    assert_eq!(p.increments_per_rev, Setting::Value(1048576.0));
    assert_eq!(p.rated_torque, Setting::Value(1.0));
    assert_eq!(p.min_cycle_us, 250);
    assert_eq!(
        p.modes,
        vec![
            ModeOfOperation::CyclicSyncTorque,
            ModeOfOperation::ProfileTorque,
            ModeOfOperation::CyclicSyncVelocity,
            ModeOfOperation::CyclicSyncPosition
        ]
    );
    let s = p.scaling(f64::NAN, f64::NAN);
    assert!((s.velocity_unit_rad_s - TAU / 1048576.0).abs() < 1e-18);
    // another product of the same vendor, another vendor: the generic fallback
    for other in [
        id(0x0000_0F1D, 0x0000_0403, 0),
        id(0x0000_009A, 0x0000_0402, 0),
    ] {
        let g = set.select(&other).unwrap();
        assert_eq!(g.name, "generic-cia402");
        assert_eq!(g.increments_per_rev, Setting::Read(0x608F));
        assert_eq!(g.rated_torque, Setting::Read(0x6076));
        assert_eq!(g.objects, ObjectMap::default());
    }
}

#[test]
fn narrower_revision_range_wins_and_dir_profiles_load() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("acme-fw2.toml"),
        r#"
name = "acme-fw2"
modes = ["CST", "CSV"]
min_cycle_us = 500
quirks = ["mode-display-lags", "keep-unused-pdos"]

[identity]
vendor_id = 0x0000_0ACE
product_code = 7
revision_min = 0x0002_0000
revision_max = 0x0002_FFFF

[objects]
target_torque = 0x2071

[units]
increments_per_rev = 131072
rated_torque = "read 0x6076"
velocity_unit = "0.1rpm"
"#,
    )
    .unwrap();
    std::fs::write(
        dir.path().join("acme-any.toml"),
        r#"
name = "acme-any"
modes = ["CST"]
min_cycle_us = 1000
[identity]
vendor_id = 0x0000_0ACE
product_code = 7
[units]
increments_per_rev = 4096
rated_torque = 2.5
"#,
    )
    .unwrap();
    std::fs::write(dir.path().join("notes.txt"), "not a profile").unwrap();
    let set = ProfileSet::builtin_and_dir(dir.path()).unwrap();
    assert_eq!(set.profiles().len(), 4);
    let fw2 = set.select(&id(0xACE, 7, 0x0002_0003)).unwrap();
    assert_eq!(fw2.name, "acme-fw2");
    assert!(fw2.has(Quirk::ModeDisplayLags) && fw2.has(Quirk::KeepUnusedPdos));
    assert_eq!(fw2.objects.target_torque, 0x2071);
    assert_eq!(fw2.objects.controlword, 0x6040);
    assert_eq!(fw2.max_pdo_entries, 8);
    let s = fw2.scaling(f64::NAN, 0.8);
    assert_eq!(s.rated_torque_nm, 0.8);
    assert!((s.velocity_rad_s(600) - TAU).abs() < 1e-12); // 60 rpm = 2 pi rad/s
    assert_eq!(
        set.select(&id(0xACE, 7, 0x0003_0000)).unwrap().name,
        "acme-any"
    );
    assert_eq!(set.select(&id(0xACE, 8, 0)).unwrap().name, "generic-cia402");
}

fn err(text: &str) -> String {
    parse("drives/x.toml", text).unwrap_err().to_string()
}

#[test]
fn errors_name_file_and_key() {
    let base = "name = \"x\"\nmodes = [\"CST\"]\nmin_cycle_us = 250\n[identity]\nvendor_id = 1\nproduct_code = 2\n";
    // unknown quirk
    let e = err(&format!(
        "quirks = [\"fast-mode\"]\n{base}[units]\nincrements_per_rev = 1\nrated_torque = 1.0\n"
    ));
    assert!(e.starts_with("firmware profile drives/x.toml: "), "{e}");
    assert!(
        e.contains("fast-mode") && e.contains("keep-unused-pdos"),
        "{e}"
    );
    // unknown key in a table
    let e = err(&format!(
        "{base}[units]\nincrements_per_rev = 1\nrated_torque = 1.0\nspeed = 3\n"
    ));
    assert!(e.contains("unknown field `speed`"), "{e}");
    // missing key
    let e = err(&format!("{base}[units]\nincrements_per_rev = 1\n"));
    assert!(e.contains("missing field `rated_torque`"), "{e}");
    // bad values
    assert_eq!(
        err(&format!("{base}[units]\nincrements_per_rev = -5\nrated_torque = 1.0\n")),
        "firmware profile drives/x.toml: key `units.increments_per_rev`: -5 is not a positive number"
    );
    assert_eq!(
        err(&format!("{base}[units]\nincrements_per_rev = 1\nrated_torque = \"ask the vendor\"\n")),
        "firmware profile drives/x.toml: key `units.rated_torque`: \"ask the vendor\": expected a number or \"read 0xIIII\""
    );
    assert!(err(&format!("{base}[units]\nincrements_per_rev = 1\nrated_torque = 1.0\nvelocity_unit = \"furlong/fortnight\"\n"))
        .contains("key `units.velocity_unit`"));
    let nine = base.replace(
        "min_cycle_us = 250",
        "min_cycle_us = 250\nmax_pdo_entries = 9",
    );
    assert!(err(&format!(
        "{nine}[units]\nincrements_per_rev = 1\nrated_torque = 1.0\n"
    ))
    .contains("key `max_pdo_entries`: 9 is outside 1..=8"));
    // only the generic profile may go without identity
    assert!(err("name = \"y\"\nmodes = [\"CST\"]\nmin_cycle_us = 250\n[units]\nincrements_per_rev = 1\nrated_torque = 1.0\n")
        .contains("key `identity`: missing"));
    // a bad file in a directory: the error names the path
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("bad.toml"), "name = 3").unwrap();
    let e = ProfileSet::builtin_and_dir(dir.path()).unwrap_err();
    assert!(
        matches!(e, ProfileError::Parse { ref file, .. } if file.ends_with("bad.toml")),
        "{e}"
    );
}

#[test]
fn bus_load_of_the_default_mapping_by_hand() {
    let m = default_mapping(&ObjectMap::default());
    // Worst-case frame bits 55 + 10 n (standard id, stuffing and IFS, flexid-can
    // timing.rs): SYNC 0 B = 55, RPDO1 4 B = 95, TPDO1 8 B = 135, TPDO2 4 B = 95.
    assert_eq!(m.cycle_bits(), 55 + 95 + 135 + 95);
    // heartbeats (1 B = 65 bits) of master and drive every 100 ms: 1300 bit/s
    let hb = [Duration::from_millis(100), Duration::from_millis(100)];
    let load = bus_load(&m, &hb, 1000.0, 1_000_000);
    assert!(
        (load - (380.0 * 1000.0 + 1300.0) / 1e6).abs() < 1e-12,
        "{load}"
    );
    assert!((load - 0.3813).abs() < 1e-12);
    // 0.7 of 1 Mbit/s: (700000 - 1300) / 380 = 1838.68 Hz (1838 in messages: rounded down)
    let max = max_cycle_rate_hz(&m, &hb, 1_000_000, 0.7);
    assert!((max - 698_700.0 / 380.0).abs() < 1e-9, "{max}");
    assert_eq!(check_bus_load(&m, &hb, 1000.0, 1_000_000, 0.7), Ok(load));
    // 2 kHz: 761300 bit/s = 76.1 %; needs 761300 / 0.7 = 1087572 bit/s
    let e = check_bus_load(&m, &hb, 2000.0, 1_000_000, 0.7).unwrap_err();
    assert_eq!(e.min_bitrate, 1_087_572);
    assert_eq!(
        e.to_string(),
        "bus load 76.1 % at 2000 Hz on 1000000 bit/s exceeds 70 %: lower the cycle rate to at most 1838 Hz or raise the bitrate to at least 1087572 bit/s (above the 1 Mbit/s of classic CAN)"
    );
    // 4 kHz on 500 kbit/s
    let e = check_bus_load(&m, &hb, 4000.0, 500_000, 0.7).unwrap_err();
    assert_eq!(
        e.to_string(),
        "bus load 304.3 % at 4000 Hz on 500000 bit/s exceeds 70 %: lower the cycle rate to at most 917 Hz or raise the bitrate to at least 2173286 bit/s (above the 1 Mbit/s of classic CAN)"
    );
}

#[test]
fn pdo_codecs_by_hand() {
    use flexid_canopen::pdo::{pack_rpdo1, Tpdo1, Tpdo2};
    assert_eq!(pack_rpdo1(0x000F, -1000), [0x0F, 0x00, 0x18, 0xFC]);
    let t = Tpdo1::unpack(&[0x37, 0x06, 0x00, 0x00, 0x10, 0x00, 0xF4, 0x01]).unwrap();
    assert_eq!(
        (t.statusword, t.position, t.torque),
        (0x0637, 0x0010_0000, 500)
    );
    assert_eq!(t.pack(), [0x37, 0x06, 0x00, 0x00, 0x10, 0x00, 0xF4, 0x01]);
    assert!(Tpdo1::unpack(&[0; 7]).is_err());
    assert_eq!(
        Tpdo2::unpack(&[0xFF, 0xFF, 0xFF, 0xFF]).unwrap().velocity,
        -1
    );
    assert!(Tpdo2::unpack(&[0; 3]).is_err());
}

#[test]
fn ethercat_identities_select_by_sii_identity_and_never_fall_back() {
    let set = ProfileSet::builtin();
    // The emulated EtherCAT servo's SII identity: the flexid-vdrive profile, its EtherCAT
    // minimum cycle.
    let p = set
        .select_ethercat(&id(0x0000_0A1D, 0x0402_0000, 3))
        .expect("known");
    assert_eq!(p.name, "flexid-vdrive");
    let e = p.ethercat.expect("[ethercat]");
    assert_eq!(e.min_cycle_us, Some(125));
    // The CAN identity of the same drive is not an EtherCAT one, and an unknown SubDevice
    // gets no profile (no generic fallback: the caller refuses it or chooses generic).
    assert!(set
        .select_ethercat(&id(0x0000_0F1D, 0x0000_0402, 0))
        .is_none());
    assert!(set
        .select_ethercat(&id(0x0000_0A1D, 0x0402_0001, 0))
        .is_none());
    assert!(set
        .get("generic-cia402")
        .expect("generic")
        .ethercat
        .is_none());
    // Revision ranges as on CAN; an empty range is an error naming the key.
    let text = |lo: u32, hi: u32| {
        format!(
            "name = \"acme-ecat\"\nmodes = [\"CST\"]\nmin_cycle_us = 1000\n\
             [identity]\nvendor_id = 1\nproduct_code = 2\n\
             [ethercat]\nvendor_id = 0x539\nproduct_code = 0x7\nrevision_min = {lo}\n\
             revision_max = {hi}\n\
             [units]\nincrements_per_rev = 4096\nrated_torque = 2.0\n"
        )
    };
    let mut set = ProfileSet::builtin();
    set.insert(parse("acme-ecat.toml", &text(2, 5)).expect("valid"));
    let acme = |rev| {
        set.select_ethercat(&id(0x539, 7, rev))
            .map(|p| p.name.clone())
    };
    assert_eq!(acme(3).as_deref(), Some("acme-ecat"));
    assert_eq!(acme(6), None);
    let err = parse("bad.toml", &text(5, 2)).unwrap_err().to_string();
    assert!(err.contains("ethercat.revision_min"), "{err}");
    let err = parse(
        "bad.toml",
        &text(2, 5).replace("revision_max", "revision_maxx"),
    )
    .unwrap_err()
    .to_string();
    assert!(err.contains("revision_maxx"), "{err}");
}
