//! Naive reference computations for the tests.

use std::f64::consts::PI;

/// Cosine amplitude `2 |X[k]| / N` and phase `arg X[k]` of lines `0 ..= N/2` of `x`, by the
/// O(N^2) DFT definition `X[k] = sum_n x[n] exp(-i 2 pi k n / N)`.
pub(crate) fn naive_line_spectrum(x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let n = x.len();
    let (c, s): (Vec<f64>, Vec<f64>) = (0..n)
        .map(|m| {
            let w = 2.0 * PI * m as f64 / n as f64;
            (w.cos(), w.sin())
        })
        .unzip();
    let mut amp = Vec::with_capacity(n / 2 + 1);
    let mut phase = Vec::with_capacity(n / 2 + 1);
    for k in 0..=n / 2 {
        let (mut re, mut im) = (0.0, 0.0);
        for (i, v) in x.iter().enumerate() {
            let m = (k * i) % n;
            re += v * c[m];
            im -= v * s[m];
        }
        amp.push(2.0 * (re * re + im * im).sqrt() / n as f64);
        phase.push(im.atan2(re));
    }
    (amp, phase)
}
