//! How much of an encoder's quantisation error two periods share when the axis wanders
//! slowly between them.
//!
//! [`super::quantisation`] splits the error `e = Q(x) - x` of a periodic record into a part
//! that repeats from period to period (it does not average) and a part the period-to-period
//! scatter holds, and takes the noise `σ` that decides the split from that scatter. That
//! holds when the motion differs between periods by noise that is new at every sample. A
//! free axis also *wanders*: the process noise moves it by a few counts from one period to
//! the next, slowly, so that within a period the offset between two periods `p`, `p'` is
//! nearly constant, `δ_pp'(t)`. Two periods then share the error to the degree the
//! sawtooth at `x` and at `x + δ` agree, which depends on `δ` modulo a count, not on how
//! many counts the axis wandered. The recorded scatter (several counts) called that
//! non-repeating, although periods whose offsets differ by nearly whole counts carry
//! nearly the same error: on a world record with about one count of motion per sample the
//! errors of consecutive periods were correlated 0.10-0.24 and the lines' `z²` against
//! the true response averaged 1.95 where noise alone gives 1.33.
//!
//! **The covariance of two periods' errors.** With the sawtooth's series
//! `e(x) = Σ_k (-1)^k q/(π k) sin(2π k x/q)`, the motion spread evenly within a count, and
//! independent Gaussian noise of standard deviation `σ` at every sample of either period,
//!
//! `E[e_p e_p'] = Σ_k q²/(2π² k²) · cos(2π k δ/q) · exp(-4π² k² σ²/q²)`,
//!
//! `q²/12` for `p = p'` (one sample's own error). At `δ = 0` this is
//! [`super::quantisation::repeating_variance`].
//!
//! **What the scatter misses.** For periods whose errors have covariance `C` (a `P x P`
//! matrix), the variance of their mean is `ΣC/P²` and the sample variance over periods
//! estimates `(tr C - ΣC/P)/(P - 1)`, a `P`-th of which the estimator reports; the
//! difference is the mean covariance of two distinct periods,
//! `c̄ = Σ_(p≠p') C_pp' / (P (P - 1))`: the power that must be added to a line's variance
//! as a repeating error ([`super::quantisation::line_variance`]). Harmonic `k` of the
//! sawtooth adds `q²/(2π² k²) · g_k` with the *gain*
//!
//! `g_k = exp(-4π² k² σ²/q²) · mean_(p≠p') mean_t cos(2π k δ_pp'(t)/q)`,
//!
//! which is `exp(-4π² k² σ²/q²)` (the repeating part of [`super::quantisation`]) when the
//! periods do not wander, and about zero when their offsets spread over the count. A
//! negative mean covariance (the scatter overstates the variance of the mean) is not
//! subtracted: the floor only adds.
//!
//! **The offsets and the noise.** The deviation of each period from the periods' mean is
//! split into a slow part, its moving average over [`SLOW_WIDTH`] samples (`δ_pp'(t)` is
//! the difference of two slow parts), and the fast rest, whose pooled scatter `S_f` holds
//! the noise and the error's non-shared part: `S_f² = σ² + q²/12 - c̄(σ)` (at `δ = 0` the
//! relation of [`super::quantisation::noise_std_from_scatter`]), increasing in `σ`, solved
//! by bisection ([`PeriodOffsets::noise_std`]).
//!
//! **Its bias.** The offsets are read through the average of the non-shared error over
//! the window, a blur of standard deviation `s`, `s² ≈ 2 S_f²/W`. Between the counts the
//! covariance is the parabola `q²/12 - u(1-u) q²/2` (`u` the offset's fraction of a
//! count), convex with curvature 1, so the blur raises it by `s²/2 ≈ S_f²/W` (at most
//! about `(q²/12 + σ²)/W`, 2.9 % of the whole error's power at `W = 35`); at whole counts
//! (offsets that share everything) the cusp is lowered by about `0.4 s q`. Both are
//! small against the sharing that matters (a tenth to a half of the error's power).

use std::f64::consts::PI;

/// Width of the moving average that separates the slow wander from the fast rest
/// [samples]: the smallest odd width whose average of a white error of variance `q²/12`
/// has a standard deviation below a twentieth of a count (`q / sqrt(12 W) <= q/20`,
/// `W >= 34`), so that the offsets are known to a twentieth of a count (the first
/// harmonic's `cos(2π δ/q)` then moves by at most 5 %), and short, so that it follows a
/// wander that the process noise changes within a tenth of a period. On two world records
/// (one and a tenth of a count per sample) the covariances it predicts between the five
/// periods matched those of the errors against the true response (for example 0.34 / 0.38
/// / 0.39 predicted, 0.39 / 0.37 / 0.26 measured); 201 samples missed the wander (0.04 /
/// 0.17 / 0.21). Where the motion stays within a count for many samples (a slow sine's
/// turning points) the error is not white and its average reads as a shared offset: the
/// estimate then errs on the side of sharing, more variance (unit test
/// `slow_motion_errs_on_the_side_of_sharing`).
pub const SLOW_WIDTH: usize = 35;

/// Harmonics of the sawtooth summed: the undamped series' tail beyond `K` holds `1/K` of
/// `Σ 1/k²`, 0.4 % at 256.
pub const HARMONICS: usize = 256;

/// Every how many samples the offsets are read [samples] (the moving average varies little
/// within a twentieth of its width).
const STRIDE: usize = 10;

/// The periods' slow offsets, reduced to what the covariances need.
#[derive(Debug, Clone, PartialEq)]
pub struct PeriodOffsets {
    /// Grid step `q` [signal unit].
    pub q: f64,
    /// `mean_(p≠p') mean_t cos(2π k δ_pp'(t)/q)` for `k = 1 ..= HARMONICS` (index `k-1`).
    pub mean_cos: Vec<f64>,
    /// Pooled period-to-period scatter of the fast rest [signal unit] (normalised by
    /// `P - 1`, as [`super::quantisation::scatter_std`]).
    pub fast_scatter: f64,
    /// Periods.
    pub periods: usize,
}

impl PeriodOffsets {
    /// From `periods` periods of `period_samples` samples of a quantised record `x` (from
    /// its start) on a grid of step `q`. `None` with fewer than 2 periods, a period
    /// shorter than three moving-average widths, or a step that is not positive.
    pub fn measure(x: &[f64], period_samples: usize, periods: usize, q: f64) -> Option<Self> {
        let n = period_samples;
        // an odd width, at most a third of the period
        let width = (SLOW_WIDTH.min(n / 3) | 1).max(3);
        if periods < 2 || n < 9 || x.len() < periods * n || !(q > 0.0) {
            return None;
        }
        let mean: Vec<f64> = (0..n)
            .map(|i| (0..periods).map(|p| x[p * n + i]).sum::<f64>() / periods as f64)
            .collect();
        let half = width / 2;
        // slow part of each period's deviation (centred moving average, samples whose
        // window lies inside the period), and the fast rest's scatter on those samples
        let inner = half..n - half;
        let mut slow = vec![vec![0.0; n]; periods];
        let mut fast_acc = 0.0;
        for (p, s) in slow.iter_mut().enumerate() {
            let dev = |i: usize| x[p * n + i] - mean[i];
            let mut run: f64 = (0..width).map(dev).sum();
            for i in inner.clone() {
                if i > half {
                    run += dev(i + half) - dev(i - half - 1);
                }
                s[i] = run / width as f64;
            }
        }
        for i in inner.clone() {
            let slow_mean = slow.iter().map(|s| s[i]).sum::<f64>() / periods as f64;
            for (p, s) in slow.iter().enumerate() {
                // the fast rest of the deviation, itself centred over the periods
                let fast = (x[p * n + i] - mean[i]) - (s[i] - slow_mean);
                fast_acc += fast * fast;
            }
        }
        let samples = inner.len();
        let fast_scatter = (fast_acc / (samples * (periods - 1)) as f64).sqrt();
        // mean over ordered pairs of distinct periods and over time of cos(2π k δ/q), by
        // the Chebyshev recurrence cos(kθ) = 2 cos θ cos((k-1)θ) - cos((k-2)θ)
        let mut mean_cos = vec![0.0; HARMONICS];
        let mut terms = 0usize;
        for a in 0..periods {
            for b in a + 1..periods {
                for i in inner.clone().step_by(STRIDE) {
                    let theta = 2.0 * PI * (slow[a][i] - slow[b][i]) / q;
                    let c1 = theta.cos();
                    let (mut prev, mut cur) = (1.0, c1);
                    for m in mean_cos.iter_mut() {
                        *m += cur;
                        let next = 2.0 * c1 * cur - prev;
                        prev = cur;
                        cur = next;
                    }
                    terms += 1;
                }
            }
        }
        if terms == 0 {
            return None;
        }
        for m in mean_cos.iter_mut() {
            *m /= terms as f64;
        }
        Some(Self {
            q,
            mean_cos,
            fast_scatter,
            periods,
        })
    }

    /// The gains `g_k`, `k = 1 ..= HARMONICS`, at noise `sigma` (see the module's
    /// documentation).
    pub fn gains(&self, sigma: f64) -> Vec<f64> {
        let damp = 4.0 * PI * PI * (sigma / self.q).powi(2);
        self.mean_cos
            .iter()
            .enumerate()
            .map(|(i, m)| {
                let k2 = ((i + 1) * (i + 1)) as f64;
                (-damp * k2).exp() * m
            })
            .collect()
    }

    /// The mean covariance of two distinct periods' errors `c̄(σ)` [(signal unit)²],
    /// `Σ_k q²/(2π² k²) g_k`.
    pub fn mean_cross_covariance(&self, sigma: f64) -> f64 {
        let c = self.q * self.q / (2.0 * PI * PI);
        self.gains(sigma)
            .iter()
            .enumerate()
            .map(|(i, g)| c / ((i + 1) * (i + 1)) as f64 * g)
            .sum()
    }

    /// The noise behind the counts [signal unit]: the root of
    /// `S_f² = σ² + q²/12 - c̄(σ)` on `[0, S_f]` by bisection (0 when the fast scatter is
    /// below what the error alone gives).
    pub fn noise_std(&self) -> f64 {
        let target = self.fast_scatter * self.fast_scatter;
        let q2 = self.q * self.q / 12.0;
        let recorded = |s: f64| s * s + q2 - self.mean_cross_covariance(s);
        if !(target > 0.0) || recorded(0.0) >= target {
            return 0.0;
        }
        super::quantisation::root_of_increasing(recorded, target, self.fast_scatter)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::quantisation::repeating_variance;
    use crate::frf::test_rng::lcg;

    fn gauss(state: &mut u64) -> f64 {
        // Box-Muller from two uniforms in [0, 1)
        let (u1, u2) = (lcg(state).max(1e-300), lcg(state));
        (-2.0 * u1.ln()).sqrt() * (2.0 * PI * u2).cos()
    }

    /// A motion of `scale` times about one count per sample, `periods` periods, each shifted by its own
    /// constant offset [counts], noise `sigma` [counts] new at every sample, quantised
    /// with `floor` at a random position within the count.
    fn record(offsets: &[f64], n: usize, sigma: f64, seed: u64) -> Vec<f64> {
        record_scaled(offsets, n, sigma, seed, 4.0)
    }

    fn motion(t: f64, scale: f64) -> f64 {
        scale * (60.0 * (2.0 * PI * 3.0 * t).sin() + 25.0 * (2.0 * PI * 17.0 * t).cos())
    }

    fn record_scaled(offsets: &[f64], n: usize, sigma: f64, seed: u64, scale: f64) -> Vec<f64> {
        let mut r = seed;
        let phase = lcg(&mut r);
        let mut x = Vec::with_capacity(offsets.len() * n);
        for &o in offsets {
            for i in 0..n {
                let v = motion(i as f64 / n as f64, scale) + o + phase + sigma * gauss(&mut r);
                x.push(v.round());
            }
        }
        x
    }

    /// The mean covariance of distinct periods' errors over `runs` records of motion
    /// `scale` (measured from the errors themselves: quantised minus unquantised, the same
    /// draws) and as [`PeriodOffsets`] predicts it from the quantised records alone.
    fn measured_and_predicted(offsets: &[f64], sigma: f64, scale: f64) -> (f64, f64) {
        let n = 2000;
        let runs = 40;
        let (mut measured, mut predicted) = (0.0, 0.0);
        for run in 0..runs {
            let x = record_scaled(offsets, n, sigma, 100 + run, scale);
            let mut r = 100 + run;
            let phase = lcg(&mut r);
            let mut e = Vec::with_capacity(x.len());
            for (p, &o) in offsets.iter().enumerate() {
                for i in 0..n {
                    let v = motion(i as f64 / n as f64, scale) + o + phase + sigma * gauss(&mut r);
                    e.push(x[p * n + i] - v);
                }
            }
            let (mut s, mut c) = (0.0, 0);
            for a in 0..offsets.len() {
                for b in 0..offsets.len() {
                    if a != b {
                        s += (0..n).map(|i| e[a * n + i] * e[b * n + i]).sum::<f64>() / n as f64;
                        c += 1;
                    }
                }
            }
            measured += s / c as f64 / runs as f64;
            let po = PeriodOffsets::measure(&x, n, offsets.len(), 1.0).unwrap();
            predicted += po.mean_cross_covariance(sigma) / runs as f64;
        }
        (measured, predicted)
    }

    /// The covariance formula against the errors themselves, for a motion of a few counts
    /// per sample (a white error): the mean over pairs of `(1/N) Σ_t e_p e_p'` over many
    /// records against `c̄(σ)` from the quantised records, which exceeds it by the blur's
    /// bias, at most `(1/12 + σ²)/W` (module documentation), and is not below it.
    #[test]
    fn mean_cross_covariance_matches_the_errors() {
        let offsets = [0.0, 0.1, 2.3, 4.05, 7.5];
        for sigma in [0.0, 0.1, 0.3] {
            let (measured, predicted) = measured_and_predicted(&offsets, sigma, 4.0);
            let bias = (1.0 / 12.0 + sigma * sigma) / SLOW_WIDTH as f64;
            // Monte Carlo scatter of 40 records: 0.002 of one sample's error power
            assert!(
                predicted - measured > -0.002 / 12.0 && predicted - measured < 1.2 * bias,
                "sigma {sigma}: measured {measured:.5}, predicted {predicted:.5}, bias bound {bias:.5}"
            );
        }
    }

    /// A motion that stays within a count for tens of samples at its turning points (half
    /// a count per sample on average): the moving average reads part of the error as a
    /// shared offset, and the prediction errs on the side of sharing (more variance, not
    /// less), by less than a third of one sample's error power.
    #[test]
    fn slow_motion_errs_on_the_side_of_sharing() {
        let offsets = [0.0, 0.1, 2.3, 4.05, 7.5];
        let (measured, predicted) = measured_and_predicted(&offsets, 0.0, 1.0);
        assert!(
            predicted >= measured && predicted - measured < 0.33 / 12.0,
            "measured {measured:.5}, predicted {predicted:.5}"
        );
    }

    /// Without wander the gains are the repeating part of `quantisation.rs` (the two
    /// derivations agree), and the noise recovered from the fast scatter is the noise put
    /// in.
    #[test]
    fn without_wander_it_is_the_repeating_variance() {
        let n = 4000;
        for sigma in [0.05, 0.2, 0.5] {
            let x = record(&[0.0; 5], n, sigma, 7);
            let po = PeriodOffsets::measure(&x, n, 5, 1.0).unwrap();
            let s = po.noise_std();
            assert!(
                (s - sigma).abs() < 0.1 * sigma + 0.01,
                "noise {sigma}: recovered {s}"
            );
            let c = po.mean_cross_covariance(sigma);
            let r = repeating_variance(1.0, sigma);
            // the cusp at whole counts lowered by the blur of the noise: by at most 0.4 s,
            // s² = 2 S_f²/W (module documentation)
            let s_blur = (2.0 * (sigma * sigma + 1.0 / 12.0 - r) / SLOW_WIDTH as f64).sqrt();
            assert!(
                c <= r + 1e-6 && r - c < 0.4 * s_blur,
                "sigma {sigma}: {c} vs repeating_variance {r} (blur {s_blur})"
            );
        }
    }

    /// Offsets of whole counts share the whole error; `P` offsets spread evenly over a
    /// count share `-1/(P-1)` of every harmonic not a multiple of `P` and all of those that
    /// are: `c̄ = q²/12 (1/P² - (1 - 1/P²)/(P - 1))`, -0.2 q²/12 for five periods.
    #[test]
    fn offsets_modulo_a_count_decide() {
        let n = 2000;
        let spread = record(&[0.0, 3.2, 6.4, 9.6, 12.8], n, 0.0, 3);
        let po = PeriodOffsets::measure(&spread, n, 5, 1.0).unwrap();
        let c = po.mean_cross_covariance(0.0);
        let p = 5.0_f64;
        let want = (1.0 / (p * p) - (1.0 - 1.0 / (p * p)) / (p - 1.0)) / 12.0;
        // raised by the blur's bias, at most (1/12)/W
        let bias = 1.0 / 12.0 / SLOW_WIDTH as f64;
        assert!(
            c >= want && c - want < 1.5 * bias,
            "spread offsets: {c} (want {want} + at most {bias})"
        );
        let whole = record(&[0.0, 3.0, 6.0, 9.0, 12.0], n, 0.0, 3);
        let po = PeriodOffsets::measure(&whole, n, 5, 1.0).unwrap();
        let c = po.mean_cross_covariance(0.0);
        assert!((c - 1.0 / 12.0).abs() < 0.05 / 12.0, "whole counts: {c}");
    }
}
