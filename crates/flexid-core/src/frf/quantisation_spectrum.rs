//! Where in frequency the repeating quantisation error of a periodic motion lies.
//!
//! [`super::quantisation`] derives the power `σ_q²` of the part of an encoder's error that
//! repeats from period to period, and spreads it evenly over the period's lines, as white
//! error. It is not white when the motion is slow against the sample rate: the repeating
//! error is the sawtooth's series `Σ_k a_k sin(2π k x(t)/q)` with `a_k = q/(π k) ·
//! exp(-2π² k² σ²/q²)`, and each harmonic is a phase-modulated wave whose instantaneous
//! frequency is `k |ẋ(t)|/q` (counts crossed per second, times `k`). By Woodward's theorem
//! (the quasi-static limit of a wide-band phase modulation) the power `a_k²/2` of harmonic
//! `k` is distributed over frequency as that instantaneous frequency is over the period.
//! The error therefore sits where the motion crosses counts: an axis that moves a tenth of
//! a count per sample puts most of it near a tenth of the sample rate and its multiples
//! (folded at Nyquist), and a floor spread evenly would be far too low there, and too high
//! at the lines below.
//!
//! The speed over the period comes from the recorded motion itself: the periods averaged,
//! kept at the excited lines only (the motion the excitation makes; the noise and the
//! repeating error are mostly elsewhere), differentiated. The per-line power is smoothed
//! over [`SMOOTH_LINES`] lines either side: Woodward's density is the expectation over
//! where the motion sits within a count, not the detail of one period's line spectrum.

use num_complex::Complex64;
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Half-width of the smoothing of the per-line power [lines]: the density holds on
/// scales wider than a line; 4 lines either side (9 in all) leave its shape (which spans
/// tens to thousands of lines) and average out the histogram's own scatter.
pub const SMOOTH_LINES: usize = 4;

/// Largest sawtooth harmonic placed by its speed: the undamped series' tail beyond `K`
/// holds about `6/(π² K)` of the power (1.9 % at 32), which is then spread evenly (the
/// high harmonics fold over the band many times: nearly even anyway). 128 cost 0.1 s per
/// diagnosis of two 16384-sample periods, a twentieth of the speed target.
pub const MAX_HARMONIC: usize = 32;

/// The repeating quantisation error's power per line `0..=n/2` of a period of `n` samples,
/// as a white-equivalent power [(signal unit)²]: the variance of a white sequence that
/// would put the same power on that line (so it plugs into
/// [`super::quantisation::line_variance`] in place of the even spread; the even spread of
/// power `P` is `P` on every line). `q`: the grid step; `sigma`: the noise behind the
/// counts (as in [`super::quantisation::repeating_variance`]); `speed`: `|dx/dk|` at each
/// sample of one period [signal unit per sample]. Its lines sum (times `2/n`) to
/// [`super::quantisation::repeating_variance`]`(q, sigma)`.
pub fn repeating_spectrum(q: f64, sigma: f64, speed: &[f64]) -> Vec<f64> {
    let damp = 4.0 * PI * PI * (sigma / q).powi(2);
    let gains: Vec<f64> = (1..=MAX_HARMONIC)
        .map(|k| (-damp * (k * k) as f64).exp())
        .collect();
    let c = q * q / (2.0 * PI * PI);
    let taken: f64 = (1..=MAX_HARMONIC)
        .map(|k| c / (k * k) as f64 * gains[k - 1])
        .sum();
    let tail = (super::quantisation::repeating_variance(q, sigma) - taken).max(0.0);
    shared_spectrum(q, &gains, tail, speed)
}

/// [`repeating_spectrum`] for harmonics that repeat by their own gains `g_k` (`gains[k-1]`,
/// from 1 up to at most [`MAX_HARMONIC`]; harmonic `k` has the power `q²/(2π² k²) g_k`)
/// and a `tail` power [(signal unit)²] of the harmonics beyond, spread evenly: the error
/// two periods share when the axis wanders between them
/// ([`super::quantisation_correlation`]). A gain may be negative (periods whose errors
/// tend to cancel); the per-line power is kept at zero or above.
pub fn shared_spectrum(q: f64, gains: &[f64], tail: f64, speed: &[f64]) -> Vec<f64> {
    let n = speed.len();
    let half = n / 2;
    let mut power = vec![0.0; half + 1];
    if n == 0 || !(q > 0.0) {
        return power;
    }
    let c = q * q / (2.0 * PI * PI);
    let mut placed = 0.0_f64;
    for (i, g) in gains.iter().take(MAX_HARMONIC).enumerate() {
        let k = i + 1;
        let harmonic = c / (k * k) as f64 * g;
        if harmonic.abs() < 1e-9 * placed.abs() {
            break;
        }
        placed += harmonic;
        let share = harmonic / n as f64;
        for &s in speed {
            // instantaneous frequency in cycles per sample, folded into [0, 1/2]
            let x = k as f64 * s / q;
            let nu = x - x.floor();
            let nu = if nu > 0.5 { 1.0 - nu } else { nu };
            let line = ((nu * n as f64).round() as usize).min(half);
            power[line] += share;
        }
    }
    for p in power.iter_mut() {
        *p += tail / (half + 1) as f64;
    }
    // per-line power -> white-equivalent (a white sequence of variance P puts 2P/n on a line)
    let white: Vec<f64> = power.iter().map(|p| p * n as f64 / 2.0).collect();
    smooth(&white, SMOOTH_LINES)
        .into_iter()
        .map(|p| p.max(0.0))
        .collect()
}

/// Moving average over `m` lines either side (fewer at the ends).
fn smooth(x: &[f64], m: usize) -> Vec<f64> {
    (0..x.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(m), (i + m).min(x.len() - 1));
            x[a..=b].iter().sum::<f64>() / (b - a + 1) as f64
        })
        .collect()
}

/// `|dx/dk|` [signal unit per sample] over one period of the periodic part of `x`:
/// `periods` periods of `period_samples` samples from its start averaged, kept at
/// `excited_lines` (line `l` has `l` cycles per period), differentiated (`j 2π l / n`).
/// `None` with no whole period or no excited line inside the period.
pub fn periodic_speed(
    x: &[f64],
    period_samples: usize,
    periods: usize,
    excited_lines: &[usize],
) -> Option<Vec<f64>> {
    let n = period_samples;
    let periods = periods.min(x.len() / n.max(1));
    if n < 4 || periods == 0 {
        return None;
    }
    let mut mean: Vec<f64> = (0..n)
        .map(|i| (0..periods).map(|m| x[m * n + i]).sum::<f64>() / periods as f64)
        .collect();
    let mut planner = RealFftPlanner::<f64>::new();
    let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
    let mut spec = fwd.make_output_vec();
    fwd.process(&mut mean, &mut spec).ok()?;
    let mut kept = vec![Complex64::new(0.0, 0.0); spec.len()];
    let mut any = false;
    for &l in excited_lines {
        // the Nyquist line of an even period has no derivative (its sine part is zero)
        if l > 0 && l < spec.len() && 2 * l != n {
            kept[l] = spec[l] * Complex64::new(0.0, 2.0 * PI * l as f64 / n as f64);
            any = true;
        }
    }
    if !any {
        return None;
    }
    let mut v = inv.make_output_vec();
    inv.process(&mut kept, &mut v).ok()?;
    Some(v.iter().map(|s| (s / n as f64).abs()).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::quantisation::repeating_variance;
    use crate::frf::test_rng::lcg;

    /// The spectrum sums to the repeating power (the same total as the even spread).
    #[test]
    fn the_spectrum_holds_the_repeating_power() {
        let n = 2000;
        let q = 1e-3;
        let speed: Vec<f64> = (0..n)
            .map(|i| 0.3 * q * (2.0 * PI * i as f64 / n as f64).sin().abs())
            .collect();
        for sigma in [0.0, 0.1 * q, 0.3 * q] {
            let s = repeating_spectrum(q, sigma, &speed);
            // undo the smoothing's edge effect by summing the unsmoothed equivalent:
            // the smoothing keeps the sum except at the two ends, where it is small here
            let total: f64 = s.iter().sum::<f64>() * 2.0 / n as f64;
            let want = repeating_variance(q, sigma);
            assert!(
                (total / want - 1.0).abs() < 0.05,
                "sigma {sigma}: {total} vs {want}"
            );
        }
    }

    /// Monte Carlo: a slow periodic motion (a few tens of counts, well under a count per
    /// sample at the high lines) quantised with a little noise; the repeating error (the
    /// mean over noise draws of `Q(x + noise) - x`) has its line power where the spectrum
    /// says, band by band (octaves of lines): within a factor 2 at the low lines, 10 % from
    /// line 64 up, where the even spread is off by a factor 4 to 18 in most bands.
    #[test]
    fn the_error_sits_where_the_motion_crosses_counts() {
        let n = 2048;
        let q = 1.0;
        let sigma = 0.05 * q;
        let x: Vec<f64> = (0..n)
            .map(|i| {
                let t = i as f64 / n as f64;
                30.0 * (2.0 * PI * t).sin() + 8.0 * (2.0 * PI * 3.0 * t + 1.0).sin()
            })
            .collect();
        let lines: Vec<usize> = vec![1, 3];
        let speed = periodic_speed(&x, n, 1, &lines).unwrap();
        // the speed from the FFT path against the exact derivative
        for (i, s) in speed.iter().enumerate() {
            let t = i as f64 / n as f64;
            let exact = (2.0 * PI / n as f64)
                * (30.0 * (2.0 * PI * t).cos() + 24.0 * (2.0 * PI * 3.0 * t + 1.0).cos());
            assert!(
                (s - exact.abs()).abs() < 1e-9,
                "{i}: {s} vs {}",
                exact.abs()
            );
        }
        let predicted = repeating_spectrum(q, sigma, &speed);
        // the repeating error by Monte Carlo over the noise
        let draws = 400;
        let mut seed = 11u64;
        let mut mean_err = vec![0.0; n];
        for _ in 0..draws {
            for (i, xi) in x.iter().enumerate() {
                // Gaussian by the sum of 12 uniforms
                let g: f64 = (0..12).map(|_| lcg(&mut seed)).sum::<f64>() - 6.0;
                let noisy = xi + sigma * g;
                mean_err[i] += ((noisy / q).round() * q - noisy) / draws as f64;
            }
        }
        let mut planner = RealFftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(n);
        let mut spec = fft.make_output_vec();
        fft.process(&mut mean_err.clone(), &mut spec).unwrap();
        // white-equivalent per line: |E(l)|² (1/n-scaled, both sides) times n/2
        let measured: Vec<f64> = spec
            .iter()
            .map(|e| 2.0 * (e / n as f64).norm_sqr() * n as f64 / 2.0)
            .collect();
        let even = repeating_variance(q, sigma);
        let mut lo = 4;
        let mut far_from_even = 0;
        while 2 * lo <= n / 2 {
            let band = lo..2 * lo;
            let m: f64 = measured[band.clone()].iter().sum();
            let p: f64 = predicted[band.clone()].iter().sum();
            let e = even * band.len() as f64;
            // the quasi-static limit is coarse where the instantaneous frequency is low (near
            // the turning points: 0.53 of the measured power at lines 8-16) and close where
            // the motion crosses many counts per cycle of the line (within 3 % above 64)
            let tol = if lo >= 64 { 0.1 } else { 2f64.ln() };
            assert!(
                (p / m).ln().abs() < tol,
                "lines {band:?}: predicted {p:e}, measured {m:e}"
            );
            if (e / m).ln().abs() > 1.0 {
                far_from_even += 1;
            }
            lo *= 2;
        }
        assert!(
            far_from_even >= 3,
            "the even spread was not far off: {far_from_even} bands"
        );
    }
}
