//! Shared test helpers: a known resonant IIR system, multisines, naive DFT.

use num_complex::Complex64;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f64::consts::PI;

/// Second-order IIR `y[k] = b0 u[k] + b1 u[k-1] + b2 u[k-2] - a1 y[k-1] - a2 y[k-2]`.
#[derive(Debug, Clone, Copy)]
pub struct Biquad {
    pub b: [f64; 3],
    pub a: [f64; 3],
}

impl Biquad {
    /// Resonator with poles `r e^{+-j 2 pi f0/fs}`.
    pub fn resonator(r: f64, f0_over_fs: f64) -> Self {
        let th = 2.0 * PI * f0_over_fs;
        Biquad {
            b: [0.2, 0.1, -0.05],
            a: [1.0, -2.0 * r * th.cos(), r * r],
        }
    }

    /// Run the difference equation from rest.
    pub fn run(&self, u: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; u.len()];
        let (mut u1, mut u2, mut y1, mut y2) = (0.0, 0.0, 0.0, 0.0);
        for (k, &x) in u.iter().enumerate() {
            let v =
                self.b[0] * x + self.b[1] * u1 + self.b[2] * u2 - self.a[1] * y1 - self.a[2] * y2;
            y[k] = v;
            u2 = u1;
            u1 = x;
            y2 = y1;
            y1 = v;
        }
        y
    }

    /// Exact FRF at normalised frequency `f/fs`.
    pub fn frf(&self, f_over_fs: f64) -> Complex64 {
        let z1 = Complex64::from_polar(1.0, -2.0 * PI * f_over_fs);
        let z2 = z1 * z1;
        (self.b[0] + self.b[1] * z1 + self.b[2] * z2)
            / (self.a[0] + self.a[1] * z1 + self.a[2] * z2)
    }
}

/// One period of a random-phase multisine: unit-amplitude cosines on `lines`.
pub fn multisine_period(n: usize, lines: &[usize], rng: &mut StdRng) -> Vec<f64> {
    let phases: Vec<f64> = lines
        .iter()
        .map(|_| rng.random::<f64>() * 2.0 * PI)
        .collect();
    (0..n)
        .map(|i| {
            lines
                .iter()
                .zip(&phases)
                .map(|(&k, &ph)| (2.0 * PI * (k * i % n) as f64 / n as f64 + ph).cos())
                .sum()
        })
        .collect()
}

/// `periods` repetitions of `period`.
pub fn tile(period: &[f64], periods: usize) -> Vec<f64> {
    period
        .iter()
        .copied()
        .cycle()
        .take(period.len() * periods)
        .collect()
}

/// Naive O(N^2) DFT at line k (no scaling).
pub fn dft_line(x: &[f64], k: usize) -> Complex64 {
    let n = x.len();
    x.iter()
        .enumerate()
        .map(|(i, &v)| Complex64::from_polar(v, -2.0 * PI * ((k * i) % n) as f64 / n as f64))
        .sum()
}

pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

/// Standard normal samples.
pub fn gauss(rng: &mut StdRng, n: usize, sigma: f64) -> Vec<f64> {
    use rand_distr::{Distribution, StandardNormal};
    (0..n)
        .map(|_| {
            let z: f64 = StandardNormal.sample(rng);
            sigma * z
        })
        .collect()
}

pub fn rel_err(a: Complex64, b: Complex64) -> f64 {
    (a - b).norm() / b.norm().max(1e-300)
}
