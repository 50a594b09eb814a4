//! Starts of the nominal chain with viscous friction to the ground, identified on the
//! measurement with that damper taken out.
//!
//! The identification fits a *free* chain. A motor with a strong damper to the ground
//! (`b` comparable to `J_total w` on the lowest lines) does not look free there, and the
//! free chain bends to mimic it: a soft extra pair below the band, a huge body on a tiny
//! spring. Fitting the damper afterwards from that chain stays in its basin. The damper
//! can be taken out of the measurement exactly instead: at the motor, the driving-point
//! mobility (velocity per torque) of a chain with a damper `b` to the ground is
//!
//! ```text
//! Y(jw) = 1 / (Z_free(jw) + b),     so     Y_free = Y / (1 - b Y)
//! ```
//!
//! with `Z_free` the free chain's driving-point impedance. `Z_free` is passive and, below
//! the first anti-resonance, `j w J_total` plus a real part of order `w^2` (the couplings'
//! dampers): `Re(1/Y)` on the lowest lines estimates `b` (biased up when an anti-resonance
//! is near them; the joint fit that follows corrects it). The identification then runs on
//! `Y_free`. (Passivity also bounds `b` by `Re(1/Y)` on every line, but not usefully: over
//! hundreds of lines some fall a few sigma low, and where `|h|` is near its noise the
//! linearised variance of `1/h` does not hold; tried on the world benchmark, the bound
//! turned a damping of 0.549 seen to 1e-4 into -1.9.)

use super::lti::LinExt;
use super::Data;
use crate::analysis::{analyze_estimate, EstimatedFrf};
use crate::frf::{Frf, FrfKind};
use num_complex::Complex64;
use std::f64::consts::PI;

/// The damper from the motor to the ground seen on the lowest lines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroundDamping {
    /// Viscous damping [N m s/rad].
    pub b_nms_per_rad: f64,
    /// Its standard deviation from the lines' variances [N m s/rad].
    pub std_nms_per_rad: f64,
}

/// Significance (in standard deviations) the damping must have before the measurement is
/// corrected for it (the project's one significance level, [`super::noise::SIGNIFICANT_SIGMA`]).
const SIGMA: f64 = super::noise::SIGNIFICANT_SIGMA;

/// The factor `g(w)` with `Y = g h`: the continuous mobility from a line of `frf`. The
/// sampling's own lag is removed: half a sample for the zero-order hold, and half a sample
/// more for a backward-differenced velocity, plus the whole-sample I/O delay `io_delay`.
fn mobility_factor(frf: &Frf, f_hz: f64, io_delay: u32) -> Option<Complex64> {
    let w = 2.0 * PI * f_hz;
    let t = 1.0 / frf.sample_rate_hz;
    let lag_samples = io_delay as f64
        + match frf.kind {
            FrfKind::DifferencedVelocity => 1.0,
            FrfKind::Position | FrfKind::Velocity => 0.5,
            FrfKind::Other => return None,
        };
    let undo_lag = Complex64::from_polar(1.0, w * t * lag_samples);
    Some(match frf.kind {
        FrfKind::Position => Complex64::new(0.0, w) * undo_lag,
        _ => undo_lag,
    })
}

/// The ground damping from `Re(1/Y)` on the lowest octave of lines (at least two; an
/// inverse-variance weighted mean).
/// `None` when the response is not a motion or there are fewer than two usable lines.
pub fn ground_damping(frf: &Frf, io_delay: u32) -> Option<GroundDamping> {
    let lines: Vec<(f64, f64, f64)> = (0..frf.len())
        .filter_map(|i| {
            let (h, v) = (frf.h[i], frf.var[i]);
            if !(v.is_finite() && v > 0.0 && h.norm() > 0.0) {
                return None;
            }
            let g = mobility_factor(frf, frf.freq_hz[i], io_delay)?;
            let z = 1.0 / (g * h);
            // var(1/(g h)) = var(h) / (|g|^2 |h|^4); half of it in the real part
            let var_re = 0.5 * v / (g.norm_sqr() * h.norm_sqr().powi(2));
            Some((frf.freq_hz[i], z.re, var_re))
        })
        .collect();
    if lines.len() < 2 {
        return None;
    }
    let f0 = lines[0].0;
    let low: Vec<&(f64, f64, f64)> = lines
        .iter()
        .enumerate()
        .take_while(|(k, l)| *k < 2 || l.0 <= 2.0 * f0)
        .map(|(_, l)| l)
        .collect();
    let (sw, swz) = low
        .iter()
        .fold((0.0, 0.0), |(a, b), l| (a + 1.0 / l.2, b + l.1 / l.2));
    let b = swz / sw;
    let std = (1.0 / sw).sqrt();
    (b.is_finite() && std.is_finite()).then_some(GroundDamping {
        b_nms_per_rad: b,
        std_nms_per_rad: std,
    })
}

/// `frf` with a damper `b` [N m s/rad] from the motor to the ground taken out:
/// `h / (1 - b g h)` per line, variances propagated (`|1 - b g h|^-4`).
pub fn without_ground_damper(frf: &Frf, b: f64, io_delay: u32) -> Frf {
    let mut out = frf.clone();
    for i in 0..out.len() {
        let Some(g) = mobility_factor(frf, frf.freq_hz[i], io_delay) else {
            continue;
        };
        let d = 1.0 - b * g * frf.h[i];
        out.h[i] = frf.h[i] / d;
        out.var[i] = frf.var[i] / d.norm_sqr().powi(2);
    }
    out.coherence = None;
    out
}

/// Start of the nominal `n`-body chain with viscous friction to the ground: the chain
/// identified on the highest level's measurement with its ground damper taken out, and
/// that damper. `None` when the lowest lines show no damper significantly above zero or
/// the identification fails.
pub fn start(
    data: &Data,
    n: usize,
    band: Option<[f64; 2]>,
    budget: &crate::identify::fit::FitBudget,
) -> Option<LinExt> {
    let top = super::top_level(data);
    let level = &data.levels[top];
    let est: EstimatedFrf = level.measured(band).ok()?;
    let damping = ground_damping(&est.frf, level.io_delay)?;
    if damping.b_nms_per_rad < SIGMA * damping.std_nms_per_rad {
        return None;
    }
    let corrected = EstimatedFrf {
        frf: without_ground_damper(&est.frf, damping.b_nms_per_rad, level.io_delay),
        ..est
    };
    let opts = super::nominal_analysis(n, band, budget);
    let chain = analyze_estimate(&level.rec, corrected, &opts)
        .ok()?
        .fit?
        .chain;
    Some(LinExt {
        motor_b: damping.b_nms_per_rad,
        ..LinExt::nominal(chain)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::diagnose::lti::Discrete;
    use crate::model::Chain;

    /// A 3-body chain with a strong damper to the ground, its sampled differenced-velocity
    /// response on a log grid: the damper is recovered from the lowest lines, and taking it
    /// out gives the free chain's response (both checked against the exact sampled models).
    #[test]
    fn the_ground_damper_is_found_and_taken_out() {
        let chain = Chain::new(
            vec![0.005, 0.012, 0.023],
            vec![2300.0, 64.0],
            vec![0.12, 0.046],
        )
        .unwrap();
        let b = 0.57;
        let fs = 4000.0;
        let f: Vec<f64> = (0..40)
            .map(|k| 1.0 * 1.2f64.powi(k))
            .filter(|&f| f < 1500.0)
            .collect();
        let with = LinExt {
            motor_b: b,
            ..LinExt::nominal(chain.clone())
        };
        let kind = FrfKind::DifferencedVelocity;
        let h_with = Discrete::new(&with, fs, 0).frf_lines(&f, kind);
        let h_free = Discrete::new(&LinExt::nominal(chain), fs, 0).frf_lines(&f, kind);
        let measured = Frf {
            freq_hz: f.clone(),
            h: h_with.clone(),
            var: h_with.iter().map(|h| 1e-6 * h.norm_sqr()).collect(),
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: fs,
        };
        let d = ground_damping(&measured, 0).unwrap();
        assert!(
            (d.b_nms_per_rad - b).abs() < 0.02 * b,
            "b {} vs {b}",
            d.b_nms_per_rad
        );
        assert!(d.b_nms_per_rad > 100.0 * d.std_nms_per_rad);
        let out = without_ground_damper(&measured, b, 0);
        for (i, (a, e)) in out.h.iter().zip(&h_free).enumerate() {
            let rel = (a - e).norm() / e.norm();
            // exact for the continuous response; the zero-order-hold chain departs from
            // it by a small multiple of (w T)^2 near its resonance and Nyquist: ample for a
            // start, and the correction matters only where b Y is not small (the low lines)
            let tol = if f[i] < 50.0 { 2e-4 } else { 1e-2 };
            assert!(rel < tol, "line {} Hz: {rel:e}", f[i]);
        }
    }

    /// A free chain has no ground damping: the estimate is zero within its scatter.
    #[test]
    fn a_free_chain_shows_no_ground_damper() {
        let chain = Chain::new(vec![0.005, 0.012], vec![2300.0], vec![0.12]).unwrap();
        let fs = 2000.0;
        let f: Vec<f64> = (2..400).map(|k| 0.5 * k as f64).collect();
        let h = Discrete::new(&LinExt::nominal(chain), fs, 0)
            .frf_lines(&f, FrfKind::DifferencedVelocity);
        let measured = Frf {
            freq_hz: f,
            var: h.iter().map(|h| 1e-4 * h.norm_sqr()).collect(),
            h,
            coherence: None,
            kind: FrfKind::DifferencedVelocity,
            sample_rate_hz: fs,
        };
        let d = ground_damping(&measured, 0).unwrap();
        assert!(d.b_nms_per_rad.abs() < SIGMA * d.std_nms_per_rad, "{d:?}");
    }
}
