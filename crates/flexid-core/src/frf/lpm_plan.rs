//! The local polynomial method planned for one input: [`LpmPlan`].
//!
//! Each line's LPM estimate is linear in the response's spectrum: in a window,
//! `θ = (KᴴK)⁻¹ Kᴴ Y`, and `G(k)` is `θ₀`, so `G(k) = Σᵢ wᵢ Y(k - n + i)` with weights
//! `wᵢ = Σⱼ [(KᴴK)⁻¹]₀ⱼ conj(Kᵢⱼ)` that depend on the input alone (the regressor `K` holds
//! the input's spectrum and the polynomial's powers). The diagnosis's search estimates the
//! simulated response of hundreds of candidates to the same recorded sweep: planned once,
//! each estimate is one FFT of the response and 15 complex products a line, where
//! [`super::estimate_lpm`] planned an FFT, transformed the input again and solved every
//! window's least squares (half of a swept sine's diagnosis). The response only: the
//! noise variance needs the residual, which a noise-free simulation does not have.

use super::error::FrfError;
use super::lpm::{window_centres, window_weights, HALF_WIDTH};
use super::types::FrfKind;
use num_complex::Complex64;
use realfft::RealToComplex;
use std::sync::Arc;

/// Lines of one window, `2 HALF_WIDTH + 1`.
const WIDTH: usize = 2 * HALF_WIDTH + 1;

/// The LPM of responses to one input `u`, planned: the lines [`super::estimate_lpm`] gives
/// for `u` (those whose window's least squares the input fixes) and each line's weights.
pub struct LpmPlan {
    fft: Arc<dyn RealToComplex<f64>>,
    len: usize,
    freq_hz: Vec<f64>,
    /// Per line, the first DFT line of its window and the window's weights (divided by
    /// the input's scale: `G = Σ w Y`).
    windows: Vec<(usize, [Complex64; WIDTH])>,
}

/// The buffers of [`LpmPlan::estimate_into`]: the response copied for the transform (which
/// overwrites its input), the spectrum and the transform's scratch.
#[derive(Default)]
pub struct LpmScratch {
    input: Vec<f64>,
    spectrum: Vec<Complex64>,
    fft: Vec<Complex64>,
}

impl std::fmt::Debug for LpmPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LpmPlan")
            .field("len", &self.len)
            .field("lines", &self.freq_hz.len())
            .finish()
    }
}

impl LpmPlan {
    /// The plan for input `u` [N m] at `sample_rate_hz`, the response of `kind`, on the
    /// lines whose window centre lies in `band_hz` (as [`super::estimate_lpm`]).
    ///
    /// Errors: as [`super::estimate_lpm`] (`TooShort`, `InvalidParameter`,
    /// `NoExcitedLines`).
    pub fn new(
        u: &[f64],
        sample_rate_hz: f64,
        kind: FrfKind,
        band_hz: Option<[f64; 2]>,
    ) -> Result<Self, FrfError> {
        super::error::check_fs(sample_rate_hz)?;
        let n = u.len();
        if n / 2 < WIDTH + 1 {
            return Err(FrfError::TooShort {
                needed: 2 * (WIDTH + 1),
                got: n,
                unit: "samples",
            });
        }
        let fft = super::plan_cache::forward(n);
        let mut input = u.to_vec();
        let mut su = fft.make_output_vec();
        fft.process(&mut input, &mut su)
            .expect("buffer lengths from the plan");
        let df = sample_rate_hz / n as f64;
        let (mut freq_hz, mut windows) = (Vec::new(), Vec::new());
        for (k, f) in window_centres(su.len(), df, band_hz.unwrap_or([df, sample_rate_hz / 2.0])) {
            if let Some(w) = window_weights(&su[k - HALF_WIDTH..=k + HALF_WIDTH], k, kind) {
                freq_hz.push(f);
                windows.push((k - HALF_WIDTH, w));
            }
        }
        if windows.is_empty() {
            return Err(FrfError::NoExcitedLines);
        }
        Ok(LpmPlan {
            fft,
            len: n,
            freq_hz,
            windows,
        })
    }

    /// The lines' frequencies [Hz].
    pub fn freq_hz(&self) -> &[f64] {
        &self.freq_hz
    }

    /// The LPM estimate `G` of the response `y` (as many samples as the input; of the
    /// plan's kind) on every line, into `out`, with `scratch`'s buffers (sized on first
    /// use, then nothing allocated). `y` of another length is an error.
    pub fn estimate_into(
        &self,
        y: &[f64],
        scratch: &mut LpmScratch,
        out: &mut Vec<Complex64>,
    ) -> Result<(), FrfError> {
        if y.len() != self.len {
            return Err(FrfError::LengthMismatch {
                u: self.len,
                y: y.len(),
            });
        }
        scratch.input.clear();
        scratch.input.extend_from_slice(y);
        scratch
            .spectrum
            .resize(self.len / 2 + 1, Complex64::new(0.0, 0.0));
        scratch
            .fft
            .resize(self.fft.get_scratch_len(), Complex64::new(0.0, 0.0));
        self.fft
            .process_with_scratch(&mut scratch.input, &mut scratch.spectrum, &mut scratch.fft)
            .expect("buffer lengths from the plan");
        out.clear();
        out.extend(self.windows.iter().map(|(first, w)| {
            w.iter()
                .zip(&scratch.spectrum[*first..*first + WIDTH])
                .map(|(w, y)| w * y)
                .sum::<Complex64>()
        }));
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::excitation::ChirpDesign;
    use crate::frf::estimate_lpm;
    use crate::frf::test_rng::lcg;

    /// A log sweep through a damped resonance, with noise: the response of any signal.
    fn sweep_and_response(fs: f64, secs: f64) -> (Vec<f64>, Vec<f64>) {
        let mut c = ChirpDesign::new(fs, 2.0, 0.4 * fs, secs, 1.0);
        c.taper_s = 0.05 * secs;
        let u = c.generate().unwrap().signal;
        let (w0, zeta, dt) = (2.0 * std::f64::consts::PI * 37.0, 0.03, 1.0 / fs);
        let mut state = 7u64;
        let (mut x, mut v) = (0.0, 0.0);
        let y = u
            .iter()
            .map(|&f| {
                let a = f - 2.0 * zeta * w0 * v - w0 * w0 * x;
                v += a * dt;
                x += v * dt;
                v + 1e-4 * (lcg(&mut state) - 0.5)
            })
            .collect();
        (u, y)
    }

    /// Planned, the estimate is the full LPM's on every line (the same lines, the same
    /// values to rounding: the weights are the solve's operations in another order, whose
    /// last bits the window's normal matrix amplifies; measured 1e-9 relative at worst),
    /// for each kind's asymptote, in a band and over all lines.
    #[test]
    fn the_planned_estimate_is_the_lpm_s() {
        let fs = 1000.0;
        let (u, y) = sweep_and_response(fs, 6.0);
        for (kind, band) in [
            (FrfKind::Velocity, None),
            (FrfKind::DifferencedVelocity, Some([5.0, 300.0])),
            (FrfKind::Position, Some([3.0, 200.0])),
            (FrfKind::Other, None),
        ] {
            let want = estimate_lpm(&u, &y, fs, kind, band).unwrap();
            let plan = LpmPlan::new(&u, fs, kind, band).unwrap();
            assert_eq!(plan.freq_hz(), &want.freq_hz[..], "{kind:?}");
            let (mut scratch, mut got) = (LpmScratch::default(), Vec::new());
            // twice with the same buffers: nothing left over from the first
            for _ in 0..2 {
                plan.estimate_into(&y, &mut scratch, &mut got).unwrap();
                let worst = got
                    .iter()
                    .zip(&want.h)
                    .map(|(g, w)| (g - w).norm() / w.norm())
                    .fold(0.0, f64::max);
                println!("{kind:?}: worst relative difference {worst:.1e}");
                assert!(worst <= 1e-8, "{kind:?}: {worst}");
            }
            assert_eq!(got.len(), want.h.len());
        }
    }

    #[test]
    fn bad_inputs_are_errors() {
        let (u, y) = sweep_and_response(1000.0, 2.0);
        assert!(matches!(
            LpmPlan::new(&u[..20], 1000.0, FrfKind::Velocity, None),
            Err(FrfError::TooShort { .. })
        ));
        assert!(LpmPlan::new(&u, 0.0, FrfKind::Velocity, None).is_err());
        assert!(matches!(
            LpmPlan::new(&u, 1000.0, FrfKind::Velocity, Some([600.0, 900.0])),
            Err(FrfError::NoExcitedLines)
        ));
        let plan = LpmPlan::new(&u, 1000.0, FrfKind::Velocity, None).unwrap();
        let mut out = Vec::new();
        assert!(matches!(
            plan.estimate_into(&y[1..], &mut LpmScratch::default(), &mut out),
            Err(FrfError::LengthMismatch { .. })
        ));
    }
}
