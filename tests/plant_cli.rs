//! `flexid simulate --plant P.toml` with and without `[effects]`, through the real binary:
//! a linear plant file keeps the exact ZOH path (same samples as `sim::simulate_position`),
//! a file with effects goes through `PlantSim`, and a bad effect is a named input error.

mod cli_common;
use cli_common::{expect_ok, flexid};

use flexid::recording::read_recording;
use std::path::{Path, PathBuf};
use std::process::Output;

fn plant(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("plants")
        .join(name)
}

fn excitation(dir: &Path) {
    let out = flexid(
        &[
            "excite",
            "multisine",
            "--period-samples",
            "2000",
            "--periods",
            "3",
            "--transient-periods",
            "1",
            "--band",
            "1",
            "400",
            "--out",
            "exc.csv",
        ],
        dir,
    );
    expect_ok(&out, "excite");
}

fn simulate(dir: &Path, plant_path: &Path, out_name: &str) -> Output {
    flexid(
        &[
            "simulate",
            "--plant",
            plant_path.to_str().unwrap(),
            "--excitation",
            "exc.csv",
            "--out",
            out_name,
        ],
        dir,
    )
}

#[test]
fn linear_plant_file_keeps_the_exact_path() {
    let dir = tempfile::tempdir().unwrap();
    excitation(dir.path());
    let p = plant("scara_shoulder.toml");
    expect_ok(&simulate(dir.path(), &p, "rec.csv"), "simulate");
    let rec = read_recording(dir.path().join("rec.csv")).unwrap();
    let file = flexid::plant_file::load_plant_file(Some(&p)).unwrap();
    assert!(!file.has_effects());
    let want =
        flexid::sim::simulate_position(&file.chain, &rec.torque_cmd_nm, &file.sim_options(1))
            .unwrap();
    let got = rec.position_rad.unwrap();
    for (a, b) in got.iter().zip(&want) {
        assert!((a - b).abs() <= 1e-12 * b.abs().max(1e-6), "{a} vs {b}");
    }
    assert!(rec.sidecar.source.unwrap().contains("exact ZOH"));
}

#[test]
fn plant_file_with_effects_goes_through_plant_sim() {
    let dir = tempfile::tempdir().unwrap();
    excitation(dir.path());
    expect_ok(
        &simulate(dir.path(), &plant("scara_shoulder.toml"), "lin.csv"),
        "linear",
    );
    expect_ok(
        &simulate(dir.path(), &plant("scara_friction.toml"), "fr.csv"),
        "friction",
    );
    let lin = read_recording(dir.path().join("lin.csv")).unwrap();
    let fr = read_recording(dir.path().join("fr.csv")).unwrap();
    assert!(fr.sidecar.source.as_deref().unwrap().contains("RK4"));
    let (a, b) = (lin.position_rad.unwrap(), fr.position_rad.unwrap());
    let scale = a.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = a
        .iter()
        .zip(&b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    assert!(
        diff > 1e-2 * scale,
        "friction changes the recording: {diff:e} vs {scale:e}"
    );

    // friction above the peak torque: the motor never moves (velocity noise is relative to
    // the velocity's RMS, here zero)
    let text = std::fs::read_to_string(plant("scara_shoulder.toml")).unwrap()
        + "\n[effects.friction]\ncoulomb_nm = 50.0\n";
    let held = dir.path().join("held.toml");
    std::fs::write(&held, text).unwrap();
    expect_ok(&simulate(dir.path(), &held, "held.csv"), "held");
    let rec = read_recording(dir.path().join("held.csv")).unwrap();
    assert!(rec.position_rad.unwrap().iter().all(|&p| p == 0.0));
}

#[test]
fn bad_effect_is_an_input_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    excitation(dir.path());
    let text = std::fs::read_to_string(plant("scara_shoulder.toml")).unwrap()
        + "\n[effects.backlash]\ncoupling = 5\nhalf_gap_rad = 1e-4\n";
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, text).unwrap();
    let out = simulate(dir.path(), &bad, "x.csv");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.toml") && err.contains("coupling"),
        "{err}"
    );
    assert!(!err.contains("panicked"));
}
