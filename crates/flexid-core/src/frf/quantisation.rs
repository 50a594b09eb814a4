//! The quantisation floor of a recorded motion signal.
//!
//! An encoder reports whole counts: the recorded position lies on a grid of step `q`
//! \[rad\]. Its error `e = Q(x) - x` has variance `q²/12` and, where the motion between two
//! samples is below a count and the excitation is periodic, it repeats period after period:
//! it is part of the *mean* over periods and is missing from the period-to-period scatter
//! that the periodic estimator takes as the line's variance. At lines where the response
//! is small (high frequencies, a coarse encoder) the measured FRF then departs from the
//! true one by more than its variance says, and a diagnosis would call that gap real.
//!
//! The floor added to each line's variance is the quantisation error's own level, not a
//! tuned constant: white error of variance `q²/12` through the operator that turns the
//! recorded signal into the estimator's output (`fs (1 - e^(-jωT))` for a differenced
//! position, 1 otherwise), with the `1/N` DFT scaling of one period of `N` samples, over
//! `|U(k)|²`:
//!
//! `var_q H(k) = q²/12 · |D(ω_k)|² / N / |U(k)|²`.
//!
//! It is not divided by the number of periods (a repeating error does not average); where
//! the motion dithers the error from period to period it is also in the scatter, and the
//! floor then overstates the variance by at most itself: conservative where quantisation
//! matters, nothing where it does not.

use super::types::FrfKind;
use num_complex::Complex64;

/// Share of samples that must lie on the grid (within [`ON_GRID`] of a step) for a grid to
/// be accepted: a quantised signal has all of them; an unquantised one about 2 %.
const ON_GRID_SHARE: f64 = 0.99;

/// Largest distance from a grid point, in steps, for a sample to count as on the grid
/// (printing to text with shortest round-trip digits keeps them within 1e-9 steps).
const ON_GRID: f64 = 1e-3;

/// The grid step of a quantised signal (an encoder count in the signal's units), or `None`
/// when the signal does not lie on a grid (unquantised, filtered, or too few distinct
/// values to tell).
///
/// The candidate is the smallest non-zero difference between consecutive samples, or an
/// integer fraction of it (1/1 to 1/8, for a signal that never moves by a single count
/// between samples); it is accepted when at least 99 % of the samples lie within 1e-3
/// steps of `x[0] + i q`.
pub fn grid_step(x: &[f64]) -> Option<f64> {
    if x.len() < 16 || x.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let smallest = x
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .filter(|d| *d > 0.0)
        .fold(f64::INFINITY, f64::min);
    if !smallest.is_finite() {
        return None;
    }
    let scale = x.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    (1..=8)
        .map(|m| smallest / m as f64)
        .filter(|q| *q > 1e-12 * scale)
        .find(|&q| on_grid_share(x, q) >= ON_GRID_SHARE)
}

/// Share of samples within [`ON_GRID`] steps of the grid `x[0] + i q`.
fn on_grid_share(x: &[f64], q: f64) -> f64 {
    let x0 = x[0];
    let on = x
        .iter()
        .filter(|v| {
            let s = (*v - x0) / q;
            (s - s.round()).abs() <= ON_GRID
        })
        .count();
    on as f64 / x.len() as f64
}

/// The variance [(unit of H)²] that a grid of step `q` (in the recorded signal's units)
/// adds to the FRF line at `freq_hz` whose mean input over one period of `period_samples`
/// samples is `u` (the `1/N`-scaled DFT). `kind` says how the recorded signal became the
/// estimator's output: a differenced position passes the error through
/// `fs (1 - e^(-jωT))`.
pub fn line_variance(
    q: f64,
    kind: FrfKind,
    freq_hz: f64,
    sample_rate_hz: f64,
    period_samples: usize,
    u: Complex64,
) -> f64 {
    let d2 = match kind {
        FrfKind::DifferencedVelocity => {
            let w = 2.0 * std::f64::consts::PI * freq_hz / sample_rate_hz;
            // |1 - e^{-jw}|² = 2 - 2 cos w
            sample_rate_hz * sample_rate_hz * (2.0 - 2.0 * w.cos())
        }
        _ => 1.0,
    };
    let v = q * q / 12.0 * d2 / period_samples as f64 / u.norm_sqr();
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f64 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*state >> 11) as f64 / (1u64 << 53) as f64
    }

    #[test]
    fn the_step_of_an_encoder_is_found_and_a_smooth_signal_has_none() {
        let q = 2.0 * std::f64::consts::PI / (1u64 << 17) as f64;
        let mut s = 7u64;
        let smooth: Vec<f64> = (0..5000)
            .map(|k| 0.3 * (k as f64 * 0.01).sin() + 1e-6 * lcg(&mut s))
            .collect();
        assert_eq!(grid_step(&smooth), None);
        let counts: Vec<f64> = smooth.iter().map(|x| (x / q).round() * q).collect();
        let found = grid_step(&counts).expect("a grid");
        assert!((found / q - 1.0).abs() < 1e-9, "{found} vs {q}");
        // never a single count between samples: the step is a fraction of the smallest move
        // (moves of 2 to 4 counts, values odd and even)
        let fast: Vec<f64> = (0..5000)
            .map(|k| (3 * k + usize::from(k % 5 == 0)) as f64 * q)
            .collect();
        let found = grid_step(&fast).expect("a grid");
        assert!((found / q - 1.0).abs() < 1e-9, "{found} vs {q}");
        // through text with shortest round-trip digits, as a CSV holds it
        let text: Vec<f64> = counts
            .iter()
            .map(|x| format!("{x:e}").parse().unwrap())
            .collect();
        assert!((grid_step(&text).unwrap() / q - 1.0).abs() < 1e-9);
        assert_eq!(grid_step(&[0.0; 100]), None);
    }

    /// The floor against a direct computation: the per-period DFT of white uniform error
    /// of step q, differenced, has mean |E(k)|² = q²/12 |D|² / N.
    #[test]
    fn the_floor_is_the_level_of_white_quantisation_error() {
        let (n, fs, q) = (256usize, 1000.0, 1e-3);
        let k = 40usize;
        let f = k as f64 * fs / n as f64;
        let trials = 4000;
        let mut s = 11u64;
        let mut acc = 0.0;
        for _ in 0..trials {
            let e: Vec<f64> = (0..=n).map(|_| (lcg(&mut s) - 0.5) * q).collect();
            let mut x = Complex64::new(0.0, 0.0);
            for i in 0..n {
                let d = (e[i + 1] - e[i]) * fs;
                x += d * Complex64::from_polar(
                    1.0,
                    -2.0 * std::f64::consts::PI * (k * i) as f64 / n as f64,
                );
            }
            acc += (x / n as f64).norm_sqr();
        }
        let mc = acc / trials as f64;
        let u = Complex64::new(1.0, 0.0);
        let v = line_variance(q, FrfKind::DifferencedVelocity, f, fs, n, u);
        assert!((v / mc - 1.0).abs() < 0.08, "floor {v} vs Monte Carlo {mc}");
        // a larger input divides it
        let v2 = line_variance(q, FrfKind::DifferencedVelocity, f, fs, n, 2.0 * u);
        assert!((v / v2 - 4.0).abs() < 1e-9);
        assert_eq!(
            line_variance(q, FrfKind::Velocity, f, fs, n, Complex64::new(0.0, 0.0)),
            0.0
        );
    }
}
