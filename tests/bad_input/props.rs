//! Property tests (proptest) over every reader of outside input: the recording reader,
//! the sidecar parser, the plant file, the daemon's configuration and the API's request
//! bodies. Each property runs a bounded number of cases (the whole file takes seconds in
//! a release build); a failing input is saved by its seed in
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
use proptest::test_runner::{Config as PtConfig, FileFailurePersistence};

fn config(cases: u32) -> PtConfig {
    PtConfig {
        cases,
        failure_persistence: Some(Box::new(FileFailurePersistence::WithSource(
            "proptest-regressions",
        ))),
        ..PtConfig::default()
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

proptest! {
    #![proptest_config(config(384))]

    /// Arbitrary text made of the format's own pieces: no panic; an error names the file.
    #[test]
    fn the_recording_reader_never_panics(parts in proptest::collection::vec(text_fragment(), 0..80)) {
        let text: String = parts.concat();
        match parse_recording(&text, None) {
            Ok(r) => {
                let rec = r.recording;
                prop_assert!(rec.sample_rate_hz.is_finite() && rec.sample_rate_hz > 0.0);
                prop_assert_eq!(rec.time_s.len(), rec.torque_cmd_nm.len());
            }
            Err(e) => prop_assert!(e.to_string().starts_with("<memory>"), "{}", e),
        }
    }

    /// Arbitrary bytes: no panic.
    #[test]
    fn the_recording_reader_takes_any_bytes(bytes in proptest::collection::vec(any::<u8>(), 0..600)) {
        let text = String::from_utf8_lossy(&bytes);
        let _ = parse_recording(&text, None);
    }

    /// A sidecar's rate, period, counts and lines against rows with or without a gap:
    /// whatever is accepted has the sidecar's time step everywhere and an excitation the
    /// rows hold.
    #[test]
    fn an_accepted_sidecar_agrees_with_the_rows(
        n in 2usize..300,
        rate in prop_oneof![Just(1000.0), Just(500.0), Just(2000.0), 1.0f64..5000.0],
        period in prop_oneof![Just(0usize), 1usize..400, Just(1_500_000_000usize)],
        periods in prop_oneof![0usize..10, Just(usize::MAX)],
        transient in 0usize..3,
        line in 0usize..300,
        gap_at in 1usize..300,
        gap_s in prop_oneof![Just(0.0), Just(0.01), Just(-0.0005), 0.0f64..0.002],
    ) {
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
                    prop_assert!(((w[1] - w[0]) * fs - 1.0).abs() <= 0.01 + 1e-9, "step {}", w[1] - w[0]);
                }
                let e = rec.sidecar.excitation.as_ref().expect("excitation");
                prop_assert!(e.period_samples >= 2);
                prop_assert!((e.transient_periods + e.periods) * e.period_samples <= rec.len());
                prop_assert!(e.excited_lines.iter().all(|&l| l <= e.period_samples / 2));
            }
            Err(e) => prop_assert!(e.to_string().starts_with("<memory>"), "{}", e),
        }
    }

    /// Arbitrary sidecar text (JSON-like pieces): no panic, an error names the sidecar.
    #[test]
    fn the_sidecar_parser_never_panics(parts in proptest::collection::vec(prop_oneof![
        Just("{".to_string()), Just("}".to_string()), Just("[".to_string()), Just("]".to_string()),
        Just(",".to_string()), Just(":".to_string()), Just("\"sample_rate_hz\"".to_string()),
        Just("\"excitation\"".to_string()), Just("\"period_samples\"".to_string()),
        Just("\"kind\"".to_string()), Just("\"multisine\"".to_string()), Just("\"blocks\"".to_string()),
        Just("1e999".to_string()), Just("-1".to_string()), Just("null".to_string()),
        "[0-9]{1,20}",
    ], 0..40)) {
        let side = parts.concat();
        if let Err(e) = parse_recording(&csv_rows(50, 50, 0.0), Some(&side)) {
            prop_assert!(e.to_string().starts_with("<memory>"), "{}", e);
        }
    }

    /// Plant files with random numbers in every key: no panic; an accepted chain is
    /// physical; an error names the file.
    #[test]
    fn the_plant_file_never_panics(
        j in proptest::collection::vec(prop_oneof![Just(-1.0f64), Just(0.0), 1e-6f64..10.0, Just(f64::MAX)], 0..5),
        c in proptest::collection::vec(prop_oneof![Just(-1.0f64), Just(0.0), 1.0f64..1e6], 0..5),
        d in proptest::collection::vec(prop_oneof![Just(-1.0f64), 0.0f64..10.0], 0..5),
        fs in prop_oneof![Just(0.0f64), Just(-5.0), 1.0f64..1e5],
        substeps in 0u32..50,
        coupling in 0usize..6,
    ) {
        let list = |v: &[f64]| v.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(", ");
        let text = format!(
            "[chain]\ninertia_kgm2 = [{}]\nstiffness_nm_per_rad = [{}]\ndamping_nms_per_rad = [{}]\n\
             [measurement]\nsample_rate_hz = {fs:e}\nsubsteps = {substeps}\n\
             [effects.backlash]\ncoupling = {coupling}\nhalf_gap_rad = 1e-3\n",
            list(&j), list(&c), list(&d)
        );
        match PlantFile::parse(&text, "P.toml") {
            Ok(p) => {
                prop_assert!(p.chain.inertia_kgm2.iter().all(|x| *x > 0.0 && x.is_finite()));
                prop_assert!(p.measurement.sample_rate_hz > 0.0);
            }
            Err(e) => prop_assert!(e.to_string().contains("P.toml"), "{}", e),
        }
    }

    /// Configurations with one value replaced by something random: no panic, an error names
    /// the file.
    #[test]
    fn the_configuration_never_panics(
        key in prop_oneof![Just("listen"), Just("peak_torque_nm"), Just("cycle_hz"), Just("bitrate"), Just("node"), Just("port"), Just("max_sweep_s")],
        value in prop_oneof![Just("-1".to_string()), Just("0".to_string()), Just("1e400".to_string()), Just("nan".to_string()), Just("\"x\"".to_string()), Just("[]".to_string()), "[0-9]{1,12}"],
    ) {
        let text = config_text().lines().map(|l| {
            if l.trim_start().starts_with(key) {
                format!("{key} = {value}")
            } else {
                l.replace(&format!("{key} = 1.0"), &format!("{key} = {value}"))
                    .replace(&format!("{key} = 60"), &format!("{key} = {value}"))
            }
        }).collect::<Vec<_>>().join("\n");
        if let Err(e) = Config::parse(&text, "flexid.toml") {
            prop_assert!(e.to_string().starts_with("flexid.toml"), "{}", e);
        }
    }

    /// Sweep request bodies with random values in every field (and random extra fields):
    /// no panic; an accepted request is within the axis's limits; a refusal is 400 or 422.
    #[test]
    fn every_request_body_is_checked(
        excitation in prop_oneof![Just("\"multisine\""), Just("\"chirp\""), Just("\"noise\""), Just("3")],
        lo in prop_oneof![Just(-1.0f64), Just(0.0), 0.1f64..600.0, Just(1e300)],
        hi in prop_oneof![Just(0.0f64), 0.1f64..600.0, Just(f64::MAX)],
        amp in prop_oneof![Just(-0.5f64), Just(0.0), 0.01f64..3.0],
        periods in prop_oneof![Just("0".to_string()), Just("2.5".to_string()), Just("1e30".to_string()), (1u64..100).prop_map(|p| p.to_string())],
        duration in prop_oneof![Just(-1.0f64), Just(0.0), 0.1f64..120.0],
        levels in proptest::option::of((0.0f64..2.0, 0.0f64..2.0)),
        masses in proptest::option::of(0usize..12),
        extra in proptest::option::of("[a-z]{1,8}"),
    ) {
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
                prop_assert!(r.band_hz[0] > 0.0 && r.band_hz[0] < r.band_hz[1] && r.band_hz[1] < axis.cycle_hz / 2.0);
                prop_assert!(r.periods >= 1);
                prop_assert!(r.duration_s > 0.0 && r.duration_s <= axis.limits.max_sweep_s);
            }
            Err(e) => prop_assert!(e.status == 400 || e.status == 422, "{:?}", e),
        }
    }
}

/// Arbitrary bytes as a request body: no panic.
#[test]
fn any_bytes_as_a_request_body() {
    let cfg = Config::parse(&config_text(), "flexid.toml").unwrap();
    let mut runner = proptest::test_runner::TestRunner::new(config(512));
    runner
        .run(&proptest::collection::vec(any::<u8>(), 0..300), |b| {
            if let Err(e) = parse_request(&b, &cfg.axis[0]) {
                prop_assert!(e.status == 400 || e.status == 422);
            }
            Ok(())
        })
        .unwrap();
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
