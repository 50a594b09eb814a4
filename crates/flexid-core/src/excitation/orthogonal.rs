//! Orthogonal random-phase multisines over `N` axes (multi-axis identification, issue 17).
//!
//! One block of `N` experiments excites every axis in every experiment. Axis `n` (0-based)
//! plays in experiment `q` of a block the random-phase multisine `R_n` of that block with
//! each line's phasor multiplied by `w_nq = exp(2 pi i n q / N)`, the element of the
//! `N`-point DFT matrix `W` (the paper's `w_np = exp(2 pi i (n-1)(p-1)/N)`, 1-based). In
//! the time domain that adds the phase `2 pi n q / N` to every line of axis `n` (the
//! mirrored bins get the conjugate, so the signals stay real). Each block draws its own
//! random phases per axis.
//!
//! # Conventions and units
//!
//! * Torques in N m, frequencies in Hz, angles in rad; line `k` of a period of
//!   `P_s = period_samples` samples lies at `k * fs / P_s` Hz.
//! * A line's phasor is the `1/P_s`-scaled DFT of one period (the convention of
//!   [`crate::frf::PeriodicEstimator`]): a cosine `A cos(2 pi k t / P_s + phi)` has the
//!   phasor `A/2 e^{i phi}` at line `k`.
//! * The reference matrix of an excited line, `R(w_k)` (`N x P`, `P = blocks * N`
//!   experiments as columns, experiment `p = b N + q`), holds those phasors:
//!   `R[n, p] = A_n / 2 * exp(i (phi_{b,n,k} + 2 pi n q / N))`.
//!
//! # Rank
//!
//! Within a block `R = D_b W` with `D_b = diag(A_n/2 e^{i phi_{b,n,k}})` and
//! `W W^H = N I`, so `R R^H = N sum_b D_b D_b^H = N B diag(A_n^2 / 4)`: `R` has full rank
//! `N` on every excited line whatever the phases, and its condition number is
//! `max_n A_n / min_n A_n`, 1 for equal amplitudes (`W / sqrt(N)` is unitary).

use std::f64::consts::PI;

use nalgebra::DMatrix;
use num_complex::Complex64;
use rand::{rngs::StdRng, SeedableRng};

use super::lines::band_lines;
use super::phases::random_phases;
use super::stats::{check_length, peak_abs, rms};
use super::synth::LineSynth;
use super::{ExcitationError, ExcitationInfo, ExcitationKind};

/// Design name written to [`ExcitationInfo::design`].
pub const ORTHOGONAL_DESIGN_NAME: &str = "orthogonal_random_phase";

/// Design of orthogonal random-phase multisines over `axes` axes: flat amplitude on every
/// line of the band (DC and Nyquist never excited), `blocks` blocks of `axes` experiments.
#[derive(Debug, Clone, PartialEq)]
pub struct OrthogonalMultisineDesign {
    /// Number of axes `N` (>= 1); also the experiments per block.
    pub axes: usize,
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Samples per period (>= 4); sets the line spacing `fs / period_samples`.
    pub period_samples: usize,
    /// Excited band `[lo, hi]` \[Hz\], inclusive.
    pub band_hz: [f64; 2],
    /// RMS torque per axis [N m rms] (one per axis, positive and finite). It is the RMS of
    /// every experiment's signal on that axis (the DFT-matrix phases do not change it);
    /// each of the `L` excited lines then has the cosine amplitude `rms * sqrt(2 / L)`.
    /// The peak is not limited (random phases: crest factor typically 3 to 4).
    pub rms_nm: Vec<f64>,
    /// Number of blocks of `axes` experiments (>= 1), each with new random phases.
    pub blocks: usize,
    /// Seed of the phase generator (same seed, same signals).
    pub seed: u64,
}

impl OrthogonalMultisineDesign {
    /// `axes` axes with the same RMS torque `rms_nm` [N m rms], one block, seed 0; adjust
    /// the public fields for other designs.
    pub fn new(
        axes: usize,
        sample_rate_hz: f64,
        period_samples: usize,
        band_hz: [f64; 2],
        rms_nm: f64,
    ) -> Self {
        Self {
            axes,
            sample_rate_hz,
            period_samples,
            band_hz,
            rms_nm: vec![rms_nm; axes],
            blocks: 1,
            seed: 0,
        }
    }

    /// Line spacing `fs / period_samples` \[Hz\].
    pub fn line_spacing_hz(&self) -> f64 {
        self.sample_rate_hz / self.period_samples as f64
    }

    /// Number of experiments `P = blocks * axes`.
    pub fn experiments(&self) -> usize {
        self.blocks * self.axes
    }

    /// Generates one period per experiment and axis, and the reference matrix per line.
    ///
    /// Errors: `ZeroCount` for no axis or no block, `AxisCountMismatch`,
    /// `InvalidAxisAmplitude`, `TooLong` and the band errors of [`band_lines`].
    pub fn generate(&self) -> Result<OrthogonalMultisine, ExcitationError> {
        self.check()?;
        let lines = band_lines(self.sample_rate_hz, self.period_samples, self.band_hz)?;
        let amplitudes_nm = self.line_amplitudes(lines.len());
        let phases_rad = self.draw_phases(lines.len());
        let signals = self.synthesize(&lines, &amplitudes_nm, &phases_rad)?;
        let references = reference_matrices(self.axes, &amplitudes_nm, &phases_rad);
        Ok(OrthogonalMultisine {
            sample_rate_hz: self.sample_rate_hz,
            axes: self.axes,
            blocks: self.blocks,
            excited_lines: lines,
            amplitudes_nm,
            phases_rad,
            signals,
            references,
        })
    }

    fn check(&self) -> Result<(), ExcitationError> {
        if self.axes == 0 {
            return Err(ExcitationError::ZeroCount { which: "axes" });
        }
        if self.blocks == 0 {
            return Err(ExcitationError::ZeroCount { which: "blocks" });
        }
        if self.rms_nm.len() != self.axes {
            return Err(ExcitationError::AxisCountMismatch {
                axes: self.axes,
                got: self.rms_nm.len(),
            });
        }
        if let Some((axis, &value_nm)) = self
            .rms_nm
            .iter()
            .enumerate()
            .find(|(_, v)| !(v.is_finite() && **v > 0.0))
        {
            return Err(ExcitationError::InvalidAxisAmplitude { axis, value_nm });
        }
        check_length(self.period_samples as f64 * self.experiments() as f64)
    }

    /// Cosine amplitude per line [N m] per axis: `rms * sqrt(2 / L)` over `L` lines.
    fn line_amplitudes(&self, lines: usize) -> Vec<f64> {
        let per_line = (2.0 / lines as f64).sqrt();
        self.rms_nm.iter().map(|r| r * per_line).collect()
    }

    /// Random phases \[rad\] `[block][axis][line]`, drawn in that order from one generator.
    fn draw_phases(&self, lines: usize) -> Vec<Vec<Vec<f64>>> {
        let mut rng = StdRng::seed_from_u64(self.seed);
        (0..self.blocks)
            .map(|_| {
                (0..self.axes)
                    .map(|_| random_phases(lines, &mut rng))
                    .collect()
            })
            .collect()
    }

    /// One period [N m] `[experiment][axis]`: each axis's block phases plus the DFT-matrix
    /// phase `2 pi n q / N` of experiment `q` of the block.
    fn synthesize(
        &self,
        lines: &[usize],
        amplitudes_nm: &[f64],
        phases_rad: &[Vec<Vec<f64>>],
    ) -> Result<Vec<Vec<Vec<f64>>>, ExcitationError> {
        let n_axes = self.axes;
        let mut synths: Vec<LineSynth> = amplitudes_nm
            .iter()
            .map(|&a| LineSynth::new(self.period_samples, lines, &vec![a; lines.len()]))
            .collect();
        let mut shifted = vec![0.0; lines.len()];
        let mut signals = Vec::with_capacity(self.experiments());
        for block in phases_rad {
            for q in 0..n_axes {
                let mut experiment = Vec::with_capacity(n_axes);
                for (n, (synth, base)) in synths.iter_mut().zip(block).enumerate() {
                    let w_phase = dft_matrix_phase(n, q, n_axes);
                    shifted
                        .iter_mut()
                        .zip(base)
                        .for_each(|(s, b)| *s = b + w_phase);
                    let mut period = vec![0.0; self.period_samples];
                    synth.synthesize(&shifted, &mut period)?;
                    experiment.push(period);
                }
                signals.push(experiment);
            }
        }
        Ok(signals)
    }
}

/// Phase \[rad\] of the DFT-matrix element `w_nq = exp(2 pi i n q / N)` (0-based indices).
fn dft_matrix_phase(n: usize, q: usize, axes: usize) -> f64 {
    2.0 * PI * ((n * q) % axes) as f64 / axes as f64
}

/// The `N x P` reference matrix per line: `R[n, bN + q] = A_n/2 e^{i(phi_bn + 2 pi n q/N)}`.
fn reference_matrices(
    axes: usize,
    amplitudes_nm: &[f64],
    phases_rad: &[Vec<Vec<f64>>],
) -> Vec<DMatrix<Complex64>> {
    let lines = phases_rad.first().map_or(0, |b| b[0].len());
    let experiments = phases_rad.len() * axes;
    (0..lines)
        .map(|j| {
            DMatrix::from_fn(axes, experiments, |n, p| {
                let (b, q) = (p / axes, p % axes);
                let phase = phases_rad[b][n][j] + dft_matrix_phase(n, q, axes);
                Complex64::from_polar(0.5 * amplitudes_nm[n], phase)
            })
        })
        .collect()
}

/// Orthogonal random-phase multisines: one period of torque [N m] per experiment and axis,
/// the excited lines and the reference matrix per line.
#[derive(Debug, Clone, PartialEq)]
pub struct OrthogonalMultisine {
    /// Sample rate \[Hz\].
    pub sample_rate_hz: f64,
    /// Number of axes `N`.
    pub axes: usize,
    /// Number of blocks of `N` experiments.
    pub blocks: usize,
    /// Excited DFT lines of the period (increasing, `1 <= k < period_samples / 2`).
    pub excited_lines: Vec<usize>,
    /// Cosine amplitude [N m] of every excited line, per axis.
    pub amplitudes_nm: Vec<f64>,
    /// The random phases \[rad\] `[block][axis][line]` before the DFT-matrix phase.
    pub phases_rad: Vec<Vec<Vec<f64>>>,
    /// One period of torque [N m] `[experiment][axis]`, experiment `p = b N + q`.
    pub signals: Vec<Vec<Vec<f64>>>,
    /// Reference matrix `R(w_k)` per excited line (same order as `excited_lines`), `N x P`
    /// phasors [N m] with the `1/period_samples` DFT scaling (see the module doc).
    pub references: Vec<DMatrix<Complex64>>,
}

impl OrthogonalMultisine {
    /// Number of experiments `P = blocks * axes`.
    pub fn experiments(&self) -> usize {
        self.signals.len()
    }

    /// Samples per period.
    pub fn period_samples(&self) -> usize {
        self.signals[0][0].len()
    }

    /// Line spacing `fs / period_samples` \[Hz\].
    pub fn line_spacing_hz(&self) -> f64 {
        self.sample_rate_hz / self.period_samples() as f64
    }

    /// Frequencies \[Hz\] of the excited lines.
    pub fn excited_frequencies_hz(&self) -> Vec<f64> {
        let df = self.line_spacing_hz();
        self.excited_lines.iter().map(|&k| k as f64 * df).collect()
    }

    /// One period [N m] of `axis` in `experiment` (panics on an index out of range, as
    /// slice indexing does).
    pub fn period(&self, experiment: usize, axis: usize) -> &[f64] {
        &self.signals[experiment][axis]
    }

    /// The period of `axis` in `experiment` repeated `total_periods` times [N m]
    /// (transient periods included).
    pub fn repeat(&self, experiment: usize, axis: usize, total_periods: usize) -> Vec<f64> {
        self.period(experiment, axis).repeat(total_periods)
    }

    /// Largest |torque| [N m] over the axes of `experiment`.
    pub fn peak_nm(&self, experiment: usize) -> f64 {
        self.signals[experiment]
            .iter()
            .map(|x| peak_abs(x))
            .fold(0.0, f64::max)
    }

    /// Largest RMS torque [N m] over the axes of `experiment`.
    pub fn rms_nm(&self, experiment: usize) -> f64 {
        self.signals[experiment]
            .iter()
            .map(|x| rms(x))
            .fold(0.0, f64::max)
    }

    /// Condition number (largest over smallest singular value) of the reference matrix at
    /// the excited line with index `line_index` into `excited_lines`; 1 for equal
    /// amplitudes on all axes.
    pub fn condition_number(&self, line_index: usize) -> f64 {
        let sv = self.references[line_index].clone().singular_values();
        sv.max() / sv.min()
    }

    /// Description of the recording of one experiment: `transient_periods + periods`
    /// repetitions of its period on every axis, the first `transient_periods` to be
    /// discarded. `peak_nm` and `rms_nm` are the largest over the axes.
    pub fn info(
        &self,
        experiment: usize,
        periods: usize,
        transient_periods: usize,
    ) -> ExcitationInfo {
        let band_hz = super::lines::band_of(&self.excited_lines, self.line_spacing_hz());
        ExcitationInfo {
            kind: ExcitationKind::Multisine,
            period_samples: self.period_samples(),
            periods,
            transient_periods,
            excited_lines: self.excited_lines.clone(),
            band_hz,
            peak_nm: Some(self.peak_nm(experiment)),
            rms_nm: Some(self.rms_nm(experiment)),
            design: Some(ORTHOGONAL_DESIGN_NAME.to_string()),
            blocks: Vec::new(),
            realisations: Vec::new(),
            band_limited: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dft_line(x: &[f64], k: usize) -> Complex64 {
        let n = x.len();
        x.iter()
            .enumerate()
            .map(|(t, &v)| Complex64::from_polar(v, -2.0 * PI * ((k * t) % n) as f64 / n as f64))
            .sum::<Complex64>()
            / n as f64
    }

    fn design(axes: usize, blocks: usize) -> OrthogonalMultisineDesign {
        let mut d = OrthogonalMultisineDesign::new(axes, 1000.0, 200, [10.0, 200.0], 1.5);
        d.blocks = blocks;
        d.seed = 17;
        d
    }

    #[test]
    fn signals_carry_the_reference_phasors_and_nothing_else() {
        let mut d = design(3, 2);
        d.rms_nm = vec![1.0, 2.0, 0.5];
        let ms = d.generate().unwrap();
        assert_eq!(ms.experiments(), 6);
        assert_eq!(ms.excited_lines, (2..=40).collect::<Vec<_>>());
        for p in 0..ms.experiments() {
            for n in 0..3 {
                let x = ms.period(p, n);
                assert_eq!(x.len(), 200);
                assert!((rms(x) - d.rms_nm[n]).abs() < 1e-12 * d.rms_nm[n]);
                for k in 0..=100 {
                    let got = dft_line(x, k);
                    let want = match ms.excited_lines.iter().position(|&l| l == k) {
                        Some(j) => ms.references[j][(n, p)],
                        None => Complex64::new(0.0, 0.0),
                    };
                    assert!((got - want).norm() < 1e-12, "p {p} n {n} k {k}");
                }
            }
        }
    }

    #[test]
    fn experiments_of_a_block_differ_by_the_dft_matrix() {
        let ms = design(3, 2).generate().unwrap();
        for (j, r) in ms.references.iter().enumerate() {
            for b in 0..2 {
                for n in 0..3 {
                    let first = r[(n, 3 * b)];
                    for q in 0..3 {
                        let w = Complex64::from_polar(1.0, 2.0 * PI * (n * q) as f64 / 3.0);
                        assert!((r[(n, 3 * b + q)] - first * w).norm() < 1e-12, "line {j}");
                    }
                }
            }
        }
        // each block draws its own phases
        assert!((ms.phases_rad[0][0][0] - ms.phases_rad[1][0][0]).abs() > 1e-6);
    }

    #[test]
    fn reference_is_perfectly_conditioned_for_equal_amplitudes() {
        for (axes, blocks) in [(1, 1), (2, 1), (3, 1), (3, 3), (6, 2)] {
            let ms = design(axes, blocks).generate().unwrap();
            for j in 0..ms.excited_lines.len() {
                let c = ms.condition_number(j);
                assert!((c - 1.0).abs() < 1e-10, "{axes} axes line {j}: {c}");
            }
        }
        // unequal amplitudes: max/min of the per-axis amplitudes, still full rank
        let mut d = design(3, 2);
        d.rms_nm = vec![1.0, 4.0, 2.0];
        let ms = d.generate().unwrap();
        for j in 0..ms.excited_lines.len() {
            assert!((ms.condition_number(j) - 4.0).abs() < 1e-9);
        }
    }

    #[test]
    fn same_seed_same_signals_other_seed_other_phases() {
        let a = design(2, 2).generate().unwrap();
        let b = design(2, 2).generate().unwrap();
        assert_eq!(a, b);
        let mut d = design(2, 2);
        d.seed = 18;
        let c = d.generate().unwrap();
        assert_ne!(a.phases_rad, c.phases_rad);
    }

    #[test]
    fn info_describes_one_experiment() {
        let ms = design(2, 1).generate().unwrap();
        let info = ms.info(1, 8, 2);
        assert_eq!(info.kind, ExcitationKind::Multisine);
        assert_eq!(info.period_samples, 200);
        assert_eq!((info.periods, info.transient_periods), (8, 2));
        assert_eq!(info.excited_lines, ms.excited_lines);
        assert_eq!(info.design.as_deref(), Some(ORTHOGONAL_DESIGN_NAME));
        assert_eq!(info.peak_nm, Some(ms.peak_nm(1)));
        assert_eq!(ms.repeat(1, 0, 3).len(), 600);
    }

    #[test]
    fn errors_not_panics() {
        let mut d = design(2, 1);
        d.axes = 0;
        d.rms_nm.clear();
        assert_eq!(
            d.generate(),
            Err(ExcitationError::ZeroCount { which: "axes" })
        );
        let mut d = design(2, 1);
        d.blocks = 0;
        assert_eq!(
            d.generate(),
            Err(ExcitationError::ZeroCount { which: "blocks" })
        );
        let mut d = design(2, 1);
        d.rms_nm = vec![1.0];
        assert_eq!(
            d.generate(),
            Err(ExcitationError::AxisCountMismatch { axes: 2, got: 1 })
        );
        let mut d = design(2, 1);
        d.rms_nm = vec![1.0, -1.0];
        assert_eq!(
            d.generate(),
            Err(ExcitationError::InvalidAxisAmplitude {
                axis: 1,
                value_nm: -1.0
            })
        );
        let mut d = design(2, 1);
        d.band_hz = [600.0, 700.0];
        assert!(matches!(
            d.generate(),
            Err(ExcitationError::BandAboveNyquist { .. })
        ));
    }
}
