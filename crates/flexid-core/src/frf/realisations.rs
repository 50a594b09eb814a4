//! The best linear approximation over several realisations of a multisine (Schoukens,
//! Pintelon & Rolain, *Mastering System Identification in 100 Exercises*, ch. 3; Pintelon
//! & Schoukens, *System Identification*, 2nd ed., ch. 3).
//!
//! Each realisation `r` is the same design (the same excited lines) with other random
//! phases, recorded for one steady period after its own lead-in. Per realisation and
//! excited line `k`, `G_r(k) = Y_r(k) / U_r(k)` (one period's DFT, no window: the period
//! is whole); the estimate is the mean over the `R` realisations,
//! `G(k) = (1/R) sum_r G_r(k)`, and its variance `sum_r |G_r - G|² / (R (R - 1))`.
//!
//! **What that variance holds.** The realisations differ in their phases, so the output of
//! a nonlinear system differs from `G U_r` by a *stochastic nonlinear distortion* that is
//! uncorrelated with the input and behaves, over realisations, like noise. The spread of
//! `G_r` is therefore noise **plus** that distortion: the variance of the best linear
//! approximation (what a linear model of the system can be asked to fit), not of the
//! noise. A nonlinear model simulated on the same realisations reproduces their
//! distortion, so it is judged against the noise alone:
//!
//! **The noise alone** comes from each realisation's lead-in: the generator played the
//! period's last `L` samples before the period, so once the transient has settled (the
//! second half of the lead-in) the output there and one period later differ by noise
//! only. The differences `(y[n] - y[n + P]) / sqrt(2)` (and the input's likewise) of every
//! realisation are cut into Hann-windowed segments (half overlapping) whose averaged
//! periodogram is the noise's spectrum per sample, `S(f)` (for white noise of variance
//! `σ²` it is `σ²` at every bin); a line of one period's `1/P`-scaled DFT then has the
//! noise variance `S(f)/P`, and the mean's noise variance at line `k` is
//! `(1/R²) sum_r (S_y + |G|² S_u) / (P |U_r|²)` (input and output noise taken as
//! uncorrelated). Without a lead-in no noise estimate is made.
//!
//! **Distortion at the non-excited lines** ([`NonExcitedLevels`]): for every line from the
//! lowest excited one to just below Nyquist that is not excited (in the band: even lines
//! of an odd design show even distortion; above the band, where an odd design that
//! excites every odd line puts the odd distortion of a cubic term), the output's power per
//! realisation, `mean_r |Y_r(k)|²`, against the noise's `S_y(f)/P`, both divided by `R`
//! (the `periods` field is `R`), so that their ratio is the distortion-to-noise ratio of
//! one realisation (about 1 for a linear system).
//!
//! The FFT is planned once for the period and once for the noise segments.

use super::error::{check_fs, FrfError};
use super::periodic::NonExcitedLevels;
use super::types::{Frf, FrfKind};
use crate::excitation::Realisation;
use num_complex::Complex64;
use realfft::RealFftPlanner;

/// Longest noise segment [samples]: a power of two, at most a quarter of the period; the
/// noise stretches are cut into segments of the largest power of two that fits the
/// shortest stretch, up to this (a finer resolution than the noise's spectrum needs
/// would cost averages).
const MAX_NOISE_SEGMENT: usize = 256;
/// Shortest noise segment [samples]: below it the spectrum's resolution (fs/16) is too
/// coarse to follow a noise that falls with frequency.
const MIN_NOISE_SEGMENT: usize = 16;

/// The estimate over realisations.
#[derive(Debug, Clone)]
pub struct RealisationsEstimate {
    /// The best linear approximation on the excited lines, its variance from the spread
    /// over realisations (noise and stochastic nonlinear distortion, see the module).
    pub frf: Frf,
    /// The variance of `frf.h` from the noise alone, per line (`None` without a lead-in
    /// long enough for one noise segment).
    pub noise_var: Option<Vec<f64>>,
    /// Noise segments averaged for [`Self::noise_var`] (over all realisations).
    pub noise_segments: usize,
    /// Output levels at the non-excited lines against the noise (see the module).
    pub nonexcited: Option<NonExcitedLevels>,
    /// Realisations used.
    pub realisations: usize,
}

/// Estimate the best linear approximation of `y` over `u` from `realisations`, each one
/// steady period of `period` samples at its `start` (see the module's documentation).
/// `lines`: the excited lines of a period (`0 < k <= period/2`).
///
/// Errors: lengths differ, a realisation outside the record, fewer than 2 realisations,
/// no lines, a line above Nyquist, a non-positive sample rate.
pub fn estimate_realisations(
    u: &[f64],
    y: &[f64],
    fs: f64,
    period: usize,
    realisations: &[Realisation],
    lines: &[usize],
    kind: FrfKind,
) -> Result<RealisationsEstimate, FrfError> {
    check_fs(fs)?;
    if u.len() != y.len() {
        return Err(FrfError::LengthMismatch {
            u: u.len(),
            y: y.len(),
        });
    }
    if period < 2 {
        return Err(FrfError::invalid(
            "period_samples",
            format!("{period}: a period needs at least 2 samples"),
        ));
    }
    if realisations.len() < 2 {
        return Err(FrfError::TooShort {
            needed: 2,
            got: realisations.len(),
            unit: "realisations (the variance is their spread)",
        });
    }
    if let Some(r) = realisations
        .iter()
        .find(|r| r.start.checked_add(period).is_none_or(|e| e > u.len()) || r.lead_in > r.start)
    {
        return Err(FrfError::invalid(
            "realisations",
            format!(
                "a realisation at row {} (lead-in {}) with a period of {period} samples does not fit the {} rows",
                r.start,
                r.lead_in,
                u.len()
            ),
        ));
    }
    let mut lines: Vec<usize> = lines.to_vec();
    lines.sort_unstable();
    lines.dedup();
    lines.retain(|&k| k > 0);
    if lines.is_empty() {
        return Err(FrfError::NoExcitedLines);
    }
    let nyq = period / 2;
    if let Some(&k) = lines.iter().find(|&&k| k > nyq) {
        return Err(FrfError::LineOutOfRange { line: k, max: nyq });
    }

    // one period's spectrum per realisation, 1/P scaled
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(period);
    let mut buf = fft.make_input_vec();
    let mut spec = fft.make_output_vec();
    let mut scratch = fft.make_scratch_vec();
    let scale = 1.0 / period as f64;
    let mut dft = |x: &[f64], out: &mut Vec<Complex64>| {
        buf.copy_from_slice(x);
        // the lengths are the plan's own: it cannot fail
        let _ = fft.process_with_scratch(&mut buf, &mut spec, &mut scratch);
        out.clear();
        out.extend(spec.iter().map(|c| c * scale));
    };
    let r_count = realisations.len();
    let mut su: Vec<Vec<Complex64>> = Vec::with_capacity(r_count);
    let mut sy: Vec<Vec<Complex64>> = Vec::with_capacity(r_count);
    for r in realisations {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        dft(&u[r.start..r.start + period], &mut a);
        dft(&y[r.start..r.start + period], &mut b);
        su.push(a);
        sy.push(b);
    }

    let rf = r_count as f64;
    let mut h = Vec::with_capacity(lines.len());
    let mut var = Vec::with_capacity(lines.len());
    for &k in &lines {
        let g: Vec<Complex64> = (0..r_count).map(|r| sy[r][k] / su[r][k]).collect();
        let mean = g.iter().sum::<Complex64>() / rf;
        let spread = g.iter().map(|v| (v - mean).norm_sqr()).sum::<f64>();
        h.push(mean);
        var.push(spread / (rf * (rf - 1.0)));
    }
    let freq_hz: Vec<f64> = lines
        .iter()
        .map(|&k| k as f64 * fs / period as f64)
        .collect();

    // the noise alone, from the second half of every lead-in
    let noise = noise_spectra(u, y, period, realisations, &mut planner);
    let noise_var = noise.as_ref().map(|n| {
        lines
            .iter()
            .zip(&h)
            .map(|(&k, g)| {
                let f = k as f64 / period as f64;
                let (s_u, s_y) = (n.at(&n.u, f), n.at(&n.y, f));
                (0..r_count)
                    .map(|r| (s_y + g.norm_sqr() * s_u) / (period as f64 * su[r][k].norm_sqr()))
                    .sum::<f64>()
                    / (rf * rf)
            })
            .collect()
    });
    let nonexcited = noise.as_ref().map(|n| {
        let excited: std::collections::BTreeSet<usize> = lines.iter().copied().collect();
        let idle: Vec<usize> = (lines[0]..nyq).filter(|k| !excited.contains(k)).collect();
        let level = |k: usize| sy.iter().map(|s| s[k].norm_sqr()).sum::<f64>() / rf / rf;
        let noise_at = |k: usize| n.at(&n.y, k as f64 / period as f64) / period as f64 / rf;
        NonExcitedLevels {
            freq_hz: idle
                .iter()
                .map(|&k| k as f64 * fs / period as f64)
                .collect(),
            mean_power_y: idle.iter().map(|&k| level(k)).collect(),
            noise_var_y: idle.iter().map(|&k| noise_at(k)).collect(),
            line: idle,
            excited_freq_hz: freq_hz.clone(),
            excited_line: lines.clone(),
            excited_noise_var_y: lines.iter().map(|&k| noise_at(k)).collect(),
            periods: r_count,
        }
    });
    Ok(RealisationsEstimate {
        frf: Frf {
            freq_hz,
            h,
            var,
            coherence: None,
            kind,
            sample_rate_hz: fs,
        },
        noise_var,
        noise_segments: noise.as_ref().map_or(0, |n| n.segments),
        nonexcited,
        realisations: r_count,
    })
}

/// The averaged periodograms of the input's and the output's noise ([`noise_spectra`]).
struct NoiseSpectra {
    /// Per bin `0..=W/2` of a segment of `W` samples: the noise's variance per sample and
    /// unit of normalised frequency (white noise of variance σ²: σ² everywhere).
    u: Vec<f64>,
    y: Vec<f64>,
    /// Segment length `W` [samples].
    w: usize,
    segments: usize,
}

impl NoiseSpectra {
    /// The spectrum `s` at normalised frequency `f` (cycles per sample), linearly
    /// interpolated between bins.
    fn at(&self, s: &[f64], f: f64) -> f64 {
        let x = (f * self.w as f64).clamp(0.0, (self.w / 2) as f64);
        let i = (x.floor() as usize).min(self.w / 2);
        let j = (i + 1).min(self.w / 2);
        let t = x - i as f64;
        s[i] * (1.0 - t) + s[j] * t
    }
}

/// The noise spectra from the second half of each realisation's lead-in (see the
/// module): `None` when the shortest such stretch holds no segment of
/// [`MIN_NOISE_SEGMENT`] samples.
fn noise_spectra(
    u: &[f64],
    y: &[f64],
    period: usize,
    realisations: &[Realisation],
    planner: &mut RealFftPlanner<f64>,
) -> Option<NoiseSpectra> {
    // stretch: rows start - lead_in/2 .. start, each compared with the row one period on
    let shortest = realisations.iter().map(|r| r.lead_in / 2).min()?;
    let mut w = MIN_NOISE_SEGMENT;
    if shortest < w {
        return None;
    }
    while 2 * w <= shortest && 2 * w <= MAX_NOISE_SEGMENT && 2 * w <= period / 4 {
        w *= 2;
    }
    let fft = planner.plan_fft_forward(w);
    let hann: Vec<f64> = (0..w)
        .map(|i| 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / w as f64).cos())
        .collect();
    let norm: f64 = hann.iter().map(|v| v * v).sum();
    let (mut pu, mut py) = (vec![0.0; w / 2 + 1], vec![0.0; w / 2 + 1]);
    let mut buf = fft.make_input_vec();
    let mut spec = fft.make_output_vec();
    let mut scratch = fft.make_scratch_vec();
    let mut segments = 0usize;
    for r in realisations {
        let from = r.start - r.lead_in / 2;
        let len = r.start - from;
        let mut s = 0;
        while s + w <= len {
            for (x, p) in [(u, &mut pu), (y, &mut py)] {
                let d: Vec<f64> = (0..w)
                    .map(|i| {
                        let n = from + s + i;
                        (x[n] - x[n + period]) / std::f64::consts::SQRT_2
                    })
                    .collect();
                // no mean removed: it would take a sixth of the noise's power from the
                // second bin too (the Hann window's main lobe); a slow drift between the
                // periods is noise of the lowest lines and stays there
                for ((b, v), hv) in buf.iter_mut().zip(&d).zip(&hann) {
                    *b = v * hv;
                }
                let _ = fft.process_with_scratch(&mut buf, &mut spec, &mut scratch);
                for (pk, c) in p.iter_mut().zip(&spec) {
                    *pk += c.norm_sqr() / norm;
                }
            }
            segments += 1;
            s += w / 2;
        }
    }
    if segments == 0 {
        return None;
    }
    for p in [&mut pu, &mut py] {
        p.iter_mut().for_each(|v| *v /= segments as f64);
        // the one-sided bins between DC and Nyquist carry the two-sided density once: the
        // periodogram |D_b|²/sum(h²) of white noise is σ² at every bin already
    }
    Some(NoiseSpectra {
        u: pu,
        y: py,
        w,
        segments,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frf::test_rng::lcg;

    /// Uniform and Gaussian draws from the shared test generator.
    struct Rng(u64);

    impl Rng {
        fn new(seed: u64) -> Self {
            Rng(seed)
        }
        fn uniform(&mut self) -> f64 {
            lcg(&mut self.0)
        }
        /// Box-Muller.
        fn normal(&mut self) -> f64 {
            let a = self.uniform().max(1e-300);
            let b = self.uniform();
            (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b).cos()
        }
    }

    /// A random-phase multisine on `lines` of a period of `p` samples, realisation `seed`.
    fn multisine(p: usize, lines: &[usize], rng: &mut Rng) -> Vec<f64> {
        let phases: Vec<f64> = lines
            .iter()
            .map(|_| rng.uniform() * 2.0 * std::f64::consts::PI)
            .collect();
        (0..p)
            .map(|n| {
                lines
                    .iter()
                    .zip(&phases)
                    .map(|(&k, ph)| {
                        (2.0 * std::f64::consts::PI * k as f64 * n as f64 / p as f64 + ph).cos()
                    })
                    .sum::<f64>()
            })
            .collect()
    }

    /// A record of `r` realisations: each the period's last `lead` samples, the period,
    /// and `gap` zeros; the realisations' descriptions.
    fn record(
        p: usize,
        lines: &[usize],
        r: usize,
        lead: usize,
        gap: usize,
        rng: &mut Rng,
    ) -> (Vec<f64>, Vec<Realisation>) {
        let mut u = vec![0.0; gap];
        let mut reals = Vec::new();
        for _ in 0..r {
            let x = multisine(p, lines, rng);
            u.extend_from_slice(&x[p - lead..]);
            reals.push(Realisation {
                start: u.len(),
                lead_in: lead,
            });
            u.extend_from_slice(&x);
            u.extend(std::iter::repeat_n(0.0, gap));
        }
        (u, reals)
    }

    /// A damped second-order system `y'' + 2ζω y' + ω² y = ω² u`, simulated by the exact
    /// discretisation of its impulse response sum (a direct IIR: the bilinear map is not
    /// needed, only some linear system the naive DFT sees the same).
    fn filter(u: &[f64]) -> Vec<f64> {
        // y[n] = a1 y[n-1] + a2 y[n-2] + b0 u[n] + b1 u[n-1]
        let (a1, a2, b0, b1) = (1.6, -0.8, 0.1, 0.1);
        let mut y = vec![0.0; u.len()];
        for n in 0..u.len() {
            let y1 = if n > 0 { y[n - 1] } else { 0.0 };
            let y2 = if n > 1 { y[n - 2] } else { 0.0 };
            let u1 = if n > 0 { u[n - 1] } else { 0.0 };
            y[n] = a1 * y1 + a2 * y2 + b0 * u[n] + b1 * u1;
        }
        y
    }

    fn filter_frf(k: usize, p: usize) -> Complex64 {
        let z1 = Complex64::from_polar(1.0, -2.0 * std::f64::consts::PI * k as f64 / p as f64);
        (0.1 + 0.1 * z1) / (1.0 - 1.6 * z1 + 0.8 * z1 * z1)
    }

    /// The naive DFT of one period, 1/P scaled.
    fn naive_dft(x: &[f64], k: usize) -> Complex64 {
        let p = x.len() as f64;
        x.iter()
            .enumerate()
            .map(|(n, v)| {
                Complex64::from_polar(*v, -2.0 * std::f64::consts::PI * k as f64 * n as f64 / p)
            })
            .sum::<Complex64>()
            / p
    }

    #[test]
    fn the_mean_and_spread_match_a_naive_dft() {
        let mut rng = Rng::new(7);
        let (p, lines) = (128, vec![1usize, 3, 5, 9, 13, 21]);
        let (u, reals) = record(p, &lines, 4, 40, 10, &mut rng);
        // a static nonlinearity makes the realisations' ratios differ
        let y: Vec<f64> = filter(&u).iter().map(|v| v + 0.05 * v * v * v).collect();
        let e = estimate_realisations(&u, &y, 100.0, p, &reals, &lines, FrfKind::Other).unwrap();
        for (i, &k) in lines.iter().enumerate() {
            let g: Vec<Complex64> = reals
                .iter()
                .map(|r| {
                    naive_dft(&y[r.start..r.start + p], k) / naive_dft(&u[r.start..r.start + p], k)
                })
                .collect();
            let m = g.iter().sum::<Complex64>() / 4.0;
            let v = g.iter().map(|x| (x - m).norm_sqr()).sum::<f64>() / 12.0;
            assert!((e.frf.h[i] - m).norm() < 1e-9 * m.norm(), "line {k}");
            assert!((e.frf.var[i] - v).abs() < 1e-9 * v, "line {k}");
            assert!((e.frf.freq_hz[i] - k as f64 * 100.0 / p as f64).abs() < 1e-12);
        }
        assert_eq!(e.realisations, 4);
    }

    #[test]
    fn a_linear_system_with_noise_has_the_variance_of_its_noise() {
        // Monte Carlo: R realisations of a linear system with white output noise; over many
        // records the estimate's error |G - G0|² averages to the variance from the spread
        // and to the variance from the lead-ins' noise, each within its Monte Carlo
        // tolerance (stated below)
        let (p, lines, r) = (256usize, vec![3usize, 7, 11, 17, 25, 37, 51], 6);
        let sigma = 0.02;
        let mut rng = Rng::new(11);
        let (mut err, mut spread, mut noise) = (0.0, 0.0, 0.0);
        let records = 200;
        let mut segments = 0;
        for _ in 0..records {
            let (u, reals) = record(p, &lines, r, 200, 30, &mut rng);
            let y: Vec<f64> = filter(&u)
                .iter()
                .map(|v| v + sigma * rng.normal())
                .collect();
            let e = estimate_realisations(&u, &y, 1.0, p, &reals, &lines, FrfKind::Other).unwrap();
            let nv = e.noise_var.as_ref().unwrap();
            segments = e.noise_segments;
            for (i, &k) in lines.iter().enumerate() {
                let g0 = filter_frf(k, p);
                // relative to the line's own expected variance, so that lines weigh alike
                let scale = nv[i];
                err += (e.frf.h[i] - g0).norm_sqr() / scale;
                spread += e.frf.var[i] / scale;
                noise += 1.0;
            }
        }
        let n = (records * lines.len()) as f64;
        let (err, spread) = (err / n, spread / n);
        // |G - G0|²/var is exponential with mean 1 per line (2 real dof): over n lines
        // its mean has a relative std of 1/sqrt(n) = 2.7 %; 4 sigma
        let tol = 4.0 / n.sqrt();
        assert!((err - 1.0).abs() < tol, "error/noise variance {err:.3}");
        // the spread's variance estimate (2(R-1) dof) averages to the same
        assert!(
            (spread - 1.0).abs() < tol,
            "spread/noise variance {spread:.3}"
        );
        assert!(noise > 0.0 && segments >= r);
    }

    #[test]
    fn nonexcited_lines_show_a_cubic_distortion_and_nothing_for_a_linear_system() {
        let mut rng = Rng::new(3);
        let p = 256;
        let lines: Vec<usize> = (1..40).filter(|k| k % 2 == 1).collect();
        let (u, reals) = record(p, &lines, 5, 120, 20, &mut rng);
        let lin = filter(&u);
        let excess = |y: &[f64]| {
            let e = estimate_realisations(&u, y, 1.0, p, &reals, &lines, FrfKind::Other).unwrap();
            let ne = e.nonexcited.unwrap();
            // above the band (odd lines of an odd design): where a cubic term shows
            let (pw, nv): (f64, f64) = ne
                .line
                .iter()
                .zip(ne.mean_power_y.iter().zip(&ne.noise_var_y))
                .filter(|(k, _)| **k > 40 && **k % 2 == 1)
                .fold((0.0, 0.0), |a, (_, (p, v))| (a.0 + p, a.1 + v));
            10.0 * (pw / nv).log10()
        };
        let noisy: Vec<f64> = lin.iter().map(|v| v + 0.01 * rng.normal()).collect();
        let cubic: Vec<f64> = lin
            .iter()
            .map(|v| v + 0.02 * v * v * v + 0.01 * rng.normal())
            .collect();
        let (a, b) = (excess(&noisy), excess(&cubic));
        assert!(a.abs() < 2.0, "linear: {a:.2} dB");
        assert!(b > 20.0, "cubic: {b:.2} dB");
    }

    #[test]
    fn bad_input_gives_errors_not_panics() {
        let u = vec![0.0; 100];
        let one = [Realisation {
            start: 10,
            lead_in: 4,
        }];
        let e = estimate_realisations(&u, &u, 1.0, 32, &one, &[1], FrfKind::Other);
        assert!(matches!(e, Err(FrfError::TooShort { .. })));
        let out = [
            Realisation {
                start: 10,
                lead_in: 4,
            },
            Realisation {
                start: 90,
                lead_in: 4,
            },
        ];
        assert!(estimate_realisations(&u, &u, 1.0, 32, &out, &[1], FrfKind::Other).is_err());
        let lead = [
            Realisation {
                start: 2,
                lead_in: 4,
            },
            Realisation {
                start: 40,
                lead_in: 4,
            },
        ];
        assert!(estimate_realisations(&u, &u, 1.0, 32, &lead, &[1], FrfKind::Other).is_err());
        let ok = [
            Realisation {
                start: 10,
                lead_in: 4,
            },
            Realisation {
                start: 50,
                lead_in: 4,
            },
        ];
        assert!(matches!(
            estimate_realisations(&u, &u, 1.0, 32, &ok, &[17], FrfKind::Other),
            Err(FrfError::LineOutOfRange { .. })
        ));
        assert!(estimate_realisations(&u, &u[..50], 1.0, 32, &ok, &[1], FrfKind::Other).is_err());
        assert!(estimate_realisations(&u, &u, f64::NAN, 32, &ok, &[1], FrfKind::Other).is_err());
    }
}
