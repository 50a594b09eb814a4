//! A nominal model whose last body has a spring to the ground (`flexid diagnose
//! --ground-spring`): the user says the axis is not free. The Silverbox (an electronic
//! Duffing oscillator, `m y'' + d y' + k y + k3 y³ = u`) has such a linear spring `k`, a
//! structure on its suspension has one; a nominal *free* chain fitted to them bends into
//! anything but the axis, and the candidates then explain the missing spring instead of
//! the effect. With the option, the ground stiffness is a parameter of the nominal model
//! ([`LinExt::ground_spring`]), fitted with the chain by the nominal fit and by every
//! candidate's fit, and `gravity` (the same spring as an effect) is not a candidate.
//!
//! The starts ([`starts`]): each identified free chain with a grid of ground stiffnesses,
//! and for one body the least-squares solution of its impedance, which a free chain's
//! identification cannot give.

use super::lti::LinExt;
use super::Data;
use crate::frf::FrfKind;
use crate::model::Chain;
use num_complex::Complex64;

/// Ground stiffnesses of the grid, as multiples of `J_t ω_min²` (the stiffness that puts the
/// chain's ground resonance at the lowest line): from well below the band to well inside.
const GRID: [f64; 5] = [0.3, 3.0, 30.0, 300.0, 3000.0];

/// Starts of the grounded nominal fit: every chain of `chains` with the ground stiffness of
/// [`GRID`] (and a tenth of critical damping to the ground), and, for one body, the body
/// whose impedance fits the level with the highest torque best ([`single_body`]).
pub fn starts(data: &Data, chains: &[Chain]) -> Vec<LinExt> {
    let w0 = 2.0 * std::f64::consts::PI * data.f_min().max(1e-6);
    let mut out: Vec<LinExt> = Vec::new();
    if let Some(top) = (0..data.levels.len()).max_by(|&a, &b| {
        data.levels[a]
            .torque_rms
            .total_cmp(&data.levels[b].torque_rms)
    }) {
        let l = &data.levels[top];
        if let Some((j, k, b)) = single_body(&l.f, &l.h, &l.var, data.fs, data.kind) {
            if let Ok(chain) = Chain::new(vec![j], vec![], vec![]) {
                out.push(LinExt {
                    ground_k: k,
                    motor_b: b,
                    ground_spring: true,
                    ..LinExt::nominal(chain)
                });
            }
        }
    }
    for c in chains {
        let jt = c.total_inertia();
        for m in GRID {
            let k = m * jt * w0 * w0;
            out.push(LinExt {
                ground_k: k,
                ground_spring: true,
                ..LinExt::nominal(c.clone())
            });
        }
    }
    out
}

/// One body on a spring and a damper to the ground, `1/X = k - J ω² + j b ω`, fitted to the
/// measured response by linear least squares on the impedance relative to its size
/// (weights `1/|Z|²` and the line's relative precision): `(J, k, b)`, or `None` when the
/// data do not give positive values (the response is not a grounded body's). The motion's
/// measure is taken out exactly: the backward difference `(1 - e^{-jωT}) fs` for a
/// differenced velocity, `jω` for a velocity.
pub fn single_body(
    f: &[f64],
    h: &[Complex64],
    var: &[f64],
    fs: f64,
    kind: FrfKind,
) -> Option<(f64, f64, f64)> {
    let (mut s11, mut s12, mut s22, mut r1, mut r2) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut bw, mut bn) = (0.0, 0.0);
    for ((&fi, &hi), &vi) in f.iter().zip(h).zip(var) {
        let w = 2.0 * std::f64::consts::PI * fi;
        let d = match kind {
            FrfKind::DifferencedVelocity => {
                (Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -w / fs)) * fs
            }
            FrfKind::Velocity => Complex64::new(0.0, w),
            FrfKind::Position => Complex64::new(1.0, 0.0),
            FrfKind::Other => return None,
        };
        // Z = 1/X = D/H
        let z = d / hi;
        let rel = hi.norm_sqr() / vi.max(f64::MIN_POSITIVE);
        let wt = rel.min(1e12) / z.norm_sqr().max(f64::MIN_POSITIVE);
        if !(wt.is_finite() && z.re.is_finite() && z.im.is_finite()) {
            continue;
        }
        // Re Z = k - J ω²: columns (1, -ω²)
        let (a1, a2) = (1.0, -w * w);
        s11 += wt * a1 * a1;
        s12 += wt * a1 * a2;
        s22 += wt * a2 * a2;
        r1 += wt * a1 * z.re;
        r2 += wt * a2 * z.re;
        // Im Z = b ω
        bw += wt * w * w;
        bn += wt * w * z.im;
    }
    let det = s11 * s22 - s12 * s12;
    if !(det.is_finite() && det.abs() > 0.0 && bw > 0.0) {
        return None;
    }
    let k = (s22 * r1 - s12 * r2) / det;
    let j = (s11 * r2 - s12 * r1) / det;
    let b = bn / bw;
    (j > 0.0 && k > 0.0 && j.is_finite() && k.is_finite()).then_some((
        j,
        k,
        b.max(0.0).max(1e-6 * (k * j).sqrt()),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::Discrete;

    /// The least squares give a sampled mass-spring-damper's parameters back from its
    /// exact sampled FRF (reference: the parameters it was made from), to the accuracy
    /// with which the hold's half-sample delay bends the impedance (a few per cent at
    /// a tenth of the sample rate).
    #[test]
    fn one_grounded_body_is_found_from_its_impedance() {
        let (j, k, b) = (2e-3, 300.0, 0.05);
        let m = LinExt {
            ground_k: k,
            motor_b: b,
            ground_spring: true,
            ..LinExt::nominal(Chain::new(vec![j], vec![], vec![]).unwrap())
        };
        let fs = 2000.0;
        let f: Vec<f64> = (1..200).map(|i| i as f64 * 0.5).collect();
        let h = Discrete::new(&m, fs, 0).frf_lines(&f, FrfKind::DifferencedVelocity);
        let var: Vec<f64> = h.iter().map(|v| 1e-6 * v.norm_sqr()).collect();
        let (j1, k1, b1) = single_body(&f, &h, &var, fs, FrfKind::DifferencedVelocity).unwrap();
        assert!((j1 / j - 1.0).abs() < 0.05, "J {j1}");
        assert!((k1 / k - 1.0).abs() < 0.05, "k {k1}");
        assert!((b1 / b - 1.0).abs() < 0.2, "b {b1}");
        // a free body has no positive spring
        let free = LinExt::nominal(Chain::new(vec![j], vec![], vec![]).unwrap());
        let hf = Discrete::new(&free, fs, 0).frf_lines(&f, FrfKind::DifferencedVelocity);
        let got = single_body(&f, &hf, &var, fs, FrfKind::DifferencedVelocity);
        assert!(got.is_none_or(|(_, k, _)| k < 1e-3 * 300.0), "{got:?}");
    }
}
