//! The N x N Bode matrix of a multi-axis measurement (issue 17): one magnitude panel per
//! element (row: the speed of motor n, column: the torque of motor m), log frequency,
//! the measurement with its two-sigma band, the lines the noise alone reaches in grey
//! (they carry no weight in the variance-weighted fit), and the model overlaid.
//! Plain SVG text, like the diagnosis plot.

use flexid_core::manipulator::cost::NOISE_ONLY_SNR;
use flexid_core::Complex64;
use nalgebra::DMatrix;
use std::fmt::Write;

/// Panel size and margins [px].
const PW: f64 = 230.0;
const PH: f64 = 150.0;
const ML: f64 = 70.0;
const MT: f64 = 60.0;
const GAP: f64 = 18.0;

/// What one Bode matrix shows.
#[derive(Debug, Clone, Copy)]
pub struct BodeMatrix<'a> {
    /// The heading.
    pub title: &'a str,
    /// Frequencies [Hz], increasing.
    pub f_hz: &'a [f64],
    /// The measured FRF matrix per line [rad/s per N m].
    pub measured: &'a [DMatrix<Complex64>],
    /// Its variance per element and line, where known.
    pub var: Option<&'a [DMatrix<f64>]>,
    /// A model's FRF matrix per line, and its label.
    pub model: Option<(&'a [DMatrix<Complex64>], &'a str)>,
}

/// The SVG text of `m`.
pub fn bode_matrix_svg(m: &BodeMatrix) -> String {
    let n = m.measured.first().map_or(0, |g| g.nrows());
    let f: Vec<f64> = m
        .f_hz
        .iter()
        .copied()
        .filter(|f| *f > 0.0 && f.is_finite())
        .collect();
    let (f0, f1) = match (f.first(), f.last()) {
        (Some(&a), Some(&b)) if b > a => (a, b),
        _ => (1.0, 10.0),
    };
    let width = ML + n as f64 * (PW + GAP) + 20.0;
    let height = MT + n as f64 * (PH + GAP) + 70.0;
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{width:.0}" height="{height:.0}" font-family="sans-serif" font-size="11">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{ML}" y="20" font-size="14">{}</text>"#,
        xml(m.title)
    );
    let _ = writeln!(
        s,
        r##"<text x="{ML}" y="40">|G| [dB re 1 rad/s per N m], motor speed n (row) / motor torque m (column), frequency [Hz]; <tspan fill="#1f77b4">measured</tspan> with its 2-sigma band, <tspan fill="#999999">lines at the noise floor</tspan>{}</text>"##,
        m.model.map_or(String::new(), |(_, l)| format!(
            r##", <tspan fill="#d62728">{}</tspan>"##,
            xml(l)
        ))
    );
    if n == 0 || m.measured.len() != m.f_hz.len() {
        let _ = writeln!(
            s,
            r#"<text x="{ML}" y="{MT}">no FRF matrix to draw</text></svg>"#
        );
        return s;
    }
    for row in 0..n {
        for col in 0..n {
            let x0 = ML + col as f64 * (PW + GAP);
            let y0 = MT + row as f64 * (PH + GAP);
            panel(&mut s, m, row, col, x0, y0, (f0, f1));
        }
    }
    let _ = writeln!(s, "</svg>");
    s
}

/// One element's panel at `(x0, y0)`.
fn panel(
    s: &mut String,
    m: &BodeMatrix,
    row: usize,
    col: usize,
    x0: f64,
    y0: f64,
    (f0, f1): (f64, f64),
) {
    let db = |g: Complex64| 20.0 * g.norm().log10();
    let meas: Vec<f64> = m.measured.iter().map(|g| db(g[(row, col)])).collect();
    let sigma: Vec<Option<f64>> = (0..m.f_hz.len())
        .map(|k| {
            m.var
                .map(|v| v[k][(row, col)].sqrt())
                .filter(|s| s.is_finite())
        })
        .collect();
    let weak: Vec<bool> = (0..m.f_hz.len())
        .map(|k| {
            let g2 = m.measured[k][(row, col)].norm_sqr();
            sigma[k].is_some_and(|s| g2 < NOISE_ONLY_SNR * s * s)
        })
        .collect();
    let model: Option<Vec<f64>> = m
        .model
        .map(|(g, _)| g.iter().map(|g| db(g[(row, col)])).collect());
    // the panel's range: the measured lines above the noise floor and the model
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (k, v) in meas.iter().enumerate() {
        if v.is_finite() && !weak[k] {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    for v in model.iter().flatten() {
        if v.is_finite() {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
    }
    if !(lo.is_finite() && hi.is_finite()) {
        (lo, hi) = (-100.0, 0.0);
    }
    let (lo, hi) = (
        (lo / 10.0).floor() * 10.0 - 5.0,
        (hi / 10.0).ceil() * 10.0 + 5.0,
    );
    let x = |f: f64| x0 + PW * (f / f0).ln() / (f1 / f0).ln();
    let y = |v: f64| y0 + PH * (hi - v.clamp(lo, hi)) / (hi - lo);
    let _ = writeln!(
        s,
        r##"<rect x="{x0:.1}" y="{y0:.1}" width="{PW}" height="{PH}" fill="none" stroke="#888"/>"##
    );
    // decade grid and labels
    let mut d = 10f64.powf(f0.log10().floor());
    while d <= f1 * 1.0001 {
        if d >= f0 {
            let xd = x(d);
            let _ = writeln!(
                s,
                r##"<line x1="{xd:.1}" y1="{y0:.1}" x2="{xd:.1}" y2="{:.1}" stroke="#ddd"/><text x="{xd:.1}" y="{:.1}" text-anchor="middle" font-size="9">{}</text>"##,
                y0 + PH,
                y0 + PH + 11.0,
                d
            );
        }
        d *= 10.0;
    }
    let step = if hi - lo > 80.0 { 40.0 } else { 20.0 };
    let mut v = (lo / step).ceil() * step;
    while v <= hi {
        let yv = y(v);
        let _ = writeln!(
            s,
            r##"<line x1="{x0:.1}" y1="{yv:.1}" x2="{:.1}" y2="{yv:.1}" stroke="#eee"/><text x="{:.1}" y="{:.1}" text-anchor="end" font-size="9">{v:.0}</text>"##,
            x0 + PW,
            x0 - 3.0,
            yv + 3.0
        );
        v += step;
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}" font-size="10">G{}{} (speed {} / torque {})</text>"#,
        x0 + 4.0,
        y0 + 11.0,
        row + 1,
        col + 1,
        row + 1,
        col + 1
    );
    // the two-sigma band where the line is above the noise floor
    let (mut upper, mut lower) = (Vec::new(), Vec::new());
    for (k, &f) in m.f_hz.iter().enumerate() {
        if let (Some(sd), false) = (sigma[k], weak[k]) {
            let g = m.measured[k][(row, col)].norm();
            upper.push((x(f), y(20.0 * (g + 2.0 * sd).log10())));
            lower.push((x(f), y(20.0 * (g - 2.0 * sd).max(g * 1e-3).log10())));
        }
    }
    if !upper.is_empty() {
        lower.reverse();
        let pts: Vec<String> = upper
            .iter()
            .chain(&lower)
            .map(|(a, b)| format!("{a:.1},{b:.1}"))
            .collect();
        let _ = writeln!(
            s,
            r##"<polygon points="{}" fill="#1f77b4" fill-opacity="0.18" stroke="none"/>"##,
            pts.join(" ")
        );
    }
    // the measurement, line by line: blue where measured, grey at the noise floor
    for (k, &f) in m.f_hz.iter().enumerate() {
        if meas[k].is_finite() {
            let colour = if weak[k] { "#999999" } else { "#1f77b4" };
            let _ = write!(
                s,
                r##"<circle cx="{:.1}" cy="{:.1}" r="1.1" fill="{colour}"/>"##,
                x(f),
                y(meas[k])
            );
        }
    }
    let _ = writeln!(s);
    if let Some(model) = model {
        let pts: Vec<String> = m
            .f_hz
            .iter()
            .zip(&model)
            .filter(|(_, v)| v.is_finite())
            .map(|(&f, &v)| format!("{:.1},{:.1}", x(f), y(v)))
            .collect();
        let _ = writeln!(
            s,
            r##"<polyline points="{}" fill="none" stroke="#d62728" stroke-width="1.2"/>"##,
            pts.join(" ")
        );
    }
}

/// Text safe inside an SVG element.
fn xml(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2 x 2 matrix of two modes, a noisy measurement of it and the model: four panels,
    /// units in the heading, the model's curve in each, the noise-floor lines in grey, and
    /// no NaN anywhere.
    #[test]
    fn a_bode_matrix_has_a_panel_per_element_and_no_nan() {
        let f: Vec<f64> = (1..200).map(|k| k as f64).collect();
        let g: Vec<DMatrix<Complex64>> = f
            .iter()
            .map(|&f| {
                let s = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
                let a = 1.0 / (s * s * 0.01 + s * 0.5 + 400.0) * s;
                DMatrix::from_row_slice(2, 2, &[a * 3.0, a * 1e-3, a * 1e-3, a])
            })
            .collect();
        let var: Vec<DMatrix<f64>> = g.iter().map(|g| g.map(|_| 1e-8)).collect();
        let svg = bode_matrix_svg(&BodeMatrix {
            title: "pose id-1",
            f_hz: &f,
            measured: &g,
            var: Some(&var),
            model: Some((&g, "identified model")),
        });
        assert_eq!(svg.matches("(speed ").count(), 4);
        assert_eq!(svg.matches("<polyline").count(), 4);
        assert!(svg.contains("[dB re 1 rad/s per N m]") && svg.contains("frequency [Hz]"));
        assert!(
            svg.contains("#999999\"/>"),
            "the weak off-diagonal lines in grey"
        );
        assert!(!svg.contains("NaN") && !svg.contains("inf"));
        // an empty measurement says so
        let empty = bode_matrix_svg(&BodeMatrix {
            title: "none",
            f_hz: &[],
            measured: &[],
            var: None,
            model: None,
        });
        assert!(empty.contains("no FRF matrix to draw"));
    }
}
