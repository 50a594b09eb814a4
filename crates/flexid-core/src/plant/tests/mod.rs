//! Tests of the plant: each effect's physical signature against an independent small
//! computation, the linear limit against the exact ZOH simulation, and the plant files.

mod effects;
mod files;
mod friction;
mod linear;

use super::*;
use crate::model::Chain;
use std::f64::consts::PI;

pub(super) fn chain2() -> Chain {
    Chain::new(vec![2e-3, 6e-3], vec![8000.0], vec![0.5]).unwrap()
}

pub(super) fn chain3() -> Chain {
    Chain::new(vec![2e-3, 4e-3, 9e-3], vec![600.0, 9000.0], vec![0.05, 0.3]).unwrap()
}

/// `periods` periods of a `p`-sample multisine of unit-amplitude cosines at `lines`.
pub(super) fn multisine(p: usize, lines: &[usize], periods: usize) -> Vec<f64> {
    let period: Vec<f64> = (0..p)
        .map(|k| {
            lines
                .iter()
                .map(|&l| (2.0 * PI * (l * k) as f64 / p as f64 + l as f64).cos())
                .sum()
        })
        .collect();
    (0..periods).flat_map(|_| period.iter().copied()).collect()
}

/// `max |a - b| / max |b|`.
pub(super) fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    a.iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()))
        / scale
}

/// DFT coefficient of `x` at `cycles` cycles over its length.
pub(super) fn dft(x: &[f64], cycles: f64) -> crate::Complex64 {
    let n = x.len() as f64;
    x.iter()
        .enumerate()
        .map(|(k, &v)| v * crate::Complex64::from_polar(1.0, -2.0 * PI * cycles * k as f64 / n))
        .sum()
}
