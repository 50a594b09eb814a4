//! `flexid bode --no-model` draws the measurement without identifying anything, so a record
//! the identification refuses is still drawn (a world stepped sine whose low level drove a
//! load on a cubic spring out of any steady state: one usable line, and `--no-model` used to
//! stop at the identification's "pair detection: 1 usable lines, at least 5 needed").

mod cli_common;

use cli_common::text;
use std::process::Command;

/// A record whose velocity does not answer its torque: independent noise (a xorshift
/// sequence each), 1 kHz, 4 s. No line of its FRF stands out of the scatter.
fn unrelated_noise(dir: &std::path::Path) -> std::path::PathBuf {
    let mut s = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let mut csv = String::from("time_s,torque_cmd_nm,velocity_rad_s\n");
    for k in 0..4000 {
        let (u, v) = (next(), next());
        csv.push_str(&format!("{:e},{u:e},{v:e}\n", k as f64 / 1000.0));
    }
    let p = dir.join("noise.csv");
    std::fs::write(&p, csv).unwrap();
    p
}

#[test]
fn the_measurement_is_drawn_without_an_identification() {
    let dir = tempfile::tempdir().unwrap();
    let rec = unrelated_noise(dir.path());
    let run = |args: &[&str]| {
        Command::new(env!("CARGO_BIN_EXE_flexid"))
            .args(args)
            .current_dir(dir.path())
            .output()
            .expect("run flexid")
    };
    let drawn = run(&[
        "bode",
        rec.to_str().unwrap(),
        "--out",
        "b.svg",
        "--no-model",
    ]);
    let err = text(&drawn.stderr);
    assert!(drawn.status.success(), "bode --no-model:\n{err}");
    assert!(!err.contains("identifying"), "nothing identified:\n{err}");
    assert!(
        !err.contains("flexid identify"),
        "no fit's progress:\n{err}"
    );
    let svg = std::fs::read_to_string(dir.path().join("b.svg")).unwrap();
    assert!(
        svg.contains("measured") && svg.contains("Magnitude [dB"),
        "{svg}"
    );
    assert!(!svg.contains("identified"), "no model drawn");
    assert!(!svg.contains("NaN"), "no NaN in the picture");
}
