//! Property tests (proptest) over every reader of outside input: the recording reader,
//! the sidecar parser, the plant file, the daemon's configuration and the API's request
//! bodies ([`TARGETS`]). Each has a test of its own with a bounded number of cases (the
//! whole file takes seconds in a release build); `fuzz_for_a_bounded_time` runs them all in
//! turn, in batches with fresh random seeds, for `FLEXID_FUZZ_SECONDS` (CI: 70 s, set by
//! scripts/test.sh under `CI=true`; unset locally: it says so and returns) and prints how
//! long and how many cases. A failing input is saved by its seed in
//! `tests/bad_input/props.proptest-regressions` (committed: proptest replays it first).
//!
//! Beyond "no panic": what a reader accepts is consistent with what it was told (a
//! recording read with a sidecar has the sidecar's time steps and an excitation its rows
//! hold; an accepted sweep request is within the axis's limits), and every error names
//! the file or the field.

use flexid::daemon::{request::parse_request, Config};
use flexid::plant::PlantFile;
use flexid::recording::parse_recording;
use proptest::prelude::*;
use proptest::test_runner::{Config as PtConfig, FileFailurePersistence, TestRunner};
use std::io::Write;
use std::time::{Duration, Instant};

fn config(cases: u32) -> PtConfig {
    PtConfig {
        cases,
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource(
            "proptest-regressions",
        ))),
        // the regressions file beside this one (what `proptest!` sets by itself)
        source_file: Some(file!()),
        ..PtConfig::default()
    }
}

/// `cases` cases of `property` over `strategy` with a fresh random seed, after the
/// regressions saved before; a failure is shrunk, saved and returned in words.
fn check<S: Strategy>(
    cases: u32,
    strategy: S,
    property: impl Fn(S::Value) -> Result<(), TestCaseError>,
) -> Result<(), String> {
    TestRunner::new(config(cases))
        .run(&strategy, property)
        .map_err(|e| e.to_string())
}

/// One reader of outside input under test: its name and `run(cases)`.
pub type Target = (&'static str, fn(u32) -> Result<(), String>);

/// Every property, by the reader it tries.
pub const TARGETS: [Target; 8] = [
    ("recording text", |n| {
        check(n, recording_text(), recording_text_property)
    }),
    ("recording bytes", |n| {
        check(n, any_bytes(600), recording_bytes_property)
    }),
    ("sidecar against the rows", |n| {
        check(n, sidecar_and_rows(), sidecar_rows_property)
    }),
    ("sidecar text", |n| {
        check(n, sidecar_text(), sidecar_text_property)
    }),
    ("plant file", |n| check(n, plant_numbers(), plant_property)),
    ("daemon configuration", |n| {
        check(n, config_value(), config_property)
    }),
    ("sweep request body", |n| {
        check(n, request_fields(), request_property)
    }),
    ("request body bytes", |n| {
        check(n, any_bytes(300), request_bytes_property)
    }),
];

/// Cases of each property's own test (seconds for the whole file).
const CASES: u32 = 384;

fn run_target(name: &str, cases: u32) {
    let (_, run) = TARGETS.iter().find(|t| t.0 == name).expect("a target");
    if let Err(e) = run(cases) {
        panic!("{name}: {e}");
    }
}

/// A CSV of `n` rows at 1 kHz with `jitter` added to row `at`'s time.
fn csv_rows(n: usize, at: usize, jitter_s: f64) -> String {
    let mut s = String::from("time_s,torque_cmd_nm,position_rad\n");
    for k in 0..n {
        let t = k as f64 * 1e-3 + if k >= at { jitter_s } else { 0.0 };
        s.push_str(&format!(
            "{t:e},{:e},{:e}\n",
            (k as f64 * 0.7).sin(),
            k as f64 * 1e-3
        ));
    }
    s
}

fn text_fragment() -> impl Strategy<Value = String> {
    prop_oneof![
        Just("time_s".to_string()),
        Just("torque_cmd_nm".to_string()),
        Just("position_rad".to_string()),
        Just("velocity_rad_s".to_string()),
        Just(",".to_string()),
        Just("\n".to_string()),
        Just("\r\n".to_string()),
        Just("#".to_string()),
        Just("NaN".to_string()),
        Just("-inf".to_string()),
        Just("1e308".to_string()),
        Just("0.001".to_string()),
        Just("\u{feff}".to_string()),
        "[0-9.eE+-]{1,8}",
        ".{0,6}",
    ]
}

/// Arbitrary text made of the format's own pieces: no panic; an error names the file.
#[test]
fn the_recording_reader_never_panics() {
    run_target("recording text", CASES);
}

fn recording_text() -> impl Strategy<Value = Vec<String>> {
    proptest::collection::vec(text_fragment(), 0..80)
}

fn recording_text_property(parts: Vec<String>) -> Result<(), TestCaseError> {
    let text: String = parts.concat();
    match parse_recording(&text, None) {
        Ok(r) => {
            let rec = r.recording;
            prop_assert!(rec.sample_rate_hz.is_finite() && rec.sample_rate_hz > 0.0);
            prop_assert_eq!(rec.time_s.len(), rec.torque_cmd_nm.len());
        }
        Err(e) => prop_assert!(e.to_string().starts_with("<memory>"), "{}", e),
    }
    Ok(())
}

/// Arbitrary bytes: no panic.
#[test]
fn the_recording_reader_takes_any_bytes() {
    run_target("recording bytes", CASES);
}

fn any_bytes(most: usize) -> impl Strategy<Value = Vec<u8>> {
    proptest::collection::vec(any::<u8>(), 0..most)
}

fn recording_bytes_property(bytes: Vec<u8>) -> Result<(), TestCaseError> {
    let text = String::from_utf8_lossy(&bytes);
    let _ = parse_recording(&text, None);
    Ok(())
}

/// A sidecar's rate, period, counts and lines against rows with or without a gap:
/// whatever is accepted has the sidecar's time step everywhere and an excitation the
/// rows hold.
#[test]
fn an_accepted_sidecar_agrees_with_the_rows() {
    run_target("sidecar against the rows", CASES);
}

type SidecarAndRows = (usize, f64, usize, usize, usize, usize, usize, f64);

fn sidecar_and_rows() -> impl Strategy<Value = SidecarAndRows> {
    (
        2usize..300,
        prop_oneof![Just(1000.0), Just(500.0), Just(2000.0), 1.0f64..5000.0],
        prop_oneof![Just(0usize), 1usize..400, Just(1_500_000_000usize)],
        prop_oneof![0usize..10, Just(usize::MAX)],
        0usize..3,
        0usize..300,
        1usize..300,
        prop_oneof![Just(0.0), Just(0.01), Just(-0.0005), 0.0f64..0.002],
    )
}

fn sidecar_rows_property(v: SidecarAndRows) -> Result<(), TestCaseError> {
    let (n, rate, period, periods, transient, line, gap_at, gap_s) = v;
    let csv = csv_rows(n, gap_at, gap_s);
    let side = format!(
        r#"{{"sample_rate_hz": {rate}, "excitation": {{"kind": "multisine", "period_samples": {period}, "periods": {periods}, "transient_periods": {transient}, "excited_lines": [{line}]}}}}"#
    );
    match parse_recording(&csv, Some(&side)) {
        Ok(r) => {
            let rec = r.recording;
            let fs = rec.sample_rate_hz;
            prop_assert_eq!(fs, rate);
            for w in rec.time_s.windows(2) {
                prop_assert!(
                    ((w[1] - w[0]) * fs - 1.0).abs() <= 0.01 + 1e-9,
                    "step {}",
                    w[1] - w[0]
                );
            }
            let e = rec.sidecar.excitation.as_ref().expect("excitation");
            prop_assert!(e.period_samples >= 2);
            prop_assert!((e.transient_periods + e.periods) * e.period_samples <= rec.len());
            prop_assert!(e.excited_lines.iter().all(|&l| l <= e.period_samples / 2));
        }
        Err(e) => prop_assert!(e.to_string().starts_with("<memory>"), "{}", e),
    }
    Ok(())
}

/// Arbitrary sidecar text (JSON-like pieces): no panic, an error names the sidecar.
#[test]
fn the_sidecar_parser_never_panics() {
    run_target("sidecar text", CASES);
}

fn sidecar_text() -> impl Strategy<Value = Vec<String>> {
    proptest::collection::vec(
        prop_oneof![
            Just("{".to_string()),
            Just("}".to_string()),
            Just("[".to_string()),
            Just("]".to_string()),
            Just(",".to_string()),
            Just(":".to_string()),
            Just("\"sample_rate_hz\"".to_string()),
            Just("\"excitation\"".to_string()),
            Just("\"period_samples\"".to_string()),
            Just("\"kind\"".to_string()),
            Just("\"multisine\"".to_string()),
            Just("\"blocks\"".to_string()),
            Just("1e999".to_string()),
            Just("-1".to_string()),
            Just("null".to_string()),
            "[0-9]{1,20}",
        ],
        0..40,
    )
}

fn sidecar_text_property(parts: Vec<String>) -> Result<(), TestCaseError> {
    let side = parts.concat();
    if let Err(e) = parse_recording(&csv_rows(50, 50, 0.0), Some(&side)) {
        prop_assert!(e.to_string().starts_with("<memory>"), "{}", e);
    }
    Ok(())
}

/// Plant files with random numbers in every key: no panic; an accepted chain is
/// physical; an error names the file.
#[test]
fn the_plant_file_never_panics() {
    run_target("plant file", CASES);
}

type PlantNumbers = (Vec<f64>, Vec<f64>, Vec<f64>, f64, u32, usize);

fn plant_numbers() -> impl Strategy<Value = PlantNumbers> {
    (
        proptest::collection::vec(
            prop_oneof![Just(-1.0f64), Just(0.0), 1e-6f64..10.0, Just(f64::MAX)],
            0..5,
        ),
        proptest::collection::vec(prop_oneof![Just(-1.0f64), Just(0.0), 1.0f64..1e6], 0..5),
        proptest::collection::vec(prop_oneof![Just(-1.0f64), 0.0f64..10.0], 0..5),
        prop_oneof![Just(0.0f64), Just(-5.0), 1.0f64..1e5],
        0u32..50,
        0usize..6,
    )
}

fn plant_property(v: PlantNumbers) -> Result<(), TestCaseError> {
    let (j, c, d, fs, substeps, coupling) = v;
    let list = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:e}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let text = format!(
        "[chain]\ninertia_kgm2 = [{}]\nstiffness_nm_per_rad = [{}]\ndamping_nms_per_rad = [{}]\n\
         [measurement]\nsample_rate_hz = {fs:e}\nsubsteps = {substeps}\n\
         [effects.backlash]\ncoupling = {coupling}\nhalf_gap_rad = 1e-3\n",
        list(&j),
        list(&c),
        list(&d)
    );
    match PlantFile::parse(&text, "P.toml") {
        Ok(p) => {
            prop_assert!(p
                .chain
                .inertia_kgm2
                .iter()
                .all(|x| *x > 0.0 && x.is_finite()));
            prop_assert!(p.measurement.sample_rate_hz > 0.0);
        }
        Err(e) => prop_assert!(e.to_string().contains("P.toml"), "{}", e),
    }
    Ok(())
}

/// Configurations with one value replaced by something random: no panic, an error names
/// the file.
#[test]
fn the_configuration_never_panics() {
    run_target("daemon configuration", CASES);
}

fn config_value() -> impl Strategy<Value = (&'static str, String)> {
    (
        prop_oneof![
            Just("listen"),
            Just("peak_torque_nm"),
            Just("cycle_hz"),
            Just("bitrate"),
            Just("node"),
            Just("port"),
            Just("max_sweep_s")
        ],
        prop_oneof![
            Just("-1".to_string()),
            Just("0".to_string()),
            Just("1e400".to_string()),
            Just("nan".to_string()),
            Just("\"x\"".to_string()),
            Just("[]".to_string()),
            "[0-9]{1,12}"
        ],
    )
}

fn config_property((key, value): (&'static str, String)) -> Result<(), TestCaseError> {
    let text = config_text()
        .lines()
        .map(|l| {
            if l.trim_start().starts_with(key) {
                format!("{key} = {value}")
            } else {
                l.replace(&format!("{key} = 1.0"), &format!("{key} = {value}"))
                    .replace(&format!("{key} = 60"), &format!("{key} = {value}"))
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    if let Err(e) = Config::parse(&text, "flexid.toml") {
        prop_assert!(e.to_string().starts_with("flexid.toml"), "{}", e);
    }
    Ok(())
}

/// Sweep request bodies with random values in every field (and random extra fields):
/// no panic; an accepted request is within the axis's limits; a refusal is 400 or 422.
#[test]
fn every_request_body_is_checked() {
    run_target("sweep request body", CASES);
}

type RequestFields = (
    &'static str,
    f64,
    f64,
    f64,
    String,
    f64,
    Option<(f64, f64)>,
    Option<usize>,
    Option<String>,
);

fn request_fields() -> impl Strategy<Value = RequestFields> {
    (
        prop_oneof![
            Just("\"multisine\""),
            Just("\"chirp\""),
            Just("\"noise\""),
            Just("3")
        ],
        prop_oneof![Just(-1.0f64), Just(0.0), 0.1f64..600.0, Just(1e300)],
        prop_oneof![Just(0.0f64), 0.1f64..600.0, Just(f64::MAX)],
        prop_oneof![Just(-0.5f64), Just(0.0), 0.01f64..3.0],
        prop_oneof![
            Just("0".to_string()),
            Just("2.5".to_string()),
            Just("1e30".to_string()),
            (1u64..100).prop_map(|p| p.to_string())
        ],
        prop_oneof![Just(-1.0f64), Just(0.0), 0.1f64..120.0],
        proptest::option::of((0.0f64..2.0, 0.0f64..2.0)),
        proptest::option::of(0usize..12),
        proptest::option::of("[a-z]{1,8}"),
    )
}

fn request_property(v: RequestFields) -> Result<(), TestCaseError> {
    let (excitation, lo, hi, amp, periods, duration, levels, masses, extra) = v;
    let mut body = format!(
        r#"{{"excitation":{excitation},"band_hz":[{lo:e},{hi:e}],"amplitude_nm":{amp:e},"periods":{periods},"duration_s":{duration:e}"#
    );
    if let Some((a, b)) = levels {
        body.push_str(&format!(r#","levels_nm":[{a:e},{b:e}]"#));
    }
    if let Some(m) = masses {
        body.push_str(&format!(r#","masses":{m}"#));
    }
    if let Some(x) = extra {
        body.push_str(&format!(r#","{x}":1"#));
    }
    body.push('}');
    let cfg = Config::parse(&config_text(), "flexid.toml").unwrap();
    let axis = &cfg.axis[0];
    match parse_request(body.as_bytes(), axis) {
        Ok(r) => {
            prop_assert!(r.amplitude_nm > 0.0 && r.amplitude_nm <= axis.limits.peak_torque_nm);
            prop_assert!(
                r.band_hz[0] > 0.0
                    && r.band_hz[0] < r.band_hz[1]
                    && r.band_hz[1] < axis.cycle_hz / 2.0
            );
            prop_assert!(r.periods >= 1);
            prop_assert!(r.duration_s > 0.0 && r.duration_s <= axis.limits.max_sweep_s);
        }
        Err(e) => prop_assert!(e.status == 400 || e.status == 422, "{:?}", e),
    }
    Ok(())
}

/// Arbitrary bytes as a request body: no panic.
#[test]
fn any_bytes_as_a_request_body() {
    run_target("request body bytes", 512);
}

fn request_bytes_property(b: Vec<u8>) -> Result<(), TestCaseError> {
    let cfg = Config::parse(&config_text(), "flexid.toml").unwrap();
    if let Err(e) = parse_request(&b, &cfg.axis[0]) {
        prop_assert!(e.status == 400 || e.status == 422);
    }
    Ok(())
}

/// Issue 16, "the fuzz targets run in CI for at least 60 s in total, with no finding":
/// every target in turn, in batches of [`FUZZ_BATCH`] cases with a fresh random seed each,
/// until `FLEXID_FUZZ_SECONDS` have passed (the last round is finished, so every target
/// gets as many batches). A finding fails the test with the shrunk input, saved by its seed
/// in the regressions file. Prints the seconds and the cases per target (to the process's
/// stderr, past the test harness's capture).
#[test]
fn fuzz_for_a_bounded_time() {
    let mut err = std::io::stderr();
    let Some(seconds) = fuzz_seconds() else {
        let _ = writeln!(
            err,
            "fuzz_for_a_bounded_time: FLEXID_FUZZ_SECONDS not set: not run (CI sets 70)"
        );
        return;
    };
    let t0 = Instant::now();
    let mut cases = [0u64; TARGETS.len()];
    let mut busy = [Duration::ZERO; TARGETS.len()];
    while t0.elapsed().as_secs_f64() < seconds {
        for (i, (name, run)) in TARGETS.iter().enumerate() {
            let t1 = Instant::now();
            if let Err(e) = run(FUZZ_BATCH) {
                panic!(
                    "fuzzing {name}: a finding after {:.1} s: {e}",
                    t0.elapsed().as_secs_f64()
                );
            }
            busy[i] += t1.elapsed();
            cases[i] += u64::from(FUZZ_BATCH);
        }
    }
    let took = t0.elapsed().as_secs_f64();
    let total: u64 = cases.iter().sum();
    let _ = writeln!(
        err,
        "fuzz_for_a_bounded_time: {took:.1} s (asked {seconds} s), {total} cases, no finding:"
    );
    for (i, (name, _)) in TARGETS.iter().enumerate() {
        let _ = writeln!(
            err,
            "  {:26} {:8} cases in {:5.1} s",
            name,
            cases[i],
            busy[i].as_secs_f64()
        );
    }
    assert!(took >= seconds && cases.iter().all(|&c| c > 0));
}

/// Cases per target and round of [`fuzz_for_a_bounded_time`].
const FUZZ_BATCH: u32 = 256;

/// `FLEXID_FUZZ_SECONDS`, when set to a positive number.
fn fuzz_seconds() -> Option<f64> {
    let v = std::env::var("FLEXID_FUZZ_SECONDS").ok()?;
    match v.trim().parse::<f64>() {
        Ok(s) if s.is_finite() && s > 0.0 => Some(s),
        Ok(_) => None,
        Err(_) => panic!("FLEXID_FUZZ_SECONDS={v:?}: not a number of seconds"),
    }
}

fn config_text() -> String {
    r#"data_dir = "/tmp/flexid-props"
[api]
listen = "127.0.0.1:0"
token_file = "/tmp/flexid-props/token"
[[bus]]
name = "vbus"
kind = "udp"
group = "239.74.163.2"
port = 43113
bitrate = 1000000
[[axis]]
name = "a1"
bus = "vbus"
node = 1
cycle_hz = 1000
clock = "simulated"
limits = { peak_torque_nm = 1.0, max_speed_rad_s = 100.0, position_window_rad = 10.0, max_sweep_s = 60 }
"#
    .to_string()
}
