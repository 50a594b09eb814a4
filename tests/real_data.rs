//! Real measurement data through the real binary: `flexid import PRESET`, `flexid identify`
//! and `flexid bode`, compared with the published figures named in the data set's
//! `SOURCE.md` (`shared/data/*/SOURCE.md` beside the repository; `FLEXID_SHARED_DATA`
//! overrides the location). A test whose data file is absent is SKIPPED with a message, it
//! does not fail: the data is not part of the repository.
//!
//! Each test prints (eprintln; `cargo test --release --test real_data -- --nocapture`) its
//! rows of the table "found vs published" that is kept in `tests/REAL_DATA.md`.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

const BIN: &str = env!("CARGO_BIN_EXE_flexid");

/// The data file of `preset`, or `None` (after a SKIP message) when it is absent.
fn data_file(preset: &str, test: &str) -> Option<PathBuf> {
    let (rel, _) = flexid::import::preset(preset).expect("known preset");
    let path = flexid::import::shared_data_dir().join(rel);
    if path.is_file() {
        Some(path)
    } else {
        eprintln!(
            "SKIP {test}: {} not found (set {} to the shared data folder)",
            path.display(),
            flexid::import::SHARED_DATA_ENV
        );
        None
    }
}

/// Runs the binary; panics with its output when it fails. Returns stdout.
fn run(args: &[&str]) -> String {
    let out = Command::new(BIN)
        .args(args)
        .env(
            flexid::import::SHARED_DATA_ENV,
            flexid::import::shared_data_dir(),
        )
        .output()
        .expect("run flexid");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "flexid {args:?} failed ({}):\n{stdout}\n{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// `flexid import PRESET --out DIR/PRESET.csv`.
fn import(preset: &str, dir: &Path) -> PathBuf {
    let rec = dir.join(format!("{preset}.csv"));
    run(&["import", preset, "--out", rec.to_str().unwrap()]);
    assert!(rec.is_file());
    rec
}

/// `flexid identify REC [extra] --json OUT`: the printed report and the JSON.
fn identify(rec: &Path, extra: &[&str], tag: &str) -> (String, Value) {
    let json = rec.with_file_name(format!("{tag}.json"));
    let mut args = vec!["identify", rec.to_str().unwrap()];
    args.extend_from_slice(extra);
    args.extend_from_slice(&["--json", json.to_str().unwrap()]);
    let report = run(&args);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (report, v)
}

/// `flexid bode REC --out DIR/TAG.svg` writes an SVG.
fn bode(rec: &Path, tag: &str) {
    let svg = rec.with_file_name(format!("{tag}.svg"));
    run(&[
        "bode",
        rec.to_str().unwrap(),
        "--out",
        svg.to_str().unwrap(),
    ]);
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("<svg"), "{tag}: not an SVG");
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default()
}

fn rel(a: f64, b: f64) -> f64 {
    (a / b - 1.0).abs()
}

/// The value of `found` nearest to `want`.
fn nearest(found: &[f64], want: f64) -> Option<f64> {
    found
        .iter()
        .copied()
        .min_by(|a, b| rel(*a, want).total_cmp(&rel(*b, want)))
}

/// One row of the results table; printed so that it can be copied into the README.
fn row(set: &str, what: &str, published: &str, found: String, tol: &str) {
    eprintln!("| {set} | {what} | {published} | {found} | {tol} |");
}

fn hz(v: &[f64]) -> String {
    let items: Vec<String> = v.iter().map(|x| format!("{x:.2}")).collect();
    items.join(", ")
}

// ---------------------------------------------------------------------------------------
// 1. FdiTools two-inertia motor bench: iq [A] -> motor angle theta_mx.
// ---------------------------------------------------------------------------------------

/// Reference (SOURCE.md, quick check on the 1 Hz grid of the 2500-sample period): motor side
/// anti-resonance ~53 Hz, resonance ~77 Hz, the same for TypeA and TypeB.
const FDI_AR_HZ: f64 = 53.0;
const FDI_R_HZ: f64 = 77.0;
/// +-3 %: the reference values are read off a 1 Hz grid (+-0.5 Hz, i.e. +-1 % at 53 Hz),
/// and "anti-resonance/resonance" there means the extremum of |H| on that grid whereas we
/// report the zero/pole of a local rational fit and of the damped chain model (with 2-3 %
/// damping the extrema of |H| and the undamped frequencies differ by up to ~1 %). Tighter
/// agreement is asserted between TypeA and TypeB (same bench, different excitation).
const FDI_TOL: f64 = 0.03;

/// (model AR, model R, pair AR, pair R) for one excitation type.
fn fditools(preset: &str, test: &str) -> Option<[f64; 4]> {
    data_file(preset, test)?;
    let dir = tempfile::tempdir().unwrap();
    let rec = import(preset, dir.path());
    let mut out = None;
    for (extra, tag) in [(&["--masses", "2"][..], "fixed"), (&[][..], "auto")] {
        let (report, v) = identify(&rec, extra, tag);
        let model = &v["model"];
        assert_eq!(
            model["masses"].as_u64(),
            Some(2),
            "{preset} {tag}: a two-inertia bench (FdiTools: n = 4); report:\n{report}"
        );
        let ar = floats(&model["antiresonance_hz"]);
        let r = floats(&model["resonance_hz"]);
        assert_eq!((ar.len(), r.len()), (1, 1), "{preset} {tag}: {model}");
        let pairs = v["pairs"].as_array().unwrap();
        assert_eq!(pairs.len(), 1, "{preset} {tag}: pairs {pairs:?}");
        let (par, pr) = (
            pairs[0]["ar_hz"].as_f64().unwrap(),
            pairs[0]["r_hz"].as_f64().unwrap(),
        );
        for (what, f, want) in [
            ("model anti-resonance", ar[0], FDI_AR_HZ),
            ("model resonance", r[0], FDI_R_HZ),
            ("detected anti-resonance", par, FDI_AR_HZ),
            ("detected resonance", pr, FDI_R_HZ),
        ] {
            assert!(
                rel(f, want) < FDI_TOL,
                "{preset} {tag}: {what} {f:.3} Hz vs ~{want} Hz (+-{} %)",
                100.0 * FDI_TOL
            );
        }
        let r_peaks = floats(&v["resonance_peaks_hz"]);
        assert!(
            nearest(&r_peaks, FDI_R_HZ).is_some_and(|f| rel(f, FDI_R_HZ) < FDI_TOL),
            "{preset} {tag}: resonance peaks {r_peaks:?}"
        );
        // inertias are in A-based units: the input is the current; the notes must say so
        let notes = v["notes"].to_string();
        assert!(
            notes.contains("current iq [A]"),
            "{preset}: notes do not say the input is a current: {notes}"
        );
        out = Some([ar[0], r[0], par, pr]);
    }
    bode(&rec, "bode");
    out
}

fn fditools_rows(set: &str, f: [f64; 4]) {
    row(
        set,
        "anti-resonance [Hz] (model / detected)",
        "~53 (quick check, SOURCE.md)",
        format!("{:.2} / {:.2}", f[0], f[2]),
        "+-3 %",
    );
    row(
        set,
        "resonance [Hz] (model / detected)",
        "~77 (quick check, SOURCE.md)",
        format!("{:.2} / {:.2}", f[1], f[3]),
        "+-3 %",
    );
    row(
        set,
        "order (automatic)",
        "2-inertia bench, n = 4 (FdiTools)",
        "2 masses".into(),
        "exact",
    );
}

#[test]
fn fditools_motor_bench_type_a_and_b() {
    let a = fditools("fditools-typeA", "fditools_motor_bench_type_a_and_b");
    let b = fditools("fditools-typeB", "fditools_motor_bench_type_a_and_b");
    if let Some(a) = a {
        fditools_rows("FdiTools TypeA (Schroeder)", a);
    }
    if let Some(b) = b {
        fditools_rows("FdiTools TypeB (odd-odd random)", b);
    }
    if let (Some(a), Some(b)) = (a, b) {
        // Same bench, two excitations: the model frequencies agree to 1 %.
        for k in 0..2 {
            assert!(rel(a[k], b[k]) < 0.01, "TypeA {a:?} vs TypeB {b:?}");
        }
    }
}

/// Load side (non-collocated): the same resonance, no anti-resonance; the pairing cannot
/// use it, the list of significant peaks must still show the resonance.
#[test]
fn fditools_motor_bench_load_side_shows_the_resonance() {
    let preset = "fditools-typeA-load";
    if data_file(preset, "fditools_motor_bench_load_side_shows_the_resonance").is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import(preset, dir.path());
    let (report, v) = identify(&rec, &[], "auto");
    let peaks = floats(&v["resonance_peaks_hz"]);
    let f = nearest(&peaks, FDI_R_HZ);
    assert!(
        f.is_some_and(|f| rel(f, FDI_R_HZ) < FDI_TOL),
        "{preset}: resonance peaks {peaks:?}; report:\n{report}"
    );
    row(
        "FdiTools TypeA load side",
        "resonance [Hz] (significant peak)",
        "~77, no anti-resonance (quick check)",
        format!("{:.2} (all peaks: {})", f.unwrap(), hz(&peaks)),
        "+-3 %",
    );
}

// ---------------------------------------------------------------------------------------
// 2. F-16 ground vibration test: shaker force -> acceleration at the excitation point.
// ---------------------------------------------------------------------------------------

/// Published (Noel & Schoukens 2017, F16Benchmark.pdf): first flexible mode (wing bending)
/// "around 5.2 Hz", wing torsion "around 7.3 Hz". +-2 %: "around" a one-decimal figure
/// (+-0.05 Hz = +-1 % at 5.2 Hz) plus one line spacing (400/8192 = 0.049 Hz, 0.9 %).
const F16_PUBLISHED_HZ: [f64; 2] = [5.2, 7.3];
const F16_TOL: f64 = 0.02;
/// Quick check of SOURCE.md (not published; Level 1, acc1): |FRF| peaks.
const F16_QUICK_HZ: [f64; 5] = [3.5, 5.2, 6.6, 7.3, 9.2];

#[test]
fn f16_gvt_level1_wing_bending_and_torsion() {
    let test = "f16_gvt_level1_wing_bending_and_torsion";
    if data_file("f16-level1", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import("f16-level1", dir.path());
    let (report, v) = identify(&rec, &[], "auto");
    // acceleration data: no chain fit, and the pipeline says why
    assert!(v["model"].is_null(), "{}", v["model"]);
    assert!(
        v["notes"].to_string().contains("acceleration"),
        "{}",
        v["notes"]
    );
    let peaks = floats(&v["resonance_peaks_hz"]);
    for want in F16_PUBLISHED_HZ {
        let f = nearest(&peaks, want);
        assert!(
            f.is_some_and(|f| rel(f, want) < F16_TOL),
            "F-16: no resonance within {} % of {want} Hz in {peaks:?}; report:\n{report}",
            100.0 * F16_TOL
        );
    }
    // the quick check's peaks (not published) within 3 %
    for want in F16_QUICK_HZ {
        assert!(
            nearest(&peaks, want).is_some_and(|f| rel(f, want) < 0.03),
            "F-16 quick check {want} Hz not in {peaks:?}"
        );
    }
    let f = |w: f64| nearest(&peaks, w).unwrap();
    row(
        "F-16 GVT Level 1 (acc1)",
        "wing bending [Hz]",
        "~5.2 (published)",
        format!("{:.3}", f(5.2)),
        "+-2 %",
    );
    row(
        "F-16 GVT Level 1 (acc1)",
        "wing torsion [Hz]",
        "~7.3 (published)",
        format!("{:.3}", f(7.3)),
        "+-2 %",
    );
    row(
        "F-16 GVT Level 1 (acc1)",
        "all significant peaks [Hz]",
        "3.5, 5.2, 6.6, 7.3, 9.2 (quick check)",
        hz(&peaks),
        "+-3 %",
    );
    bode(&rec, "bode");
}

/// The wing torsion mode is the most nonlinear one (published): at the highest level it is
/// still found, and it moves (printed, not asserted beyond +-5 %).
#[test]
fn f16_gvt_level7_torsion_mode_is_still_found() {
    let test = "f16_gvt_level7_torsion_mode_is_still_found";
    if data_file("f16-level7", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import("f16-level7", dir.path());
    let (report, v) = identify(&rec, &[], "auto");
    let peaks = floats(&v["resonance_peaks_hz"]);
    let f = nearest(&peaks, 7.3);
    assert!(
        f.is_some_and(|f| rel(f, 7.3) < 0.05),
        "F-16 level 7: peaks {peaks:?}; report:\n{report}"
    );
    row(
        "F-16 GVT Level 7 (97.8 N RMS)",
        "wing torsion [Hz]",
        "~7.3 at low level, most nonlinear mode (published)",
        format!("{:.3} (all peaks: {})", f.unwrap(), hz(&peaks)),
        "+-5 %",
    );
}

/// The F-16's levels 1, 3 and 7 (`flexid diagnose L1 L3 L7 --masses 3 --band 3 12`): no
/// chain fits the airframe, but the FRF changes between the levels in the band of the wing
/// torsion mode, and the local modal fit of that band names it: an amplitude-dependent
/// mode within 5 % of 7.3 Hz whose frequency falls with the level (published: the torsion
/// mode, the most nonlinear one, softens). Checked independently: the resonance peak the
/// identification reads off the level-7 FRF alone lies below the level-1 one.
#[test]
fn f16_gvt_levels_name_the_softening_torsion_mode() {
    let test = "f16_gvt_levels_name_the_softening_torsion_mode";
    if ["f16-level1", "f16-level3", "f16-level7"]
        .iter()
        .any(|p| data_file(p, test).is_none())
    {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let recs: Vec<PathBuf> = ["f16-level1", "f16-level3", "f16-level7"]
        .iter()
        .map(|p| import(p, dir.path()))
        .collect();
    let json = dir.path().join("f16-diagnosis.json");
    let report = run(&[
        "diagnose",
        recs[0].to_str().unwrap(),
        recs[1].to_str().unwrap(),
        recs[2].to_str().unwrap(),
        "--masses",
        "3",
        "--band",
        "3",
        "12",
        "--json",
        json.to_str().unwrap(),
    ]);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(
        v["verdict"], "amplitude_dependent_mode",
        "report:\n{report}"
    );
    let a = &v["amplitude_mode"];
    let named = &a["named"];
    assert_eq!(named["change"], "softening_stiffness", "report:\n{report}");
    let f0 = named["frequency_hz"].as_f64().unwrap();
    assert!(rel(f0, 7.3) < 0.05, "mode at {f0} Hz; report:\n{report}");
    let z = named["frequency_shift_sigmas"].as_f64().unwrap();
    let zc = a["z_crit"].as_f64().unwrap();
    assert!(z < -zc, "shift {z} sigma, threshold {zc}");
    let mode = &a["modes"][named["mode"].as_u64().unwrap() as usize];
    let per_level: Vec<(f64, f64)> = mode["levels"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| {
            (
                l["frequency_hz"].as_f64().unwrap_or(f64::NAN),
                l["frequency_std_hz"].as_f64().unwrap_or(f64::NAN),
            )
        })
        .collect();
    // independent: the identification's resonance peak near 7.3 Hz at level 7 is below
    // the level-1 one
    let peak = |rec: &Path, tag: &str| {
        let (_, v) = identify(rec, &[], tag);
        nearest(&floats(&v["resonance_peaks_hz"]), 7.3).unwrap_or(f64::NAN)
    };
    let (p1, p7) = (peak(&recs[0], "id-l1"), peak(&recs[2], "id-l7"));
    assert!(
        p7 < p1,
        "identify's peaks: level 1 {p1} Hz, level 7 {p7} Hz"
    );
    let set = "F-16 GVT levels 1, 3, 7 (`diagnose --masses 3 --band 3 12`)";
    row(
        set,
        "verdict",
        "nonlinear wing torsion mode near 7.3 Hz (softening)",
        format!("{} ({})", v["verdict"], named["change"]),
        "exact; mode +-5 %",
    );
    row(
        set,
        "torsion mode per level [Hz] (levels 1, 3, 7)",
        "~7.3 at low level, lower at high level",
        per_level
            .iter()
            .map(|(f, s)| format!("{f:.4} +- {s:.4}"))
            .collect::<Vec<_>>()
            .join(", "),
        "shift < -z_crit",
    );
    row(
        set,
        "frequency shift level 1 -> 7 [sigma]",
        "-",
        format!("{z:.1} (threshold {zc:.2})"),
        "-",
    );
    row(
        set,
        "identify's peak near 7.3 Hz, level 1 / level 7 [Hz]",
        "-",
        format!("{p1:.3} / {p7:.3}"),
        "level 7 lower",
    );
}

// ---------------------------------------------------------------------------------------
// 3. DaISy flexible robot arm: reaction torque -> arm acceleration, fs unknown.
// ---------------------------------------------------------------------------------------

/// What is compared to what: DaISy gives no sampling time; the preset assumes fs = 100 Hz
/// (as ControlSystemIdentification.jl does), so frequencies are compared in cycles/sample
/// (f / fs). Published (ControlSystemIdentification.jl, SLICOT demo): "a model of order 4 is
/// reasonable, a double-mass model" — four states hold at most two lightly damped modes; the
/// data shows two significant peaks, whose positions are compared with the quick check of
/// SOURCE.md (NOT published: maxima of a 1024-point DFT
/// near 0.060 and 0.126 cycles/sample). The record is not periodic at any integer period,
/// so it is estimated with Welch (256-sample segments, 0.0039 cycles/sample per line):
/// tolerance +-0.006 cycles/sample, i.e. +-1.5 lines.
#[test]
fn daisy_robot_arm_double_mass() {
    let test = "daisy_robot_arm_double_mass";
    if data_file("daisy-robot-arm", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import("daisy-robot-arm", dir.path());
    let (report, v) = identify(&rec, &[], "auto");
    let fs = v["frf"]["sample_rate_hz"].as_f64().unwrap();
    let peaks: Vec<f64> = floats(&v["resonance_peaks_hz"])
        .iter()
        .map(|f| f / fs)
        .collect();
    let mut found = Vec::new();
    for want in [0.060, 0.126] {
        let f = nearest(&peaks, want);
        assert!(
            f.is_some_and(|f| (f - want).abs() < 0.006),
            "robot arm: no peak near {want} cycles/sample in {peaks:?}; report:\n{report}"
        );
        found.push(f.unwrap());
    }
    row(
        "DaISy robot arm (fs 100 Hz assumed)",
        "resonances [cycles/sample]",
        "order 4 = double mass (published); maxima ~0.060, 0.126 (quick check)",
        format!(
            "{:.4}, {:.4} ({} significant peaks; {:.2} / {:.2} Hz at the assumed fs)",
            found[0],
            found[1],
            peaks.len(),
            found[0] * fs,
            found[1] * fs
        ),
        "+-0.006",
    );
    bode(&rec, "bode");
}

// ---------------------------------------------------------------------------------------
// 4. EMPS: closed loop, bang-bang trajectories, rigid body + friction (negative case).
// ---------------------------------------------------------------------------------------

/// Published: a rigid-body model (M = 95.1 kg, friction) describes the drive; the
/// flexibility the validation pulses excited is not in the estimation record. Asserted: the
/// pipeline runs and reports no compliant pair below 20 Hz (the position-loop bandwidth).
#[test]
fn emps_runs_and_finds_no_low_compliance() {
    let test = "emps_runs_and_finds_no_low_compliance";
    if data_file("emps", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import("emps", dir.path());
    let (report, v) = identify(&rec, &[], "auto");
    let pairs = v["pairs"].as_array().unwrap();
    for p in pairs {
        let (ar, r) = (p["ar_hz"].as_f64().unwrap(), p["r_hz"].as_f64().unwrap());
        assert!(
            ar > 20.0 && r > 20.0,
            "EMPS: compliant pair below 20 Hz: {p}; report:\n{report}"
        );
    }
    let j = v["total_inertia"]["j_kgm2"].as_f64().unwrap_or(f64::NAN);
    let pairs_hz: Vec<String> = pairs
        .iter()
        .map(|p| {
            let f = |k: &str| p[k].as_f64().unwrap_or(f64::NAN);
            let edge = if p["r_above_band"].as_bool() == Some(true) {
                " (R above the band)"
            } else {
                ""
            };
            format!("{:.0}/{:.0}{edge}", f("ar_hz"), f("r_hz"))
        })
        .collect();
    row(
        "EMPS (closed loop)",
        "compliant pairs below 20 Hz / mass",
        "none (rigid body); M = 95.1 kg",
        format!(
            "none (pairs AR/R: {}); low-frequency mass J = {j:.1} kg (the preset's force is gtau x vir [N])",
            if pairs_hz.is_empty() {
                "-".into()
            } else {
                pairs_hz.join(", ")
            },
        ),
        "-",
    );
}

/// Published IDIM-LS (Janot, Gautier & Brunot 2019, symmetric friction), force = gtau vir.
const EMPS_M_KG: f64 = 95.1089;
const EMPS_FV_NS_PER_M: f64 = 203.5034;
const EMPS_FC_N: f64 = 20.3935;
const EMPS_OFFSET_N: f64 = -3.1648;
/// +-25 %: the published values come from the same method with the authors' own filter
/// choices (a 100 Hz cut-off, their decimation, no zero-order-hold alignment), which move
/// Fv and Fc by a few percent; 25 % separates "found the friction" from "did not".
const EMPS_TOL: f64 = 0.25;

/// `flexid diagnose REC... --masses 1 --json OUT`: the printed report and the JSON.
fn diagnose(recs: &[&Path], tag: &str) -> (String, Value) {
    let json = recs[0].with_file_name(format!("{tag}.json"));
    let mut args = vec!["diagnose"];
    args.extend(recs.iter().map(|r| r.to_str().unwrap()));
    args.extend_from_slice(&["--masses", "1", "--json", json.to_str().unwrap()]);
    let report = run(&args);
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    (report, v)
}

/// The trajectory path's parameter `name` (value, std) from `flexid diagnose --json`.
fn traj_param(v: &Value, name: &str) -> (f64, f64) {
    named_param(&v["trajectory"]["params"], name)
}

/// `(value, std)` of the entry `name` of a JSON list of `{"name", "value", "std"}`.
fn named_param(list: &Value, name: &str) -> (f64, f64) {
    let p = list
        .as_array()
        .and_then(|a| a.iter().find(|p| p["name"] == name))
        .unwrap_or_else(|| panic!("no parameter {name} in {list}"));
    (
        p["value"].as_f64().unwrap_or(f64::NAN),
        p["std"].as_f64().unwrap_or(f64::NAN),
    )
}

/// EMPS on the trajectory path: IDIM-LS of the rigid body with Coulomb and viscous
/// friction (`flexid import emps`, `flexid diagnose ... --masses 1`), the PULSES record as
/// the cross-test. Asserted: verdict `coulomb_friction`, Fc and Fv within 25 % of the
/// published values (the preset's force is gtau x vir in N), the cross-test's error below
/// the rigid body's without friction.
#[test]
fn emps_trajectory_finds_coulomb_and_viscous_friction() {
    let test = "emps_trajectory_finds_coulomb_and_viscous_friction";
    if data_file("emps", test).is_none() || data_file("emps-pulses", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec = import("emps", dir.path());
    let pulses = import("emps-pulses", dir.path());
    let t0 = std::time::Instant::now();
    let (report, v) = diagnose(&[&rec, &pulses], "trajectory");
    let wall = t0.elapsed().as_secs_f64();
    assert_eq!(v["verdict"], "coulomb_friction", "report:\n{report}");
    assert_eq!(v["effects"][0]["effect"], "coulomb_friction");
    let t = &v["trajectory"];
    let (m, sm) = traj_param(&v, "inertia_kgm2");
    let (fv, sfv) = traj_param(&v, "viscous_nms_per_rad");
    let (fc, sfc) = traj_param(&v, "coulomb_nm");
    let (off, soff) = traj_param(&v, "offset_nm");
    for (what, got, want) in [("Fc", fc, EMPS_FC_N), ("Fv", fv, EMPS_FV_NS_PER_M)] {
        assert!(
            rel(got, want) < EMPS_TOL,
            "EMPS {what} = {got} vs published {want}; report:\n{report}"
        );
    }
    let f = |x: &Value| x.as_f64().unwrap_or(f64::NAN);
    let direct = f(&t["relative_error_pct"]);
    let rigid = f(&t["models"]["rigid"]["relative_error_pct"]);
    let cross = f(&t["cross_tests"][0]["relative_error_pct"]);
    assert!(
        cross < rigid,
        "cross-test {cross} % vs rigid body {rigid} %"
    );
    assert!(
        f(&v["gap"]["after_rms_db"]) < f(&v["gap"]["before_rms_db"]),
        "{}",
        v["gap"]
    );
    let set = "EMPS (IDIM-LS, trajectory path)";
    let pm = |x: f64, s: f64| format!("{x:.4} +- {s:.4}");
    row(
        set,
        "M [kg]",
        &format!("{EMPS_M_KG} +- 0.1085"),
        pm(m, sm),
        "not asserted",
    );
    row(
        set,
        "Fv [N s/m]",
        &format!("{EMPS_FV_NS_PER_M} +- 1.1460"),
        pm(fv, sfv),
        "+-25 %",
    );
    row(
        set,
        "Fc [N]",
        &format!("{EMPS_FC_N} +- 0.1012"),
        pm(fc, sfc),
        "+-25 %",
    );
    row(
        set,
        "offset [N]",
        &format!("{EMPS_OFFSET_N} +- 0.0444"),
        pm(off, soff),
        "-",
    );
    row(
        set,
        "condition number",
        "25.99",
        format!("{:.2}", f(&t["condition_number"])),
        "-",
    );
    row(
        set,
        "relative force error, direct / cross-test (PULSES)",
        "4.08 % / 5.98 %",
        format!("{direct:.2} % / {cross:.2} % (rigid body without friction: {rigid:.1} %)"),
        "cross < rigid",
    );
    row(
        set,
        "cut-off (from the data) / decimation / samples used",
        "100 Hz (5 x 20 Hz, the authors' choice)",
        format!(
            "{:.1} Hz / {} / {} of {}; {:.2} s wall (both records, binary)",
            f(&t["cutoff_hz"]),
            t["decimation"],
            t["samples_used"],
            t["samples_total"],
            wall
        ),
        "-",
    );
}

/// A Python with numpy and scipy: the repository's `.venv-interop` (scripts/pyenv-interop.sh,
/// run by the test command) or `.venv` (scripts/bench.sh), else `python3` on the PATH;
/// `None` when none imports both.
fn python_with_scipy() -> Option<PathBuf> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let interop = root.join(".venv-interop/bin/python");
    let venv = root.join(".venv/bin/python");
    [interop, venv, PathBuf::from("python3")]
        .into_iter()
        .find(|py| {
            Command::new(py)
                .args(["-c", "import numpy, scipy.signal, scipy.io"])
                .output()
                .is_ok_and(|o| o.status.success())
        })
}

/// The trajectory path against an independent implementation of the same method
/// (tests/interop/idim_ls.py: scipy's Butterworth, sosfiltfilt, Welch and loadmat, numpy's
/// lstsq, on the MAT files themselves): cut-off, decimation and samples equal, every
/// parameter, its standard deviation and the relative errors within 1 %.
#[test]
fn emps_trajectory_matches_an_independent_python_idim() {
    let test = "emps_trajectory_matches_an_independent_python_idim";
    let (Some(mat), Some(mat2)) = (data_file("emps", test), data_file("emps-pulses", test)) else {
        return;
    };
    let Some(py) = python_with_scipy() else {
        eprintln!(
            "SKIP {test}: no python with numpy and scipy (scripts/bench.sh makes .venv, or pip install numpy scipy)"
        );
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let rec = import("emps", dir.path());
    let pulses = import("emps-pulses", dir.path());
    let (_, v) = diagnose(&[&rec, &pulses], "rust");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/interop/idim_ls.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(&mat)
        .arg(&mat2)
        .output()
        .expect("run python");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let p: Value = serde_json::from_slice(&out.stdout).unwrap();
    let t = &v["trajectory"];
    let f = |x: &Value| x.as_f64().unwrap_or(f64::NAN);
    for key in [
        "decimation",
        "edge_samples",
        "spread_samples",
        "samples_used",
    ] {
        assert_eq!(t[key], p[key], "{key}: rust {} python {}", t[key], p[key]);
    }
    let mut worst: f64 = 0.0;
    let mut check = |what: &str, a: f64, b: f64| {
        let r = rel(a, b);
        assert!(r < 0.01, "{what}: rust {a} python {b} ({:.3} %)", 100.0 * r);
        worst = worst.max(r);
    };
    check("cutoff_hz", f(&t["cutoff_hz"]), f(&p["cutoff_hz"]));
    for name in [
        "inertia_kgm2",
        "viscous_nms_per_rad",
        "coulomb_nm",
        "offset_nm",
    ] {
        let (value, std) = traj_param(&v, name);
        check(name, value, f(&p["params"][name]["value"]));
        check(name, std, f(&p["params"][name]["std"]));
    }
    check(
        "condition_number",
        f(&t["condition_number"]),
        f(&p["condition_number"]),
    );
    check(
        "relative_error_pct",
        f(&t["relative_error_pct"]),
        f(&p["relative_error_pct"]),
    );
    check(
        "cross-test relative_error_pct",
        f(&t["cross_tests"][0]["relative_error_pct"]),
        f(&p["cross_test_relative_error_pct"]),
    );
    row(
        "EMPS (IDIM-LS, trajectory path)",
        "flexid vs independent python (scipy/numpy)",
        "-",
        format!("largest relative difference {:.1e}", worst),
        "1 %",
    );
}

// ---------------------------------------------------------------------------------------
// Silverbox: an electronic Duffing oscillator, V1 [V] -> V2 [V].
// ---------------------------------------------------------------------------------------

/// A parameter of `flexid diagnose --json`'s first named effect: (value, std).
fn effect_param(v: &Value, name: &str) -> (f64, f64) {
    named_param(&v["effects"][0]["params"], name)
}

/// The output of `J y'' + b y' + k y + k3 y³ = u(t)` from rest, at the sample instants:
/// an independent RK4 on 8 sub-steps per sample, the input between the samples by
/// Catmull-Rom interpolation (the measured input is band-limited, not held).
fn duffing_rk4(u: &[f64], fs: f64, [j, b, k, k3]: [f64; 4]) -> Vec<f64> {
    let sub = 8;
    let h = 1.0 / fs / sub as f64;
    let at = |t: f64| -> f64 {
        let i = t.floor() as isize;
        let x = t - i as f64;
        let g = |n: isize| u[n.clamp(0, u.len() as isize - 1) as usize];
        let (p0, p1, p2, p3) = (g(i - 1), g(i), g(i + 1), g(i + 2));
        p1 + 0.5
            * x
            * (p2 - p0
                + x * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + x * (3.0 * (p1 - p2) + p3 - p0)))
    };
    let f = |t: f64, y: f64, v: f64| (v, (at(t) - b * v - k * y - k3 * y * y * y) / j);
    let (mut y, mut v) = (0.0, 0.0);
    let mut out = Vec::with_capacity(u.len());
    for n in 0..u.len() {
        out.push(y);
        for s in 0..sub {
            // time in samples
            let t = n as f64 + s as f64 / sub as f64;
            let dt = 1.0 / sub as f64;
            let (a1, b1) = f(t, y, v);
            let (a2, b2) = f(t + dt / 2.0, y + h / 2.0 * a1, v + h / 2.0 * b1);
            let (a3, b3) = f(t + dt / 2.0, y + h / 2.0 * a2, v + h / 2.0 * b2);
            let (a4, b4) = f(t + dt, y + h * a3, v + h * b3);
            y += h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4);
            v += h / 6.0 * (b1 + 2.0 * b2 + 2.0 * b3 + b4);
        }
    }
    out
}

/// RMS of `sim - meas` over the realisations' steady periods relative to the measured
/// output's RMS there (each period's mean removed from both: the box's own offset).
fn steady_error(rec: &flexid::recording::Recording, sim: &[f64]) -> f64 {
    let e = rec.sidecar.excitation.as_ref().unwrap();
    let y = rec.position_rad.as_ref().unwrap();
    let (mut err, mut pow) = (0.0, 0.0);
    for r in &e.realisations {
        let span = r.start..r.start + e.period_samples;
        let n = e.period_samples as f64;
        let (my, ms) = (
            y[span.clone()].iter().sum::<f64>() / n,
            sim[span.clone()].iter().sum::<f64>() / n,
        );
        for i in span {
            err += ((sim[i] - ms) - (y[i] - my)).powi(2);
            pow += (y[i] - my).powi(2);
        }
    }
    (err / pow).sqrt()
}

/// Silverbox (Wigren & Schoukens 2013): `flexid import silverbox` (the 10 realisations of
/// the odd random-phase multisine), `flexid diagnose --masses 1 --ground-spring`.
/// Asserted: the published naming, a hardening (cubic) stiffness to the ground, with `k3`
/// at least 3 sigma from zero and the gap at most half of the nominal model's; and,
/// independently, an RK4 of the Duffing equation with the fitted parameters driven by the
/// measured input reproduces the measured output at least twice as well as the linear
/// nominal model does.
#[test]
fn silverbox_is_named_a_hardening_stiffness_to_the_ground() {
    let test = "silverbox_is_named_a_hardening_stiffness_to_the_ground";
    if data_file("silverbox", test).is_none() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let rec_path = import("silverbox", dir.path());
    let rec = flexid::recording::read_recording(&rec_path).unwrap();
    let e = rec.sidecar.excitation.as_ref().unwrap();
    assert_eq!(e.realisations.len(), 10, "{:?}", e.realisations);
    assert_eq!(e.period_samples, 8192);
    assert!(e.band_limited);
    let t0 = std::time::Instant::now();
    let json = rec_path.with_file_name("silverbox-diagnosis.json");
    let report = run(&[
        "diagnose",
        rec_path.to_str().unwrap(),
        "--masses",
        "1",
        "--ground-spring",
        "--json",
        json.to_str().unwrap(),
    ]);
    let wall = t0.elapsed().as_secs_f64();
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["verdict"], "hardening_stiffness", "report:\n{report}");
    let (k3, sk3) = effect_param(&v, "ground_k3_nm_per_rad3");
    let (to_ground, _) = effect_param(&v, "to_ground");
    assert_eq!(to_ground, 1.0, "the cubic spring is the ground's: {report}");
    assert!(k3 > 3.0 * sk3, "k3 = {k3} +- {sk3}");
    let f = |x: &Value| x.as_f64().unwrap_or(f64::NAN);
    let (before, after) = (f(&v["gap"]["before_rms_db"]), f(&v["gap"]["after_rms_db"]));
    assert!(after <= 0.5 * before, "gap {before} -> {after} dB");
    // the independent check: RK4 of the fitted Duffing oscillator and of the nominal model
    let m = &v["effects"][0]["model"];
    let nl = [
        f(&m["inertia_kgm2"][0]),
        f(&m["viscous_nms_per_rad"]),
        f(&m["ground_stiffness_nm_per_rad"]),
        k3,
    ];
    let n = &v["nominal"];
    let lin = [
        f(&n["inertia_kgm2"][0]),
        f(&n["viscous_nms_per_rad"]),
        f(&n["ground_stiffness_nm_per_rad"]),
        0.0,
    ];
    let fs = rec.sample_rate_hz;
    let e_nl = steady_error(&rec, &duffing_rk4(&rec.torque_cmd_nm, fs, nl));
    let e_lin = steady_error(&rec, &duffing_rk4(&rec.torque_cmd_nm, fs, lin));
    assert!(
        e_nl < 0.5 * e_lin,
        "RK4 output error: Duffing {e_nl:.4} vs linear {e_lin:.4}"
    );
    // a second design: the Schroeder multisine of `Schroeder80mV.mat` (one period at
    // rows 10585.., its README), not used by the diagnosis
    let schroeder = schroeder_errors(&data_file("silverbox", test).unwrap(), fs, nl, lin);
    if let Some((s_nl, s_lin)) = schroeder {
        assert!(
            s_nl < 0.5 * s_lin,
            "Schroeder period: Duffing {s_nl:.4} vs linear {s_lin:.4}"
        );
    }
    let set = "Silverbox (10 realisations, --masses 1 --ground-spring)";
    row(
        set,
        "verdict",
        "Duffing oscillator: cubic stiffness to the ground",
        v["verdict"].to_string(),
        "exact",
    );
    row(
        set,
        "k3 [V/V³] (`ground_k3_nm_per_rad3`)",
        "not published in these units",
        format!("{k3:.4} +- {sk3:.4}"),
        "> 3 sigma",
    );
    row(
        set,
        "linear part J / b / k (with the cubic term)",
        "-",
        format!("{:.4e} / {:.4e} / {:.4}", nl[0], nl[1], nl[2]),
        "-",
    );
    row(
        set,
        "gap before -> after [dB]",
        "-",
        format!("{before:.3} -> {after:.3}"),
        "after <= before/2",
    );
    row(
        set,
        "RK4 output error, steady periods (Duffing / linear nominal)",
        "-",
        format!("{:.2} % / {:.2} %", 100.0 * e_nl, 100.0 * e_lin),
        "Duffing < linear/2",
    );
    if let Some((s_nl, s_lin)) = schroeder {
        row(
            set,
            "RK4 output error on the Schroeder period of Schroeder80mV.mat (Duffing / linear)",
            "-",
            format!("{:.2} % / {:.2} %", 100.0 * s_nl, 100.0 * s_lin),
            "Duffing < linear/2",
        );
    }
    eprintln!(
        "silverbox: spread over realisations {} dB over noise; {wall:.1} s",
        v["residual"]["levels"][0]["realisation_excess_db"]
    );
}

/// The relative RMS output error of the RK4 of `nl` and of `lin` ([`duffing_rk4`]) on the
/// Schroeder period of `Schroeder80mV.mat` beside `snls` (rows 10585..10585+1024, the means
/// of the whole file removed as its README says; simulated from row 8000, from rest, so
/// that the start has died out): `None` when the file is absent.
fn schroeder_errors(snls: &Path, fs: f64, nl: [f64; 4], lin: [f64; 4]) -> Option<(f64, f64)> {
    let path = snls.with_file_name("Schroeder80mV.mat");
    if !path.is_file() {
        eprintln!("SKIP the Schroeder check: {} not found", path.display());
        return None;
    }
    let mat = flexid::import::MatFile::read(&path).unwrap();
    let centred = |name: &str| {
        let x = flexid::import::signal(&mat, &path, name, None).unwrap();
        let m = x.iter().sum::<f64>() / x.len() as f64;
        x.iter().map(|v| v - m).collect::<Vec<f64>>()
    };
    let (u, y) = (centred("V1"), centred("V2"));
    let (from, start, period) = (8000, 10585, 1024);
    let meas = &y[start..start + period];
    let err = |p: [f64; 4]| {
        let sim = duffing_rk4(&u[from..start + period], fs, p);
        let sim = &sim[start - from..];
        let (ms, mm) = (
            sim.iter().sum::<f64>() / period as f64,
            meas.iter().sum::<f64>() / period as f64,
        );
        let e: f64 = sim
            .iter()
            .zip(meas)
            .map(|(a, b)| ((a - ms) - (b - mm)).powi(2))
            .sum();
        let p: f64 = meas.iter().map(|b| (b - mm).powi(2)).sum();
        (e / p).sqrt()
    };
    Some((err(nl), err(lin)))
}
