//! The damper from the motor to the ground, seen on the lowest lines and taken out of the
//! measurement, so that a *free* chain can be identified on what remains.
//!
//! The chain model is free at both ends. A motor with a strong damper to the ground
//! (bearings, seals, the motor's own losses: `b` comparable to `J_total w` on the lowest
//! lines) does not look free there, and a free chain fitted anyway bends to mimic it: a
//! soft extra pair below the band, a huge body on a tiny spring (a 4-body fit of a 0.05 kg
//! m^2 axis returned J4 = 65 kg m^2 behind a 0.05 N m/rad spring, its damper standing in
//! for the ground's). The damper can be taken out of the measurement exactly instead: at
//! the motor, the driving-point mobility (velocity per torque) of a chain with a damper
//! `b` to the ground is
//!
//! ```text
//! Y(jw) = 1 / (Z_free(jw) + b),     so     Y_free = Y / (1 - b Y)
//! ```
//!
//! with `Z_free` the free chain's driving-point impedance. `Z_free` is passive and, below
//! the first anti-resonance, `j w J_total` plus a real part of order `w^2` (the couplings'
//! dampers): `Re(1/Y)` on the lowest lines estimates `b` (biased up when an anti-resonance
//! is near them). (Passivity also bounds `b` by `Re(1/Y)` on every line, but not usefully:
//! over hundreds of lines some fall a few sigma low, and where `|h|` is near its noise the
//! linearised variance of `1/h` does not hold; tried on the world benchmark, the bound
//! turned a damping of 0.549 seen to 1e-4 into -1.9.)
//!
//! The relation is that of the continuous mobility; the sampled FRF is brought to it by
//! undoing the sampling's own lag (half a sample for the zero-order hold, half more for a
//! backward difference). The zero-order-hold response departs from the continuous one by
//! a small multiple of `(w T)^2` near its resonances and Nyquist, where `b Y` is small and
//! the correction hardly acts.

use super::SIGNIFICANT_SIGMA;
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

/// The factor `g(w)` with `Y = g h`: the continuous mobility from a line of `frf`. The
/// sampling's own lag is removed: half a sample for the zero-order hold, and half a sample
/// more for a backward-differenced velocity, plus the whole-sample I/O delay `io_delay`.
pub fn mobility_factor(frf: &Frf, f_hz: f64, io_delay: u32) -> Option<Complex64> {
    mobility_factor_at(frf.kind, frf.sample_rate_hz, f_hz, io_delay)
}

/// [`mobility_factor`] for a response of `kind` sampled at `fs_hz`.
pub fn mobility_factor_at(
    kind: FrfKind,
    fs_hz: f64,
    f_hz: f64,
    io_delay: u32,
) -> Option<Complex64> {
    let w = 2.0 * PI * f_hz;
    let t = 1.0 / fs_hz;
    let lag_samples = io_delay as f64
        + match kind {
            FrfKind::DifferencedVelocity => 1.0,
            FrfKind::Position | FrfKind::Velocity => 0.5,
            FrfKind::Other => return None,
        };
    let undo_lag = Complex64::from_polar(1.0, w * t * lag_samples);
    Some(match kind {
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

/// `frf` with the ground damper taken out when the lowest lines show one significantly
/// above zero (at least [`SIGNIFICANT_SIGMA`] standard deviations), and that damper;
/// `None` otherwise (no damper seen, or not a motion response).
pub fn take_out(frf: &Frf, io_delay: u32) -> Option<(Frf, GroundDamping)> {
    let d = ground_damping(frf, io_delay)?;
    (d.b_nms_per_rad >= SIGNIFICANT_SIGMA * d.std_nms_per_rad && d.b_nms_per_rad > 0.0)
        .then(|| (without_ground_damper(frf, d.b_nms_per_rad, io_delay), d))
}

/// A free chain's response `h_free` at `f_hz` (on the footing of `kind`, sampled at
/// `fs_hz`) with the damper `b` put back: `h / (1 + b g h)`, the inverse of
/// [`without_ground_damper`].
pub fn with_ground_damper(
    h_free: Complex64,
    f_hz: f64,
    kind: FrfKind,
    fs_hz: f64,
    b: f64,
    io_delay: u32,
) -> Complex64 {
    let Some(g) = mobility_factor_at(kind, fs_hz, f_hz, io_delay) else {
        return h_free;
    };
    h_free / (1.0 + b * g * h_free)
}
