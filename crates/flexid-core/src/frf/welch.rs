//! Welch-averaged H1 estimator (with coherence) for arbitrary excitation: swept sines,
//! noise, or anything not periodic in the record.
//!
//! Each segment of `nperseg` samples (successive segments `nperseg - overlap` apart) has its
//! mean removed (like scipy's `detrend='constant'`), is windowed and transformed with one
//! real FFT per signal; the auto and cross spectra are accumulated in one fused pass:
//!
//! * `H1(k) = S_yu(k) / S_uu(k)` with `S_yu = sum_i Y_i conj(U_i)`,
//! * `gamma^2(k) = |S_yu|^2 / (S_uu S_yy)`,
//! * `var H1(k) = |H1|^2 (1 - gamma^2) / (n_eff gamma^2)` (Bendat & Piersol).
//!
//! The variance is that of the *complex* estimate, `E|H1_est - H|^2`, as [`Frf::var`]
//! defines it: Bendat & Piersol give `|H|^2 (1-g^2)/(2 n g^2)` for the variance of the
//! magnitude and `(1-g^2)/(2 n g^2)` for that of the phase [rad^2]; the complex variance is
//! their sum, `|H|^2 (1-g^2)/(n g^2)`.
//!
//! `n_eff` is the *effective* number of averages: overlapped segments are correlated. For
//! (locally) white signals the correlation of the products between segments `j` apart is
//! `rho_j^2` with `rho_j = sum_n w[n] w[n + j s] / sum_n w[n]^2` (`s` the step), so
//! `n_eff = n / (1 + 2 sum_{j=1}^{n-1} (1 - j/n) rho_j^2)`. For Hann at 50 % overlap
//! (`rho_1 = 1/6`) this is about `0.95 n`; without overlap `n_eff = n`.

use super::error::{check_fs, FrfError};
use super::types::{Frf, FrfKind};
use num_complex::Complex64;
use realfft::{RealFftPlanner, RealToComplex};
use std::f64::consts::PI;
use std::sync::Arc;

/// Segment window.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Window {
    /// Periodic ("DFT-even") Hann, `w[n] = 0.5 - 0.5 cos(2 pi n / N)`, as scipy's
    /// `get_window('hann', N)` used by `scipy.signal.welch`/`csd`.
    #[default]
    Hann,
    /// No window (all ones). Only sensible for signals periodic in the segment.
    Rectangular,
}

impl Window {
    /// The `n` window coefficients.
    pub fn coefficients(self, n: usize) -> Vec<f64> {
        match self {
            Window::Hann => (0..n)
                .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / n as f64).cos())
                .collect(),
            Window::Rectangular => vec![1.0; n],
        }
    }
}

/// Everything needed to process one segment (kept apart from the tails so that a segment
/// can be read from the tail while the engine is borrowed mutably).
struct Engine {
    window: Vec<f64>,
    fft: Arc<dyn RealToComplex<f64>>,
    in_u: Vec<f64>,
    in_y: Vec<f64>,
    spec_u: Vec<Complex64>,
    spec_y: Vec<Complex64>,
    scratch: Vec<Complex64>,
    suu: Vec<f64>,
    syy: Vec<f64>,
    syu: Vec<Complex64>,
    segments: usize,
}

/// Copy `a ++ b` into `buf`, remove its mean and apply the window, in place.
/// The mean is summed over `buf` (not over `a`, `b`) so the result does not depend on how
/// the segment was split between the tail and the new chunk.
#[inline]
fn load_detrend_window(a: &[f64], b: &[f64], window: &[f64], buf: &mut [f64]) {
    let (ba, bb) = buf.split_at_mut(a.len());
    ba.copy_from_slice(a);
    bb.copy_from_slice(b);
    // four partial sums: breaks the add-latency chain, lets the compiler vectorise
    let mut acc = [0.0_f64; 4];
    let mut chunks = buf.chunks_exact(4);
    for c in &mut chunks {
        acc[0] += c[0];
        acc[1] += c[1];
        acc[2] += c[2];
        acc[3] += c[3];
    }
    let mut sum = (acc[0] + acc[1]) + (acc[2] + acc[3]);
    for &x in chunks.remainder() {
        sum += x;
    }
    let mean = sum / buf.len() as f64;
    for (x, &w) in buf.iter_mut().zip(window) {
        *x = (*x - mean) * w;
    }
}

impl Engine {
    fn segment(&mut self, u: (&[f64], &[f64]), y: (&[f64], &[f64])) {
        load_detrend_window(u.0, u.1, &self.window, &mut self.in_u);
        load_detrend_window(y.0, y.1, &self.window, &mut self.in_y);
        self.fft
            .process_with_scratch(&mut self.in_u, &mut self.spec_u, &mut self.scratch)
            .expect("buffer lengths fixed at construction");
        self.fft
            .process_with_scratch(&mut self.in_y, &mut self.spec_y, &mut self.scratch)
            .expect("buffer lengths fixed at construction");
        for ((((suu, syy), syu), u), y) in self
            .suu
            .iter_mut()
            .zip(self.syy.iter_mut())
            .zip(self.syu.iter_mut())
            .zip(&self.spec_u)
            .zip(&self.spec_y)
        {
            *suu += u.re * u.re + u.im * u.im;
            *syy += y.re * y.re + y.im * y.im;
            // Y conj(U)
            syu.re += y.re * u.re + y.im * u.im;
            syu.im += y.im * u.re - y.re * u.im;
        }
        self.segments += 1;
    }
}

/// Streaming Welch H1 estimator with coherence.
///
/// Feed input/output chunks of any length with [`push`](Self::push); every complete
/// segment is processed at once and only the samples of the next, incomplete segment are
/// kept. The FFT plan and every buffer are allocated by the constructor; `push` does not
/// allocate.
pub struct WelchH1 {
    nperseg: usize,
    step: usize,
    fs: f64,
    kind: FrfKind,
    engine: Engine,
    /// Samples from the start of the next segment on (always fewer than `nperseg`).
    tail_u: Vec<f64>,
    tail_y: Vec<f64>,
    samples: usize,
    /// `rho_j^2` for segments `j = 1, 2, ...` apart while they overlap.
    rho2: Vec<f64>,
}

impl std::fmt::Debug for WelchH1 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WelchH1")
            .field("nperseg", &self.nperseg)
            .field("step", &self.step)
            .field("sample_rate_hz", &self.fs)
            .field("kind", &self.kind)
            .field("segments", &self.engine.segments)
            .field("samples", &self.samples)
            .finish_non_exhaustive()
    }
}

impl WelchH1 {
    /// Plan an estimator with segments of `nperseg` samples overlapping by
    /// `overlap_samples` (`< nperseg`; `nperseg / 2` is the usual choice for Hann), at
    /// sample rate `fs` \[Hz\]. The FRF kind defaults to [`FrfKind::Other`]; set it with
    /// [`with_kind`](Self::with_kind).
    ///
    /// Errors: `InvalidParameter` for `nperseg < 4`, `overlap_samples >= nperseg` or a bad
    /// sample rate.
    pub fn new(
        nperseg: usize,
        overlap_samples: usize,
        window: Window,
        fs: f64,
    ) -> Result<Self, FrfError> {
        check_fs(fs)?;
        if nperseg < 4 {
            return Err(FrfError::invalid(
                "nperseg",
                format!("must be at least 4, got {nperseg}"),
            ));
        }
        if overlap_samples >= nperseg {
            return Err(FrfError::invalid(
                "overlap_samples",
                format!("must be less than nperseg = {nperseg}, got {overlap_samples}"),
            ));
        }
        let step = nperseg - overlap_samples;
        let w = window.coefficients(nperseg);
        let w2: f64 = w.iter().map(|x| x * x).sum();
        let rho2 = (1..)
            .map(|j| j * step)
            .take_while(|&s| s < nperseg)
            .map(|s| {
                let r: f64 = (0..nperseg - s).map(|n| w[n] * w[n + s]).sum::<f64>() / w2;
                r * r
            })
            .collect();
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(nperseg);
        let nl = nperseg / 2 + 1;
        let engine = Engine {
            window: w,
            in_u: fft.make_input_vec(),
            in_y: fft.make_input_vec(),
            spec_u: fft.make_output_vec(),
            spec_y: fft.make_output_vec(),
            scratch: fft.make_scratch_vec(),
            fft,
            suu: vec![0.0; nl],
            syy: vec![0.0; nl],
            syu: vec![Complex64::new(0.0, 0.0); nl],
            segments: 0,
        };
        Ok(Self {
            nperseg,
            step,
            fs,
            kind: FrfKind::Other,
            engine,
            tail_u: Vec::with_capacity(nperseg),
            tail_y: Vec::with_capacity(nperseg),
            samples: 0,
            rho2,
        })
    }

    /// Set the kind recorded in the estimated [`Frf`].
    pub fn with_kind(mut self, kind: FrfKind) -> Self {
        self.kind = kind;
        self
    }

    /// Segment length \[samples\].
    pub fn nperseg(&self) -> usize {
        self.nperseg
    }

    /// Number of segments averaged so far.
    pub fn segments(&self) -> usize {
        self.engine.segments
    }

    /// Number of sample pairs pushed so far.
    pub fn samples(&self) -> usize {
        self.samples
    }

    /// Effective number of independent averages for the current segment count (see the
    /// module documentation).
    pub fn effective_averages(&self) -> f64 {
        let n = self.engine.segments;
        if n == 0 {
            return 0.0;
        }
        let nf = n as f64;
        let corr: f64 = self
            .rho2
            .iter()
            .enumerate()
            .take(n - 1)
            .map(|(i, r2)| (1.0 - (i + 1) as f64 / nf) * r2)
            .sum();
        nf / (1.0 + 2.0 * corr)
    }

    /// Forget all data (keeps the plan and settings).
    pub fn reset(&mut self) {
        let e = &mut self.engine;
        e.suu.fill(0.0);
        e.syy.fill(0.0);
        e.syu.fill(Complex64::new(0.0, 0.0));
        e.segments = 0;
        self.tail_u.clear();
        self.tail_y.clear();
        self.samples = 0;
    }

    /// Feed a chunk of input `u` and output `y` (equal lengths, any length). Every segment
    /// completed by the chunk is processed; the chunk is read in place (no copy of the
    /// chunk beyond the remainder kept for the next segment). Does not allocate.
    pub fn push(&mut self, u: &[f64], y: &[f64]) -> Result<(), FrfError> {
        if u.len() != y.len() {
            return Err(FrfError::LengthMismatch {
                u: u.len(),
                y: y.len(),
            });
        }
        let n = self.nperseg;
        let t = self.tail_u.len();
        let m = u.len();
        // Segments start at offsets s of the virtual concatenation tail ++ chunk.
        let mut s = 0;
        while s + n <= t + m {
            if s < t {
                let rest = n - (t - s);
                self.engine.segment(
                    (&self.tail_u[s..], &u[..rest]),
                    (&self.tail_y[s..], &y[..rest]),
                );
            } else {
                let a = s - t;
                self.engine
                    .segment((&[], &u[a..a + n]), (&[], &y[a..a + n]));
            }
            s += self.step;
        }
        if s < t {
            self.tail_u.copy_within(s.., 0);
            self.tail_y.copy_within(s.., 0);
            self.tail_u.truncate(t - s);
            self.tail_y.truncate(t - s);
            self.tail_u.extend_from_slice(u);
            self.tail_y.extend_from_slice(y);
        } else {
            self.tail_u.clear();
            self.tail_y.clear();
            self.tail_u.extend_from_slice(&u[s - t..]);
            self.tail_y.extend_from_slice(&y[s - t..]);
        }
        self.samples += m;
        Ok(())
    }

    /// H1 estimate at lines `1..=nperseg/2` (`k * fs / nperseg` Hz) with coherence and the
    /// variance `|H1|^2 (1 - g^2) / (n_eff g^2)` (written as
    /// `(S_yy - |S_yu|^2/S_uu) / (n_eff S_uu)` so that zero coherence gives a finite
    /// value); `INFINITY` with fewer than 2 segments or where `S_uu = 0`.
    ///
    /// Errors: `TooShort` before the first complete segment.
    pub fn estimate(&self) -> Result<Frf, FrfError> {
        let e = &self.engine;
        if e.segments == 0 {
            return Err(FrfError::TooShort {
                needed: self.nperseg,
                got: self.samples,
                unit: "samples",
            });
        }
        let n_eff = self.effective_averages();
        let nl = self.nperseg / 2;
        let df = self.fs / self.nperseg as f64;
        let mut frf = Frf {
            freq_hz: (1..=nl).map(|k| k as f64 * df).collect(),
            h: Vec::with_capacity(nl),
            var: Vec::with_capacity(nl),
            coherence: Some(Vec::with_capacity(nl)),
            kind: self.kind,
            sample_rate_hz: self.fs,
        };
        let coh = frf.coherence.as_mut().expect("just set");
        for k in 1..=nl {
            let (suu, syy, syu) = (e.suu[k], e.syy[k], e.syu[k]);
            let h = syu / suu;
            let g = syu.norm_sqr() / (suu * syy);
            let g = if g.is_finite() {
                g.clamp(0.0, 1.0)
            } else {
                0.0
            };
            let var = if e.segments < 2 || suu <= 0.0 {
                f64::INFINITY
            } else {
                ((syy - syu.norm_sqr() / suu) / (n_eff * suu)).max(0.0)
            };
            frf.h.push(h);
            frf.var.push(var);
            coh.push(g);
        }
        Ok(frf)
    }
}

/// Batch Welch H1 with a Hann window: segments of `nperseg` samples overlapping by
/// `overlap` samples, at sample rate `fs` \[Hz\]; kind [`FrfKind::Other`] (set `kind` on the
/// result). Equal to streaming the same samples through [`WelchH1`].
///
/// Errors: `LengthMismatch`, `InvalidParameter`, `TooShort` (fewer than `nperseg` samples).
pub fn welch_h1(
    u: &[f64],
    y: &[f64],
    fs: f64,
    nperseg: usize,
    overlap: usize,
) -> Result<Frf, FrfError> {
    if u.len() != y.len() {
        return Err(FrfError::LengthMismatch {
            u: u.len(),
            y: y.len(),
        });
    }
    let mut w = WelchH1::new(nperseg, overlap, Window::Hann, fs)?;
    w.push(u, y)?;
    w.estimate()
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::frf::testutil::*;
    use rand::Rng;

    /// Allocation-heavy reference: slice every segment, remove the mean, window with the
    /// Hann formula, direct DFT, sum; n_eff by a double sum over segment pairs.
    fn naive(
        u: &[f64],
        y: &[f64],
        nperseg: usize,
        overlap: usize,
    ) -> (Vec<Complex64>, Vec<f64>, Vec<f64>) {
        let step = nperseg - overlap;
        let w: Vec<f64> = (0..nperseg)
            .map(|i| (PI * i as f64 / nperseg as f64).sin().powi(2))
            .collect();
        let starts: Vec<usize> = (0..)
            .map(|i| i * step)
            .take_while(|s| s + nperseg <= u.len())
            .collect();
        let nl = nperseg / 2;
        let mut suu = vec![0.0; nl + 1];
        let mut syy = vec![0.0; nl + 1];
        let mut syu = vec![Complex64::new(0.0, 0.0); nl + 1];
        for &s in &starts {
            let prep = |x: &[f64]| -> Vec<f64> {
                let seg = &x[s..s + nperseg];
                let m = seg.iter().sum::<f64>() / nperseg as f64;
                seg.iter().zip(&w).map(|(v, w)| (v - m) * w).collect()
            };
            let (su, sy) = (prep(u), prep(y));
            for k in 0..=nl {
                let (uk, yk) = (dft_line(&su, k), dft_line(&sy, k));
                suu[k] += uk.norm_sqr();
                syy[k] += yk.norm_sqr();
                syu[k] += yk * uk.conj();
            }
        }
        let n = starts.len();
        let w2: f64 = w.iter().map(|x| x * x).sum();
        let mut denom = 0.0;
        for i in 0..n {
            for j in 0..n {
                let lag = i.abs_diff(j) * step;
                if lag < nperseg {
                    let r: f64 = (0..nperseg - lag).map(|t| w[t] * w[t + lag]).sum::<f64>() / w2;
                    denom += r * r;
                }
            }
        }
        let n_eff = (n * n) as f64 / denom;
        let mut h = vec![];
        let mut coh = vec![];
        let mut var = vec![];
        for k in 1..=nl {
            let hk = syu[k] / suu[k];
            let g = syu[k].norm_sqr() / (suu[k] * syy[k]);
            h.push(hk);
            coh.push(g);
            var.push(hk.norm_sqr() * (1.0 - g) / (n_eff * g));
        }
        (h, coh, var)
    }

    fn noisy_system(seed: u64, len: usize, noise: f64) -> (Vec<f64>, Vec<f64>, Biquad) {
        let mut r = rng(seed);
        let sys = Biquad::resonator(0.95, 0.1);
        let u = gauss(&mut r, len + 500, 1.0);
        let mut y = sys.run(&u);
        for (x, e) in y.iter_mut().zip(gauss(&mut r, len + 500, noise)) {
            *x += e;
        }
        // drop the start-up transient
        (u[500..].to_vec(), y[500..].to_vec(), sys)
    }

    #[test]
    fn fast_equals_naive_reference() {
        for &(nperseg, overlap) in &[(48, 20), (64, 32), (50, 0)] {
            let (mut u, mut y, _) = noisy_system(10, 700, 0.05);
            u.iter_mut().for_each(|x| *x += 3.0);
            y.iter_mut().for_each(|x| *x -= 1.5);
            let frf = welch_h1(&u, &y, 200.0, nperseg, overlap).unwrap();
            let (h, coh, var) = naive(&u, &y, nperseg, overlap);
            assert_eq!(frf.len(), nperseg / 2);
            let c = frf.coherence.as_ref().unwrap();
            for i in 0..frf.len() {
                assert!((frf.freq_hz[i] - (i + 1) as f64 * 200.0 / nperseg as f64).abs() < 1e-12);
                assert!(rel_err(frf.h[i], h[i]) < 1e-9, "{nperseg} line {}", i + 1);
                assert!((c[i] - coh[i]).abs() < 1e-9);
                assert!(
                    (frf.var[i] - var[i]).abs() <= 1e-8 * var[i],
                    "{} {}",
                    frf.var[i],
                    var[i]
                );
            }
        }
    }

    #[test]
    fn streaming_random_chunks_equals_batch() {
        let (u, y, _) = noisy_system(11, 5000, 0.1);
        let batch = welch_h1(&u, &y, 1000.0, 128, 64).unwrap();
        let mut r = rng(12);
        for trial in 0..20 {
            let mut w = WelchH1::new(128, 64, Window::Hann, 1000.0).unwrap();
            let mut pos = 0;
            while pos < u.len() {
                let c = r
                    .random_range(0..=(if trial % 2 == 0 { 9 } else { 700 }))
                    .min(u.len() - pos);
                w.push(&u[pos..pos + c], &y[pos..pos + c]).unwrap();
                pos += c;
            }
            assert_eq!(w.segments(), (5000 - 128) / 64 + 1);
            assert_eq!(w.estimate().unwrap(), batch);
        }
    }

    #[test]
    fn h1_of_white_noise_through_resonator() {
        let nperseg = 1024;
        let (u, y, sys) = noisy_system(13, 1 << 17, 0.0);
        let frf = welch_h1(&u, &y, 1.0, nperseg, nperseg / 2).unwrap();
        let c = frf.coherence.clone().unwrap();
        let mut worst = 0.0_f64;
        for i in 0..frf.len() {
            let exact = sys.frf(frf.freq_hz[i]);
            assert!(
                c[i] > 0.99,
                "noise-free coherence {} at {}",
                c[i],
                frf.freq_hz[i]
            );
            worst = worst.max(rel_err(frf.h[i], exact));
        }
        assert!(worst < 0.03, "worst relative error {worst}");

        // with output noise: coherence follows |H|^2 s_u^2 / (|H|^2 s_u^2 + s_n^2) and drops
        // where the noise dominates; the estimate stays close where coherence is high
        let sn = 0.3;
        let (u, y, _) = noisy_system(14, 1 << 17, sn);
        let frf = welch_h1(&u, &y, 1.0, nperseg, nperseg / 2).unwrap();
        let c = frf.coherence.clone().unwrap();
        let (mut low, mut high) = (0, 0);
        let n_avg = (1usize << 17) / (nperseg / 2) - 1;
        let mut dev = 0.0;
        for i in 0..frf.len() {
            let exact = sys.frf(frf.freq_hz[i]);
            let snr = exact.norm_sqr() / (sn * sn);
            let theory = snr / (1.0 + snr);
            // std of the coherence estimate ~ sqrt(2) g (1 - g^2) / sqrt(n)
            let sd = 2f64.sqrt() * theory.sqrt() * (1.0 - theory) / (n_avg as f64).sqrt();
            assert!(
                (c[i] - theory).abs() < 5.0 * sd + 0.01,
                "coherence {} vs {theory}",
                c[i]
            );
            dev += (c[i] - theory).abs() / frf.len() as f64;
            if theory < 0.3 {
                low += 1;
                assert!(c[i] < 0.4);
            }
            if c[i] > 0.95 {
                high += 1;
                assert!(rel_err(frf.h[i], exact) < 0.05);
            }
        }
        assert!(low > 50 && high > 10, "{low} {high}");
        assert!(dev < 0.02, "mean |coherence - theory| = {dev}");
    }

    #[test]
    fn reported_variance_matches_scatter() {
        let (nperseg, len, reals) = (256, 1 << 14, 100);
        let sys = Biquad::resonator(0.95, 0.1);
        let nl = nperseg / 2;
        let mut emp = vec![0.0; nl];
        let mut rep = vec![0.0; nl];
        let mut w = WelchH1::new(nperseg, nperseg / 2, Window::Hann, 1.0).unwrap();
        for s in 0..reals {
            let (u, y, _) = noisy_system(100 + s, len, 0.2);
            w.reset();
            w.push(&u, &y).unwrap();
            let frf = w.estimate().unwrap();
            for i in 0..nl {
                emp[i] += (frf.h[i] - sys.frf(frf.freq_hz[i])).norm_sqr() / reals as f64;
                rep[i] += frf.var[i] / reals as f64;
            }
        }
        let mut ratios: Vec<f64> = (0..nl).map(|i| (emp[i] / rep[i]).sqrt()).collect();
        ratios.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let med = ratios[nl / 2];
        assert!((0.85..1.15).contains(&med), "median std ratio {med}");
        assert!(
            ratios[nl / 10] > 0.75 && ratios[9 * nl / 10] < 1.25,
            "{:?}",
            (ratios[nl / 10], ratios[9 * nl / 10])
        );
    }

    #[test]
    fn errors_not_panics() {
        assert_eq!(
            welch_h1(&[0.0; 10], &[0.0; 11], 1.0, 8, 4),
            Err(FrfError::LengthMismatch { u: 10, y: 11 })
        );
        assert_eq!(
            welch_h1(&[0.0; 10], &[0.0; 10], 1.0, 16, 8),
            Err(FrfError::TooShort {
                needed: 16,
                got: 10,
                unit: "samples"
            })
        );
        assert!(matches!(
            welch_h1(&[0.0; 10], &[0.0; 10], 1.0, 8, 8),
            Err(FrfError::InvalidParameter { .. })
        ));
        assert!(matches!(
            WelchH1::new(2, 0, Window::Hann, 1.0),
            Err(FrfError::InvalidParameter { .. })
        ));
        assert!(matches!(
            WelchH1::new(8, 0, Window::Hann, 0.0),
            Err(FrfError::InvalidParameter { .. })
        ));
        let mut w = WelchH1::new(8, 4, Window::Rectangular, 1.0).unwrap();
        assert!(w.push(&[1.0], &[]).is_err());
        assert!(w.estimate().is_err());
    }

    /// Throughput of H1 + coherence; run with
    /// `cargo test --release --lib frf::welch -- --ignored --nocapture`.
    #[test]
    #[ignore]
    fn throughput() {
        let len = 1 << 22;
        let (u, y, _) = noisy_system(20, len, 0.1);
        for &nperseg in &[256usize, 1024, 4096] {
            let t = std::time::Instant::now();
            let mut reps = 0;
            while t.elapsed().as_secs_f64() < 1.0 {
                let frf = welch_h1(&u, &y, 1.0, nperseg, nperseg / 2).unwrap();
                std::hint::black_box(frf);
                reps += 1;
            }
            let dt = t.elapsed().as_secs_f64() / reps as f64;
            println!(
                "welch_h1 nperseg={nperseg} overlap=50%: {:.1} Msamples/s ({:.2} ms per {len} samples)",
                len as f64 / dt / 1e6,
                dt * 1e3
            );
        }
    }
}
