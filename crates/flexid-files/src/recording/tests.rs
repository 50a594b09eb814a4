//! Tests of the recording format.

use super::*;
use flexid_core::excitation::{ExcitationInfo, ExcitationKind};
use std::path::Path;

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

/// Rows of `time_s,torque_cmd_nm,position_rad` at 1 kHz, starting at file line 2.
fn csv_rows(n: usize) -> String {
    let mut s = String::from("time_s,torque_cmd_nm,position_rad\n");
    for k in 0..n {
        s.push_str(&format!(
            "{:e},{:e},{:e}\n",
            k as f64 * 1e-3,
            (k as f64).sin(),
            k as f64 * 0.01
        ));
    }
    s
}

fn err(csv: &str) -> RecordingError {
    parse_recording(csv, None).unwrap_err()
}

#[test]
fn round_trip_is_bit_identical() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("REC.csv");
    let n = 1000;
    let fs = 4000.0 / 3.0;
    let odd = [
        0.0,
        -0.0,
        5e-324,
        -1.7976931348623157e308,
        1.0 / 3.0,
        2.2250738585072014e-308,
    ];
    let torque: Vec<f64> = (0..n)
        .map(|k| {
            if k < odd.len() {
                odd[k]
            } else {
                (k as f64 * 0.37).sin() * 1e-7
            }
        })
        .collect();
    let rec = Recording {
        time_s: (0..n).map(|k| k as f64 / fs).collect(),
        torque_cmd_nm: torque,
        position_rad: Some(
            (0..n)
                .map(|k| (k as f64).sqrt() * std::f64::consts::PI)
                .collect(),
        ),
        velocity_rad_s: None,
        acceleration_rad_s2: Some((0..n).map(|k| -(k as f64).ln_1p() * 1e12).collect()),
        torque_actual_nm: Some((0..n).map(|k| k as f64 * 1e-3).collect()),
        sample_rate_hz: fs,
        sidecar: Sidecar {
            sample_rate_hz: Some(fs),
            excitation: Some(ExcitationInfo {
                kind: ExcitationKind::Other,
                period_samples: 0,
                periods: 0,
                transient_periods: 0,
                excited_lines: vec![],
                band_hz: None,
                peak_nm: Some(0.1),
                rms_nm: None,
                design: Some("test".into()),
                blocks: Vec::new(),
                realisations: Vec::new(),
                band_limited: false,
            }),
            source: Some("unit test, with \"quotes\"".into()),
            io_delay_samples: Some(1),
            ..Default::default()
        },
    };
    write_recording(&path, &rec).unwrap();
    assert!(sidecar_path(&path).exists());
    let back = read_recording(&path).unwrap();
    assert_eq!(bits(&back.time_s), bits(&rec.time_s));
    assert_eq!(bits(&back.torque_cmd_nm), bits(&rec.torque_cmd_nm));
    assert_eq!(
        bits(back.position_rad.as_ref().unwrap()),
        bits(rec.position_rad.as_ref().unwrap())
    );
    assert_eq!(
        bits(back.acceleration_rad_s2.as_ref().unwrap()),
        bits(rec.acceleration_rad_s2.as_ref().unwrap())
    );
    assert_eq!(back.sample_rate_hz.to_bits(), fs.to_bits());
    assert_eq!(back, rec);
    // Only the two files: no temporaries left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 2);
}

#[test]
fn read_write_read_is_identical_without_sidecar() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.csv");
    std::fs::write(&a, csv_rows(300)).unwrap();
    let first = read_recording(&a).unwrap();
    let b = dir.path().join("b.csv");
    write_recording(&b, &first).unwrap();
    let second = read_recording(&b).unwrap();
    assert_eq!(first, second);
}

#[test]
fn rate_is_inferred_from_time() {
    let r = parse_recording(&csv_rows(500), None).unwrap();
    let rec = r.recording;
    assert!(
        (rec.sample_rate_hz - 1000.0).abs() < 1e-9,
        "{}",
        rec.sample_rate_hz
    );
    assert_eq!(rec.sidecar.sample_rate_hz, Some(rec.sample_rate_hz));
    assert_eq!(rec.len(), 500);
    assert!(rec.velocity_rad_s.is_none());
}

#[test]
fn sidecar_rate_wins() {
    // within 1 % of time_s's rate the sidecar's rate is the one used
    let r = parse_recording(&csv_rows(10), Some(r#"{"sample_rate_hz": 1005.0}"#)).unwrap();
    assert_eq!(r.recording.sample_rate_hz, 1005.0);
}

/// Issue 16: a sidecar rate contradicting time_s (twice, or 2.4 % off) was only a
/// warning; it is an error naming both rates.
#[test]
fn sidecar_rate_contradicting_time_is_refused() {
    for fs in ["1024.0", "2000", "500"] {
        let side = format!(r#"{{"sample_rate_hz": {fs}}}"#);
        let e = parse_recording(&csv_rows(10), Some(&side)).unwrap_err();
        assert!(matches!(e, RecordingError::RateContradiction { .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.contains("sample_rate_hz") && msg.contains("1000"),
            "{msg}"
        );
    }
}

/// Issue 16: a 10 ms gap in time_s with a sidecar gave a wrong model and exit 0; it is
/// refused, naming the line.
#[test]
fn a_gap_in_time_with_a_sidecar_is_refused() {
    let mut csv = String::from("time_s,torque_cmd_nm,position_rad\n");
    for k in 0..100 {
        let t = if k < 50 {
            k as f64 * 1e-3
        } else {
            k as f64 * 1e-3 + 0.01
        };
        csv.push_str(&format!("{t:e},{},{}\n", (k as f64).sin(), k as f64 * 0.01));
    }
    let e = parse_recording(&csv, Some(r#"{"sample_rate_hz": 1000}"#)).unwrap_err();
    assert!(matches!(e, RecordingError::TimeGap { line: 52, .. }), "{e}");
    assert!(e.to_string().contains("line 52"), "{e}");
}

/// Issue 16: `period_samples: 0` of a multisine, a period count the rows cannot hold,
/// an excited line above Nyquist: each refused, naming the key.
#[test]
fn sidecar_excitation_contradicting_the_rows_is_refused() {
    let side = |ps: &str, periods: &str, lines: &str| {
        format!(
            r#"{{"sample_rate_hz": 1000, "excitation": {{"kind": "multisine", "period_samples": {ps}, "periods": {periods}, "transient_periods": 1, "excited_lines": [{lines}]}}}}"#
        )
    };
    let csv = csv_rows(100);
    for (s, key) in [
        (side("0", "4", "1"), "period_samples 0"),
        (side("20", "8", "1"), "periods 8"),
        (side("20", "18446744073709551615", "1"), "more than 2^64"),
        (side("20", "4", "11"), "excited_lines"),
    ] {
        let e = parse_recording(&csv, Some(&s)).unwrap_err();
        assert!(matches!(e, RecordingError::Sidecar { .. }), "{e}");
        assert!(e.to_string().contains(key), "{e} does not name {key}");
    }
    assert!(parse_recording(&csv, Some(&side("20", "4", "1,10"))).is_ok());
}

/// Realisations of a multisine whose period runs past the rows, or whose lead-in starts
/// before the first row, are refused naming `excitation.realisations[i]`; ones inside are
/// read back.
#[test]
fn sidecar_realisations_outside_the_rows_are_refused() {
    let side = |reals: &str| {
        format!(
            r#"{{"sample_rate_hz": 1000, "excitation": {{"kind": "multisine", "period_samples": 20, "periods": 2, "transient_periods": 0, "excited_lines": [1], "realisations": [{reals}]}}}}"#
        )
    };
    let csv = csv_rows(100);
    for (s, key) in [
        (
            side(r#"{"start": 10, "lead_in": 5}, {"start": 90, "lead_in": 5}"#),
            "realisations[1]",
        ),
        (
            side(r#"{"start": 4, "lead_in": 5}, {"start": 40, "lead_in": 5}"#),
            "realisations[0]",
        ),
        (
            side(r#"{"start": 18446744073709551615, "lead_in": 0}"#),
            "realisations[0]",
        ),
    ] {
        let e = parse_recording(&csv, Some(&s)).unwrap_err();
        assert!(matches!(e, RecordingError::Sidecar { .. }), "{e}");
        assert!(e.to_string().contains(key), "{e} does not name {key}");
    }
    let ok = parse_recording(
        &csv,
        Some(&side(
            r#"{"start": 10, "lead_in": 5}, {"start": 60, "lead_in": 5}"#,
        )),
    )
    .unwrap();
    let e = ok.recording.sidecar.excitation.unwrap();
    assert_eq!(e.realisations.len(), 2);
    assert_eq!(e.realisations[1].start, 60);
}

/// A line without an end (a file of one huge line, `/dev/zero`) is refused at
/// `MAX_LINE_BYTES`, not read into memory whole.
#[test]
fn an_endless_line_is_refused() {
    let mut csv = String::from("time_s,torque_cmd_nm,position_rad\n0,");
    csv.push_str(&"1".repeat(MAX_LINE_BYTES + 10));
    let e = parse_recording(&csv, None).unwrap_err();
    assert!(
        matches!(e, RecordingError::LineTooLong { line: 2, .. }),
        "{e}"
    );
}

/// A sidecar that is a FIFO is refused without blocking; one larger than
/// `MAX_SIDECAR_BYTES` without being read.
#[test]
fn a_sidecar_that_is_no_regular_file_or_too_large_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("REC.csv");
    std::fs::write(&csv, csv_rows(10)).unwrap();
    let side = sidecar_path(&csv);
    let st = std::process::Command::new("mkfifo")
        .arg(&side)
        .status()
        .unwrap();
    assert!(st.success());
    let e = read_recording(&csv).unwrap_err();
    assert!(e.to_string().contains("not a regular file"), "{e}");
    std::fs::remove_file(&side).unwrap();
    let f = std::fs::File::create(&side).unwrap();
    f.set_len(MAX_SIDECAR_BYTES + 1).unwrap();
    let e = read_recording(&csv).unwrap_err();
    assert!(e.to_string().contains("more than a sidecar holds"), "{e}");
}

#[test]
fn tolerant_syntax() {
    let csv = "\u{feff}# recorded on axis 2\r\n\
                 position_rad , drive_temp_c,torque_cmd_nm , time_s \r\n\
               # a comment between rows\r\n\
                1.5 , 40 , 0.25 , 0.0\r\n\
               \r\n\
               1.25,40.5,-0.25,0.5\r\n\
               \r\n";
    let r = parse_recording(csv, None).unwrap();
    let rec = &r.recording;
    assert_eq!(rec.position_rad.as_deref(), Some(&[1.5, 1.25][..]));
    assert_eq!(rec.torque_cmd_nm, vec![0.25, -0.25]);
    assert_eq!(rec.sample_rate_hz, 2.0);
    assert!(
        r.warnings.iter().any(|w| w.contains("drive_temp_c")),
        "{:?}",
        r.warnings
    );
}

#[test]
fn time_is_optional_with_sidecar_rate() {
    let csv = "torque_cmd_nm,velocity_rad_s\n1,2\n3,4\n";
    let r = parse_recording(csv, Some(r#"{"sample_rate_hz": 100}"#)).unwrap();
    assert_eq!(r.recording.time_s, vec![0.0, 0.01]);
    assert_eq!(
        r.recording.preferred_motion().unwrap().0,
        MotionSignal::Velocity
    );
}

#[test]
fn period_is_inferred_with_transient() {
    let p = 200;
    let lines = [2usize, 5, 11, 30];
    let n = 7 * p + 50;
    let mut csv = String::from("time_s,torque_cmd_nm,position_rad\n");
    for k in 0..n {
        let ph = 2.0 * std::f64::consts::PI * (k % p) as f64 / p as f64;
        let mut u: f64 = lines
            .iter()
            .map(|&l| (l as f64 * ph + l as f64).sin())
            .sum();
        if k < 60 {
            u *= k as f64 / 60.0; // fade-in
        }
        csv.push_str(&format!("{:e},{:e},0\n", k as f64 / 500.0, u));
    }
    let r = parse_recording(&csv, None).unwrap();
    let ex = r.recording.sidecar.excitation.clone().unwrap();
    assert_eq!(ex.kind, ExcitationKind::Multisine);
    assert_eq!(ex.period_samples, p);
    assert_eq!(ex.transient_periods, 1);
    assert_eq!(ex.periods, 6);
    assert_eq!(ex.excited_lines, lines.to_vec());
    let band = ex.band_hz.unwrap();
    assert!(
        (band[0] - 5.0).abs() < 1e-9 && (band[1] - 75.0).abs() < 1e-9,
        "{band:?}"
    );
    assert!(r.warnings.iter().any(|w| w.contains("inferred")));
}

#[test]
fn sidecar_excitation_is_kept() {
    let json = r#"{"excitation": {"kind": "chirp"}}"#;
    let r = parse_recording(&csv_rows(100), Some(json)).unwrap();
    assert_eq!(
        r.recording.sidecar.excitation.unwrap().kind,
        ExcitationKind::Chirp
    );
}

#[test]
fn parse_error_names_line_and_column() {
    let mut csv = csv_rows(20);
    // Data row k is on line k + 2; line 17 is row 15.
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    lines[16] = "0.015,0.5,1.2.3".into();
    csv = lines.join("\n");
    let e = err(&csv);
    let msg = e.to_string();
    assert!(
        msg.contains("line 17, column position_rad: cannot parse \"1.2.3\""),
        "{msg}"
    );
    assert!(
        matches!(e, RecordingError::Parse { line: 17, ref column, ref text, .. }
        if column == "position_rad" && text == "1.2.3")
    );
}

#[test]
fn error_variants() {
    use RecordingError as E;
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,1\n");
    assert!(
        matches!(
            e,
            E::RowLength {
                line: 3,
                expected: 3,
                got: 2,
                ..
            }
        ),
        "{e}"
    );
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,1,2,3\n");
    assert!(
        matches!(
            e,
            E::RowLength {
                line: 3,
                expected: 3,
                got: 4,
                ..
            }
        ),
        "{e}"
    );
    let e = err("time_s,position_rad\n0,1\n");
    assert!(
        matches!(e, E::MissingColumn { line: 1, ref column, .. } if column == "torque_cmd_nm"),
        "{e}"
    );
    let e = err("torque_cmd_nm,position_rad\n0,1\n");
    assert!(
        matches!(e, E::MissingColumn { ref column, .. } if column == "time_s"),
        "{e}"
    );
    let e = err("# c\ntime_s,torque_cmd_nm,torque_cmd_nm,position_rad\n");
    assert!(
        matches!(e, E::DuplicateColumn { line: 2, ref column, .. } if column == "torque_cmd_nm"),
        "{e}"
    );
    let e = err("time_s,torque_cmd_nm,speed\n0,1,2\n");
    assert!(matches!(e, E::NoMotionColumn { line: 1, .. }), "{e}");
    let e = err("time_s,torque_cmd_nm,position_rad\n# only comments\n\n");
    assert!(matches!(e, E::Empty { .. }), "{e}");
    let e = err("");
    assert!(matches!(e, E::Empty { .. }), "{e}");
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,NaN,2\n");
    assert!(
        matches!(e, E::NonFinite { line: 3, ref column, .. } if column == "torque_cmd_nm"),
        "{e}"
    );
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,inf,2\n");
    assert!(matches!(e, E::NonFinite { line: 3, .. }), "{e}");
    let e = err("time_s,torque_cmd_nm,position_rad\n0,,2\n");
    assert!(
        matches!(e, E::Parse { line: 2, ref text, .. } if text.is_empty()),
        "{e}"
    );
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,1,2\n0.1,1,2\n");
    assert!(matches!(e, E::TimeNotIncreasing { line: 4, .. }), "{e}");
    let e = err(
        "time_s,torque_cmd_nm,position_rad\n0,1,2\n0.1,1,2\n0.2,1,2\n# gap\n0.35,1,2\n0.45,1,2\n",
    );
    assert!(matches!(e, E::NotUniform { line: 6, .. }), "{e}");
    assert!(e.to_string().contains("line 6, column time_s"), "{e}");
    let e = err("time_s,torque_cmd_nm,position_rad\n0,1,2\n");
    assert!(matches!(e, E::NoSampleRate { .. }), "{e}");
    let e = parse_recording(
        "time_s,torque_cmd_nm,position_rad\n0,1,2\n",
        Some("{\"sample_rate_hz\": "),
    )
    .unwrap_err();
    assert!(matches!(e, E::Sidecar { .. }), "{e}");
    let e = parse_recording(
        "time_s,torque_cmd_nm,position_rad\n0,1,2\n",
        Some(r#"{"sample_rate_hz": -1}"#),
    )
    .unwrap_err();
    assert!(matches!(e, E::Sidecar { .. }), "{e}");
    let e = read_recording_from(
        &b"time_s,torque_cmd_nm,position_rad\n0,\xff,2\n"[..],
        Path::new("x.csv"),
        None,
    )
    .unwrap_err();
    assert!(matches!(e, E::NotUtf8 { line: 2, .. }), "{e}");
}

#[test]
fn file_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("missing.csv");
    let e = read_recording(&path).unwrap_err();
    assert!(matches!(e, RecordingError::Io { .. }));
    assert!(e.to_string().contains("missing.csv"), "{e}");

    let path = dir.path().join("REC.csv");
    std::fs::write(&path, csv_rows(5)).unwrap();
    std::fs::write(sidecar_path(&path), "{\"sample_rate_hz\": \"fast\"}").unwrap();
    let e = read_recording(&path).unwrap_err();
    assert!(matches!(e, RecordingError::Sidecar { .. }));
    assert!(e.to_string().contains("REC.json"), "{e}");

    let bad = Recording {
        time_s: vec![0.0],
        torque_cmd_nm: vec![1.0, 2.0],
        position_rad: Some(vec![0.0, 0.0]),
        sample_rate_hz: 1.0,
        ..Default::default()
    };
    let e = write_recording(dir.path().join("bad.csv"), &bad).unwrap_err();
    assert!(matches!(e, RecordingError::Invalid { .. }), "{e}");
    assert!(!dir.path().join("bad.csv").exists());
}

#[test]
fn million_rows() {
    let n = 1_000_000;
    let fs = 8000.0;
    let p = 1000;
    let rec = Recording {
        time_s: (0..n).map(|k| k as f64 / fs).collect(),
        torque_cmd_nm: (0..n)
            .map(|k| {
                let ph = 2.0 * std::f64::consts::PI * (k % p) as f64 / p as f64;
                (3.0 * ph).sin() + 0.5 * (17.0 * ph).cos()
            })
            .collect(),
        position_rad: Some((0..n).map(|k| (k as f64 * 1e-4).sin()).collect()),
        sample_rate_hz: fs,
        ..Default::default()
    };
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.csv");
    let t0 = std::time::Instant::now();
    write_recording(&path, &rec).unwrap();
    let t1 = std::time::Instant::now();
    let back = read_recording_report(&path).unwrap().recording;
    let t2 = std::time::Instant::now();
    eprintln!("1e6 rows: write {:?}, read {:?}", t1 - t0, t2 - t1);
    assert_eq!(back.len(), n);
    assert_eq!(bits(&back.torque_cmd_nm), bits(&rec.torque_cmd_nm));
    let ex = back.sidecar.excitation.unwrap();
    assert_eq!((ex.period_samples, ex.excited_lines), (p, vec![3, 17]));
}

/// A recording whose sidecar target is refused (a FIFO) leaves nothing written: the CSV
/// is not replaced beside a sidecar that could not be.
#[test]
fn a_refused_sidecar_target_writes_no_csv() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("REC.csv");
    std::fs::write(&path, "old").unwrap();
    let st = std::process::Command::new("mkfifo")
        .arg(sidecar_path(&path))
        .status()
        .unwrap();
    assert!(st.success());
    let rec = parse_recording(&csv_rows(10), None).unwrap().recording;
    let e = write_recording(&path, &rec).unwrap_err();
    assert!(e.to_string().contains("FIFO"), "{e}");
    assert_eq!(std::fs::read_to_string(&path).unwrap(), "old");
}
