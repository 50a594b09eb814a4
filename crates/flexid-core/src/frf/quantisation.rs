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
//! It is not divided by the number of periods: a repeating error does not average. Only
//! the repeating part counts, though: where the motion differs from period to period (noise,
//! drift) the error differs too and is already in the scatter. With a non-repeating
//! position part of standard deviation `σ` (Gaussian), the error's mean over that part is
//! the sawtooth's Fourier series `e(x) = Σ_k (-1)^k q/(π k) sin(2π k x/q)` with each
//! harmonic scaled by the characteristic function `exp(-2π² k² σ²/q²)`, so its power is
//!
//! `σ_q² = Σ_k q²/(2π² k²) · exp(-4π² k² σ²/q²)`
//!
//! (`q²/12` at `σ = 0`, `Σ 1/k² = π²/6`; already below 1e-3 of it at `σ = q/2`), and
//! `q²/12` above becomes `σ_q²` ([`repeating_variance`]).
//!
//! `σ` is not the scatter of the recorded (quantised) signal itself: with little noise a
//! sample either stays on its count or jumps a whole one, so the recorded scatter is far
//! larger than the noise behind it (noise of `0.05 q` scatters the counts by about
//! `0.2 q`, and `σ_q²` taken at `0.2 q` is five times too small). Averaged over where the
//! motion sits within a count, the recorded scatter's variance is that of the noise plus
//! the part of the error that does not repeat:
//!
//! `S² = σ² + q²/12 - σ_q²(σ)`,
//!
//! increasing in `σ` (0 at `σ = 0`, `σ² + q²/12` for `σ ≫ q`, Widrow's additive noise);
//! [`noise_std_from_scatter`] solves it for `σ`.

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

/// The power of the part of the quantisation error that repeats from period to period
/// [(signal unit)²], for a grid of step `q` and a non-repeating motion of standard
/// deviation `sigma` (both in the signal's units): `Σ_k q²/(2π²k²) exp(-4π²k²σ²/q²)`.
pub fn repeating_variance(q: f64, sigma: f64) -> f64 {
    let a = 4.0 * std::f64::consts::PI.powi(2) * (sigma / q).powi(2);
    let c = q * q / (2.0 * std::f64::consts::PI.powi(2));
    let mut sum = 0.0;
    for k in 1..=10_000u32 {
        let k2 = f64::from(k * k);
        let term = c / k2 * (-a * k2).exp();
        sum += term;
        // every later term is smaller; zero once the damping underflows (a motion of
        // many counts: without this the loop ran all its terms on zeros)
        if term < 1e-12 * sum || term == 0.0 {
            break;
        }
    }
    // the tail of the undamped series, sum over k > K of 1/k² ~ 1/K, when sigma = 0
    if a == 0.0 {
        sum += c / 10_000.0;
    }
    sum
}

/// The standard deviation [signal unit] of the noise behind a quantised record whose
/// period-to-period scatter is `scatter` on a grid of step `q`: the root of `S² = σ² +
/// q²/12 - σ_q²(σ)` (see the module's documentation), by bisection on `[0, S]` (the root
/// lies there: the error's non-repeating part only adds). `scatter` itself when `q` is
/// not positive.
pub fn noise_std_from_scatter(q: f64, scatter: f64) -> f64 {
    if !(q > 0.0 && scatter > 0.0 && scatter.is_finite()) {
        return scatter.max(0.0);
    }
    let recorded = |sigma: f64| sigma * sigma + q * q / 12.0 - repeating_variance(q, sigma);
    root_of_increasing(recorded, scatter * scatter, scatter)
}

/// The root in `[0, hi]` of `f(σ) = target` for `f` increasing in `σ`, by 60 bisections
/// (the recorded scatter as a function of the noise behind the counts, here and in
/// [`super::quantisation_correlation`]).
pub(crate) fn root_of_increasing(f: impl Fn(f64) -> f64, target: f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, hi);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f(mid) < target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The repeating power [(signal unit)²] of a quantised periodic record from its recorded
/// period-to-period scatter: [`repeating_variance`] at the noise
/// [`noise_std_from_scatter`] finds behind the scatter.
pub fn repeating_from_scatter(q: f64, scatter: f64) -> f64 {
    repeating_variance(q, noise_std_from_scatter(q, scatter))
}

/// Standard deviation of the non-repeating part of a periodic record: the period-to-period
/// scatter of each sample, pooled over the period. `x` holds `periods` periods of
/// `period_samples` samples from its start. `None` with fewer than 2 periods.
pub fn scatter_std(x: &[f64], period_samples: usize, periods: usize) -> Option<f64> {
    if periods < 2 || period_samples == 0 || x.len() < periods * period_samples {
        return None;
    }
    let n = period_samples;
    let mut acc = 0.0;
    for i in 0..n {
        let mean = (0..periods).map(|m| x[m * n + i]).sum::<f64>() / periods as f64;
        acc += (0..periods)
            .map(|m| (x[m * n + i] - mean).powi(2))
            .sum::<f64>();
    }
    Some((acc / (n * (periods - 1)) as f64).sqrt())
}

/// Bessel function of the first kind, order 1: its power series below 12, the
/// Hankel asymptotic expansion with two correction terms above (relative error below
/// 1e-5 there: ample for a variance).
pub fn bessel_j1(x: f64) -> f64 {
    let ax = x.abs();
    let v = if ax < 12.0 {
        // sum (-1)^m (x/2)^(2m+1) / (m! (m+1)!)
        let h = 0.5 * ax;
        let (mut term, mut sum) = (h, h);
        for m in 1..60 {
            term *= -h * h / (m as f64 * (m + 1) as f64);
            sum += term;
            if term.abs() < 1e-17 * sum.abs() {
                break;
            }
        }
        sum
    } else {
        let chi = ax - 0.75 * std::f64::consts::PI;
        let p = 1.0 + 0.1171875 / (ax * ax);
        let q = 0.375 / ax - 0.1025390625 / (ax * ax * ax);
        (2.0 / (std::f64::consts::PI * ax)).sqrt() * (p * chi.cos() - q * chi.sin())
    };
    if x < 0.0 {
        -v
    } else {
        v
    }
}

/// Mean power of the fundamental of a quantised tone's repeating count error: a tone of
/// amplitude `a` on a grid of step `q`, behind noise of standard deviation `sigma`, its
/// offset within a count unknown (uniform).
///
/// With `x = c + a sin θ` the sawtooth `e(x) = Σ_k (-1)^k q/(π k) sin(2π k x/q)` holds
/// `sin(φ_k + β_k sin θ)`, `β_k = 2π k a/q`, whose `sin θ` part is `2 J₁(β_k) cos φ_k`
/// (Jacobi-Anger): the error's fundamental is in phase with the tone (a gain error,
/// the quantiser's describing function), `E₁ = Σ_k (-1)^k 2q/(π k) J₁(β_k) cos φ_k`, each
/// term damped by the noise's characteristic function `exp(-2π² k² σ²/q²)` in the mean over
/// periods. Over a uniform offset the cross terms vanish:
///
/// `E[E₁²] = Σ_k 2q²/(π² k²) J₁(β_k)² exp(-4π² k² σ²/q²)` [(signal unit)²].
///
/// A single tone puts its whole error on a few harmonics, where white error spreads
/// `q²/12` over every line: for a tone of a few counts the fundamental's share is many
/// times the white floor's. Continuous time: with few samples per period the harmonics
/// that alias onto the fundamental add to it (not counted).
pub fn tone_error_power(q: f64, a: f64, sigma: f64) -> f64 {
    if !(q > 0.0 && a > 0.0) {
        return 0.0;
    }
    let damp = 4.0 * std::f64::consts::PI.powi(2) * (sigma / q).powi(2);
    let mut sum = 0.0;
    for k in 1..=20_000u32 {
        let kf = f64::from(k);
        let damping = (-damp * kf * kf).exp();
        if damping == 0.0 {
            // underflowed: this term and every later one are zero (noise of many counts;
            // without this the loop ran all its terms, Bessel functions and all, on zeros:
            // 9 % of a stepped sine's diagnosis)
            break;
        }
        let j = bessel_j1(2.0 * std::f64::consts::PI * kf * a / q);
        let term = 2.0 * q * q / (std::f64::consts::PI.powi(2) * kf * kf) * j * j * damping;
        sum += term;
        // the terms fall as 1/k³ at least; stop when the rest cannot matter
        if kf > 50.0 && term * kf < 1e-9 * sum {
            break;
        }
    }
    sum
}

/// The largest [`tone_error_power`] over the amplitudes a measured tone of amplitude
/// `measured` can have come from: the error's fundamental is at most `2q/π` (that of a
/// square wave of ±q/2, the largest error a count allows), so the true amplitude lies
/// within `2q/π` of the measured one. A tone measured near zero can be a tone of half a
/// count that the counts lost: its variance is that of the loss, not of a zero tone.
pub fn tone_error_power_bound(q: f64, measured: f64, sigma: f64) -> f64 {
    let r = 2.0 * q / std::f64::consts::PI;
    if measured > 2.0 * r {
        // well clear of a count: the measured amplitude is the tone's to within a count,
        // where the power varies slowly (as 1/a), and the bound would only widen it
        return tone_error_power(q, measured, sigma);
    }
    let (lo, hi) = ((measured - r).max(0.0), measured + r);
    (0..=16)
        .map(|i| tone_error_power(q, lo + (hi - lo) * i as f64 / 16.0, sigma))
        .fold(0.0, f64::max)
}

/// Adds to each line of a single sweep's estimate the variance of its count error as a
/// tone's ([`tone_error_power_bound`]): a sweep plays one tone at a time, so while it passes
/// a line the recorded motion is that tone, and the counts' error is a gain error of the
/// tone (the quantiser's describing function at the tone's amplitude), not white error
/// spread over every line. The tone's torque amplitude is `sqrt(2)` times the command's
/// RMS (a constant-amplitude sweep); its amplitude in the recorded signal at each line is
/// the line's response times that (`|H| / |D|`, `D` the differencing of a position). An
/// error `E₁` on the recorded tone is `E₁ |D| / a` on the line: `var += E[E₁²] |D|² / a²`.
pub fn add_sweep_tone_variance(frf: &mut super::Frf, q: f64, torque_cmd: &[f64]) {
    let n = torque_cmd.len().max(1) as f64;
    let a = (2.0 * torque_cmd.iter().map(|v| v * v).sum::<f64>() / n).sqrt();
    if !(a > 0.0 && q > 0.0) {
        return;
    }
    let fs = frf.sample_rate_hz;
    for i in 0..frf.freq_hz.len() {
        let d2 = differencing_gain2(frf.kind, frf.freq_hz[i], fs);
        let amplitude = frf.h[i].norm() / d2.sqrt() * a;
        let tone = tone_error_power_bound(q, amplitude, 0.0);
        let v = tone * d2 / (a * a);
        if v.is_finite() {
            frf.var[i] += v;
        }
    }
}

/// `|D(ω)|²` of the operator that turns the recorded signal into the estimator's output:
/// `fs (1 - e^(-jωT))` for a differenced position, 1 otherwise.
fn differencing_gain2(kind: FrfKind, freq_hz: f64, sample_rate_hz: f64) -> f64 {
    match kind {
        FrfKind::DifferencedVelocity => {
            let w = 2.0 * std::f64::consts::PI * freq_hz / sample_rate_hz;
            // |1 - e^{-jw}|² = 2 - 2 cos w
            sample_rate_hz * sample_rate_hz * (2.0 - 2.0 * w.cos())
        }
        _ => 1.0,
    }
}

/// The variance [(unit of H)²] that a repeating error of power `repeating_var` (in the
/// recorded signal's units², [`repeating_variance`]) adds to the FRF line at `freq_hz`
/// whose mean input over one period of `period_samples` samples is `u` (the `1/N`-scaled
/// DFT). `kind` says how the recorded signal became the estimator's output: a differenced
/// position passes the error through `fs (1 - e^(-jωT))`.
pub fn line_variance(
    repeating_var: f64,
    kind: FrfKind,
    freq_hz: f64,
    sample_rate_hz: f64,
    period_samples: usize,
    u: Complex64,
) -> f64 {
    let d2 = differencing_gain2(kind, freq_hz, sample_rate_hz);
    let v = repeating_var * d2 / period_samples as f64 / u.norm_sqr();
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::test_rng::lcg;

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

    #[test]
    fn bessel_j1_matches_known_values() {
        // tabulated values (Abramowitz & Stegun, table 9.1)
        for (x, want) in [
            (0.5, 0.242_268_457_7),
            (1.0, 0.440_050_585_7),
            (5.0, -0.327_579_137_6),
            (10.0, 0.043_472_746_2),
            (15.0, 0.205_104_038_5),
            (40.0, 0.126_038_318_1),
        ] {
            assert!(
                (bessel_j1(x) - want).abs() < 2e-6,
                "J1({x}) = {} vs {want}",
                bessel_j1(x)
            );
        }
        assert_eq!(bessel_j1(-1.0), -bessel_j1(1.0));
    }

    /// A quantised tone by Monte Carlo: uniform offsets, 256 samples per period, the
    /// fundamental of the mean error over the periods with noise behind the counts; its
    /// mean square against the series, for tones of a fraction of a count to several
    /// counts. With noise, 200 periods: the non-repeating part of the error then adds
    /// `2 S²/(n P)`, under 2 % of the repeating part (the series is that part only; the
    /// rest is in the estimator's period-to-period scatter).
    #[test]
    fn a_quantised_tone_has_the_error_power_of_the_series() {
        let (n, q) = (256usize, 1.0);
        let mut s = 23u64;
        for (a, sigma) in [
            (0.3, 0.0),
            (0.8, 0.0),
            (2.0, 0.0),
            (5.0, 0.0),
            (2.0, 0.15),
            (0.8, 0.3),
        ] {
            let (periods, trials) = if sigma > 0.0 { (200, 400) } else { (1, 1500) };
            let mut acc = 0.0;
            for _ in 0..trials {
                let c = lcg(&mut s) * q;
                let mut e1 = 0.0;
                for _ in 0..periods {
                    for i in 0..n {
                        let th = 2.0 * std::f64::consts::PI * i as f64 / n as f64;
                        let x = c + a * th.sin();
                        // Gaussian noise by Box-Muller from the shared generator
                        let g = if sigma > 0.0 {
                            let (u1, u2) = (lcg(&mut s).max(1e-300), lcg(&mut s));
                            sigma
                                * (-2.0 * u1.ln()).sqrt()
                                * (2.0 * std::f64::consts::PI * u2).cos()
                        } else {
                            0.0
                        };
                        let e = ((x + g) / q).round() * q - x;
                        e1 += e * th.sin();
                    }
                }
                let e1 = 2.0 * e1 / (n * periods) as f64;
                acc += e1 * e1;
            }
            let mc = acc / trials as f64;
            let want = tone_error_power(q, a, sigma);
            assert!(
                (want / mc - 1.0).abs() < 0.15,
                "a {a} q, sigma {sigma} q: series {want:.4e}, Monte Carlo {mc:.4e}"
            );
        }
        // a tone far beyond a count: the error's fundamental is a small part of the white floor's total
        assert!(tone_error_power(q, 200.0, 0.0) < 1e-3 * q * q / 12.0 * 100.0);
        // the bound over a tone measured at zero is that of a lost tone of about half a count
        let lost = tone_error_power_bound(q, 0.0, 0.0);
        assert!(lost >= tone_error_power(q, 0.4, 0.0), "{lost}");
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
        let v = line_variance(q * q / 12.0, FrfKind::DifferencedVelocity, f, fs, n, u);
        assert!((v / mc - 1.0).abs() < 0.08, "floor {v} vs Monte Carlo {mc}");
        // a larger input divides it
        let v2 = line_variance(
            q * q / 12.0,
            FrfKind::DifferencedVelocity,
            f,
            fs,
            n,
            2.0 * u,
        );
        assert!((v / v2 - 4.0).abs() < 1e-9);
        assert_eq!(
            line_variance(q, FrfKind::Velocity, f, fs, n, Complex64::new(0.0, 0.0)),
            0.0
        );
    }

    /// The repeating part against Monte Carlo: quantise a fixed value plus Gaussian noise of
    /// std sigma, average the error over the noise, and take the power of that mean over
    /// values spread across a count.
    #[test]
    fn the_repeating_part_fades_with_the_dither() {
        let q = 1.0;
        assert!((repeating_variance(q, 0.0) / (q * q / 12.0) - 1.0).abs() < 1e-3);
        let mut s = 3u64;
        for sigma in [0.1, 0.2, 0.3] {
            let (values, draws) = (200, 4000);
            let mut power = 0.0;
            for v in 0..values {
                let x = v as f64 / values as f64 * q;
                let mut mean = 0.0;
                for _ in 0..draws {
                    // Box-Muller
                    let (u1, u2) = (lcg(&mut s).max(1e-300), lcg(&mut s));
                    let n =
                        sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
                    let y = x + n;
                    mean += (y / q).round() * q - y;
                }
                mean /= draws as f64;
                power += mean * mean;
            }
            power /= values as f64;
            let model = repeating_variance(q, sigma);
            // Monte Carlo noise of the mean: q²/12 / draws per value
            let tol = 3.0 * (1.0 / 12.0) / draws as f64 + 0.1 * model;
            assert!(
                (power - model).abs() < tol,
                "sigma {sigma}: {power} vs {model}"
            );
        }
        assert!(repeating_variance(q, 0.5) < 1e-3 * repeating_variance(q, 0.0));
    }

    /// The noise behind a quantised periodic record, recovered from the scatter of the
    /// counts (Monte Carlo: a slow sine of many counts, its samples quantised with Gaussian
    /// noise period after period), where the scatter itself overstates small noise
    /// several times.
    #[test]
    fn the_noise_behind_the_counts_is_recovered_from_their_scatter() {
        let q = 1.0;
        let (n, periods) = (2000usize, 40usize);
        let mut s = 11u64;
        for sigma in [0.03, 0.1, 0.3, 1.0] {
            let mut x = Vec::with_capacity(n * periods);
            for _ in 0..periods {
                for k in 0..n {
                    let clean = 37.3 * (2.0 * std::f64::consts::PI * k as f64 / n as f64).sin();
                    let (u1, u2) = (lcg(&mut s).max(1e-300), lcg(&mut s));
                    let noise =
                        sigma * (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos();
                    x.push(((clean + noise) / q).round() * q);
                }
            }
            let scatter = scatter_std(&x, n, periods).unwrap();
            let found = noise_std_from_scatter(q, scatter);
            assert!(
                (found / sigma - 1.0).abs() < 0.1,
                "sigma {sigma}: scatter {scatter}, found {found}"
            );
            if sigma < 0.05 {
                assert!(scatter > 3.0 * sigma, "the scatter overstates small noise");
            }
        }
        assert_eq!(noise_std_from_scatter(q, 0.0), 0.0);
        assert!((noise_std_from_scatter(0.0, 0.4) - 0.4).abs() < 1e-15);
    }

    #[test]
    fn the_scatter_of_a_repeating_record_is_zero() {
        let x: Vec<f64> = (0..300).map(|k| ((k % 100) as f64).sin()).collect();
        assert!(scatter_std(&x, 100, 3).unwrap() < 1e-12);
        let y: Vec<f64> = x
            .iter()
            .enumerate()
            .map(|(k, v)| v + (k / 100) as f64)
            .collect();
        // period offsets 0, 1, 2: each sample's scatter is 1
        assert!((scatter_std(&y, 100, 3).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(scatter_std(&y, 100, 1), None);
    }
}
