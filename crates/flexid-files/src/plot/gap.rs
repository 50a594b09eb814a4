//! The diagnosis plot: measured FRF (each level) with its two-sigma uncertainty band, the
//! nominal model, the model with the named effects, and the localised bands: the core of
//! each (where the error is at least half its largest) shaded, the rest of the significant
//! range faint, each labelled with its excess, the gap after and what explains it;
//! magnitude over phase, log frequency. Plain SVG text.

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

/// Text safe inside an SVG element.
fn xml(t: &str) -> String {
    t.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
}

/// The bands to draw, one per distinct core (the level with the largest excess where the
/// cores of several levels overlap), each with its label: the excess, the gap after, and
/// what explains it (the named effects, or the band's shape when nothing does).
fn labelled_bands(d: &Diagnosis) -> Vec<(flexid_core::diagnose::localise::Band, String)> {
    let mut bands: Vec<&(flexid_core::diagnose::localise::Band, f64)> =
        d.gap.bands.iter().collect();
    bands.sort_by(|a, b| b.0.excess_db.total_cmp(&a.0.excess_db));
    let mut kept: Vec<(flexid_core::diagnose::localise::Band, String)> = Vec::new();
    for (b, after) in bands {
        if kept
            .iter()
            .any(|(k, _)| b.core_lo_hz <= k.core_hi_hz && k.core_lo_hz <= b.core_hi_hz)
        {
            continue;
        }
        let why = if d.verdict == flexid_core::diagnose::Effect::None {
            format!("({}; the gap overall is within the noise)", b.shape.words())
        } else if d.effects.is_empty() {
            format!("unexplained: {}", b.shape.words())
        } else {
            let names: Vec<&str> = d.effects.iter().map(|e| e.effect.name()).collect();
            format!("-> {after:.2} dB with {}", names.join(" + "))
        };
        kept.push((
            b.clone(),
            format!("{:.2} dB at {:.3} Hz {why}", b.excess_db, b.peak_hz),
        ));
    }
    kept.sort_by(|a, b| a.0.core_lo_hz.total_cmp(&b.0.core_lo_hz));
    kept
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
    if data.lines() == 0 || !(f0.is_finite() && f1.is_finite() && f1 > f0) {
        // nothing to draw (the decade grid below would never end on an infinite range)
        return format!(
            r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="60" font-family="sans-serif" font-size="12"><rect width="100%" height="100%" fill="white"/><text x="10" y="30">flexid diagnose: verdict {}; no FRF lines to draw</text></svg>
"#,
            d.verdict
        );
    }
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
        if let Some(w) = d.effects.last().map(|s| &s.fit) {
            let names: Vec<&str> = d.effects.iter().map(|s| s.effect.name()).collect();
            curves.push((
                format!("with {}", names.join(" + ")),
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
    let named: Vec<&str> = d.effects.iter().map(|e| e.effect.name()).collect();
    let _ = writeln!(
        s,
        r#"<text x="{L}" y="14">flexid diagnose: verdict {}{}, gap {:.3} dB -> {:.3} dB (noise {:.3} dB)</text>"#,
        d.verdict,
        if named.len() > 1 {
            format!(" (effects {})", named.join(" + "))
        } else {
            String::new()
        },
        d.gap.before_rms_db,
        d.gap.after_rms_db,
        d.gap.noise_rms_db
    );
    let bands = labelled_bands(d);
    for (top, label) in [(20.0, "magnitude [dB]"), (20.0 + H, "phase [deg]")] {
        for (b, _) in &bands {
            let (xa, xb) = (x(b.lo_hz), x(b.hi_hz).max(x(b.lo_hz) + 2.0));
            let (ca, cb) = (x(b.core_lo_hz), x(b.core_hi_hz).max(x(b.core_lo_hz) + 3.0));
            let _ = writeln!(
                s,
                r##"<rect x="{xa:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#ffcc00" fill-opacity="0.08"/><rect x="{ca:.1}" y="{:.1}" width="{:.1}" height="{:.1}" fill="#ffcc00" fill-opacity="0.35"/>"##,
                top + 20.0,
                xb - xa,
                H - 40.0,
                top + 20.0,
                cb - ca,
                H - 40.0
            );
        }
        if top < H {
            // the labels, staggered so that neighbours do not overwrite each other
            for (k, (b, text)) in bands.iter().enumerate() {
                let _ = writeln!(
                    s,
                    r#"<text x="{:.1}" y="{:.1}" font-size="11">{}</text>"#,
                    x(b.core_lo_hz),
                    top + 32.0 + 13.0 * (k % 4) as f64,
                    xml(text)
                );
            }
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
    // the measurement's two-sigma band (magnitude): sigma of 20 log10|H| is
    // 8.69 sqrt(var/2)/|H|
    for (i, l) in data.levels.iter().enumerate() {
        let band = |sign: f64| -> Vec<(f64, f64)> {
            l.f.iter()
                .zip(&l.h)
                .zip(&l.var)
                .map(|((f, h), v)| {
                    let db = 20.0 * h.norm().log10();
                    let sig = 8.685889638065035 * (v / 2.0).sqrt() / h.norm();
                    (x(*f), ym(db + sign * 2.0 * sig.min(20.0), 20.0))
                })
                .collect()
        };
        let mut pts = band(1.0);
        pts.extend(band(-1.0).into_iter().rev());
        if pts.iter().all(|(a, b)| a.is_finite() && b.is_finite()) && !pts.is_empty() {
            let _ = writeln!(
                s,
                r#"<path d="{}Z" fill="{}" fill-opacity="0.15" stroke="none"><title>measured, level {i}: two-sigma band</title></path>"#,
                path(&pts),
                COLORS[i % 4]
            );
        }
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
        r##"<rect x="{:.1}" y="{:.1}" width="30" height="10" fill="#ffcc00" fill-opacity="0.35"/><text x="{:.1}" y="{:.1}">where the nominal model misses (core shaded, significant range faint)</text>"##,
        W / 2.0,
        2.0 * H + 45.0,
        W / 2.0 + 36.0,
        2.0 * H + 54.0
    );
    s.push_str("</svg>\n");
    s
}
