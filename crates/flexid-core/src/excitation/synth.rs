//! Line-spectrum synthesis of one period with real FFTs, and crest-factor reduction by
//! iterative clipping with re-imposed amplitudes.
//!
//! A period `x[n] = sum_j A_j cos(2 pi k_j n / N + phi_j)` is synthesised from the half
//! spectrum `X[k_j] = A_j / 2 * exp(i phi_j)` (zero elsewhere) by an unnormalised inverse
//! real FFT. All buffers are allocated once in [`LineSynth::new`].

use std::sync::Arc;

use num_complex::Complex64;
use realfft::{ComplexToReal, RealFftPlanner, RealToComplex};

use super::stats::{crest_factor, peak_abs};
use super::ExcitationError;

/// Clip level of the first crest-reduction iteration, relative to the current peak.
const CLIP_START: f64 = 0.8;
/// Clip level never goes above this fraction of the peak (too gentle to make progress).
const CLIP_MAX: f64 = 0.98;

fn fft_err(e: realfft::FftError) -> ExcitationError {
    ExcitationError::Fft {
        detail: e.to_string(),
    }
}

/// FFT plans, buffers and the target amplitude spectrum of one multisine period.
pub(crate) struct LineSynth {
    lines: Vec<usize>,
    /// Target |X[k]| = A / 2 per excited line (same order as `lines`).
    half_amps: Vec<f64>,
    r2c: Arc<dyn RealToComplex<f64>>,
    c2r: Arc<dyn ComplexToReal<f64>>,
    spec: Vec<Complex64>,
    scratch_fwd: Vec<Complex64>,
    scratch_inv: Vec<Complex64>,
}

impl LineSynth {
    /// Plans for a period of `n` samples exciting `lines` (each `1 <= k`, `2 k < n`) with
    /// cosine amplitudes `amps` (one per line).
    pub(crate) fn new(n: usize, lines: &[usize], amps: &[f64]) -> Self {
        let mut planner = RealFftPlanner::<f64>::new();
        let r2c = planner.plan_fft_forward(n);
        let c2r = planner.plan_fft_inverse(n);
        let spec = r2c.make_output_vec();
        let scratch_fwd = r2c.make_scratch_vec();
        let scratch_inv = c2r.make_scratch_vec();
        Self {
            lines: lines.to_vec(),
            half_amps: amps.iter().map(|a| 0.5 * a).collect(),
            r2c,
            c2r,
            spec,
            scratch_fwd,
            scratch_inv,
        }
    }

    /// Writes the period with the target amplitudes and `phases` \[rad\] (one per line) to `out`.
    pub(crate) fn synthesize(
        &mut self,
        phases: &[f64],
        out: &mut [f64],
    ) -> Result<(), ExcitationError> {
        self.spec
            .iter_mut()
            .for_each(|c| *c = Complex64::new(0.0, 0.0));
        for ((&k, &h), &phi) in self.lines.iter().zip(&self.half_amps).zip(phases) {
            self.spec[k] = Complex64::from_polar(h, phi);
        }
        self.c2r
            .process_with_scratch(&mut self.spec, out, &mut self.scratch_inv)
            .map_err(fft_err)
    }

    /// Replaces `x` by the period with the target amplitudes and the phases of `x` at the
    /// excited lines; all other lines are zeroed. Lines where `x` has no energy keep phase 0.
    pub(crate) fn reimpose(&mut self, x: &mut [f64]) -> Result<(), ExcitationError> {
        self.r2c
            .process_with_scratch(x, &mut self.spec, &mut self.scratch_fwd)
            .map_err(fft_err)?;
        let mut next = 0;
        for (k, c) in self.spec.iter_mut().enumerate() {
            if next < self.lines.len() && self.lines[next] == k {
                let phi = if c.norm() > 0.0 { c.arg() } else { 0.0 };
                *c = Complex64::from_polar(self.half_amps[next], phi);
                next += 1;
            } else {
                *c = Complex64::new(0.0, 0.0);
            }
        }
        self.c2r
            .process_with_scratch(&mut self.spec, x, &mut self.scratch_inv)
            .map_err(fft_err)
    }

    /// Phases \[rad\] of the excited lines of the cosine series of `x` (one per line).
    /// `x` is used as FFT scratch and left unspecified.
    pub(crate) fn line_phases(&mut self, x: &mut [f64]) -> Result<Vec<f64>, ExcitationError> {
        self.r2c
            .process_with_scratch(x, &mut self.spec, &mut self.scratch_fwd)
            .map_err(fft_err)?;
        Ok(self.lines.iter().map(|&k| self.spec[k].arg()).collect())
    }

    /// Crest-factor reduction of `x` (a period with the target amplitude spectrum), in place.
    ///
    /// Each iteration clips the current iterate at a fraction of its peak, then re-imposes
    /// the target amplitudes keeping the new phases. The clip fraction starts at 0.8 and
    /// moves towards 1 whenever an iteration fails to improve. The best iterate (lowest crest
    /// factor, the input included) is kept, so the crest factor never increases and the
    /// amplitude spectrum is always exactly the target one.
    /// Returns the final crest factor.
    pub(crate) fn reduce_crest(
        &mut self,
        x: &mut [f64],
        iterations: usize,
    ) -> Result<f64, ExcitationError> {
        let mut best_cf = crest_factor(x);
        if iterations == 0 {
            return Ok(best_cf);
        }
        let mut cur = x.to_vec();
        let mut alpha = CLIP_START;
        for _ in 0..iterations {
            let c = alpha * peak_abs(&cur);
            cur.iter_mut().for_each(|v| *v = v.clamp(-c, c));
            self.reimpose(&mut cur)?;
            let cf = crest_factor(&cur);
            if cf < best_cf {
                best_cf = cf;
                x.copy_from_slice(&cur);
            } else {
                alpha = (0.5 * (alpha + 1.0)).min(CLIP_MAX);
            }
        }
        Ok(best_cf)
    }
}
