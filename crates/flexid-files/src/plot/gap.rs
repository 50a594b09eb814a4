//! The diagnosis plot: measured FRF (each level), the nominal model, the model with the
//! winning effect, and the localised bands shaded; magnitude over phase, log frequency.
//! Plain SVG text.

use flexid_core::diagnose::Diagnosis;
use std::fmt::Write;

const W: f64 = 900.0;
const H: f64 = 300.0;
const L: f64 = 70.0;
const R: f64 = 20.0;
const COLORS: [&str; 4] = ["#1f77b4", "#2ca02c", "#9467bd", "#8c564b"];

fn path(pts: &[(f64, f64)]) -> String {
    let mut s = String::new();
    for (i, (x, y)) in pts.iter().enumerate() {
        if x.is_finite() && y.is_finite() {
            let _ = write!(s, "{}{:.1},{:.1} ", if i == 0 { "M" } else { "L" }, x, y);
        }
    }
    s
}

fn unwrap(p: &mut [f64]) {
    for i in 1..p.len() {
        while p[i] - p[i - 1] > 180.0 {
            p[i] -= 360.0;
        }
        while p[i] - p[i - 1] < -180.0 {
            p[i] += 360.0;
        }
    }
}

/// The SVG text of the diagnosis plot (on the trajectory path, which has no FRF, the
/// force plot of [`super::trajectory_svg`]).
pub fn gap_svg(d: &Diagnosis) -> String {
    if d.trajectory.is_some() {
        return super::trajectory_svg(d);
    }
    let data = &d.data;
    let (f0, f1) = (
        data.f_min().max(1e-6),
        data.f_max().max(data.f_min() * 1.01),
    );
    let x = |f: f64| L + (W - L - R) * (f / f0).ln() / (f1 / f0).ln();
    let mut curves: Vec<(String, &str, Vec<f64>, Vec<f64>, Vec<f64>, bool)> = Vec::new();
    for (i, l) in data.levels.iter().enumerate() {
        let mag = |h: &[flexid_core::Complex64]| {
            h.iter()
                .map(|h| 20.0 * h.norm().log10())
                .collect::<Vec<_>>()
        };
        let ph = |h: &[flexid_core::Complex64]| {
            let mut p: Vec<f64> = h.iter().map(|h| h.arg().to_degrees()).collect();
            unwrap(&mut p);
            p
        };
        curves.push((
            format!("measured, level {i} ({:.3} N m RMS)", l.torque_rms),
            COLORS[i % 4],
            l.f.clone(),
            mag(&l.h),
            ph(&l.h),
            false,
        ));
        curves.push((
            format!("nominal {}-mass model", d.masses),
            "#d62728",
            l.f.clone(),
            mag(&d.nominal.model[i]),
            ph(&d.nominal.model[i]),
            true,
        ));
        if let Some(w) = &d.winner {
            curves.push((
                format!("with {}", w.effect),
                "#ff7f0e",
                l.f.clone(),
                mag(&w.model[i]),
                ph(&w.model[i]),
                true,
            ));
        }
    }
    let (mut mlo, mut mhi, mut plo, mut phi) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for c in &curves {
        for v in &c.3 {
            if v.is_finite() {
                mlo = mlo.min(*v);
                mhi = mhi.max(*v);
            }
        }
        for v in &c.4 {
            if v.is_finite() {
                plo = plo.min(*v);
                phi = phi.max(*v);
            }
        }
    }
    let ym = |v: f64, top: f64| top + 20.0 + (H - 40.0) * (mhi - v) / (mhi - mlo).max(1e-9);
    let yp = |v: f64, top: f64| top + 20.0 + (H - 40.0) * (phi - v) / (phi - plo).max(1e-9);
    let mut s = String::new();
    let total_h = 2.0 * H + 60.0 + 18.0 * (curves.len().min(8) as f64);
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{total_h}" font-family="sans-serif" font-size="12">"#
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{L}" y="14">flexid diagnose: verdict {}, gap {:.3} dB -> {:.3} dB</text>"#,
        d.verdict, d.gap.before_rms_db, d.gap.after_rms_db
    );
    for (top, label) in [(20.0, "magnitude [dB]"), (20.0 + H, "phase [deg]")] {
        for (b, _) in &d.gap.bands {
            let (xa, xb) = (x(b.lo_hz), x(b.hi_hz).max(x(b.lo_hz) + 2.0));
            let _ = writeln!(
                s,
                r##"<rect x="{xa:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#ffcc00" fill-opacity="0.25"/>"##,
                top + 20.0,
                xb - xa,
                H - 40.0
            );
        }
        let _ = writeln!(
            s,
            r#"<rect x="{L}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
            top + 20.0,
            W - L - R,
            H - 40.0
        );
        let _ = writeln!(s, r#"<text x="5" y="{:.1}">{label}</text>"#, top + 14.0);
        let mut dec = 10f64.powf(f0.log10().floor());
        while dec <= f1 {
            for m in 1..10 {
                let f = dec * m as f64;
                if f >= f0 && f <= f1 {
                    let xx = x(f);
                    let _ = writeln!(
                        s,
                        r##"<line x1="{xx:.1}" x2="{xx:.1}" y1="{:.1}" y2="{:.1}" stroke="#ddd"/>"##,
                        top + 20.0,
                        top + H - 20.0
                    );
                    if m == 1 {
                        let _ = writeln!(
                            s,
                            r#"<text x="{xx:.1}" y="{:.1}" text-anchor="middle">{f} Hz</text>"#,
                            top + H - 5.0
                        );
                    }
                }
            }
            dec *= 10.0;
        }
        let (lo, hi) = if top < H { (mlo, mhi) } else { (plo, phi) };
        let _ = writeln!(
            s,
            r#"<text x="{:.1}" y="{:.1}" text-anchor="end">{:.0}</text><text x="{:.1}" y="{:.1}" text-anchor="end">{:.0}</text>"#,
            L - 4.0,
            top + 28.0,
            hi,
            L - 4.0,
            top + H - 20.0,
            lo
        );
    }
    for (name, color, f, m, p, dashed) in &curves {
        let dash = if *dashed {
            r#" stroke-dasharray="6,3""#
        } else {
            ""
        };
        let pm: Vec<(f64, f64)> = f
            .iter()
            .zip(m)
            .map(|(f, v)| (x(*f), ym(*v, 20.0)))
            .collect();
        let pp: Vec<(f64, f64)> = f
            .iter()
            .zip(p)
            .map(|(f, v)| (x(*f), yp(*v, 20.0 + H)))
            .collect();
        for pts in [pm, pp] {
            let _ = writeln!(
                s,
                r#"<path d="{}" fill="none" stroke="{color}" stroke-width="1.2"{dash}><title>{name}</title></path>"#,
                path(&pts)
            );
        }
    }
    let mut seen = Vec::new();
    let mut y = 2.0 * H + 50.0;
    for (name, color, _, _, _, dashed) in &curves {
        if seen.contains(name) {
            continue;
        }
        seen.push(name.clone());
        let dash = if *dashed {
            r#" stroke-dasharray="6,3""#
        } else {
            ""
        };
        let _ = writeln!(
            s,
            r#"<line x1="{L}" x2="{:.1}" y1="{y:.1}" y2="{y:.1}" stroke="{color}" stroke-width="2"{dash}/><text x="{:.1}" y="{:.1}">{name}</text>"#,
            L + 30.0,
            L + 36.0,
            y + 4.0
        );
        y += 18.0;
    }
    let _ = writeln!(
        s,
        r##"<rect x="{:.1}" y="{:.1}" width="30" height="10" fill="#ffcc00" fill-opacity="0.25"/><text x="{:.1}" y="{:.1}">significant bands (nominal model)</text>"##,
        W / 2.0,
        2.0 * H + 45.0,
        W / 2.0 + 36.0,
        2.0 * H + 54.0
    );
    s.push_str("</svg>\n");
    s
}
