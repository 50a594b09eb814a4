//! Velocity from encoder position, and the exact response of the difference quotient.
//!
//! # Why differenced velocity
//!
//! A servo axis without position control is a *free* axis: its position is the integral of
//! its velocity, and any velocity offset (friction imbalance, gravity, a small torque offset)
//! or low-frequency disturbance (a random walk) makes the position drift without bound.
//! The DFT of such a position record is dominated by the drift, which leaks into every
//! line (a ramp over the record has a 1/k spectrum), so the FRF must **never** be taken as
//! `j w` times the DFT of the raw position. Instead, differentiate in the time domain:
//! the backward difference turns a ramp into a constant (which only touches the DC line)
//! and a random walk in position into bounded noise. The difference quotient is itself a
//! linear filter with the exact response [`difference_quotient_response`]; a model FRF is
//! compared with a [`super::FrfKind::DifferencedVelocity`] measurement by multiplying the
//! model's position response by that factor (not by `j w`).
//!
//! When a position signal has to be used directly (e.g. [`super::FrfKind::Position`] over a
//! short, clamped record), at least remove its least-squares line first with
//! [`remove_linear_trend`].

use num_complex::Complex64;
use std::f64::consts::PI;

/// Backward-difference velocity `v[k] = (p[k] - p[k-1]) * fs` [rad/s] from sampled
/// position `p` \[rad\] at sample rate `fs` \[Hz\].
///
/// The output has the same length as the input. Sample 0 has no predecessor; it is defined
/// with `p[-1] := p[0]`, i.e. `v[0] = 0` (the axis is taken to be at rest before the record;
/// this sample lies in the transient that the periodic estimator discards anyway, and the
/// rule needs no look-ahead, so [`differenced_velocity_into`] can run on streamed chunks).
pub fn differenced_velocity(position_rad: &[f64], fs: f64) -> Vec<f64> {
    let mut out = vec![0.0; position_rad.len()];
    differenced_velocity_into(position_rad, fs, None, &mut out);
    out
}

/// Allocation-free form of [`differenced_velocity`] for streamed chunks.
///
/// `prev` is the last position sample of the previous chunk (`None` for the first chunk,
/// which then uses `p[-1] := p[0]`). `out` must have the length of `position_rad`.
/// Returns the last position sample of this chunk, to pass as `prev` for the next one.
///
/// # Panics
/// If `out.len() != position_rad.len()`.
pub fn differenced_velocity_into(
    position_rad: &[f64],
    fs: f64,
    prev: Option<f64>,
    out: &mut [f64],
) -> Option<f64> {
    assert_eq!(
        out.len(),
        position_rad.len(),
        "output length must match input"
    );
    let Some(&first) = position_rad.first() else {
        return prev;
    };
    let mut last = prev.unwrap_or(first);
    for (o, &p) in out.iter_mut().zip(position_rad) {
        *o = (p - last) * fs;
        last = p;
    }
    Some(last)
}

/// Exact frequency response of the backward difference quotient,
/// `D(f) = (1 - exp(-j w Ts)) / Ts` with `w = 2 pi f`, `Ts = 1/fs` [1/s].
///
/// For `f << fs` this tends to `j w`; at higher frequencies it differs in magnitude
/// (`|D| = 2 fs sin(w Ts / 2)`) and phase (a half-sample delay, `-w Ts / 2`).
/// `D(f) * P(f)` is the DFT-domain response of [`differenced_velocity`] to a position with
/// response `P(f)`.
pub fn difference_quotient_response(f_hz: f64, fs: f64) -> Complex64 {
    let theta = 2.0 * PI * f_hz / fs;
    // 1 - e^{-j theta} = (1 - cos theta) + j sin theta
    Complex64::new(1.0 - theta.cos(), theta.sin()) * fs
}

/// Remove the least-squares straight line `a + b k` (k = sample index) from `x` in place.
///
/// Returns `(a, b)`: offset [unit of x] and slope [unit of x per sample]. Signals shorter
/// than 2 samples only have their mean (or nothing) removed, with `b = 0`.
pub fn remove_linear_trend(x: &mut [f64]) -> (f64, f64) {
    let n = x.len();
    if n == 0 {
        return (0.0, 0.0);
    }
    if n == 1 {
        let a = x[0];
        x[0] = 0.0;
        return (a, 0.0);
    }
    // Centre the abscissa for numerical stability: k - kc, kc = (n-1)/2.
    let nf = n as f64;
    let kc = (nf - 1.0) / 2.0;
    let mut sx = 0.0;
    let mut skx = 0.0;
    for (k, &v) in x.iter().enumerate() {
        sx += v;
        skx += (k as f64 - kc) * v;
    }
    // sum (k - kc)^2 = n (n^2 - 1) / 12
    let skk = nf * (nf * nf - 1.0) / 12.0;
    let mean = sx / nf;
    let b = skx / skk;
    for (k, v) in x.iter_mut().enumerate() {
        *v -= mean + b * (k as f64 - kc);
    }
    (mean - b * kc, b)
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;

    #[test]
    fn differenced_velocity_definition() {
        let p = [1.0, 1.5, 1.25, 2.0];
        let v = differenced_velocity(&p, 10.0);
        assert_eq!(v, vec![0.0, 5.0, -2.5, 7.5]);
        // chunked form equals the batch form
        let mut out = vec![0.0; 4];
        let last = differenced_velocity_into(&p[..1], 10.0, None, &mut out[..1]);
        differenced_velocity_into(&p[1..], 10.0, last, &mut out[1..]);
        assert_eq!(out, v);
    }

    #[test]
    fn difference_quotient_matches_differenced_sinusoid() {
        let fs = 1000.0;
        for &(f, a, phi) in &[(3.7, 1.3, 0.2), (123.4, 0.5, -1.0), (449.0, 2.0, 2.5)] {
            let w = 2.0 * PI * f;
            let p: Vec<f64> = (0..200)
                .map(|k| a * (w * k as f64 / fs + phi).cos())
                .collect();
            let v = differenced_velocity(&p, fs);
            let d = difference_quotient_response(f, fs);
            // closed form against the formula's own definition
            let direct = (Complex64::new(1.0, 0.0) - Complex64::from_polar(1.0, -w / fs)) * fs;
            assert!((d - direct).norm() <= 1e-12 * direct.norm());
            for k in 1..p.len() {
                let expect = (d * Complex64::from_polar(a, w * k as f64 / fs + phi)).re;
                assert!(
                    (v[k] - expect).abs() <= 1e-9 * a * fs,
                    "f={f} k={k}: {} vs {expect}",
                    v[k]
                );
            }
            // and it is NOT j w at high frequency (half-sample delay, sinc magnitude)
            if f > 100.0 {
                assert!((d - Complex64::new(0.0, w)).norm() > 1e-3 * w);
            }
        }
    }

    #[test]
    fn linear_trend_removed() {
        let mut x: Vec<f64> = (0..101)
            .map(|k| 3.0 - 0.25 * k as f64 + (0.3 * k as f64).sin() * 1e-3)
            .collect();
        let (a, b) = remove_linear_trend(&mut x);
        assert!((a - 3.0).abs() < 1e-3 && (b + 0.25).abs() < 1e-4, "{a} {b}");
        let mean: f64 = x.iter().sum::<f64>() / x.len() as f64;
        let slope: f64 = x
            .iter()
            .enumerate()
            .map(|(k, v)| (k as f64 - 50.0) * v)
            .sum();
        assert!(mean.abs() < 1e-12 && slope.abs() < 1e-9);
        assert!(x.iter().all(|v| v.abs() < 2e-3));
    }
}
