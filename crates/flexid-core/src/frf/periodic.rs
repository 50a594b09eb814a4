//! Periodic (multisine) FRF estimator: per-line averaging over steady-state periods with the
//! errors-in-variables variance, plus the levels at non-excited lines (nonlinear distortion
//! detection).
//!
//! # Conventions
//!
//! * A period has `N = period_samples` samples; DFT line `k` is at `k * fs / N` Hz.
//! * Per-period spectra are the DFT of one period scaled by `1/N`,
//!   `X_p(k) = (1/N) sum_n x[pN + n] e^{-j 2 pi k n / N}`, so a cosine of amplitude `A` on
//!   line `0 < k < N/2` has `|X_p(k)| = A/2`. The FRF does not depend on this scaling; the
//!   levels in [`NonExcitedLevels`] do (units: (unit of y)^2).
//! * Statistics over periods are updated with Welford's algorithm after every completed
//!   period, so streaming costs one real FFT per signal per period and O(N) memory,
//!   independent of the number of periods.

use super::error::{check_fs, FrfError};
use super::types::{Frf, FrfKind};
use crate::excitation::ExcitationInfo;
use num_complex::Complex64;
use realfft::RealToComplex;
use std::sync::Arc;

/// Default relative threshold for inferring excited lines from the input spectrum.
pub const DEFAULT_INFER_THRESHOLD: f64 = 1e-6;

/// Running (Welford) statistics of one DFT line over the steady periods.
#[derive(Debug, Clone, Copy, Default)]
struct LineStats {
    /// Running mean of U_p(k).
    mu: Complex64,
    /// Running mean of Y_p(k).
    my: Complex64,
    /// Sum of squared deviations of U_p(k).
    m2u: f64,
    /// Sum of squared deviations of Y_p(k).
    m2y: f64,
    /// Sum of cross deviations (Y_p - mean Y) conj(U_p - mean U).
    m2yu: Complex64,
}

impl LineStats {
    /// Welford's update with one more period's line `u`, `y` (unscaled DFT values, times
    /// `scale`), `inv_p` = 1 / the periods so far including this one.
    #[inline(always)]
    fn update(&mut self, u: Complex64, y: Complex64, scale: f64, inv_p: f64) {
        let u = u * scale;
        let y = y * scale;
        let du = u - self.mu;
        self.mu += du * inv_p;
        let du_new = u - self.mu;
        let dy = y - self.my;
        self.my += dy * inv_p;
        let dy_new = y - self.my;
        self.m2u += du.re * du_new.re + du.im * du_new.im;
        self.m2y += dy.re * dy_new.re + dy.im * dy_new.im;
        self.m2yu += dy * du_new.conj();
    }
}

/// Output levels at the non-excited lines of a periodic experiment (and the noise level at
/// the excited ones), in (unit of y)^2 with the `1/N` DFT scaling of this module.
///
/// For a linear system with noise, `mean_power_y[i]` is about `noise_var_y[i]` (both are
/// levels *of the mean over periods*); coherent output well above it (say 10 dB and more)
/// at a non-excited line is nonlinear distortion: odd lines for odd (e.g. cubic)
/// nonlinearities, even lines for even ones.
#[derive(Debug, Clone, PartialEq)]
pub struct NonExcitedLevels {
    /// Frequencies of the non-excited lines \[Hz\] (ascending).
    pub freq_hz: Vec<f64>,
    /// DFT line indices of the non-excited lines within one period: every line strictly
    /// between the lowest and the highest excited line that is not excited.
    pub line: Vec<usize>,
    /// `|mean_p Y_p(k)|^2` at each non-excited line [(unit of y)^2].
    pub mean_power_y: Vec<f64>,
    /// Variance of the mean `mean_p Y_p(k)`: the sample variance of `Y_p(k)` over periods
    /// divided by the number of periods [(unit of y)^2]; `INFINITY` with fewer than 2
    /// periods.
    pub noise_var_y: Vec<f64>,
    /// Frequencies of the excited lines \[Hz\].
    pub excited_freq_hz: Vec<f64>,
    /// Excited line indices.
    pub excited_line: Vec<usize>,
    /// Variance of the mean output at each excited line (same definition as `noise_var_y`).
    pub excited_noise_var_y: Vec<f64>,
    /// Number of steady periods the statistics are taken over (multiply a variance of the
    /// mean by this to get the per-period variance).
    pub periods: usize,
}

/// The repeating quantisation error of the recorded motion, as a white-equivalent power
/// [(signal unit)²] ([`super::quantisation`]).
#[derive(Debug, Clone, PartialEq)]
enum RepeatingError {
    /// The same on every line (the error spread evenly).
    Even(f64),
    /// Per line `0..=N/2` (where the motion crosses counts).
    PerLine(Vec<f64>),
}

impl RepeatingError {
    fn at_line(&self, k: usize) -> f64 {
        match self {
            RepeatingError::Even(p) => *p,
            RepeatingError::PerLine(v) => v.get(k).copied().unwrap_or(0.0),
        }
    }
}

/// Streaming FRF estimator for periodic excitation.
///
/// Feed input (torque) and output samples with [`push`](Self::push) in chunks of any
/// length; the first `transient_periods` periods are discarded, and after every further
/// completed period the per-line running means and (co)variances of `U_p(k)`, `Y_p(k)`
/// are updated. A trailing incomplete period is held until completed.
///
/// The FFT plan and all buffers are allocated by the constructor; `push` does not allocate.
pub struct PeriodicEstimator {
    n: usize,
    fs: f64,
    kind: FrfKind,
    transient_periods: usize,
    /// Sorted, deduplicated excited lines; empty = infer from the input spectrum.
    lines: Vec<usize>,
    infer_threshold: f64,
    /// Power of the repeating quantisation error of the recorded motion signal (an
    /// encoder's counts), when known: added to each line's variance
    /// ([`super::quantisation`]).
    quantum: Option<RepeatingError>,
    fft: Arc<dyn RealToComplex<f64>>,
    buf_u: Vec<f64>,
    buf_y: Vec<f64>,
    fill: usize,
    spec_u: Vec<Complex64>,
    spec_y: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// Completed periods including the transient ones.
    periods_seen: usize,
    /// Statistics for lines 0..=N/2 over the steady periods.
    stats: Vec<LineStats>,
    /// `sum_m m Y_m(0)` over the steady periods `m = 0, 1, ...`: with the mean of `Y_m(0)`,
    /// the slope of the period means (a velocity ramp, see `ramp.rs`).
    dc_moment: f64,
    /// Statistics kept at line 0 and the given excited lines only
    /// ([`Self::excited_lines_only`]).
    excited_only: bool,
}

impl std::fmt::Debug for PeriodicEstimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PeriodicEstimator")
            .field("period_samples", &self.n)
            .field("sample_rate_hz", &self.fs)
            .field("kind", &self.kind)
            .field("transient_periods", &self.transient_periods)
            .field("excited_lines", &self.lines)
            .field("periods_done", &self.periods_done())
            .finish_non_exhaustive()
    }
}

impl PeriodicEstimator {
    /// Plan an estimator for periods of `period_samples` samples at `sample_rate_hz` \[Hz\].
    ///
    /// `excited_lines` are DFT line indices within one period (`0..=period_samples/2`,
    /// any order, duplicates ignored). If empty, the excited lines are inferred at
    /// [`estimate`](Self::estimate) time from the mean input spectrum: every line
    /// `1..=N/2` whose `|mean U(k)|` exceeds [`DEFAULT_INFER_THRESHOLD`] times the largest
    /// such value (see [`with_infer_threshold`](Self::with_infer_threshold)).
    ///
    /// Errors: `InvalidParameter` for `period_samples < 2` or a bad sample rate,
    /// `LineOutOfRange` for a line above `period_samples / 2`.
    pub fn new(
        period_samples: usize,
        excited_lines: &[usize],
        sample_rate_hz: f64,
        kind: FrfKind,
    ) -> Result<Self, FrfError> {
        check_fs(sample_rate_hz)?;
        if period_samples < 2 {
            return Err(FrfError::invalid(
                "period_samples",
                format!("must be at least 2, got {period_samples}"),
            ));
        }
        let max = period_samples / 2;
        let mut lines = excited_lines.to_vec();
        lines.sort_unstable();
        lines.dedup();
        if let Some(&line) = lines.last() {
            if line > max {
                return Err(FrfError::LineOutOfRange { line, max });
            }
        }
        let fft = super::plan_cache::forward(period_samples);
        let spec_u = fft.make_output_vec();
        let spec_y = fft.make_output_vec();
        let scratch = fft.make_scratch_vec();
        Ok(Self {
            n: period_samples,
            fs: sample_rate_hz,
            kind,
            transient_periods: 0,
            lines,
            infer_threshold: DEFAULT_INFER_THRESHOLD,
            quantum: None,
            fft,
            buf_u: vec![0.0; period_samples],
            buf_y: vec![0.0; period_samples],
            fill: 0,
            spec_u,
            spec_y,
            scratch,
            periods_seen: 0,
            stats: vec![LineStats::default(); max + 1],
            dc_moment: 0.0,
            excited_only: false,
        })
    }

    /// Plan an estimator from an excitation description (`period_samples`,
    /// `transient_periods`, `excited_lines`).
    pub fn from_info(
        info: &ExcitationInfo,
        sample_rate_hz: f64,
        kind: FrfKind,
    ) -> Result<Self, FrfError> {
        Ok(Self::new(
            info.period_samples,
            &info.excited_lines,
            sample_rate_hz,
            kind,
        )?
        .with_transient_periods(info.transient_periods))
    }

    /// Discard the first `periods` periods (transient). Set before the first `push`.
    pub fn with_transient_periods(mut self, periods: usize) -> Self {
        self.transient_periods = periods;
        self
    }

    /// The power of the repeating quantisation error of the recorded motion signal (for a
    /// differenced velocity, of the position) in its own units squared
    /// ([`super::quantisation::repeating_variance`]): each line's variance gets the floor of
    /// [`super::quantisation::line_variance`]. `None` (the default) adds nothing.
    pub fn with_quantum(mut self, repeating_var: Option<f64>) -> Self {
        self.quantum = repeating_var
            .filter(|q| q.is_finite() && *q > 0.0)
            .map(RepeatingError::Even);
        self
    }

    /// The repeating quantisation error as a white-equivalent power per line `0..=N/2`
    /// ([`super::quantisation_spectrum::repeating_spectrum`]: where a slow motion crosses
    /// counts), in place of [`Self::with_quantum`]'s even spread.
    pub fn with_quantum_spectrum(mut self, per_line: Option<Vec<f64>>) -> Self {
        self.quantum = per_line
            .filter(|v| v.len() == self.n / 2 + 1 && v.iter().all(|p| p.is_finite() && *p >= 0.0))
            .map(RepeatingError::PerLine);
        self
    }

    /// Keep the per-line statistics at line 0 (the ramp of a velocity) and the excited
    /// lines given to the constructor only, not at every line of the period: the estimate
    /// is the same to the bit, [`Self::nonexcited`] is then an error. For one line per
    /// period (a stepped sine's block, [`super::estimate_stepped`]), where updating all
    /// `N/2 + 1` lines took as long as the transforms. No effect when the lines are to be
    /// inferred.
    pub(crate) fn excited_lines_only(mut self) -> Self {
        self.excited_only = !self.lines.is_empty();
        self
    }

    /// Relative threshold for inferring excited lines when none were given (default
    /// [`DEFAULT_INFER_THRESHOLD`]). Raise it (e.g. to 1e-2) when the input is a measured
    /// torque with noise at the non-excited lines.
    pub fn with_infer_threshold(mut self, rel: f64) -> Self {
        self.infer_threshold = rel;
        self
    }

    /// Samples per period.
    pub fn period_samples(&self) -> usize {
        self.n
    }

    /// Number of completed steady-state periods (transient periods not counted).
    pub fn periods_done(&self) -> usize {
        self.periods_seen.saturating_sub(self.transient_periods)
    }

    /// Forget all data (keeps the plan, lines and settings).
    pub fn reset(&mut self) {
        self.fill = 0;
        self.periods_seen = 0;
        self.stats.fill(LineStats::default());
        self.dc_moment = 0.0;
    }

    /// Feed a chunk of input `u` and output `y` samples (equal lengths, any length;
    /// chunks may split periods anywhere). Does not allocate.
    pub fn push(&mut self, u: &[f64], y: &[f64]) -> Result<(), FrfError> {
        if u.len() != y.len() {
            return Err(FrfError::LengthMismatch {
                u: u.len(),
                y: y.len(),
            });
        }
        let mut pos = 0;
        while pos < u.len() {
            let take = (self.n - self.fill).min(u.len() - pos);
            if self.periods_seen >= self.transient_periods {
                let dst = self.fill..self.fill + take;
                self.buf_u[dst.clone()].copy_from_slice(&u[pos..pos + take]);
                self.buf_y[dst].copy_from_slice(&y[pos..pos + take]);
            }
            self.fill += take;
            pos += take;
            if self.fill == self.n {
                self.finish_period();
                self.fill = 0;
            }
        }
        Ok(())
    }

    fn finish_period(&mut self) {
        if self.periods_seen >= self.transient_periods {
            // The FFT input buffers are used as scratch by realfft: they are refilled anyway.
            self.fft
                .process_with_scratch(&mut self.buf_u, &mut self.spec_u, &mut self.scratch)
                .expect("buffer lengths fixed at construction");
            self.fft
                .process_with_scratch(&mut self.buf_y, &mut self.spec_y, &mut self.scratch)
                .expect("buffer lengths fixed at construction");
            let p = (self.periods_seen - self.transient_periods + 1) as f64;
            let inv_p = 1.0 / p;
            let scale = 1.0 / self.n as f64;
            self.dc_moment += (p - 1.0) * self.spec_y[0].re * scale;
            if self.excited_only {
                let (u, y) = (&self.spec_u, &self.spec_y);
                self.stats[0].update(u[0], y[0], scale, inv_p);
                for &k in self.lines.iter().filter(|&&k| k != 0) {
                    self.stats[k].update(u[k], y[k], scale, inv_p);
                }
            } else {
                for ((s, &u), &y) in self.stats.iter_mut().zip(&self.spec_u).zip(&self.spec_y) {
                    s.update(u, y, scale, inv_p);
                }
            }
        }
        self.periods_seen += 1;
    }

    /// The excited lines: as given to the constructor, or inferred from the mean input
    /// spectrum (needs at least one steady period).
    pub fn excited_lines(&self) -> Result<Vec<usize>, FrfError> {
        if !self.lines.is_empty() {
            return Ok(self.lines.clone());
        }
        self.require_period()?;
        let max_u = self.stats[1..]
            .iter()
            .map(|s| s.mu.norm())
            .fold(0.0_f64, f64::max);
        if max_u <= 0.0 || !max_u.is_finite() {
            return Err(FrfError::NoExcitedLines);
        }
        let thr = self.infer_threshold * max_u;
        Ok((1..self.stats.len())
            .filter(|&k| self.stats[k].mu.norm() > thr)
            .collect())
    }

    fn require_period(&self) -> Result<usize, FrfError> {
        let p = self.periods_done();
        if p == 0 {
            Err(FrfError::TooShort {
                needed: 1,
                got: 0,
                unit: "periods",
            })
        } else {
            Ok(p)
        }
    }

    /// Mean output at line `k` over the steady periods; for a velocity response, without
    /// the ramp of a constant acceleration (the same bias in every period; `ramp.rs`).
    fn mean_y(&self, k: usize, p: usize) -> Complex64 {
        let my = self.stats[k].my;
        if !matches!(self.kind, FrfKind::DifferencedVelocity | FrfKind::Velocity) {
            return my;
        }
        let slope = super::ramp::period_slope(self.dc_moment, self.stats[0].my.re, p);
        my - super::ramp::ramp_line(slope, k, self.n)
    }

    /// Variance of the mean output at line `k` (INFINITY with < 2 periods).
    fn var_mean_y(&self, k: usize, p: usize) -> f64 {
        if p < 2 {
            f64::INFINITY
        } else {
            self.stats[k].m2y / ((p - 1) as f64 * p as f64)
        }
    }

    /// The FRF at the excited lines: `H = mean Y / mean U` with the first-order
    /// errors-in-variables variance of the mean (Pintelon & Schoukens),
    /// `var H = (s2_Y + |H|^2 s2_U - 2 Re(conj(H) s2_YU)) / (P |mean U|^2)`
    /// `    = |H|^2 (s2_Y/|Y|^2 + s2_U/|U|^2 - 2 Re(s2_YU / (Y conj U))) / P`,
    /// where `s2` are the sample (co)variances over the `P` periods. `var` is `INFINITY`
    /// while `P < 2`.
    ///
    /// `coherence` (for `P >= 2`) is the coherence of the per-period spectra,
    /// `|S_yu|^2 / (S_uu S_yy)` with `S_xy = mean_p X_p conj(Y_p)` (what a rectangular-window
    /// Welch estimate with one segment per period would give): 1 without noise and about
    /// `SNR / (1 + SNR)` with output noise.
    ///
    /// Errors: `TooShort` before the first steady period, `NoExcitedLines`.
    pub fn estimate(&self) -> Result<Frf, FrfError> {
        let p = self.require_period()?;
        let lines = self.excited_lines()?;
        if lines.is_empty() {
            return Err(FrfError::NoExcitedLines);
        }
        let pf = p as f64;
        let df = self.fs / self.n as f64;
        let mut frf = Frf {
            freq_hz: Vec::with_capacity(lines.len()),
            h: Vec::with_capacity(lines.len()),
            var: Vec::with_capacity(lines.len()),
            coherence: (p >= 2).then(|| Vec::with_capacity(lines.len())),
            kind: self.kind,
            sample_rate_hz: self.fs,
        };
        for &k in &lines {
            let s = &self.stats[k];
            let my = self.mean_y(k, p);
            let h = my / s.mu;
            let var = if p < 2 {
                f64::INFINITY
            } else {
                let d = (p - 1) as f64;
                let (su, sy, syu) = (s.m2u / d, s.m2y / d, s.m2yu / d);
                let v =
                    (sy + h.norm_sqr() * su - 2.0 * (h.conj() * syu).re) / (pf * s.mu.norm_sqr());
                let floor = self.quantum.as_ref().map_or(0.0, |q| {
                    super::quantisation::line_variance(
                        q.at_line(k),
                        self.kind,
                        k as f64 * df,
                        self.fs,
                        self.n,
                        s.mu,
                    )
                });
                if v.is_nan() {
                    f64::INFINITY
                } else {
                    v.max(0.0) + floor
                }
            };
            frf.freq_hz.push(k as f64 * df);
            frf.h.push(h);
            frf.var.push(var);
            if let Some(c) = frf.coherence.as_mut() {
                let suu = s.mu.norm_sqr() + s.m2u / pf;
                let syy = my.norm_sqr() + s.m2y / pf;
                let syu = my * s.mu.conj() + s.m2yu / pf;
                let g = syu.norm_sqr() / (suu * syy);
                c.push(if g.is_finite() {
                    g.clamp(0.0, 1.0)
                } else {
                    0.0
                });
            }
        }
        Ok(frf)
    }

    /// Levels at every non-excited line between the lowest and highest excited line (even
    /// lines and odd detection lines alike), and the noise level at the excited lines.
    ///
    /// Errors: as [`estimate`](Self::estimate).
    pub fn nonexcited(&self) -> Result<NonExcitedLevels, FrfError> {
        if self.excited_only {
            return Err(FrfError::invalid(
                "nonexcited",
                "statistics kept at the excited lines only",
            ));
        }
        let p = self.require_period()?;
        let lines = self.excited_lines()?;
        let (Some(&lo), Some(&hi)) = (lines.first(), lines.last()) else {
            return Err(FrfError::NoExcitedLines);
        };
        let df = self.fs / self.n as f64;
        let mut out = NonExcitedLevels {
            freq_hz: Vec::new(),
            line: Vec::new(),
            mean_power_y: Vec::new(),
            noise_var_y: Vec::new(),
            excited_freq_hz: lines.iter().map(|&k| k as f64 * df).collect(),
            excited_line: lines.clone(),
            excited_noise_var_y: lines.iter().map(|&k| self.var_mean_y(k, p)).collect(),
            periods: p,
        };
        let mut next = lines.iter().peekable();
        for k in lo..=hi {
            if next.peek() == Some(&&k) {
                next.next();
                continue;
            }
            out.freq_hz.push(k as f64 * df);
            out.line.push(k);
            out.mean_power_y.push(self.mean_y(k, p).norm_sqr());
            out.noise_var_y.push(self.var_mean_y(k, p));
        }
        Ok(out)
    }
}

/// Batch periodic estimate over a whole record: discards `info.transient_periods`, uses
/// every complete period after them (`info.periods` is informational; a trailing partial
/// period is ignored) and the lines `info.excited_lines` (inferred when empty).
/// Bit-identical to streaming the same samples through [`PeriodicEstimator`].
///
/// Errors: `LengthMismatch`, `InvalidParameter` (`period_samples == 0`), `TooShort` (fewer
/// than `transient_periods + 1` periods), `LineOutOfRange`, `NoExcitedLines`.
pub fn estimate_periodic(
    u: &[f64],
    y: &[f64],
    info: &ExcitationInfo,
    fs: f64,
    kind: FrfKind,
) -> Result<Frf, FrfError> {
    if u.len() != y.len() {
        return Err(FrfError::LengthMismatch {
            u: u.len(),
            y: y.len(),
        });
    }
    let mut est = PeriodicEstimator::from_info(info, fs, kind)?;
    let needed = (info.transient_periods + 1) * info.period_samples;
    if u.len() < needed {
        return Err(FrfError::TooShort {
            needed,
            got: u.len(),
            unit: "samples",
        });
    }
    est.push(u, y)?;
    est.estimate()
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::excitation::ExcitationKind;
    use crate::frf::testutil::*;
    use crate::frf::velocity::{difference_quotient_response, differenced_velocity};
    use rand::Rng;

    fn info(n: usize, periods: usize, transient: usize, lines: &[usize]) -> ExcitationInfo {
        ExcitationInfo {
            kind: ExcitationKind::Multisine,
            period_samples: n,
            periods,
            transient_periods: transient,
            excited_lines: lines.to_vec(),
            band_hz: None,
            peak_nm: None,
            rms_nm: None,
            design: None,
            blocks: Vec::new(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }

    /// Straightforward reference: direct DFT of every steady period, two-pass mean and
    /// (co)variances, the textbook EIV formula.
    struct Naive {
        h: Vec<Complex64>,
        var: Vec<f64>,
        coh: Vec<f64>,
        /// (line, |mean Y|^2, var of mean Y) at every line 0..=N/2
        levels: Vec<(usize, f64, f64)>,
    }

    fn naive(u: &[f64], y: &[f64], n: usize, transient: usize, lines: &[usize]) -> Naive {
        let periods: Vec<usize> = (transient..u.len() / n).collect();
        let p = periods.len() as f64;
        let spec = |x: &[f64], k: usize| -> Vec<Complex64> {
            periods
                .iter()
                .map(|&q| dft_line(&x[q * n..(q + 1) * n], k) / n as f64)
                .collect()
        };
        let mut out = Naive {
            h: vec![],
            var: vec![],
            coh: vec![],
            levels: vec![],
        };
        for k in 0..=n / 2 {
            let us = spec(u, k);
            let ys = spec(y, k);
            let mu: Complex64 = us.iter().sum::<Complex64>() / p;
            let my: Complex64 = ys.iter().sum::<Complex64>() / p;
            let su: f64 = us.iter().map(|x| (x - mu).norm_sqr()).sum::<f64>() / (p - 1.0);
            let sy: f64 = ys.iter().map(|x| (x - my).norm_sqr()).sum::<f64>() / (p - 1.0);
            let syu: Complex64 = ys
                .iter()
                .zip(&us)
                .map(|(y, u)| (y - my) * (u - mu).conj())
                .sum::<Complex64>()
                / (p - 1.0);
            out.levels.push((k, my.norm_sqr(), sy / p));
            if lines.contains(&k) {
                let h = my / mu;
                let var = h.norm_sqr()
                    * (sy / my.norm_sqr() + su / mu.norm_sqr() - 2.0 * (syu / (my * mu.conj())).re)
                    / p;
                let suu: f64 = us.iter().map(|x| x.norm_sqr()).sum::<f64>() / p;
                let syy: f64 = ys.iter().map(|x| x.norm_sqr()).sum::<f64>() / p;
                let cyu: Complex64 = ys
                    .iter()
                    .zip(&us)
                    .map(|(y, u)| y * u.conj())
                    .sum::<Complex64>()
                    / p;
                out.h.push(h);
                out.var.push(var);
                out.coh.push(cyu.norm_sqr() / (suu * syy));
            }
        }
        out
    }

    #[test]
    fn excited_lines_only_give_the_same_estimate_to_the_bit() {
        let n = 60;
        for lines in [vec![7usize], vec![1, 2, 3, 5, 11], vec![0, 4, 9]] {
            let mut r = rng(3);
            let per = multisine_period(n, &lines, &mut r);
            let mut u = tile(&per, 6);
            for (x, e) in u.iter_mut().zip(gauss(&mut r, 6 * n, 0.05)) {
                *x += e + 0.3;
            }
            let mut y = Biquad::resonator(0.9, 0.1).run(&u);
            for (x, e) in y.iter_mut().zip(gauss(&mut r, 6 * n, 0.02)) {
                *x += e;
            }
            for kind in [FrfKind::Other, FrfKind::DifferencedVelocity] {
                let est = |only: bool| {
                    let mut e = PeriodicEstimator::new(n, &lines, 100.0, kind)
                        .unwrap()
                        .with_transient_periods(2);
                    if only {
                        e = e.excited_lines_only();
                    }
                    // in two chunks that split a period
                    e.push(&u[..150], &y[..150]).unwrap();
                    e.push(&u[150..], &y[150..]).unwrap();
                    e
                };
                let (full, only) = (est(false), est(true));
                let (a, b) = (full.estimate().unwrap(), only.estimate().unwrap());
                let bits = |f: &Frf| -> Vec<u64> {
                    f.h.iter()
                        .flat_map(|h| [h.re.to_bits(), h.im.to_bits()])
                        .chain(f.var.iter().map(|v| v.to_bits()))
                        .chain(f.coherence.iter().flatten().map(|c| c.to_bits()))
                        .collect()
                };
                assert_eq!(bits(&a), bits(&b), "{lines:?} {kind:?}");
                assert!(full.nonexcited().is_ok());
                assert!(only.nonexcited().is_err());
            }
        }
    }

    #[test]
    fn fast_equals_naive_reference() {
        let n = 60; // not a power of two
        let lines = [1, 2, 3, 5, 7, 11, 13, 17];
        let mut r = rng(1);
        let per = multisine_period(n, &lines, &mut r);
        let mut u = tile(&per, 9);
        // input noise too, so that the U variance and the YU covariance enter the formula
        for (x, e) in u.iter_mut().zip(gauss(&mut r, 9 * n, 0.05)) {
            *x += e + 0.3; // and an offset (DC line)
        }
        let sys = Biquad::resonator(0.9, 0.1);
        let mut y = sys.run(&u);
        for (x, e) in y.iter_mut().zip(gauss(&mut r, 9 * n, 0.02)) {
            *x += e;
        }
        let mut est = PeriodicEstimator::new(n, &lines, 100.0, FrfKind::Other)
            .unwrap()
            .with_transient_periods(2);
        est.push(&u, &y).unwrap();
        assert_eq!(est.periods_done(), 7);
        let frf = est.estimate().unwrap();
        let nv = naive(&u, &y, n, 2, &lines);
        for i in 0..lines.len() {
            assert!((frf.freq_hz[i] - lines[i] as f64 * 100.0 / 60.0).abs() < 1e-12);
            assert!(rel_err(frf.h[i], nv.h[i]) < 1e-9, "line {}", lines[i]);
            assert!(
                (frf.var[i] - nv.var[i]).abs() <= 1e-9 * nv.var[i],
                "var line {}",
                lines[i]
            );
            let c = frf.coherence.as_ref().unwrap()[i];
            assert!((c - nv.coh[i]).abs() < 1e-9);
        }
        let ne = est.nonexcited().unwrap();
        assert_eq!(ne.line, vec![4, 6, 8, 9, 10, 12, 14, 15, 16]);
        for (i, &k) in ne.line.iter().enumerate() {
            let (_, pw, v) = nv.levels[k];
            assert!((ne.mean_power_y[i] - pw).abs() <= 1e-9 * pw.max(1e-12));
            assert!((ne.noise_var_y[i] - v).abs() <= 1e-9 * v);
        }
        for (i, &k) in ne.excited_line.iter().enumerate() {
            assert!((ne.excited_noise_var_y[i] - nv.levels[k].2).abs() <= 1e-9 * nv.levels[k].2);
        }
    }

    #[test]
    fn noise_free_estimate_equals_exact_frf() {
        let n = 512;
        let lines: Vec<usize> = (1..=150).collect();
        let mut r = rng(2);
        let per = multisine_period(n, &lines, &mut r);
        let u = tile(&per, 6);
        let sys = Biquad::resonator(0.97, 0.05);
        let y = sys.run(&u);
        let frf = estimate_periodic(&u, &y, &info(n, 4, 2, &lines), 1.0, FrfKind::Other).unwrap();
        assert_eq!(frf.len(), 150);
        for (i, &k) in lines.iter().enumerate() {
            let exact = sys.frf(k as f64 / n as f64);
            assert!(
                rel_err(frf.h[i], exact) < 1e-9,
                "line {k}: {} vs {exact}",
                frf.h[i]
            );
            assert!(frf.var[i] < 1e-20 * exact.norm_sqr());
            assert!(frf.coherence.as_ref().unwrap()[i] > 1.0 - 1e-12);
        }
        // one steady period: estimate available, variance unknown
        let one = estimate_periodic(
            &u[..3 * n],
            &y[..3 * n],
            &info(n, 1, 2, &lines),
            1.0,
            FrfKind::Other,
        )
        .unwrap();
        assert!(one.var.iter().all(|v| v.is_infinite()));
        assert!(one.coherence.is_none());
        assert!(rel_err(one.h[10], sys.frf(11.0 / n as f64)) < 1e-9);
    }

    #[test]
    fn reported_variance_matches_scatter() {
        let n = 256;
        let (tr, p) = (2, 8);
        let lines: Vec<usize> = (1..=100).collect();
        let mut r = rng(3);
        let per = multisine_period(n, &lines, &mut r);
        let u = tile(&per, tr + p);
        let sys = Biquad::resonator(0.95, 0.08);
        let y0 = sys.run(&u);
        let exact: Vec<Complex64> = lines
            .iter()
            .map(|&k| sys.frf(k as f64 / n as f64))
            .collect();
        let reals = 200;
        let mut emp = vec![0.0; lines.len()];
        let mut rep = vec![0.0; lines.len()];
        let mut inside = 0usize;
        let mut est = PeriodicEstimator::new(n, &lines, 1.0, FrfKind::Other)
            .unwrap()
            .with_transient_periods(tr);
        for _ in 0..reals {
            let mut y = y0.clone();
            for (x, e) in y.iter_mut().zip(gauss(&mut r, y0.len(), 0.01)) {
                *x += e;
            }
            est.reset();
            est.push(&u, &y).unwrap();
            let frf = est.estimate().unwrap();
            for i in 0..lines.len() {
                let e2 = (frf.h[i] - exact[i]).norm_sqr();
                emp[i] += e2 / reals as f64;
                rep[i] += frf.var[i] / reals as f64;
                if e2 < 9.0 * frf.var[i] {
                    inside += 1;
                }
            }
        }
        for i in 0..lines.len() {
            let ratio = (emp[i] / rep[i]).sqrt();
            assert!(
                (0.8..1.2).contains(&ratio),
                "line {}: std ratio {ratio}",
                lines[i]
            );
        }
        let frac = inside as f64 / (reals * lines.len()) as f64;
        assert!(frac >= 0.98, "only {frac} within 3 sigma");
    }

    #[test]
    fn streaming_random_chunks_equals_batch() {
        let n = 100;
        let lines = [2, 3, 5, 8, 13, 21, 34];
        let mut r = rng(4);
        let per = multisine_period(n, &lines, &mut r);
        let mut u = tile(&per, 7);
        u.truncate(7 * n - 37); // trailing partial period
        let sys = Biquad::resonator(0.9, 0.13);
        let mut y = sys.run(&u);
        for (x, e) in y.iter_mut().zip(gauss(&mut r, u.len(), 0.01)) {
            *x += e;
        }
        let inf = info(n, 5, 1, &lines);
        let batch = estimate_periodic(&u, &y, &inf, 250.0, FrfKind::DifferencedVelocity).unwrap();
        let mut b =
            PeriodicEstimator::from_info(&inf, 250.0, FrfKind::DifferencedVelocity).unwrap();
        b.push(&u, &y).unwrap();
        let batch_ne = b.nonexcited().unwrap();
        for trial in 0..20 {
            let mut s =
                PeriodicEstimator::from_info(&inf, 250.0, FrfKind::DifferencedVelocity).unwrap();
            let mut pos = 0;
            while pos < u.len() {
                let c = r
                    .random_range(0..=(if trial % 2 == 0 { 7 } else { 250 }))
                    .min(u.len() - pos);
                s.push(&u[pos..pos + c], &y[pos..pos + c]).unwrap();
                pos += c;
            }
            assert_eq!(s.periods_done(), 5);
            assert_eq!(s.estimate().unwrap(), batch);
            assert_eq!(s.nonexcited().unwrap(), batch_ne);
        }
    }

    #[test]
    fn excited_lines_inferred_from_input() {
        let n = 128;
        let lines = [3, 4, 9, 10, 31, 40, 64];
        let mut r = rng(5);
        let per = multisine_period(n, &lines, &mut r);
        let u: Vec<f64> = tile(&per, 5).iter().map(|x| x + 0.7).collect(); // DC not a line
        let y = Biquad::resonator(0.9, 0.2).run(&u);
        let given = estimate_periodic(&u, &y, &info(n, 4, 1, &lines), 1.0, FrfKind::Other).unwrap();
        let mut est = PeriodicEstimator::new(n, &[], 1.0, FrfKind::Other)
            .unwrap()
            .with_transient_periods(1);
        est.push(&u, &y).unwrap();
        assert_eq!(est.excited_lines().unwrap(), lines.to_vec());
        assert_eq!(est.estimate().unwrap(), given);
        // no excitation at all
        let mut z = PeriodicEstimator::new(n, &[], 1.0, FrfKind::Other).unwrap();
        z.push(&vec![0.0; n], &vec![0.0; n]).unwrap();
        assert_eq!(z.estimate(), Err(FrfError::NoExcitedLines));
    }

    /// Odd random-phase multisine with one detection line left out per group of 4 odd lines.
    fn odd_design(r: &mut StdRngAlias, lo: usize, hi: usize) -> (Vec<usize>, Vec<usize>) {
        let odd: Vec<usize> = (lo..=hi).filter(|k| k % 2 == 1).collect();
        let mut exc = vec![];
        let mut det = vec![];
        for g in odd.chunks(4) {
            let skip = r.random_range(0..g.len());
            for (i, &k) in g.iter().enumerate() {
                if i == skip && g.len() == 4 {
                    det.push(k)
                } else {
                    exc.push(k)
                }
            }
        }
        (exc, det)
    }
    type StdRngAlias = rand::rngs::StdRng;

    #[test]
    fn nonexcited_lines_reveal_cubic_distortion() {
        let n = 512;
        let (tr, p) = (2, 8);
        let mut r = rng(6);
        let (exc, det) = odd_design(&mut r, 3, 121);
        let per = multisine_period(n, &exc, &mut r);
        let u = tile(&per, tr + p);
        let sys = Biquad::resonator(0.95, 0.05);
        let ylin = sys.run(&u);
        let rms = (ylin.iter().map(|x| x * x).sum::<f64>() / ylin.len() as f64).sqrt();
        let noise = gauss(&mut r, u.len(), 1e-3);
        let levels = |nl: bool| {
            let y: Vec<f64> = ylin
                .iter()
                .zip(&noise)
                .map(|(&x, &e)| {
                    let x = x / rms;
                    (if nl { x + 0.1 * x * x * x } else { x }) + e
                })
                .collect();
            let mut est = PeriodicEstimator::new(n, &exc, 1.0, FrfKind::Other)
                .unwrap()
                .with_transient_periods(tr);
            est.push(&u, &y).unwrap();
            est.nonexcited().unwrap()
        };
        let median = |mut v: Vec<f64>| {
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            v[v.len() / 2]
        };
        let ratios = |lv: &NonExcitedLevels, want: &dyn Fn(usize) -> bool| -> Vec<f64> {
            lv.line
                .iter()
                .enumerate()
                .filter(|(_, &k)| want(k))
                .map(|(i, _)| lv.mean_power_y[i] / lv.noise_var_y[i])
                .collect()
        };
        let lin = levels(false);
        let cub = levels(true);
        assert_eq!(lin.periods, p);
        // the band holds all even lines and the odd detection lines
        let odd_lin: Vec<usize> = lin.line.iter().copied().filter(|k| k % 2 == 1).collect();
        let (lo, hi) = (exc[0], exc[exc.len() - 1]);
        let det_in_band: Vec<usize> = det.iter().copied().filter(|&k| k > lo && k < hi).collect();
        assert_eq!(odd_lin, det_in_band);
        assert_eq!(lin.line.len(), (lo..=hi).count() - exc.len());
        let is_det = |k: usize| k % 2 == 1;
        let is_even = |k: usize| k % 2 == 0;
        let lin_odd = median(ratios(&lin, &is_det));
        let lin_even = median(ratios(&lin, &is_even));
        let cub_odd = median(ratios(&cub, &is_det));
        let cub_even = median(ratios(&cub, &is_even));
        // linear: coherent power at the noise level; cubic: odd lines far above it, even
        // lines (not produced by an odd nonlinearity) still at the noise level
        assert!(lin_odd < 4.0 && lin_even < 4.0, "{lin_odd} {lin_even}");
        assert!(cub_odd > 1e4, "cubic distortion ratio only {cub_odd}");
        assert!(cub_even < 4.0, "{cub_even}");
        // noise level at the excited lines is the same order as at the non-excited ones
        let ev = median(cub.excited_noise_var_y.clone());
        let nv = median(cub.noise_var_y.clone());
        assert!(ev / nv > 0.3 && ev / nv < 3.0);
    }

    #[test]
    fn drifting_axis_differenced_velocity_is_unbiased() {
        // position = filtered torque response + velocity offset * t + integral of a random
        // walk; the FRF torque -> differenced velocity must be G * D at the excited lines.
        let n = 256;
        let fs = 1000.0;
        let (tr, p) = (2, 16);
        let lines: Vec<usize> = (1..=60).collect();
        let mut r = rng(7);
        let per = multisine_period(n, &lines, &mut r);
        let u = tile(&per, tr + p);
        let sys = Biquad::resonator(0.95, 0.03);
        let ypos = sys.run(&u);
        let exact: Vec<Complex64> = lines
            .iter()
            .map(|&k| {
                let f = k as f64 * fs / n as f64;
                sys.frf(k as f64 / n as f64) * difference_quotient_response(f, fs)
            })
            .collect();
        let vel_rms = {
            let v = differenced_velocity(&ypos, fs);
            (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
        };
        let reals = 40;
        let mut mean_err = vec![Complex64::new(0.0, 0.0); lines.len()];
        let mut mean_var = vec![0.0; lines.len()];
        let mut worst_naive = 0.0_f64;
        let mut worst_diff = 0.0_f64;
        let mut within3 = 0usize;
        for _ in 0..reals {
            let steps = gauss(&mut r, u.len(), 2e-3 * vel_rms);
            let mut walk = 0.0;
            let mut drift = 0.0;
            let pos: Vec<f64> = ypos
                .iter()
                .zip(&steps)
                .map(|(&yp, &s)| {
                    walk += s;
                    drift += (0.5 * vel_rms + walk) / fs;
                    yp + drift
                })
                .collect();
            let v = differenced_velocity(&pos, fs);
            let frf = estimate_periodic(
                &u,
                &v,
                &info(n, p, tr, &lines),
                fs,
                FrfKind::DifferencedVelocity,
            )
            .unwrap();
            for i in 0..lines.len() {
                mean_err[i] += (frf.h[i] - exact[i]) / reals as f64;
                mean_var[i] += frf.var[i] / reals as f64;
                worst_diff = worst_diff.max(rel_err(frf.h[i], exact[i]));
                if (frf.h[i] - exact[i]).norm_sqr() < 9.0 * frf.var[i] {
                    within3 += 1;
                }
            }
            // the forbidden way: j w times the DFT of the raw position over the steady record
            let rec = &pos[tr * n..];
            let urec = &u[tr * n..];
            for (i, &k) in lines.iter().enumerate().step_by(7) {
                let f = k as f64 * fs / n as f64;
                let jw = Complex64::new(0.0, 2.0 * std::f64::consts::PI * f);
                let h = jw * dft_line(rec, k * p) / dft_line(urec, k * p);
                worst_naive = worst_naive.max(rel_err(h, exact[i]));
            }
        }
        // unbiased: the mean error over realisations is within 4 standard errors
        let mut ok = 0;
        for i in 0..lines.len() {
            let se = (mean_var[i] / reals as f64).sqrt();
            if mean_err[i].norm() < 4.0 * se {
                ok += 1;
            }
        }
        assert!(
            ok as f64 >= 0.95 * lines.len() as f64,
            "{ok} of {}",
            lines.len()
        );
        // errors consistent with the reported variance, and far below the naive way's
        assert!(
            within3 as f64 >= 0.95 * (reals * lines.len()) as f64,
            "{within3}"
        );
        assert!(worst_diff < 0.2, "differenced velocity error {worst_diff}");
        assert!(
            worst_naive > 10.0 * worst_diff,
            "naive position error only {worst_naive}"
        );
    }

    #[test]
    fn constant_acceleration_ramp_is_removed_from_a_velocity_frf() {
        // a periodic velocity response plus the ramp of a constant acceleration (what a
        // small mean torque does to a free chain): the same FRF as without the ramp; the
        // naive reference (no correction) is biased at the lowest line
        let (n, fs, tr, p) = (128, 1000.0, 1, 6);
        let lines: Vec<usize> = (1..=40).collect();
        let per = multisine_period(n, &lines, &mut rng(11));
        let u = tile(&per, tr + p);
        let steady = Biquad::resonator(0.95, 0.03).run(&tile(&per, 30));
        let y = tile(&steady[29 * n..], tr + p);
        let ramped: Vec<f64> = y
            .iter()
            .enumerate()
            .map(|(i, v)| v + 0.1 + 5.0 * i as f64 / fs)
            .collect();
        let inf = info(n, p, tr, &lines);
        for kind in [FrfKind::Velocity, FrfKind::DifferencedVelocity] {
            let clean = estimate_periodic(&u, &y, &inf, fs, kind).unwrap();
            let got = estimate_periodic(&u, &ramped, &inf, fs, kind).unwrap();
            for i in 0..lines.len() {
                assert!(rel_err(got.h[i], clean.h[i]) < 1e-9, "line {}", lines[i]);
            }
        }
        let biased = naive(&u, &ramped, n, tr, &lines);
        let clean = estimate_periodic(&u, &y, &inf, fs, FrfKind::Velocity).unwrap();
        assert!(rel_err(biased.h[0], clean.h[0]) > 1e-2);
        // a position response is left as it is
        let pos = estimate_periodic(&u, &ramped, &inf, fs, FrfKind::Position).unwrap();
        assert!(rel_err(pos.h[0], biased.h[0]) < 1e-9);
    }

    #[test]
    fn errors_not_panics() {
        let lines = [1, 2, 3];
        assert_eq!(
            PeriodicEstimator::new(64, &[1, 33], 1.0, FrfKind::Other).unwrap_err(),
            FrfError::LineOutOfRange { line: 33, max: 32 }
        );
        assert!(matches!(
            PeriodicEstimator::new(0, &lines, 1.0, FrfKind::Other),
            Err(FrfError::InvalidParameter { .. })
        ));
        assert!(matches!(
            PeriodicEstimator::new(64, &lines, -1.0, FrfKind::Other),
            Err(FrfError::InvalidParameter { .. })
        ));
        let mut est = PeriodicEstimator::new(64, &lines, 1.0, FrfKind::Other).unwrap();
        assert_eq!(
            est.push(&[0.0; 10], &[0.0; 9]),
            Err(FrfError::LengthMismatch { u: 10, y: 9 })
        );
        assert!(matches!(est.estimate(), Err(FrfError::TooShort { .. })));
        est.push(&[1.0; 63], &[1.0; 63]).unwrap();
        assert!(matches!(est.nonexcited(), Err(FrfError::TooShort { .. })));
        let inf = info(64, 3, 2, &lines);
        assert_eq!(
            estimate_periodic(&[0.0; 100], &[0.0; 100], &inf, 1.0, FrfKind::Other),
            Err(FrfError::TooShort {
                needed: 192,
                got: 100,
                unit: "samples"
            })
        );
        assert_eq!(
            estimate_periodic(&[0.0; 100], &[0.0; 99], &inf, 1.0, FrfKind::Other),
            Err(FrfError::LengthMismatch { u: 100, y: 99 })
        );
        let bad = info(64, 3, 0, &[40]);
        assert_eq!(
            estimate_periodic(&[0.0; 128], &[0.0; 128], &bad, 1.0, FrfKind::Other),
            Err(FrfError::LineOutOfRange { line: 40, max: 32 })
        );
    }
}
