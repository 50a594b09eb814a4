//! Log lines carry no ANSI colour codes when stderr is not a terminal (a pipe, a file, the
//! journal, CI logs), with or without `NO_COLOR`.

mod cli_common;

use cli_common::text;
use std::process::Command;

/// A recording with an unknown column: reading it logs a warning through `tracing`.
fn recording_with_unknown_column(dir: &std::path::Path) -> std::path::PathBuf {
    let mut csv = String::from("time_s,torque_cmd_nm,velocity_rad_s,mystery_unit\n");
    for k in 0..64 {
        let t = k as f64 / 1000.0;
        let u = (2.0 * std::f64::consts::PI * 50.0 * t).sin();
        csv.push_str(&format!("{t:e},{u:e},{:e},0\n", 0.5 * u));
    }
    let p = dir.join("rec.csv");
    std::fs::write(&p, csv).unwrap();
    p
}

#[test]
fn warnings_on_a_pipe_have_no_colour_codes() {
    let dir = tempfile::tempdir().unwrap();
    let rec = recording_with_unknown_column(dir.path());
    for no_color in [None, Some("1")] {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_flexid"));
        cmd.args([
            "bode",
            rec.to_str().unwrap(),
            "--out",
            "b.svg",
            "--no-model",
        ])
        .current_dir(dir.path())
        .env("FLEXID_LOG", "warn")
        .env_remove("NO_COLOR");
        if let Some(v) = no_color {
            cmd.env("NO_COLOR", v);
        }
        let out = cmd.output().expect("run flexid");
        let err = text(&out.stderr);
        assert!(
            err.contains("ignoring unknown column `mystery_unit`"),
            "the reader's warning reaches stderr (NO_COLOR={no_color:?}):\n{err}"
        );
        assert!(
            !err.contains('\u{1b}'),
            "no escape codes on a pipe (NO_COLOR={no_color:?}):\n{err:?}"
        );
    }
}
