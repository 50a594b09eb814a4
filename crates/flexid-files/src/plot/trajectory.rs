//! The trajectory path's plot: the filtered force against time with the rigid body
//! without friction and the model kept, and the kept model's residual below. Plain SVG.

use flexid_core::diagnose::trajectory::Trace;
use flexid_core::diagnose::Diagnosis;
use std::fmt::Write;

const W: f64 = 900.0;
const H: f64 = 280.0;
const L: f64 = 70.0;
const R: f64 = 20.0;
/// Points drawn per curve at most (every k-th equation beyond that).
const MAX_POINTS: usize = 3000;

/// One panel: its top [px], label, value range and curves (values, colour, name).
struct Panel<'a> {
    top: f64,
    label: &'static str,
    lo: f64,
    hi: f64,
    curves: Vec<(&'a [f64], &'static str, &'static str)>,
}

fn range(vs: &[&[f64]]) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for v in vs.iter().flat_map(|v| v.iter()).filter(|v| v.is_finite()) {
        lo = lo.min(*v);
        hi = hi.max(*v);
    }
    if lo < hi {
        (lo, hi)
    } else if lo.is_finite() {
        (lo - 1.0, lo + 1.0)
    } else {
        (-1.0, 1.0)
    }
}

/// The SVG text of the trajectory plot of `d` (`d.trajectory` must be `Some`; an empty
/// frame otherwise).
pub fn trajectory_svg(d: &Diagnosis) -> String {
    let empty = Trace::default();
    let tr = d.trajectory.as_ref().map_or(&empty, |t| &t.trace);
    let n = tr.time_s.len();
    let step = n.div_ceil(MAX_POINTS).max(1);
    let (t0, t1) = (
        tr.time_s.first().copied().unwrap_or(0.0),
        tr.time_s.last().copied().unwrap_or(1.0).max(1e-9),
    );
    let x = |t: f64| L + (W - L - R) * (t - t0) / (t1 - t0).max(1e-9);
    let residual: Vec<f64> = tr
        .force_nm
        .iter()
        .zip(&tr.kept_nm)
        .map(|(y, m)| y - m)
        .collect();
    let (flo, fhi) = range(&[&tr.force_nm, &tr.rigid_nm, &tr.kept_nm]);
    let (rlo, rhi) = range(&[&residual]);
    let mut s = String::new();
    let _ = writeln!(
        s,
        r#"<svg xmlns="http://www.w3.org/2000/svg" width="{W}" height="{:.0}" font-family="sans-serif" font-size="12">"#,
        2.0 * H + 80.0
    );
    let _ = writeln!(s, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        s,
        r#"<text x="{L}" y="14">flexid diagnose (trajectory path): verdict {}, relative force error {:.2} % without friction, {:.2} % with the model kept</text>"#,
        d.verdict,
        100.0
            * d.trajectory
                .as_ref()
                .map_or(f64::NAN, |t| t.rigid.relative_error),
        100.0
            * d.trajectory
                .as_ref()
                .map_or(f64::NAN, |t| t.kept_fit().relative_error),
    );
    let panels = [
        Panel {
            top: 20.0,
            label: "filtered force [N m]",
            lo: flo,
            hi: fhi,
            curves: vec![
                (&tr.force_nm, "#1f77b4", "measured (filtered)"),
                (&tr.rigid_nm, "#d62728", "rigid body, no friction"),
                (&tr.kept_nm, "#ff7f0e", "model kept"),
            ],
        },
        Panel {
            top: 20.0 + H,
            label: "residual [N m]",
            lo: rlo,
            hi: rhi,
            curves: vec![(&residual, "#2ca02c", "measured - model kept")],
        },
    ];
    for Panel {
        top,
        label,
        lo,
        hi,
        curves,
    } in &panels
    {
        let y = |v: f64| top + 20.0 + (H - 40.0) * (hi - v) / (hi - lo);
        let _ = writeln!(
            s,
            r#"<rect x="{L}" y="{:.1}" width="{:.1}" height="{:.1}" fill="none" stroke="black"/>"#,
            top + 20.0,
            W - L - R,
            H - 40.0
        );
        let _ = writeln!(s, r#"<text x="5" y="{:.1}">{label}</text>"#, top + 14.0);
        let _ = writeln!(
            s,
            r#"<text x="5" y="{:.1}">{hi:.3}</text><text x="5" y="{:.1}">{lo:.3}</text>"#,
            top + 32.0,
            top + H - 22.0
        );
        for (i, (v, color, name)) in curves.iter().enumerate() {
            let mut p = String::new();
            for k in (0..v.len().min(n)).step_by(step) {
                let (xx, yy) = (x(tr.time_s[k]), y(v[k]));
                if xx.is_finite() && yy.is_finite() {
                    let _ = write!(
                        p,
                        "{}{xx:.1},{yy:.1} ",
                        if p.is_empty() { "M" } else { "L" }
                    );
                }
            }
            let _ = writeln!(
                s,
                r#"<path d="{p}" fill="none" stroke="{color}" stroke-width="1"/><text x="{:.1}" y="{:.1}" fill="{color}">{name}</text>"#,
                L + 10.0 + 220.0 * i as f64,
                top + H - 6.0
            );
        }
    }
    let _ = writeln!(
        s,
        r#"<text x="{:.1}" y="{:.1}">time [s] ({t0:.2} - {t1:.2})</text>"#,
        W / 2.0 - 40.0,
        2.0 * H + 60.0
    );
    s.push_str("</svg>\n");
    s
}
