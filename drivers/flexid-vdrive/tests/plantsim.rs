//! The main crate's nonlinear plant behind the drive: TPDO positions through RPDO1 + SYNC against
//! `flexid_core::plant::simulate_positions` of the same spec.

mod common;
use common::*;

use flexid_vdrive::{plant_drive, ClockMode, DrivePlant};

#[test]
fn plantsim_behind_the_protocol_matches_its_own_simulation() {
    let text = format!(
        "{}\n[effects]\ncurrent_loop = {{ bandwidth_hz = 600.0 }}\nfriction = {{ coulomb_nm = 0.02, viscous_nms_per_rad = 0.001 }}\n",
        flexid_core::plant::DEFAULT_PLANT
    );
    let p = DrivePlant::parse(&text, "effects plant").unwrap();
    assert!(p.plant.has_effects());
    let mut d = plant_drive(&p, ClockMode::LockStep, 7).unwrap();
    let now = std::time::Duration::ZERO;
    d.power_on(now);
    d.on_frame(&frame(0x000, &[0x01, 0x05]), now);
    for cw in [0x06u8, 0x07, 0x0F] {
        d.on_frame(&frame(0x205, &[cw, 0, 0, 0]), now);
    }
    let permille: Vec<i16> = (0..2000)
        .map(|k| (300.0 * (k as f64 * 0.05).sin() + 100.0).round() as i16)
        .collect();
    let mut got = Vec::new();
    for &t in &permille {
        let [a, b] = t.to_le_bytes();
        d.on_frame(&frame(0x205, &[0x0F, 0, a, b]), now);
        let out = d.on_frame(&frame(0x080, &[]), now);
        let f = out.iter().find(|f| f.id().raw() == 0x185).unwrap();
        got.push(i32::from_le_bytes(f.data()[2..6].try_into().unwrap()));
    }
    let torque: Vec<f64> = permille.iter().map(|&t| f64::from(t) / 1000.0).collect();
    let want = flexid_core::plant::simulate_positions(
        &p.plant.spec(),
        &torque,
        2000.0,
        p.plant.substeps(),
        7,
    )
    .unwrap();
    let inc = f64::from(1u32 << 20) / (2.0 * std::f64::consts::PI);
    for k in 0..torque.len() {
        assert!(
            (f64::from(got[k]) - want[k] * inc).abs() <= 0.5 + 1e-6,
            "sample {k}"
        );
    }
    assert!(want.last().unwrap().abs() * inc > 1000.0, "the axis moved");
}
