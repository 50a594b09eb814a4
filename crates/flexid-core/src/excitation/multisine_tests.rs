//! Tests of the multisine generator against a naive DFT and a naive cosine sum.

use super::*;
use crate::excitation::test_util::naive_line_spectrum;
use std::f64::consts::PI;

fn design(fs: f64, n: usize, band: [f64; 2]) -> MultisineDesign {
    MultisineDesign::new(fs, n, band, 10.0, 100.0)
}

/// Checks that the period has energy only at the excited lines, with the reported amplitudes
/// and phases, and that it equals the naive cosine sum.
fn check_spectrum(ms: &Multisine) {
    let (amp, phase) = naive_line_spectrum(&ms.period);
    let peak_line = amp.iter().cloned().fold(0.0, f64::max);
    let mut next = 0;
    for (k, &a) in amp.iter().enumerate() {
        if next < ms.excited_lines.len() && ms.excited_lines[next] == k {
            let want = ms.amplitudes_nm[next];
            assert!(
                (a - want).abs() <= 1e-9 * want,
                "line {k}: amplitude {a} vs {want}"
            );
            let d = (phase[k] - ms.phases_rad[next]).rem_euclid(2.0 * PI);
            assert!(d.min(2.0 * PI - d) < 1e-9, "line {k}: phase");
            next += 1;
        } else {
            assert!(
                a < 1e-9 * peak_line,
                "non-excited line {k} has amplitude {a}"
            );
        }
    }
    assert_eq!(next, ms.excited_lines.len());
    // Fast synthesis == naive cosine sum.
    let n = ms.period.len();
    let tol = 1e-11 * ms.peak_nm();
    for (i, &v) in ms.period.iter().enumerate() {
        let naive: f64 = ms
            .excited_lines
            .iter()
            .zip(&ms.amplitudes_nm)
            .zip(&ms.phases_rad)
            .map(|((&k, &a), &p)| a * (2.0 * PI * ((k * i) % n) as f64 / n as f64 + p).cos())
            .sum();
        assert!((v - naive).abs() < tol, "sample {i}: {v} vs {naive}");
    }
}

#[test]
fn flat_schroeder_has_flat_spectrum_at_excited_lines_only() {
    let ms = design(1000.0, 1024, [10.0, 200.0]).generate().unwrap();
    let df = 1000.0 / 1024.0;
    assert_eq!(ms.excited_lines.first(), Some(&((10.0 / df) as usize + 1)));
    assert_eq!(ms.excited_lines.last(), Some(&((200.0 / df) as usize)));
    assert!(ms.detection_lines.is_empty());
    check_spectrum(&ms);
    let a0 = ms.amplitudes_nm[0];
    assert!(ms
        .amplitudes_nm
        .iter()
        .all(|a| (a - a0).abs() <= 1e-12 * a0));
}

#[test]
fn power_law_shape_is_followed() {
    let mut d = design(500.0, 2000, [1.0, 50.0]);
    d.amplitude = AmplitudeShape::PowerLaw { exponent: 1.0 };
    d.phases = PhaseDesign::Random { seed: 3 };
    let ms = d.generate().unwrap();
    check_spectrum(&ms);
    let (k0, a0) = (ms.excited_lines[0] as f64, ms.amplitudes_nm[0]);
    for (&k, &a) in ms.excited_lines.iter().zip(&ms.amplitudes_nm) {
        let want = a0 * k as f64 / k0;
        assert!((a - want).abs() <= 1e-9 * want);
    }
}

#[test]
fn crest_reduction_reimposes_custom_amplitudes_exactly() {
    let mut d = design(1000.0, 512, [20.0, 100.0]);
    let count = band_lines(1000.0, 512, [20.0, 100.0]).unwrap().len();
    let custom: Vec<f64> = (0..count).map(|i| 1.0 + (i % 5) as f64).collect();
    d.amplitude = AmplitudeShape::Custom(custom.clone());
    d.phases = PhaseDesign::Random { seed: 11 };
    d.crest_iterations = 50;
    let ms = d.generate().unwrap();
    check_spectrum(&ms);
    let g = ms.amplitudes_nm[0] / custom[0];
    for (a, c) in ms.amplitudes_nm.iter().zip(&custom) {
        assert!((a - g * c).abs() <= 1e-12 * a);
    }
}

#[test]
fn odd_random_design_has_detection_lines() {
    let mut d = design(1000.0, 2048, [2.0, 300.0]);
    d.phases = PhaseDesign::OddRandom { seed: 42, group: 4 };
    d.crest_iterations = 20;
    let ms = d.generate().unwrap();
    check_spectrum(&ms); // also: detection and even lines carry no energy
    assert!(ms.excited_lines.iter().all(|k| k % 2 == 1));
    assert!(ms.detection_lines.iter().all(|k| k % 2 == 1));
    let odd: Vec<usize> = band_lines(1000.0, 2048, [2.0, 300.0])
        .unwrap()
        .into_iter()
        .filter(|k| k % 2 == 1)
        .collect();
    let full_groups = odd.len() / 4;
    assert_eq!(ms.detection_lines.len(), full_groups);
    for g in odd.chunks(4) {
        let det = g.iter().filter(|k| ms.detection_lines.contains(k)).count();
        let exc = g.iter().filter(|k| ms.excited_lines.contains(k)).count();
        if g.len() == 4 {
            assert_eq!((det, exc), (1, 3), "group {g:?}");
        } else {
            assert_eq!((det, exc), (0, g.len()));
        }
    }
    // Detection lines and even lines carry no energy (checked explicitly too).
    let (amp, _) = naive_line_spectrum(&ms.period);
    let top = amp.iter().cloned().fold(0.0, f64::max);
    for &k in &ms.detection_lines {
        assert!(amp[k] < 1e-9 * top);
        assert!(amp[k + 1] < 1e-9 * top);
    }
    assert_eq!(ms.info(3, 1).design.as_deref(), Some("odd_random_phase"));
}

#[test]
fn schroeder_crest_factor_below_two_for_flat_200_lines() {
    let ms = design(4096.0, 4096, [1.0, 200.0]).generate().unwrap();
    assert_eq!(ms.excited_lines.len(), 200);
    let cf = ms.crest_factor();
    assert!(cf < 2.0, "Schroeder crest factor {cf}");
    let mut d = design(4096.0, 4096, [1.0, 200.0]);
    d.crest_iterations = 30;
    assert!(d.generate().unwrap().crest_factor() <= cf);
}

#[test]
fn crest_reduction_lowers_random_phase_crest_and_never_raises_it() {
    let mut d = design(4096.0, 4096, [1.0, 200.0]);
    for seed in [1, 2, 3] {
        d.phases = PhaseDesign::Random { seed };
        d.crest_iterations = 0;
        let start = d.generate().unwrap().crest_factor();
        let mut last = start;
        for it in [1, 2, 5, 20, 100] {
            d.crest_iterations = it;
            let ms = d.generate().unwrap();
            let cf = ms.crest_factor();
            assert!(
                cf <= last + 1e-12,
                "seed {seed}, {it} iterations: {cf} > {last}"
            );
            last = cf;
        }
        assert!(
            last < 2.0 || last <= 0.75 * start,
            "seed {seed}: {start} -> {last}"
        );
        println!("seed {seed}: crest {start:.3} -> {last:.3}");
    }
}

#[test]
fn limits_hold_and_the_binding_one_is_met() {
    let mut d = design(1000.0, 1000, [1.0, 100.0]);
    d.phases = PhaseDesign::Random { seed: 5 };
    // Peak binds: rms limit generous.
    d.peak_limit_nm = 3.0;
    d.rms_limit_nm = 10.0;
    let ms = d.generate().unwrap();
    assert!((ms.peak_nm() - 3.0).abs() <= 1e-12 * 3.0);
    assert!(ms.rms_nm() < 10.0);
    // RMS binds.
    d.rms_limit_nm = 0.5;
    let ms = d.generate().unwrap();
    assert!((ms.rms_nm() - 0.5).abs() <= 1e-12 * 0.5);
    assert!(ms.peak_nm() <= 3.0);
    let info = ms.info(4, 2);
    assert_eq!(info.kind, ExcitationKind::Multisine);
    assert_eq!(
        (info.period_samples, info.periods, info.transient_periods),
        (1000, 4, 2)
    );
    assert_eq!(info.excited_lines, ms.excited_lines);
    assert_eq!(info.band_hz, Some([1.0, 100.0]));
    assert!((info.rms_nm.unwrap() - 0.5).abs() < 1e-12);
    let rec = ms.repeat(6);
    assert_eq!(rec.len(), 6000);
    assert_eq!(&rec[5000..], &ms.period[..]);
}

#[test]
fn bad_inputs_give_the_right_error() {
    use ExcitationError as E;
    let ok = design(1000.0, 1000, [1.0, 100.0]);
    let with = |f: &dyn Fn(&mut MultisineDesign)| {
        let mut d = ok.clone();
        f(&mut d);
        d.generate().unwrap_err()
    };
    assert!(matches!(
        with(&|d| d.peak_limit_nm = 0.0),
        E::NonPositiveLimit { which: "peak", .. }
    ));
    assert!(matches!(
        with(&|d| d.rms_limit_nm = -1.0),
        E::NonPositiveLimit { which: "rms", .. }
    ));
    assert!(matches!(
        with(&|d| d.rms_limit_nm = f64::NAN),
        E::NonPositiveLimit { .. }
    ));
    assert!(matches!(
        with(&|d| d.band_hz = [1.0, 600.0]),
        E::BandAboveNyquist { .. }
    ));
    assert!(matches!(
        with(&|d| d.band_hz = [0.0, 0.5]),
        E::BandBelowLineSpacing { .. }
    ));
    assert!(matches!(
        with(&|d| d.band_hz = [10.2, 10.8]),
        E::NoLineInBand { .. }
    ));
    assert!(matches!(
        with(&|d| d.band_hz = [5.0, 1.0]),
        E::InvalidBand { .. }
    ));
    assert!(matches!(
        with(&|d| d.period_samples = 2),
        E::PeriodTooShort { .. }
    ));
    assert!(matches!(
        with(&|d| d.period_samples = usize::MAX),
        E::TooLong { .. }
    ));
    assert!(matches!(
        with(&|d| d.sample_rate_hz = -1.0),
        E::InvalidSampleRate { .. }
    ));
    assert!(matches!(
        with(&|d| {
            d.band_hz = [10.0, 10.0];
            d.phases = PhaseDesign::OddRandom { seed: 0, group: 3 };
        }),
        E::NoLineInBand { .. }
    ));
    assert!(matches!(
        with(&|d| d.phases = PhaseDesign::OddRandom { seed: 0, group: 1 }),
        E::InvalidGroup { group: 1 }
    ));
    assert!(matches!(
        with(&|d| d.amplitude = AmplitudeShape::Custom(vec![1.0; 3])),
        E::AmplitudeLengthMismatch {
            expected: 100,
            got: 3
        }
    ));
    assert!(matches!(
        with(&|d| d.amplitude = AmplitudeShape::Custom(vec![0.0; 100])),
        E::InvalidAmplitude { .. }
    ));
    assert!(matches!(
        with(&|d| {
            let mut a = vec![1.0; 100];
            a[7] = -1.0;
            d.amplitude = AmplitudeShape::Custom(a);
        }),
        E::InvalidAmplitude { index: 7, .. }
    ));
    assert!(matches!(
        with(&|d| d.amplitude = AmplitudeShape::PowerLaw {
            exponent: f64::INFINITY
        }),
        E::InvalidExponent { .. }
    ));
}

#[test]
fn zero_custom_amplitudes_drop_lines() {
    let mut d = design(1000.0, 1000, [1.0, 10.0]);
    d.amplitude = AmplitudeShape::Custom(vec![1.0, 0.0, 1.0, 1.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
    let ms = d.generate().unwrap();
    assert_eq!(ms.excited_lines, vec![1, 3, 4, 6, 7, 8, 9, 10]);
    check_spectrum(&ms);
}
