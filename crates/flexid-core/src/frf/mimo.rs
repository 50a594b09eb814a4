//! The `N x N` FRF matrix of `N` coupled axes from `P >= N` periodic experiments
//! (orthogonal multisines, [`crate::excitation::OrthogonalMultisine`]), with the variance of
//! every element and the symmetrised estimate (issue 17).
//!
//! # Method (direct method, per excited line `k`)
//!
//! 1. Every steady period of experiment `p` gives the phasors of the `N` measured torques
//!    `u_p` [N m] and the `N` motor velocities `y_p` [rad/s] at each excited line (the DFT of
//!    the period scaled by `1/period_samples`, as in [`super::PeriodicEstimator`]); their
//!    mean over the periods and the sample covariance of the stacked `z = [u; y]` are
//!    updated by Welford's algorithm after every period.
//! 2. The means form the `N x P` matrices `U` and `Y` (one column per experiment) and
//!    `G = Y U^+` [(rad/s)/(N m)], `U^+` the (Moore-Penrose) right inverse: `U^-1` when
//!    `P = N`, `U^H (U U^H)^-1` when `P > N` (least squares over the experiments).
//! 3. The variance of every element from the noise covariance of the means (below).
//! 4. The symmetrised estimate (the paper's eq. 14): `S_nm = (G_nm + G_mn) / 2` off the
//!    diagonal, `S_nn = G_nn`, for a reciprocal plant (collocated torque -> velocity of a
//!    passive mechanism: `G = G^T`).
//!
//! The zero-frequency line is never estimated (absolute positions and the static holding
//! torque live there) and neither is the Nyquist line. Under a position loop the measured
//! torque holds the feedback of the noise; averaging the spectra over periods before
//! dividing keeps the estimate consistent (the bias is second order in the noise), but near
//! and below the loop's bandwidth the first-order variance below understates the error.
//!
//! # Variance (linear propagation of the noise covariance of the means)
//!
//! Let `U0`, `Y0 = G0 U0` be the noise-free means and `dU`, `dY` their noise. As `U U^+ = I`
//! for a full-rank `U` (`U = U0 + dU`), exactly
//!
//! `G - G0 = (Y - G0 U) U^+ = E U^+`,  `E = dY - G0 dU`,
//!
//! whose column `p`, `e_p = T dz_p` with `T = [-G0, I]` (`N x 2N`), is the noise of
//! experiment `p` alone; the experiments' noises are independent. With `C_p` the covariance
//! of the mean `z_p` (the sample covariance of the per-period phasors over the `M_p` steady
//! periods divided by `M_p`, i.e. `sum (z - mean)(z - mean)^H / ((M_p - 1) M_p)`), and
//! `Ce_p = T C_p T^H`,
//!
//! `var G_nm = E|dG_nm|^2 = sum_p |U^+_pm|^2 Ce_p[n, n]`,
//! `cov(G_nm, G_mn) = E[dG_nm conj(dG_mn)] = sum_p U^+_pm conj(U^+_pn) Ce_p[n, m]`,
//! `var S_nm = (var G_nm + var G_mn + 2 Re cov(G_nm, G_mn)) / 4`.
//!
//! To first order `G0` and `U` are replaced by the estimates `G` and the measured `U` (the
//! DFT noise at a line other than DC and Nyquist is circular, so these Hermitian moments
//! are all the first-order variance needs). It takes `M_p >= 2` steady periods in every
//! experiment; with fewer the variances are `INFINITY`. Each variance is that of the
//! estimate, `E|G_est - G_true|^2` [((rad/s)/(N m))^2], as [`Frf::var`].

use std::sync::Arc;

use nalgebra::DMatrix;
use num_complex::Complex64;
use realfft::RealToComplex;
use thiserror::Error;

use super::types::{Frf, FrfKind};
use crate::excitation::OrthogonalMultisine;

/// Largest accepted condition number of the input matrix `U` at a line; above it the line
/// is reported as rank-deficient instead of giving a meaningless inverse.
pub const MAX_INPUT_CONDITION: f64 = 1e10;

/// Iterations the SVD of the small `N x P` input matrix may take before it is given up
/// (reported as rank-deficient); a few dozen suffice.
const SVD_MAX_ITERATIONS: usize = 10_000;

/// Why the FRF matrix could not be planned, fed or estimated. Every variant carries the
/// numbers needed to act on it.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MimoError {
    /// A parameter has an invalid value (no axis, a too short period, a bad sample rate).
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter {
        /// Parameter name.
        name: &'static str,
        /// What is wrong with it.
        reason: String,
    },
    /// No excited line was given.
    #[error("no excited line given")]
    NoLines,
    /// A line is DC, the Nyquist line or above it (valid: `1..=max`).
    #[error("DFT line {line} out of range: the excited lines must lie in 1..={max}")]
    LineOutOfRange {
        /// The offending line index.
        line: usize,
        /// Highest valid line, `(period_samples - 1) / 2`.
        max: usize,
    },
    /// Fewer experiments than axes: `U` (`N x P`) cannot have full rank `N`.
    #[error("{experiments} experiments cannot identify {axes} axes (need at least {axes})")]
    TooFewExperiments {
        /// Number of axes `N`.
        axes: usize,
        /// Number of experiments `P`.
        experiments: usize,
    },
    /// A period was pushed for an experiment that does not exist.
    #[error("experiment {experiment} out of range: the estimator was planned for {experiments}")]
    ExperimentOutOfRange {
        /// The offending (0-based) experiment.
        experiment: usize,
        /// Number of planned experiments.
        experiments: usize,
    },
    /// A pushed period has a number of channels other than the axes.
    #[error("{signal} has {got} channels, expected one per axis ({expected})")]
    ChannelCount {
        /// `"u"` (torques) or `"y"` (velocities).
        signal: &'static str,
        /// Number of axes.
        expected: usize,
        /// Number of channels given.
        got: usize,
    },
    /// A pushed channel is not one period long \[samples\].
    #[error("{signal} channel {channel} has {got} samples, expected one period of {expected}")]
    ChannelLength {
        /// `"u"` (torques) or `"y"` (velocities).
        signal: &'static str,
        /// The offending (0-based) channel.
        channel: usize,
        /// Samples per period.
        expected: usize,
        /// Samples given.
        got: usize,
    },
    /// An experiment has no steady period (all pushed periods were transient).
    #[error(
        "experiment {experiment} has no steady period ({pushed} pushed, {transient_periods} \
         transient)"
    )]
    NoSteadyPeriod {
        /// The (0-based) experiment.
        experiment: usize,
        /// Periods pushed for it.
        pushed: usize,
        /// Leading periods discarded per experiment.
        transient_periods: usize,
    },
    /// A mean phasor at a line is not finite (a NaN or infinite sample was pushed).
    #[error("non-finite torque or velocity phasor at line {line} ({freq_hz} Hz)")]
    NonFinite {
        /// DFT line index.
        line: usize,
        /// Its frequency \[Hz\].
        freq_hz: f64,
    },
    /// The input matrix `U` is (numerically) rank-deficient at a line: the experiments do
    /// not excite the axes independently there.
    #[error(
        "input matrix rank-deficient at line {line} ({freq_hz} Hz): condition number \
         {condition:e} above {MAX_INPUT_CONDITION:e}"
    )]
    RankDeficient {
        /// DFT line index.
        line: usize,
        /// Its frequency \[Hz\].
        freq_hz: f64,
        /// Condition number of `U` there (`INFINITY` when singular).
        condition: f64,
    },
}

impl MimoError {
    fn invalid(name: &'static str, reason: impl Into<String>) -> Self {
        MimoError::InvalidParameter {
            name,
            reason: reason.into(),
        }
    }
}

/// The `N x N` FRF matrix estimate per excited line with the variance of every element.
///
/// Element `(n, m)` is the response of output `n` (motor velocity of axis `n` [rad/s]) to
/// input `m` (torque of axis `m` [N m]), in (rad/s)/(N m) for the direct method.
#[derive(Debug, Clone, PartialEq)]
pub struct MimoFrf {
    /// Number of axes `N`.
    pub axes: usize,
    /// Sample rate of the recordings \[Hz\].
    pub sample_rate_hz: f64,
    /// Excited DFT lines within one period (increasing).
    pub lines: Vec<usize>,
    /// Their frequencies \[Hz\].
    pub freq_hz: Vec<f64>,
    /// `G = Y U^+` per line (`N x N`).
    pub g: Vec<DMatrix<Complex64>>,
    /// `E|G_nm - G0_nm|^2` per line and element (`N x N`, real); `INFINITY` without two
    /// steady periods in every experiment.
    pub var: Vec<DMatrix<f64>>,
    /// The symmetrised estimate per line: `(G_nm + G_mn) / 2` off the diagonal.
    pub g_sym: Vec<DMatrix<Complex64>>,
    /// Variance of each element of `g_sym` (equal to `var` on the diagonal).
    pub var_sym: Vec<DMatrix<f64>>,
    /// Condition number of `U` per line (1 for orthogonal multisines of equal amplitudes).
    pub condition: Vec<f64>,
    /// Steady periods averaged per experiment.
    pub periods: Vec<usize>,
}

impl MimoFrf {
    /// Number of lines.
    pub fn len(&self) -> usize {
        self.lines.len()
    }

    /// True when there are no lines.
    pub fn is_empty(&self) -> bool {
        self.lines.is_empty()
    }

    /// Element `(output, input)` over the lines as a single-axis [`Frf`] of `kind` (panics
    /// on an axis out of range); `symmetrised` picks `g_sym` / `var_sym`.
    pub fn element(&self, output: usize, input: usize, symmetrised: bool, kind: FrfKind) -> Frf {
        let (g, var) = if symmetrised {
            (&self.g_sym, &self.var_sym)
        } else {
            (&self.g, &self.var)
        };
        Frf {
            freq_hz: self.freq_hz.clone(),
            h: g.iter().map(|m| m[(output, input)]).collect(),
            var: var.iter().map(|m| m[(output, input)]).collect(),
            coherence: None,
            kind,
            sample_rate_hz: self.sample_rate_hz,
        }
    }
}

/// Running (Welford) statistics of one experiment over its steady periods: per line the
/// mean of `z = [u_1..u_N, y_1..y_N]` and the sum of outer products of its deviations.
#[derive(Debug, Clone)]
struct ExperimentStats {
    /// Mean of `z` per line, `lines x 2N` (row-major).
    mean: Vec<Complex64>,
    /// `sum (z - mean)(z - mean)^H` per line, `lines x 2N x 2N` (row-major).
    m2: Vec<Complex64>,
}

impl ExperimentStats {
    fn new(lines: usize, channels: usize) -> Self {
        Self {
            mean: vec![Complex64::new(0.0, 0.0); lines * channels],
            m2: vec![Complex64::new(0.0, 0.0); lines * channels * channels],
        }
    }

    fn reset(&mut self) {
        self.mean.fill(Complex64::new(0.0, 0.0));
        self.m2.fill(Complex64::new(0.0, 0.0));
    }

    /// Welford's update of line `j` with this period's phasors `z` (`2N`), `periods` the
    /// steady periods including this one; `delta` is scratch of `2N`.
    #[inline]
    fn update(&mut self, j: usize, z: &[Complex64], periods: usize, delta: &mut [Complex64]) {
        let c = z.len();
        let mean = &mut self.mean[j * c..(j + 1) * c];
        let inv = 1.0 / periods as f64;
        for ((d, m), &v) in delta.iter_mut().zip(mean.iter_mut()).zip(z) {
            *d = v - *m;
            *m += *d * inv;
        }
        // (z - old mean)(z - new mean)^H = (1 - 1/M) d d^H: Hermitian by construction.
        let w = 1.0 - inv;
        let m2 = &mut self.m2[j * c * c..(j + 1) * c * c];
        for (row, &da) in m2.chunks_exact_mut(c).zip(delta.iter()) {
            let wa = da * w;
            for (cell, &db) in row.iter_mut().zip(delta.iter()) {
                *cell += wa * db.conj();
            }
        }
    }
}

/// Plan-once estimator of the `N x N` FRF matrix from `P >= N` periodic experiments.
///
/// Feed whole periods of every experiment with [`push_period`](Self::push_period) (in any
/// order of experiments); the first `transient_periods` periods of each experiment are
/// discarded. The FFT plan and every buffer are allocated by the constructor: pushing a
/// period does not allocate. [`estimate`](Self::estimate) then forms `G` per line.
pub struct MimoEstimator {
    axes: usize,
    n: usize,
    fs: f64,
    /// Excited lines, increasing.
    lines: Vec<usize>,
    transient_periods: usize,
    fft: Arc<dyn RealToComplex<f64>>,
    buf: Vec<f64>,
    spec: Vec<Complex64>,
    scratch: Vec<Complex64>,
    /// This period's phasors, `lines x 2N` (row-major).
    z: Vec<Complex64>,
    /// Welford scratch, `2N`.
    delta: Vec<Complex64>,
    /// Periods pushed per experiment, transient ones included.
    pushed: Vec<usize>,
    stats: Vec<ExperimentStats>,
}

impl std::fmt::Debug for MimoEstimator {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MimoEstimator")
            .field("axes", &self.axes)
            .field("period_samples", &self.n)
            .field("sample_rate_hz", &self.fs)
            .field("lines", &self.lines)
            .field("transient_periods", &self.transient_periods)
            .field("pushed", &self.pushed)
            .finish_non_exhaustive()
    }
}

impl MimoEstimator {
    /// Plans an estimator for `axes` axes, periods of `period_samples` samples at
    /// `sample_rate_hz` \[Hz\], the excited DFT `lines` within one period (any order,
    /// duplicates ignored) and `experiments` experiments.
    ///
    /// Errors: `InvalidParameter` (no axis, `period_samples < 4`, a bad sample rate),
    /// `NoLines`, `LineOutOfRange` (DC, Nyquist or above), `TooFewExperiments` (`< axes`).
    pub fn new(
        axes: usize,
        period_samples: usize,
        lines: &[usize],
        experiments: usize,
        sample_rate_hz: f64,
    ) -> Result<Self, MimoError> {
        if axes == 0 {
            return Err(MimoError::invalid("axes", "must be at least 1"));
        }
        if period_samples < 4 {
            return Err(MimoError::invalid(
                "period_samples",
                format!("must be at least 4, got {period_samples}"),
            ));
        }
        if !(sample_rate_hz.is_finite() && sample_rate_hz > 0.0) {
            return Err(MimoError::invalid(
                "sample_rate_hz",
                format!("must be positive and finite, got {sample_rate_hz}"),
            ));
        }
        let lines = checked_lines(lines, period_samples)?;
        if experiments < axes {
            return Err(MimoError::TooFewExperiments { axes, experiments });
        }
        let fft = super::plan_cache::forward(period_samples);
        let channels = 2 * axes;
        Ok(Self {
            axes,
            n: period_samples,
            fs: sample_rate_hz,
            transient_periods: 0,
            spec: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            buf: vec![0.0; period_samples],
            z: vec![Complex64::new(0.0, 0.0); lines.len() * channels],
            delta: vec![Complex64::new(0.0, 0.0); channels],
            pushed: vec![0; experiments],
            stats: vec![ExperimentStats::new(lines.len(), channels); experiments],
            lines,
        })
    }

    /// Plans the estimator of the experiments of `excitation` (its axes, period, lines,
    /// experiments and sample rate).
    pub fn from_multisine(excitation: &OrthogonalMultisine) -> Result<Self, MimoError> {
        Self::new(
            excitation.axes,
            excitation.period_samples(),
            &excitation.excited_lines,
            excitation.experiments(),
            excitation.sample_rate_hz,
        )
    }

    /// Discards the first `periods` periods of every experiment (transient). Set before
    /// the first push.
    pub fn with_transient_periods(mut self, periods: usize) -> Self {
        self.transient_periods = periods;
        self
    }

    /// Number of axes `N`.
    pub fn axes(&self) -> usize {
        self.axes
    }

    /// Number of experiments `P`.
    pub fn experiments(&self) -> usize {
        self.pushed.len()
    }

    /// Samples per period.
    pub fn period_samples(&self) -> usize {
        self.n
    }

    /// The excited lines, increasing.
    pub fn lines(&self) -> &[usize] {
        &self.lines
    }

    /// Steady periods averaged so far for `experiment` (0 for one out of range).
    pub fn periods_done(&self, experiment: usize) -> usize {
        self.pushed
            .get(experiment)
            .map_or(0, |p| p.saturating_sub(self.transient_periods))
    }

    /// Forgets all data (keeps the plan, lines and settings).
    pub fn reset(&mut self) {
        self.pushed.fill(0);
        self.stats.iter_mut().for_each(ExperimentStats::reset);
    }

    /// Feeds one whole period of `experiment` (0-based): `u` the `N` measured torques
    /// [N m], `y` the `N` motor velocities [rad/s], one slice of `period_samples` samples
    /// per axis each. Transient periods are counted and dropped. Does not allocate.
    ///
    /// Errors (nothing is changed): `ExperimentOutOfRange`, `ChannelCount`, `ChannelLength`.
    pub fn push_period(
        &mut self,
        experiment: usize,
        u: &[&[f64]],
        y: &[&[f64]],
    ) -> Result<(), MimoError> {
        self.check_period(experiment, u, y)?;
        self.pushed[experiment] += 1;
        let periods = self.pushed[experiment];
        if periods <= self.transient_periods {
            return Ok(());
        }
        self.transform_period(u, y);
        self.accumulate(experiment, periods - self.transient_periods);
        Ok(())
    }

    fn check_period(&self, experiment: usize, u: &[&[f64]], y: &[&[f64]]) -> Result<(), MimoError> {
        if experiment >= self.pushed.len() {
            return Err(MimoError::ExperimentOutOfRange {
                experiment,
                experiments: self.pushed.len(),
            });
        }
        for (signal, chans) in [("u", u), ("y", y)] {
            if chans.len() != self.axes {
                return Err(MimoError::ChannelCount {
                    signal,
                    expected: self.axes,
                    got: chans.len(),
                });
            }
            if let Some((channel, c)) = chans.iter().enumerate().find(|(_, c)| c.len() != self.n) {
                return Err(MimoError::ChannelLength {
                    signal,
                    channel,
                    expected: self.n,
                    got: c.len(),
                });
            }
        }
        Ok(())
    }

    /// The phasors of every channel at the excited lines into `z` (`1/N`-scaled DFT).
    fn transform_period(&mut self, u: &[&[f64]], y: &[&[f64]]) {
        let channels = 2 * self.axes;
        let scale = 1.0 / self.n as f64;
        for (c, x) in u.iter().chain(y.iter()).enumerate() {
            // realfft uses its input as scratch: copy the channel into the plan's buffer.
            self.buf.copy_from_slice(x);
            self.fft
                .process_with_scratch(&mut self.buf, &mut self.spec, &mut self.scratch)
                .expect("buffer lengths fixed at construction");
            for (zj, &k) in self.z.chunks_exact_mut(channels).zip(&self.lines) {
                zj[c] = self.spec[k] * scale;
            }
        }
    }

    /// Welford's update of every line of `experiment` with `z`, `periods` its steady
    /// periods including this one.
    fn accumulate(&mut self, experiment: usize, periods: usize) {
        let channels = 2 * self.axes;
        let stats = &mut self.stats[experiment];
        for (j, zj) in self.z.chunks_exact(channels).enumerate() {
            stats.update(j, zj, periods, &mut self.delta);
        }
    }

    /// The FRF matrix per excited line with the variance of every element and the
    /// symmetrised estimate (see the module doc for the formulas).
    ///
    /// Errors: `NoSteadyPeriod` for an experiment without one, `NonFinite` for a NaN or
    /// infinite mean phasor, `RankDeficient` where the
    /// condition number of `U` exceeds [`MAX_INPUT_CONDITION`].
    pub fn estimate(&self) -> Result<MimoFrf, MimoError> {
        let periods = self.steady_periods()?;
        let df = self.fs / self.n as f64;
        let mut out = MimoFrf {
            axes: self.axes,
            sample_rate_hz: self.fs,
            lines: self.lines.clone(),
            freq_hz: self.lines.iter().map(|&k| k as f64 * df).collect(),
            g: Vec::with_capacity(self.lines.len()),
            var: Vec::with_capacity(self.lines.len()),
            g_sym: Vec::with_capacity(self.lines.len()),
            var_sym: Vec::with_capacity(self.lines.len()),
            condition: Vec::with_capacity(self.lines.len()),
            periods: periods.clone(),
        };
        for (j, &k) in self.lines.iter().enumerate() {
            let (u, y) = self.mean_matrices(j);
            if !u
                .iter()
                .chain(y.iter())
                .all(|v| v.re.is_finite() && v.im.is_finite())
            {
                return Err(MimoError::NonFinite {
                    line: k,
                    freq_hz: k as f64 * df,
                });
            }
            let (u_pinv, condition) = right_inverse(&u, k, k as f64 * df)?;
            let g = &y * &u_pinv;
            let noise: Option<Vec<DMatrix<Complex64>>> = (0..self.experiments())
                .map(|p| self.error_covariance(p, j, periods[p], &g))
                .collect();
            let (var, var_sym) = match noise {
                Some(ce) => propagated_variances(&u_pinv, &ce),
                None => (
                    DMatrix::from_element(self.axes, self.axes, f64::INFINITY),
                    DMatrix::from_element(self.axes, self.axes, f64::INFINITY),
                ),
            };
            out.g_sym.push(symmetrised(&g));
            out.g.push(g);
            out.var.push(var);
            out.var_sym.push(var_sym);
            out.condition.push(condition);
        }
        Ok(out)
    }

    /// Steady periods per experiment; an error for one without any.
    fn steady_periods(&self) -> Result<Vec<usize>, MimoError> {
        (0..self.experiments())
            .map(|p| match self.periods_done(p) {
                0 => Err(MimoError::NoSteadyPeriod {
                    experiment: p,
                    pushed: self.pushed[p],
                    transient_periods: self.transient_periods,
                }),
                m => Ok(m),
            })
            .collect()
    }

    /// The mean phasors at line `j` as `U`, `Y` (`N x P`, one column per experiment).
    fn mean_matrices(&self, j: usize) -> (DMatrix<Complex64>, DMatrix<Complex64>) {
        let (n, c) = (self.axes, 2 * self.axes);
        let at = |p: usize, ch: usize| self.stats[p].mean[j * c + ch];
        (
            DMatrix::from_fn(n, self.experiments(), |a, p| at(p, a)),
            DMatrix::from_fn(n, self.experiments(), |a, p| at(p, n + a)),
        )
    }

    /// `Ce_p = T C_p T^H`, `T = [-G, I]`, with `C_p` the covariance of the mean `z` of
    /// experiment `p` at line `j` over its `periods` steady periods; `None` below two.
    fn error_covariance(
        &self,
        p: usize,
        j: usize,
        periods: usize,
        g: &DMatrix<Complex64>,
    ) -> Option<DMatrix<Complex64>> {
        if periods < 2 {
            return None;
        }
        let (n, c) = (self.axes, 2 * self.axes);
        let norm = 1.0 / ((periods - 1) as f64 * periods as f64);
        let m2 = &self.stats[p].m2[j * c * c..(j + 1) * c * c];
        let cov = DMatrix::from_fn(c, c, |a, b| m2[a * c + b] * norm);
        let mut t = DMatrix::zeros(n, c);
        t.view_mut((0, 0), (n, n)).copy_from(&(-g));
        t.view_mut((0, n), (n, n)).fill_with_identity();
        Some(&t * cov * t.adjoint())
    }
}

/// Sorted, deduplicated lines, each in `1..=(period_samples - 1) / 2`.
fn checked_lines(lines: &[usize], period_samples: usize) -> Result<Vec<usize>, MimoError> {
    let max = (period_samples - 1) / 2;
    let mut lines = lines.to_vec();
    lines.sort_unstable();
    lines.dedup();
    if lines.is_empty() {
        return Err(MimoError::NoLines);
    }
    if let Some(&line) = lines.iter().find(|&&k| k == 0 || k > max) {
        return Err(MimoError::LineOutOfRange { line, max });
    }
    Ok(lines)
}

/// The right inverse `U^+` (`P x N`) of `U` (`N x P`, `P >= N`) by the SVD, and the
/// condition number of `U`; `RankDeficient` above [`MAX_INPUT_CONDITION`].
fn right_inverse(
    u: &DMatrix<Complex64>,
    line: usize,
    freq_hz: f64,
) -> Result<(DMatrix<Complex64>, f64), MimoError> {
    let rank_deficient = |condition| MimoError::RankDeficient {
        line,
        freq_hz,
        condition,
    };
    let svd = u
        .clone()
        .try_svd(true, true, f64::EPSILON, SVD_MAX_ITERATIONS)
        .ok_or_else(|| rank_deficient(f64::NAN))?;
    let (hi, lo) = (svd.singular_values.max(), svd.singular_values.min());
    let condition = if lo > 0.0 { hi / lo } else { f64::INFINITY };
    if condition.is_nan() || condition > MAX_INPUT_CONDITION {
        return Err(rank_deficient(condition));
    }
    let pinv = svd
        .pseudo_inverse(0.0)
        .expect("U and V were computed, eps is not negative");
    Ok((pinv, condition))
}

/// `var G_nm = sum_p |U^+_pm|^2 Ce_p[n,n]` and the variance of the symmetrised estimate,
/// `(var G_nm + var G_mn + 2 Re sum_p U^+_pm conj(U^+_pn) Ce_p[n,m]) / 4` off the diagonal.
fn propagated_variances(
    u_pinv: &DMatrix<Complex64>,
    ce: &[DMatrix<Complex64>],
) -> (DMatrix<f64>, DMatrix<f64>) {
    let n = u_pinv.ncols();
    let var = DMatrix::from_fn(n, n, |a, m| {
        ce.iter()
            .enumerate()
            .map(|(p, c)| u_pinv[(p, m)].norm_sqr() * c[(a, a)].re)
            .sum::<f64>()
            .max(0.0)
    });
    let cross = |a: usize, m: usize| -> Complex64 {
        ce.iter()
            .enumerate()
            .map(|(p, c)| u_pinv[(p, m)] * u_pinv[(p, a)].conj() * c[(a, m)])
            .sum()
    };
    let var_sym = DMatrix::from_fn(n, n, |a, m| {
        if a == m {
            var[(a, a)]
        } else {
            (0.25 * (var[(a, m)] + var[(m, a)] + 2.0 * cross(a, m).re)).max(0.0)
        }
    });
    (var, var_sym)
}

/// The paper's eq. (14): `(G_nm + G_mn) / 2` off the diagonal, the diagonal kept.
fn symmetrised(g: &DMatrix<Complex64>) -> DMatrix<Complex64> {
    DMatrix::from_fn(g.nrows(), g.ncols(), |a, m| 0.5 * (g[(a, m)] + g[(m, a)]))
}

#[cfg(test)]
#[path = "mimo_tests.rs"]
mod tests;
