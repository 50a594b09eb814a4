//! Tests of the Bode plot.

use super::*;
use flexid_core::frf::{Frf, FrfKind};
use num_complex::Complex64;

/// Analytic 2-mass chain mobility H(jω) = (J2 s² + d s + c) / (s (J1 J2 s² + (J1+J2)(d s + c))).
fn two_mass(freq_hz: &[f64]) -> Vec<Complex64> {
    let (j1, j2, c, d) = (0.02, 0.03, 2000.0, 0.5);
    freq_hz
        .iter()
        .map(|&f| {
            let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
            (j2 * s * s + d * s + c) / (s * (j1 * j2 * s * s + (j1 + j2) * (d * s + c)))
        })
        .collect()
}

/// Anti-resonance and resonance of `two_mass` [Hz].
fn ar_r() -> (f64, f64) {
    let (j1, j2, c) = (0.02_f64, 0.03_f64, 2000.0_f64);
    let ar = (c / j2).sqrt() / (2.0 * std::f64::consts::PI);
    let r = (c * (j1 + j2) / (j1 * j2)).sqrt() / (2.0 * std::f64::consts::PI);
    (ar, r)
}

/// A "measured" 2-mass FRF: the model with deterministic scatter, relative std 3 %.
pub(crate) fn measured_two_mass(with_coherence: bool) -> Frf {
    let freq: Vec<f64> = (1..=400).map(|k| k as f64 * 0.5).collect();
    let h0 = two_mass(&freq);
    let mut s = 7_u64;
    let mut rnd = || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    // Relative std: 1 % at low frequency, rising towards 200 Hz; absolute noise floor
    // makes the anti-resonance uncertain.
    let sd: Vec<f64> = freq
        .iter()
        .zip(&h0)
        .map(|(f, h)| h.norm() * (0.01 + 0.08 * (f / 200.0).powi(2)) + 0.004)
        .collect();
    let h: Vec<Complex64> = h0
        .iter()
        .zip(&sd)
        .map(|(h, s)| h + Complex64::new(s * rnd(), s * rnd()))
        .collect();
    let var: Vec<f64> = sd.iter().map(|s| s * s).collect();
    let coherence = with_coherence.then(|| {
        let (ar, _) = ar_r();
        freq.iter()
            .map(|f| 1.0 - 0.6 * (-(f - ar).powi(2) / 4.0).exp() - 0.02 * (rnd() + 0.5))
            .collect()
    });
    Frf {
        freq_hz: freq,
        h,
        var,
        coherence,
        kind: FrfKind::DifferencedVelocity,
        sample_rate_hz: 4000.0,
    }
}

fn model_frf() -> Frf {
    let freq: Vec<f64> = (0..600)
        .map(|k| 0.5 * 10f64.powf(k as f64 / 599.0 * 2.61))
        .collect();
    let h = two_mass(&freq);
    Frf {
        var: vec![0.0; freq.len()],
        freq_hz: freq,
        h,
        coherence: None,
        kind: FrfKind::DifferencedVelocity,
        sample_rate_hz: 4000.0,
    }
}

fn full_plot_svg(with_coherence: bool) -> String {
    let m = measured_two_mass(with_coherence);
    let model = model_frf();
    let (ar, r) = ar_r();
    BodePlot::new(&m)
        .model(&model, "identified 2-mass model")
        .anti_resonance(ar)
        .resonance(r)
        .title("Axis 2: motor mobility")
        .subtitle("multisine 0.5-200 Hz, 8 periods, fs = 4 kHz")
        .render_svg()
        .unwrap()
}

#[test]
fn svg_has_labels_markers_and_band() {
    let svg = full_plot_svg(true);
    assert!(svg.starts_with("<svg"));
    assert!(svg.contains("Frequency [Hz]"));
    assert!(svg.contains("Magnitude [dB re 1 (rad/s)/(N m)]"));
    assert!(svg.contains("Phase [deg]"));
    assert!(svg.contains("Coherence [-]"));
    assert!(svg.contains("identified 2-mass model"));
    let (ar, r) = ar_r();
    assert!(svg.contains(&format!("AR1 {ar:.1} Hz")), "AR label");
    assert!(svg.contains(&format!("R1 {r:.1} Hz")), "R label");
    // Band: filled polygons with the band opacity (magnitude and phase).
    let band_polys = svg
        .lines()
        .filter(|l| l.contains("<polygon") && l.contains("opacity=\"0.22\""))
        .count();
    assert!(band_polys >= 2, "{band_polys} band polygons");
    std::fs::create_dir_all("target/plot-test").ok();
    std::fs::write("target/plot-test/bode_full.svg", &svg).ok();
    std::fs::write("target/plot-test/bode_nocoh.svg", full_plot_svg(false)).ok();
}

#[test]
fn gaps_and_write() {
    let mut m = measured_two_mass(false);
    for i in 100..110 {
        m.var[i] = f64::INFINITY;
    }
    m.var[200] = f64::INFINITY;
    m.var[202] = f64::INFINITY;
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("bode.svg");
    BodePlot::new(&m).write_svg(&p).unwrap();
    let svg = std::fs::read_to_string(&p).unwrap();
    assert!(svg.contains("Phase [deg]") && !svg.contains("Coherence"));
}

#[test]
fn bad_inputs_are_errors() {
    let good = measured_two_mass(true);
    let plot_err = |f: &Frf| BodePlot::new(f).render_svg().unwrap_err();

    let mut m = good.clone();
    m.var[5] = 0.0;
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidVariance { index: 5, .. }
    ));
    m.var[5] = -1.0;
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidVariance { index: 5, .. }
    ));
    m.var[5] = f64::NAN;
    assert!(matches!(plot_err(&m), PlotError::InvalidVariance { .. }));

    let empty = Frf {
        freq_hz: vec![],
        h: vec![],
        var: vec![],
        coherence: None,
        kind: FrfKind::Other,
        sample_rate_hz: 1.0,
    };
    assert!(matches!(plot_err(&empty), PlotError::Empty { .. }));

    let mut m = good.clone();
    m.var.iter_mut().for_each(|v| *v = f64::INFINITY);
    assert!(matches!(plot_err(&m), PlotError::Empty { .. }));

    let mut m = good.clone();
    m.var.pop();
    assert!(matches!(
        plot_err(&m),
        PlotError::LengthMismatch { field: "var", .. }
    ));

    let mut m = good.clone();
    m.freq_hz[0] = 0.0;
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidFrequency { index: 0, .. }
    ));
    let mut m = good.clone();
    m.freq_hz[3] = m.freq_hz[2];
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidFrequency { index: 3, .. }
    ));

    let mut m = good.clone();
    m.h[7] = Complex64::new(0.0, 0.0);
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidResponse { index: 7, .. }
    ));

    let mut m = good.clone();
    m.coherence.as_mut().unwrap()[1] = 1.5;
    assert!(matches!(
        plot_err(&m),
        PlotError::InvalidCoherence { index: 1, .. }
    ));

    let e = BodePlot::new(&good)
        .resonance(f64::NAN)
        .render_svg()
        .unwrap_err();
    assert!(matches!(e, PlotError::InvalidMarker { .. }));
    let e = BodePlot::new(&good)
        .model(&empty, "m")
        .render_svg()
        .unwrap_err();
    assert!(matches!(e, PlotError::Empty { ref what, .. } if what == "m"));
    let e = BodePlot::new(&good).size(10, 10).render_svg().unwrap_err();
    assert!(matches!(e, PlotError::InvalidSize { .. }));
}

#[test]
fn single_line_and_other_kind() {
    let m = Frf {
        freq_hz: vec![10.0],
        h: vec![Complex64::new(1.0, 1.0)],
        var: vec![0.01],
        coherence: None,
        kind: FrfKind::Other,
        sample_rate_hz: 1000.0,
    };
    let svg = BodePlot::new(&m).render_svg().unwrap();
    assert!(svg.contains("Magnitude [dB]"));
}

#[test]
fn helpers() {
    use super::series::{freq_label, log_ticks, marker_freq_text, nice_ticks, DB_STEPS};
    let (major, minor) = log_ticks(0.5, 200.0);
    assert_eq!(major, vec![1.0, 10.0, 100.0]);
    assert!(minor.contains(&2.0) && minor.contains(&0.5) && !minor.contains(&10.0));
    let (major, _) = log_ticks(20.0, 90.0);
    assert_eq!(major, vec![20.0, 50.0]);
    assert_eq!(freq_label(0.5), "0.5");
    assert_eq!(freq_label(1000.0), "1000");
    assert_eq!(marker_freq_text(52.94), "52.9 Hz");
    assert_eq!(marker_freq_text(5.234), "5.23 Hz");
    let (a, b, t) = nice_ticks(-83.0, -12.0, 9, &DB_STEPS);
    assert_eq!((a, b), (-90.0, -10.0));
    assert_eq!(t.len(), 9);
    assert_eq!(
        magnitude_label(FrfKind::Position),
        "Magnitude [dB re 1 rad/(N m)]"
    );
}

#[test]
fn lines_outside_the_band_used_are_shaded_and_named_in_the_legend() {
    let m = measured_two_mass(true);
    let plain = BodePlot::new(&m).render_svg().unwrap();
    let lo = m.freq_hz[0];
    let hi = *m.freq_hz.last().unwrap();
    let band = [lo * 4.0, hi / 2.0];
    let shaded = BodePlot::new(&m).band_used(band).render_svg().unwrap();
    let grey = |svg: &str| {
        svg.lines()
            .filter(|l| l.contains("<rect") && l.contains("#969696"))
            .count()
    };
    assert_eq!(grey(&plain), 0, "no shade without a band");
    // both sides in the three panels, and the legend's swatch
    assert_eq!(grey(&shaded), 2 * 3 + 1, "{}", grey(&shaded));
    assert!(
        shaded.contains("no information (SNR &lt; 2), not used")
            || shaded.contains("no information (SNR < 2), not used")
    );
    // a band that covers everything shades nothing but keeps the legend entry
    let whole = BodePlot::new(&m)
        .band_used([lo / 2.0, hi * 2.0])
        .render_svg()
        .unwrap();
    assert_eq!(grey(&whole), 1);
}
