//! The `flexid` command line is a contract other tools call; these tests drive the real
//! binary (`CARGO_BIN_EXE_flexid`) in temporary folders and check:
//!
//! * `excite multisine` writes the CSV and its JSON description; `simulate` (default plant)
//!   writes a recording and its sidecar; `identify --json` exits 0, prints a table with
//!   units and writes `model.masses`, `model.inertia_kgm2` (motor first),
//!   `model.stiffness_nm_per_rad`, `model.resonance_hz`, `model.antiresonance_hz` that match
//!   `plants/scara_shoulder.toml` within a few %; `--masses N` is honoured;
//!   `bode --out` writes an SVG with its axis labels;
//! * malformed recordings (a bad number, a missing column, non-uniform time) give exit
//!   code 2 and a message naming the line and column, never a panic; a missing file gives
//!   exit code 2 and names the path; nonsense options (`--masses 0`, `--band 5 1`) fail with
//!   a message;
//! * without the JSON sidecar the rate is inferred from `time_s` and the period from the
//!   torque, and the model is still right;
//! * `demo --out DIR` writes excitation.csv, recording.csv, result.json and bode.svg;
//! * `diagnose --masses 1` on a non-periodic recording takes the trajectory path (IDIM-LS
//!   of a rigid body with friction), keeps the JSON contract and draws a force plot.

mod cli_common;
use cli_common::{expect_code, flexid, text};

use flexid::cli::plant::PlantFile;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn read_json(p: &Path) -> Value {
    let t = std::fs::read_to_string(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
    serde_json::from_str(&t).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

fn floats(v: &Value, key: &str) -> Vec<f64> {
    v[key]
        .as_array()
        .unwrap_or_else(|| panic!("`{key}` is not an array in {v}"))
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

fn plant() -> PlantFile {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("plants/scara_shoulder.toml");
    flexid::plant_file::load_plant_file(Some(&path)).expect("plant file")
}

fn assert_close(got: &[f64], want: &[f64], tol: f64, what: &str) {
    assert_eq!(got.len(), want.len(), "{what}: {got:?} vs {want:?}");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            ((g - w) / w).abs() <= tol,
            "{what}[{i}] = {g:e}, plant {w:e} ({:+.2} %, tolerance {} %)",
            100.0 * (g - w) / w,
            100.0 * tol
        );
    }
}

/// The model of `identify --json` matches the default plant within `tol`.
fn assert_matches_plant(model: &Value, tol: f64) {
    let p = plant();
    let ch = &p.chain;
    assert_eq!(
        model["masses"].as_u64(),
        Some(ch.masses() as u64),
        "{model}"
    );
    assert_close(
        &floats(model, "inertia_kgm2"),
        &ch.inertia_kgm2,
        tol,
        "inertia_kgm2",
    );
    assert_close(
        &floats(model, "stiffness_nm_per_rad"),
        &ch.stiffness_nm_per_rad,
        tol,
        "stiffness_nm_per_rad",
    );
    assert_close(
        &floats(model, "resonance_hz"),
        &ch.resonances_hz(),
        tol,
        "resonance_hz",
    );
    assert_close(
        &floats(model, "antiresonance_hz"),
        &ch.antiresonances_hz(),
        tol,
        "antiresonance_hz",
    );
}

/// A recording of the default plant with an excitation that resolves it (like the demo:
/// line spacing 0.25 Hz < AR1/10, band to 800 Hz = 0.4 fs beyond the 590 Hz resonance,
/// amplitude rising with frequency). Returns the recording's path.
fn resolving_recording(dir: &Path) -> PathBuf {
    let out = flexid(
        &[
            "excite",
            "multisine",
            "--fs",
            "2000",
            "--period-samples",
            "8000",
            "--band",
            "0.25",
            "800",
            "--amplitude-exponent",
            "1",
            "--peak-nm",
            "2",
            "--periods",
            "8",
            "--out",
            "EXC.csv",
        ],
        dir,
    );
    expect_code(&out, 0, "excite");
    let out = flexid(
        &["simulate", "--excitation", "EXC.csv", "--out", "REC.csv"],
        dir,
    );
    expect_code(&out, 0, "simulate");
    dir.join("REC.csv")
}

#[test]
fn excite_simulate_identify_bode() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // the documented example invocation
    let out = flexid(
        &[
            "excite",
            "multisine",
            "--fs",
            "2000",
            "--period-samples",
            "4000",
            "--band",
            "1",
            "400",
            "--periods",
            "6",
            "--out",
            "EXC.csv",
        ],
        dir,
    );
    expect_code(&out, 0, "excite");
    let csv = std::fs::read_to_string(dir.join("EXC.csv")).unwrap();
    assert!(csv.starts_with("time_s,torque_cmd_nm"), "{}", &csv[..40]);
    assert_eq!(csv.lines().count(), 1 + 7 * 4000, "1 transient + 6 periods");
    let desc = read_json(&dir.join("EXC.json"));
    assert_eq!(desc["sample_rate_hz"].as_f64(), Some(2000.0), "{desc}");
    let exc = &desc["excitation"];
    assert_eq!(exc["period_samples"].as_u64(), Some(4000), "{desc}");
    assert_eq!(exc["periods"].as_u64(), Some(6), "{desc}");
    assert_eq!(exc["transient_periods"].as_u64(), Some(1), "{desc}");
    let band = floats(exc, "band_hz");
    assert!(band[0] >= 1.0 - 1e-9 && band[1] <= 400.0 + 1e-9, "{band:?}");

    let out = flexid(
        &["simulate", "--excitation", "EXC.csv", "--out", "REC.csv"],
        dir,
    );
    expect_code(&out, 0, "simulate");
    assert!(dir.join("REC.csv").is_file() && dir.join("REC.json").is_file());
    let rec = flexid::recording::read_recording(dir.join("REC.csv")).unwrap();
    assert_eq!(rec.len(), 7 * 4000);
    assert!(rec.position_rad.is_some());

    let out = flexid(&["identify", "REC.csv", "--json", "OUT.json"], dir);
    let (so, _) = expect_code(&out, 0, "identify");
    for unit in ["kg m^2", "N m/rad", "Hz"] {
        assert!(so.contains(unit), "table lacks the unit {unit:?}:\n{so}");
    }
    let j = read_json(&dir.join("OUT.json"));
    let m = &j["model"];
    let n = m["masses"].as_u64().expect("model.masses") as usize;
    assert!(n >= 2, "{m}");
    assert_eq!(floats(m, "inertia_kgm2").len(), n);
    assert_eq!(floats(m, "stiffness_nm_per_rad").len(), n - 1);
    assert_eq!(floats(m, "resonance_hz").len(), n - 1);
    assert_eq!(floats(m, "antiresonance_hz").len(), n - 1);
    // this band (1..400 Hz) holds the 2.9/5 Hz arm pair; the harmonic-drive resonance at
    // 590 Hz lies above it, so only the arm pair is required here
    let p = plant();
    let ar = floats(m, "antiresonance_hz");
    let r = floats(m, "resonance_hz");
    let (ar1, r1) = (p.chain.antiresonances_hz()[0], p.chain.resonances_hz()[0]);
    assert!(((ar[0] - ar1) / ar1).abs() < 0.03, "AR1 {} vs {ar1}", ar[0]);
    assert!(((r[0] - r1) / r1).abs() < 0.03, "R1 {} vs {r1}", r[0]);

    // --masses is honoured, whatever the automatic choice was
    let out = flexid(
        &["identify", "REC.csv", "--masses", "3", "--json", "M3.json"],
        dir,
    );
    expect_code(&out, 0, "identify --masses 3");
    let m3 = read_json(&dir.join("M3.json"));
    assert_eq!(m3["model"]["masses"].as_u64(), Some(3), "{}", m3["model"]);
    assert_eq!(floats(&m3["model"], "inertia_kgm2").len(), 3);
    assert_eq!(floats(&m3["model"], "stiffness_nm_per_rad").len(), 2);

    let out = flexid(&["bode", "REC.csv", "--out", "bode.svg"], dir);
    expect_code(&out, 0, "bode");
    let svg = std::fs::read_to_string(dir.join("bode.svg")).unwrap();
    assert!(svg.contains("<svg"), "not an SVG");
    assert!(svg.contains("Frequency [Hz]"), "no frequency axis label");
    assert!(svg.contains("Magnitude"), "no magnitude axis label");
}

#[test]
fn identify_matches_the_plant_file() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    resolving_recording(dir);
    let out = flexid(&["identify", "REC.csv", "--json", "OUT.json"], dir);
    expect_code(&out, 0, "identify");
    let j = read_json(&dir.join("OUT.json"));
    assert_matches_plant(&j["model"], 0.03);
}

/// `--masses 2` on the 3-body plant asks for the best 2-body approximation: it must be
/// honoured (exit 0, a 2-body model), not fail.
#[test]
fn masses_below_the_true_order_is_honoured() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    resolving_recording(dir);
    let out = flexid(
        &["identify", "REC.csv", "--masses", "2", "--json", "M2.json"],
        dir,
    );
    expect_code(&out, 0, "identify --masses 2");
    let j = read_json(&dir.join("M2.json"));
    assert_eq!(j["model"]["masses"].as_u64(), Some(2), "{}", j["model"]);
    assert_eq!(floats(&j["model"], "inertia_kgm2").len(), 2);
}

#[test]
fn identify_without_sidecar_infers_rate_and_period() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    resolving_recording(dir);
    std::fs::remove_file(dir.join("REC.json")).unwrap();
    let rec = flexid::recording::read_recording(dir.join("REC.csv")).unwrap();
    assert!(
        (rec.sample_rate_hz - 2000.0).abs() < 1e-6,
        "{}",
        rec.sample_rate_hz
    );
    let exc = rec
        .sidecar
        .excitation
        .as_ref()
        .expect("inferred excitation");
    assert_eq!(exc.period_samples, 8000, "{exc:?}");
    let out = flexid(&["identify", "REC.csv", "--json", "OUT.json"], dir);
    expect_code(&out, 0, "identify without sidecar");
    let j = read_json(&dir.join("OUT.json"));
    assert_matches_plant(&j["model"], 0.03);
}

/// Write a recording whose line `line` (1-based) is replaced by `f(line text)`.
fn corrupt(src: &Path, dst: &Path, edit: impl Fn(usize, &str) -> Option<String>) {
    let t = std::fs::read_to_string(src).unwrap();
    let mut out = String::new();
    for (i, l) in t.lines().enumerate() {
        if let Some(s) = edit(i + 1, l) {
            out.push_str(&s);
            out.push('\n');
        }
    }
    std::fs::write(dst, out).unwrap();
}

#[test]
fn malformed_recordings_exit_2_with_line_and_column() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    // a short recording is enough: the reader fails before any analysis
    let exc = flexid(
        &[
            "excite",
            "multisine",
            "--period-samples",
            "400",
            "--band",
            "5",
            "400",
            "--periods",
            "3",
            "--out",
            "EXC.csv",
        ],
        dir,
    );
    expect_code(&exc, 0, "excite");
    let sim = flexid(
        &["simulate", "--excitation", "EXC.csv", "--out", "REC.csv"],
        dir,
    );
    expect_code(&sim, 0, "simulate");
    let src = dir.join("REC.csv");
    let header = std::fs::read_to_string(&src)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_string();
    let cols: Vec<&str> = header.split(',').collect();
    let pos_col = cols.iter().position(|c| *c == "position_rad").unwrap();

    // a bad number on line 7, column position_rad
    corrupt(&src, &dir.join("bad.csv"), |i, l| {
        Some(if i == 7 {
            let mut f: Vec<String> = l.split(',').map(String::from).collect();
            f[pos_col] = "1.2.3".into();
            f.join(",")
        } else {
            l.to_string()
        })
    });
    let out = flexid(&["identify", "bad.csv"], dir);
    let (_, se) = expect_code(&out, 2, "bad number");
    assert!(se.contains("line 7"), "{se}");
    assert!(se.contains("position_rad"), "{se}");
    assert!(se.contains("1.2.3"), "{se}");

    // a missing column: torque_cmd_nm removed everywhere
    let tq = cols.iter().position(|c| *c == "torque_cmd_nm").unwrap();
    corrupt(&src, &dir.join("nocol.csv"), |_, l| {
        let f: Vec<&str> = l
            .split(',')
            .enumerate()
            .filter(|(k, _)| *k != tq)
            .map(|(_, x)| x)
            .collect();
        Some(f.join(","))
    });
    let out = flexid(&["identify", "nocol.csv"], dir);
    let (_, se) = expect_code(&out, 2, "missing column");
    assert!(se.contains("line 1"), "{se}");
    assert!(se.contains("torque_cmd_nm"), "{se}");

    // non-uniform time: line 50 jumps by half a step (no sidecar, so time_s sets the rate)
    corrupt(&src, &dir.join("jitter.csv"), |i, l| {
        Some(if i == 50 {
            let mut f: Vec<String> = l.split(',').map(String::from).collect();
            let t: f64 = f[0].parse().unwrap();
            f[0] = format!("{:e}", t + 0.5 / 2000.0);
            f.join(",")
        } else {
            l.to_string()
        })
    });
    let out = flexid(&["identify", "jitter.csv"], dir);
    let (_, se) = expect_code(&out, 2, "non-uniform time");
    assert!(se.contains("line 50") || se.contains("line 51"), "{se}");
    assert!(se.contains("time_s"), "{se}");

    // a row with a field missing
    corrupt(&src, &dir.join("short.csv"), |i, l| {
        Some(if i == 12 {
            l.rsplit_once(',').unwrap().0.to_string()
        } else {
            l.to_string()
        })
    });
    let out = flexid(&["identify", "short.csv"], dir);
    let (_, se) = expect_code(&out, 2, "short row");
    assert!(se.contains("line 12"), "{se}");

    // bode reads the same way
    let out = flexid(&["bode", "bad.csv", "--out", "b.svg"], dir);
    let (_, se) = expect_code(&out, 2, "bode on a bad file");
    assert!(se.contains("line 7"), "{se}");
}

#[test]
fn missing_file_and_nonsense_options() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out = flexid(&["identify", "does/not/exist.csv"], dir);
    let (_, se) = expect_code(&out, 2, "missing file");
    assert!(se.contains("does/not/exist.csv"), "{se}");

    resolving_recording(dir);
    for (args, what) in [
        (vec!["identify", "REC.csv", "--masses", "0"], "--masses 0"),
        (
            vec!["identify", "REC.csv", "--band", "5", "1"],
            "--band 5 1",
        ),
        (
            vec!["bode", "REC.csv", "--out", "b.svg", "--band", "5", "1"],
            "bode --band 5 1",
        ),
        (vec!["identify", "REC.csv", "--starts", "0"], "--starts 0"),
        (
            vec!["excite", "multisine", "--band", "5", "1", "--out", "E.csv"],
            "excite --band 5 1",
        ),
    ] {
        let out = flexid(&args, dir);
        let (so, se) = (text(&out.stdout), text(&out.stderr));
        assert!(
            !out.status.success(),
            "{what}: exit status {:?}\n{so}\n{se}",
            out.status
        );
        assert!(!se.contains("panicked"), "{what}: panic\n{se}");
        assert!(se.contains("error"), "{what}: no message\n{se}");
        assert!(
            se.contains("masses") || se.contains("band") || se.contains("starts"),
            "{what}: the message does not name the option\n{se}"
        );
    }
    assert!(
        !dir.join("E.csv").exists(),
        "a rejected excitation was written"
    );
    // issue 16: a cap beyond what a duration holds panicked; it is no cap
    let out = flexid(
        &[
            "identify",
            "REC.csv",
            "--max-seconds",
            "1e300",
            "--json",
            "cap.json",
        ],
        dir,
    );
    let se = text(&out.stderr);
    assert!(!se.contains("panicked"), "--max-seconds 1e300: panic\n{se}");
    assert!(
        out.status.success(),
        "--max-seconds 1e300: {:?}\n{se}",
        out.status
    );
    assert!(dir.join("cap.json").is_file());
}

#[test]
fn demo_writes_its_four_files() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let out = flexid(&["demo", "--out", "demo"], dir);
    let (so, se) = expect_code(&out, 0, "demo");
    if se.contains("bus load") {
        // over the bus: an honest 1 Mbit/s classic CAN bus, within the 70 % admission
        assert!(se.contains("% at 1000000 bit/s"), "{se}");
        assert!(se.contains("at 1800 Hz"), "{se}");
    }
    for f in ["excitation.csv", "recording.csv", "result.json", "bode.svg"] {
        let p = dir.join("demo").join(f);
        assert!(
            p.is_file() && std::fs::metadata(&p).unwrap().len() > 0,
            "{f} missing"
        );
    }
    assert!(so.contains("kg m^2"), "{so}");
    let j = read_json(&dir.join("demo/result.json"));
    // a wrong model order says everything the demo printed (cycle counters, fit notes), so
    // that a failure on a loaded CI host can be told apart from an identification defect
    let masses = j["model"]["masses"].as_u64();
    assert_eq!(
        masses,
        Some(plant().chain.masses() as u64),
        "demo model: {}\n--- stdout\n{so}\n--- stderr\n{se}",
        j["model"]
    );
    assert_matches_plant(&j["model"], 0.03);
}

/// A non-periodic recording of a rigid body with Coulomb and viscous friction, written as
/// `REC.csv` + `REC.json` (no excitation: not periodic): open loop, a bang-bang torque
/// plus a sine, held over each sample, integrated on 20 sub-steps with stiction, the
/// encoder quantised to 2^16 counts per turn. Returns (J, Fv, Fc) [kg m², N m s/rad, N m].
fn trajectory_recording(dir: &Path, velocity_only: bool) -> (f64, f64, f64) {
    let (j, fv, fc, fs, sub) = (0.05, 0.3, 0.4, 1000.0, 20);
    let count = 2.0 * std::f64::consts::PI / 65536.0;
    let h = 1.0 / (fs * sub as f64);
    let (mut q, mut v) = (0.0f64, 0.0f64);
    let mut csv = if velocity_only {
        String::from("time_s,torque_cmd_nm,velocity_rad_s\n")
    } else {
        String::from("time_s,torque_cmd_nm,position_rad\n")
    };
    for k in 0..12_000 {
        let t = k as f64 / fs;
        let tau = 1.5 * (2.0 * std::f64::consts::PI * 0.37 * t).sin().signum()
            + 0.6 * (2.0 * std::f64::consts::PI * 1.7 * t).sin();
        let motion = if velocity_only {
            v
        } else {
            (q / count).round() * count
        };
        csv += &format!("{t},{tau},{motion}\n");
        for _ in 0..sub {
            if v == 0.0 && tau.abs() <= fc {
                continue;
            }
            let dir = if v != 0.0 { v.signum() } else { tau.signum() };
            let a = (tau - fv * v - fc * dir) / j;
            let vn = v + a * h;
            if v != 0.0 && vn * v < 0.0 {
                q -= 0.5 * v * v / a;
                v = 0.0;
            } else {
                q += v * h + 0.5 * a * h * h;
                v = vn;
            }
        }
    }
    std::fs::write(dir.join("REC.csv"), csv).unwrap();
    std::fs::write(dir.join("REC.json"), r#"{"sample_rate_hz": 1000.0}"#).unwrap();
    (j, fv, fc)
}

/// `diagnose --masses 1` on a non-periodic recording takes the trajectory path: the JSON
/// contract (`verdict`, `effects`, `gap.before_rms_db`, `gap.after_rms_db`, `gap.bands`,
/// `ranking`) with `null` where a figure does not apply, never NaN; the friction found;
/// `--svg` a force plot. A recording without a position exits 1 and says why.
#[test]
fn diagnose_a_trajectory_recording() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let (j, fv, fc) = trajectory_recording(dir, false);
    let out = flexid(
        &[
            "diagnose", "REC.csv", "--masses", "1", "--json", "d.json", "--svg", "d.svg",
        ],
        dir,
    );
    let (so, _) = expect_code(&out, 0, "diagnose trajectory");
    assert!(so.contains("trajectory path"), "{so}");
    let raw = std::fs::read_to_string(dir.join("d.json")).unwrap();
    assert!(!raw.contains("NaN") && !raw.contains("inf"), "{raw}");
    let d: Value = serde_json::from_str(&raw).unwrap();
    assert_eq!(d["verdict"], "coulomb_friction", "{so}");
    assert_eq!(d["effects"][0]["effect"], "coulomb_friction");
    let gap = &d["gap"];
    let (before, after) = (
        gap["before_rms_db"].as_f64().unwrap(),
        gap["after_rms_db"].as_f64().unwrap(),
    );
    assert!(after < before, "{gap}");
    assert!(gap["bands"].as_array().unwrap().is_empty());
    assert!(gap["before_magnitude_rms_db"].is_null());
    assert!(!d["ranking"].as_array().unwrap().is_empty());
    let param = |name: &str| {
        d["trajectory"]["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .and_then(|p| p["value"].as_f64())
            .unwrap()
    };
    for (name, want) in [
        ("inertia_kgm2", j),
        ("viscous_nms_per_rad", fv),
        ("coulomb_nm", fc),
    ] {
        let got = param(name);
        assert!((got / want - 1.0).abs() < 0.05, "{name}: {got} vs {want}");
    }
    let svg = std::fs::read_to_string(dir.join("d.svg")).unwrap();
    assert!(svg.contains("<svg") && svg.contains("filtered force"));
    assert!(!svg.contains("NaN"));

    let vel = tempfile::tempdir().unwrap();
    trajectory_recording(vel.path(), true);
    let out = flexid(&["diagnose", "REC.csv", "--masses", "1"], vel.path());
    let (_, se) = expect_code(&out, 1, "diagnose without a position");
    assert!(se.contains("position"), "{se}");
}
