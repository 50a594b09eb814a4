//! The EDS (`eds/flexid-vdrive.eds`) describes exactly the object dictionary the drive
//! implements (issue 16, item 8): every entry of the dictionary is in the EDS and every
//! EDS entry is in the dictionary, with the same data type, access, PDO mappability and
//! default value (except the defaults a plant file sets).

use std::collections::BTreeMap;

use canopen_rs::{AccessType, Address, Value};
use flexid_vdrive::od::{self, OdDefaults};

/// One EDS sub-object: (DataType, AccessType, DefaultValue, PDOMapping).
#[derive(Debug, Clone, Default)]
struct EdsEntry {
    data_type: u16,
    access: String,
    default: Option<String>,
    pdo_mapping: bool,
}

fn parse_eds(text: &str) -> BTreeMap<(u16, u8), EdsEntry> {
    let mut sections: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    let mut current = String::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with(';') {
            continue;
        }
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            current = name.to_ascii_uppercase();
            sections.entry(current.clone()).or_default();
        } else if let Some((k, v)) = line.split_once('=') {
            sections
                .get_mut(&current)
                .expect("key before any section")
                .insert(k.trim().to_string(), v.trim().to_string());
        }
    }
    let mut out = BTreeMap::new();
    for (name, keys) in &sections {
        let (index, sub) = match name.split_once("SUB") {
            Some((i, s)) => (i, s.parse::<u8>().expect("sub-index")),
            None => (name.as_str(), 0),
        };
        let Ok(index) = u16::from_str_radix(index, 16) else {
            continue; // FileInfo, DeviceInfo, ...
        };
        let object_type = keys.get("ObjectType").map(String::as_str).unwrap_or("0x7");
        if object_type != "0x7" {
            continue; // a record or array head: its subs are the entries
        }
        let num = |k: &str| {
            let v = keys.get(k).unwrap_or_else(|| panic!("[{name}] has no {k}"));
            u16::from_str_radix(v.trim_start_matches("0x"), 16).unwrap()
        };
        out.insert(
            (index, sub),
            EdsEntry {
                data_type: num("DataType"),
                access: keys["AccessType"].to_ascii_lowercase(),
                default: keys.get("DefaultValue").cloned(),
                pdo_mapping: keys.get("PDOMapping").is_some_and(|v| v == "1"),
            },
        );
    }
    out
}

/// An EDS default as a number (`$NODEID+0x180` with node `id`).
fn eds_number(v: &str, id: u8) -> i64 {
    let v = v.trim();
    let (base, rest) = match v.strip_prefix("$NODEID+") {
        Some(r) => (i64::from(id), r),
        None => (0, v),
    };
    let n = match rest.strip_prefix("0x").or_else(|| rest.strip_prefix("0X")) {
        Some(h) => i64::from_str_radix(h, 16).unwrap(),
        None => rest.parse::<i64>().unwrap(),
    };
    base + n
}

fn value_number(v: &Value) -> Option<i64> {
    Some(match *v {
        Value::Unsigned8(x) => x.into(),
        Value::Unsigned16(x) => x.into(),
        Value::Unsigned32(x) => x.into(),
        Value::Integer8(x) => x.into(),
        Value::Integer16(x) => x.into(),
        Value::Integer32(x) => x.into(),
        _ => return None,
    })
}

/// Defaults that come from the plant file's `[drive]` section and cycle, not the EDS.
const PLANT_DEFAULTS: [(u16, u8); 5] = [
    (0x1006, 0),
    (0x1016, 1),
    (0x1017, 0),
    (0x6072, 0),
    (0x6076, 0),
];

#[test]
fn the_eds_matches_the_object_dictionary() {
    let id = 5;
    let dict = od::build(&OdDefaults {
        node_id: id,
        cycle_us: 500,
        heartbeat_ms: 0,
        heartbeat_consumer: 0,
        rated_torque_mnm: 1000,
        max_torque_permille: 3000,
        mode: 10,
    })
    .unwrap();
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/eds/flexid-vdrive.eds"
    ))
    .unwrap();
    let eds = parse_eds(&text);
    let mut problems = Vec::new();
    // every dictionary entry is in the EDS, as the EDS says
    let ranges = [(0x1000u16, 0x1FFFu16), (0x2000, 0x2FFF), (0x6000, 0x67FF)];
    let mut in_od = 0;
    for (lo, hi) in ranges {
        for index in lo..=hi {
            for sub in 0..=u8::MAX {
                let Some(e) = dict.entry(Address::new(index, sub)) else {
                    continue;
                };
                in_od += 1;
                let Some(x) = eds.get(&(index, sub)) else {
                    problems.push(format!("{index:04X}sub{sub} is not in the EDS"));
                    continue;
                };
                let dt = e.value.data_type() as u16;
                if dt != x.data_type {
                    problems.push(format!(
                        "{index:04X}sub{sub}: DataType {:#06x} in the EDS, {dt:#06x} in the drive",
                        x.data_type
                    ));
                }
                let access = match e.access {
                    AccessType::Ro => "ro",
                    AccessType::Wo => "wo",
                    AccessType::Rw => "rw",
                    AccessType::Const => "const",
                };
                if access != x.access {
                    problems.push(format!(
                        "{index:04X}sub{sub}: AccessType {} in the EDS, {access} in the drive",
                        x.access
                    ));
                }
                let mappable = sub == 0
                    && (od::RPDO_MAPPABLE.contains(&index) || od::TPDO_MAPPABLE.contains(&index));
                if mappable != x.pdo_mapping {
                    problems.push(format!(
                        "{index:04X}sub{sub}: PDOMapping {} in the EDS, {mappable} in the drive",
                        x.pdo_mapping
                    ));
                }
                if PLANT_DEFAULTS.contains(&(index, sub)) {
                    continue;
                }
                if let (Some(want), Some(d)) = (value_number(&e.value), &x.default) {
                    let got = eds_number(d, id);
                    if got != want {
                        problems.push(format!(
                            "{index:04X}sub{sub}: DefaultValue {d} in the EDS, {want:#x} in the drive"
                        ));
                    }
                }
            }
        }
    }
    // every EDS entry is in the dictionary
    for (index, sub) in eds.keys() {
        if dict.entry(Address::new(*index, *sub)).is_none() {
            problems.push(format!(
                "{index:04X}sub{sub} is in the EDS, not in the drive"
            ));
        }
    }
    // the object lists name every object of the dictionary
    let listed: Vec<u16> = text
        .lines()
        .filter_map(|l| l.split_once("=0x"))
        .filter(|(k, _)| k.chars().all(|c| c.is_ascii_digit()))
        .map(|(_, v)| u16::from_str_radix(v.trim(), 16).unwrap())
        .collect();
    for (index, _) in eds.keys().filter(|(_, s)| *s == 0) {
        if !listed.contains(index) {
            problems.push(format!("{index:04X} is not in the EDS object lists"));
        }
    }
    assert!(in_od > 60, "{in_od} entries probed");
    assert!(
        problems.is_empty(),
        "EDS vs drive:\n{}",
        problems.join("\n")
    );
}
